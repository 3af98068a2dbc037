"""``serve --ros``: the live demo following a ROS 1 run (a real roscore, the simulator as a
robot), its sets holding the published truth; and the options it refuses, one line each, exit 2.

The graph test needs Debian's ROS 1 (``.ci/run`` installs it); without it that test is skipped
saying so (in CI, ``TILEVIZ_REQUIRE_ROS=1``, it fails instead)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tileviz.testing.ros import free_port, ros_missing, roscore

_WHY = ros_missing()
if _WHY is not None and os.environ.get("TILEVIZ_REQUIRE_ROS"):  # CI (.ci/run): never a skip
    raise RuntimeError(f"TILEVIZ_REQUIRE_ROS is set but ROS 1 cannot run: {_WHY}")
needs_ros = pytest.mark.skipif(_WHY is not None, reason=f"ROS 1 is not installed: {_WHY}")

FRAMES = 40


def _serve(*argv: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tileviz", "serve", *argv], env=env,
                          capture_output=True, text=True, timeout=300)


@needs_ros
def test_serve_follows_a_ros_run_with_the_truth_inside(tmp_path: Path) -> None:
    """The page's loop takes the simulator's frames off the topics: every one of them is
    processed (the simulator waits for the viewer's subscription), contracted, and its set holds
    the true pose published on /truth."""
    with roscore(tmp_path) as graph:
        sim = graph.start("sim", "ros-sim", "--frames", str(FRAMES + 20), "--rate", "1",
                          "--subscribers", "1", "--wait", "300", "--linger", "3")
        serve = graph.start("serve", "serve", "--ros", "--frames", str(FRAMES), "--port", "0",
                            "--no-display", f"--out-dir={tmp_path / 'runs'}")
        assert serve.wait(600) == 0, graph.log("serve")
        assert sim.wait(300) == 0, graph.log("sim")
    log = graph.log("serve")
    assert "following the ROS run on /camera/image, /odom, /imu" in log
    summary = next(line for line in log.splitlines() if " frames in " in line)
    assert summary.startswith(f"tileviz serve: {FRAMES} frames in "), summary
    statuses = dict((k, int(n)) for n, k in re.findall(r"(\d+) (contracted|predicted|lost)",
                                                       summary.split("statuses: ")[1]))
    assert statuses.get("contracted", 0) >= FRAMES - 2 and "lost" not in statuses, summary
    assert f"truth inside the set in 100.0 % of the {FRAMES} frames" in summary, summary


@needs_ros
def test_serve_ros_without_a_master_is_one_line(tmp_path: Path) -> None:
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}",
               ROS_HOME=str(tmp_path))
    r = _serve("--ros", "--port", "0", env=env)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines()[-1].startswith("tileviz serve: error: no ROS master")
    assert "Traceback" not in r.stderr


def test_serve_ros_with_a_dataset_is_one_line(tmp_path: Path) -> None:
    r = _serve("--ros", "--dataset", str(tmp_path))
    assert r.returncode == 2
    assert r.stderr == ("tileviz serve: error: --ros cannot be used with --dataset (one run at "
                        "a time)\n")
    r = _serve("--ros", "--tile-size", "0.3")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--tile-size cannot" in r.stderr


def test_serve_ros_without_ros_names_the_install(monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str],
                                                 tmp_path: Path) -> None:
    import tileviz.ros
    from tileviz.app import serve_cli

    monkeypatch.setitem(sys.modules, "rospy", None)  # import rospy raises ImportError
    monkeypatch.setattr(tileviz.ros, "SYSTEM_DIST_PACKAGES", tmp_path / "none")
    assert serve_cli.main("serve", ["--ros", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("tileviz serve: error: ROS 1 (rospy) is not installed: apt-get "
                          "install -y ros-core python3-rospy")


def test_serve_foxglove_on_a_busy_port_is_one_line() -> None:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        r = _serve("--foxglove", str(port), "--frames", "1", "--port", "0")
    assert r.returncode == 2
    assert r.stderr.splitlines()[-1].startswith(
        f"tileviz serve: error: --foxglove: cannot serve on 127.0.0.1:{port}"), r.stderr
    assert "Traceback" not in r.stderr
