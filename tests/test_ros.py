"""The ROS 1 graph against a real roscore (started on a free port and stopped here): the
simulator as a robot, the live localizer node and ``rosbag record``; statuses over a run with a
camera dropout and a kidnap; the recorded bag through import-bag and replay gives the very sets
the live node published; SIGINT stops every node cleanly.

Needs Debian's ROS 1 (``.ci/run`` installs it); without rospy or roscore the module is skipped
saying so (in CI, ``TILEVIZ_REQUIRE_ROS=1``, it fails instead)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tileviz.testing.ros import RosGraph, ros_missing, roscore

_WHY = ros_missing()
if _WHY is not None and os.environ.get("TILEVIZ_REQUIRE_ROS"):  # CI (.ci/run): never a skip
    raise RuntimeError(f"TILEVIZ_REQUIRE_ROS is set but ROS 1 cannot run: {_WHY}")
pytestmark = pytest.mark.skipif(_WHY is not None, reason=f"ROS 1 is not installed: {_WHY}")

FRAMES = 90
DROPOUT_AT, DROPOUT_FRAMES = 30, 8
KIDNAP_AT = 60


def _wait_for(graph: RosGraph, name: str, text: str, proc: subprocess.Popen[bytes],
              timeout: float = 300) -> None:
    end = time.monotonic() + timeout
    while text not in graph.log(name):
        if time.monotonic() > end or proc.poll() is not None:
            raise AssertionError(f"{name} never said {text!r}: {graph.log(name)[-800:]}")
        time.sleep(0.2)


def _statuses(bag: Path) -> list[dict]:
    from rosbags.highlevel import AnyReader

    out = []
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == "/tileviz/status"]
        for conn, _, raw in reader.messages(connections=conns):
            out.append(json.loads(reader.deserialize(raw, conn.msgtype).data))
    return out


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> dict:
    tmp = tmp_path_factory.mktemp("ros")
    bag = tmp / "run.bag"
    with roscore(tmp) as graph:
        sim = graph.start(
            "sim", "ros-sim", "--frames", str(FRAMES), "--rate", "0.5", "--subscribers", "2",
            "--linger", "3", "--inject",
            f'{DROPOUT_AT}:{{"kind": "dropout", "frames": {DROPOUT_FRAMES}}}',
            "--inject", f'{KIDNAP_AT}:{{"kind": "kidnap", "x": 0.61, "y": -0.37, "theta": 2.2}}')
        node = graph.start("node", "ros", "_meta_param:=/tileviz_sim/meta",
                           "_max_pending:=100000")
        _wait_for(graph, "node", "tileviz: ready", node)
        rec = graph.start("record", "rosbag", "record", "-O", str(bag), "/camera/image", "/odom",
                          "/imu", "/truth", "/tileviz/status", python=False)
        assert sim.wait(600) == 0, graph.log("sim")
        # the node says so once it has processed every image and waited a second
        _wait_for(graph, "node", "for over 1 s", node)
        time.sleep(2)  # rosbag writes the last statuses
        record_rc = graph.stop(rec)
        node_rc = graph.stop(node)
        alive = [graph.group_alive(p) for p in (node, rec, sim)]
        node_log = graph.log("node")
    return {"tmp": tmp, "bag": bag, "node_rc": node_rc, "record_rc": record_rc,
            "alive": alive, "node_log": node_log}


def test_node_statuses_follow_the_run(run: dict) -> None:
    """contracted on a clear view, predicted while the camera is dark, lost after a kidnap;
    every frame processed, none dropped."""
    st = [s for s in _statuses(run["bag"]) if not s.get("stale")]
    assert [s["index"] for s in st] == list(range(FRAMES)), run["node_log"][-2000:]
    by = {s["index"]: s["status"] for s in st}
    assert by[DROPOUT_AT - 2] == "contracted"
    dark = [by[k] for k in range(DROPOUT_AT + 1, DROPOUT_AT + DROPOUT_FRAMES)]
    assert set(dark) == {"predicted"}, dark
    assert by[DROPOUT_AT + DROPOUT_FRAMES + 6] == "contracted"
    assert by[FRAMES - 1] == "lost"
    assert "lost" not in {by[k] for k in range(KIDNAP_AT)}
    last = st[-1]["counts"]
    assert last["dropped_behind"] == 0 and last["late"] == 0 and last["frames"] == FRAMES
    assert last["images"] == FRAMES


def test_shutdown_on_sigint_is_clean(run: dict) -> None:
    assert run["node_rc"] == 0, run["node_log"][-1500:]
    assert "Traceback" not in run["node_log"]
    assert run["alive"] == [False, False, False]


def test_replay_of_the_recorded_bag_gives_the_live_sets(run: dict) -> None:
    """rosbag record -> import-bag -> replay: every box of every frame equal to the live
    node's."""
    from tileviz.config import preset
    from tileviz.pipeline.replay import replay
    from tileviz.ros.sim_node import sim_meta

    meta = sim_meta(preset("default"))  # what ros-sim publishes without options
    out = run["tmp"] / "imported"
    arg = [sys.executable, "-m", "tileviz", "import-bag", str(run["bag"]), str(out),
           "--image-topic", "/camera/image", "--odom-topic", "/odom", "--imu-topic", "/imu",
           "--tile-size", repr(meta["tile_size"]), "--ppm", repr(meta["ppm"]),
           "--camera-offset", ",".join(map(repr, meta["camera_offset"])),
           "--speed-error", repr(meta["speed_error"]),
           "--yaw-rate-error", repr(meta["yaw_rate_error"]),
           "--compass-error", repr(meta["compass_error"]),
           "--start-pose", ",".join(map(repr, meta["initial_pose"])),
           "--start-error", ",".join(map(repr, meta["initial_pose_error"]))]
    done = subprocess.run(arg, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "bounds widened by 0 m/s, 0 rad/s, 0 rad" in done.stdout
    sets: dict[int, list[list[float]]] = {}
    statuses: dict[int, str] = {}

    def keep(rec: object) -> None:
        sets[rec.index] = [list(b.as_tuple()) for b in rec.updated.boxes]  # type: ignore[attr-defined]
        statuses[rec.index] = rec.status  # type: ignore[attr-defined]

    assert replay(out, jobs=1, on_frame=keep) == FRAMES
    live = {s["index"]: s for s in _statuses(run["bag"]) if not s.get("stale")}
    assert sorted(live) == sorted(sets)
    for k in sorted(sets):
        assert live[k]["set"] == sets[k], f"frame {k}"
        assert live[k]["status"] == statuses[k], f"frame {k}"
