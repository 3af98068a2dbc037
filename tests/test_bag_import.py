"""record -> ROS bag (ROS 2 sqlite3 / MCAP, ROS 1) -> import-bag -> replay: the truth stays in
every set, boxes no wider than the original's plus the import's documented widening; bad bags
are one line and keep the frames written before the problem."""

from __future__ import annotations

import csv
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the [ros] extra (pip install -e '.[ros]')")

from tileviz.__main__ import main as tileviz_main  # noqa: E402
from tileviz.datasets import DatasetSource, read_meta  # noqa: E402
from tileviz.datasets.bag_import import combine_compass, combine_odometry  # noqa: E402
from tileviz.datasets.sample import write_bag  # noqa: E402


def _rows(path: Path) -> list[list[str]]:
    with open(path, newline="") as f:
        return list(csv.reader(f))[1:]


@pytest.fixture(scope="module")
def original(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[list[str]]]:
    folder = tmp_path_factory.mktemp("orig") / "ds"
    assert tileviz_main(["record", str(folder), "--duration", "3", "--quiet", "--seed",
                         "4"]) == 0
    # the baseline: the original replayed with the settings an imported dataset gets (a bag
    # carries no tileviz configuration, so the general vision bounds rather than the preset's)
    plain = folder.parent / "plain"
    shutil.copytree(folder, plain)
    meta = json.loads((plain / "meta.json").read_text())
    del meta["tileviz_config"]
    (plain / "meta.json").write_text(json.dumps(meta))
    out = folder.parent / "replay.csv"
    assert tileviz_main(["replay", str(plain), "--out", str(out), "--quiet", "--jobs",
                         "1"]) == 0
    return folder, _rows(out)


def _import_args(ds: Path, bag: Path, out: Path, *extra: str) -> list[str]:
    meta = read_meta(ds)
    return ["import-bag", str(bag), str(out), "--image-topic", "/camera/image",
            "--odom-topic", "/odom", "--imu-topic", "/imu", "--tile-size", "1", "--ppm", "200",
            "--camera-offset", "0.3,0", "--speed-error", "0.02", "--yaw-rate-error", "0.01",
            "--compass-error", "0.02",
            "--start-pose", ",".join(repr(v) for v in meta.initial_pose),
            "--start-error", ",".join(repr(v) for v in meta.initial_pose_error), *extra]


def _check_replay(ds: Path, imported: Path, original_rows: list[list[str]],
                  slack: float) -> None:
    out = imported.parent / (imported.name + ".csv")
    assert tileviz_main(["replay", str(imported), "--out", str(out), "--quiet"]) == 0
    rows = _rows(out)
    truths = _rows(ds / "frames.csv")
    assert len(rows) == len(original_rows) == len(truths)
    for r, o, t in zip(rows, original_rows, truths, strict=True):
        assert r[2] in ("contracted", "predicted", "rejected")
        x, y, th = (float(v) for v in t[6:9])
        lo = [float(v) for v in r[3:9]]
        th += 2 * math.pi * round(((lo[4] + lo[5]) / 2 - th) / (2 * math.pi))
        assert lo[0] <= x <= lo[1] and lo[2] <= y <= lo[3] and lo[4] <= th <= lo[5]
        ol = [float(v) for v in o[3:9]]
        for i in (0, 2, 4):
            assert lo[i + 1] - lo[i] <= ol[i + 1] - ol[i] + slack


@pytest.mark.parametrize("kind", ["ros2-sqlite3", "ros2-mcap-compressed", "ros1"])
def test_round_trip_through_a_bag(original: tuple[Path, list[list[str]]], tmp_path: Path,
                                  kind: str) -> None:
    """Messages stamped at the images: no widening, so the boxes are the original's (up to the
    nanosecond rounding of the stamps)."""
    ds, orig_rows = original
    bag = write_bag(ds, tmp_path / "bag", ros1=kind == "ros1",
                    storage="mcap" if "mcap" in kind else "sqlite3",
                    compressed="compressed" in kind)
    out = tmp_path / "imported"
    assert tileviz_main(_import_args(ds, bag, out)) == 0
    meta = read_meta(out)
    assert meta.extra["import_widening"] == {"speed": 0.0, "yaw_rate": 0.0, "compass": 0.0}
    a = list(DatasetSource(ds))
    b = list(DatasetSource(out))
    assert all(np.array_equal(x.image, y.image) for x, y in zip(a, b, strict=True))
    _check_replay(ds, out, orig_rows, slack=1e-6)


def test_asynchronous_messages_widen_the_bounds(original: tuple[Path, list[list[str]]],
                                                tmp_path: Path) -> None:
    """Odometry three times a frame, the IMU twice a frame a third of a frame late: the compass
    bound grows by the largest half-arc between two IMU messages around an image; the truth stays
    inside every set."""
    ds, orig_rows = original
    bag = write_bag(ds, tmp_path / "bag", odom_rate=3, imu_rate=2, imu_offset=0.3)
    out = tmp_path / "imported"
    assert tileviz_main(_import_args(ds, bag, out)) == 0
    meta = read_meta(out)
    w = meta.extra["import_widening"]
    assert w["compass"] > 0 and meta.compass_error == pytest.approx(0.02 + w["compass"])
    comp = [float(r[5]) for r in _rows(ds / "frames.csv")]
    d = [math.remainder(b - a, 2 * math.pi) for a, b in zip(comp, comp[1:], strict=False)]
    # around image k: the IMU messages at 0.65 of frame k-1 and at 0.15 of frame k
    half_arcs = [0.5 * abs(math.remainder(comp[k] + 0.15 * d[k] - comp[k - 1] - 0.65 * d[k - 1],
                                          2 * math.pi)) for k in range(1, len(comp) - 1)]
    assert w["compass"] == pytest.approx(max(half_arcs), rel=1e-6)
    imported = _rows(out / "frames.csv")
    assert imported[0][5] == imported[-1][5] == ""  # no IMU message before / after them
    # the wider compass bound may widen theta by twice its growth (both sides)
    _check_replay(ds, out, orig_rows, slack=1e-6 + 2 * w["compass"] + 0.05)


def test_combine_odometry_and_compass() -> None:
    t = np.array([0.0, 0.1, 0.2, 0.3])
    v = np.array([1.0, 1.4, 0.8, 2.0])
    assert combine_odometry(t, v, 0.05, 0.25) == pytest.approx((1.1, 0.3))  # 1.0, 1.4, 0.8
    assert combine_odometry(t, v, 0.1, 0.2) == pytest.approx((1.4, 0.0))
    assert combine_odometry(t, v, -1.0, 0.0) is None
    yaws = np.array([3.1, -3.1, 0.0])
    mid, half = combine_compass(np.array([0.0, 1.0, 2.0]), yaws, 0.5)
    assert abs(math.remainder(mid - math.pi, 2 * math.pi)) < 1e-12
    assert half == pytest.approx(0.5 * (2 * math.pi - 6.2))
    assert combine_compass(np.array([0.0, 1.0]), yaws[:2], 1.0) == (-3.1, 0.0)
    assert combine_compass(np.array([0.0, 1.0]), yaws[:2], 1.5) is None


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tileviz", *args], capture_output=True,
                          text=True, timeout=300)


def test_bad_bags_are_one_line(original: tuple[Path, list[list[str]]], tmp_path: Path) -> None:
    ds, _ = original
    bag = write_bag(ds, tmp_path / "bag")
    args = _import_args(ds, bag, tmp_path / "o1")
    args[args.index("/imu")] = "/gyro"
    r = _cli(*args)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "no topic '/gyro' (--imu-topic); its topics: /camera/image (sensor_msgs/msg/Image)" \
        in r.stderr and "/odom (nav_msgs/msg/Odometry)" in r.stderr
    args = _import_args(ds, bag, tmp_path / "o2")
    args[args.index("/odom")] = "/imu"
    r = _cli(*args)
    assert r.returncode == 2 and "topic '/imu' is sensor_msgs/msg/Imu, --odom-topic needs " \
        "nav_msgs/msg/Odometry" in r.stderr
    r = _cli(*_import_args(ds, tmp_path / "nothing", tmp_path / "o3"))
    assert r.returncode == 2 and "no such bag" in r.stderr


def test_a_truncated_bag_keeps_the_frames_before_it(original: tuple[Path, list[list[str]]],
                                                    tmp_path: Path) -> None:
    """A ROS 2 MCAP recording cut short: the frames before the cut are imported and replay; a
    ROS 1 bag without its index: one line."""
    ds, _ = original
    bag = write_bag(ds, tmp_path / "b", storage="mcap")
    (mcap,) = bag.glob("*.mcap")
    raw = mcap.read_bytes()
    mcap.write_bytes(raw[: len(raw) * 2 // 3])
    out = tmp_path / "o"
    r = _cli(*_import_args(ds, bag, out))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "truncated or damaged after" in lines[0] and "frame(s) before it were written" \
        in lines[0]
    n = len(_rows(out / "frames.csv"))
    assert 10 < n < 61
    assert tileviz_main(["replay", str(out), "--out", str(tmp_path / "r.csv"), "--quiet"]) == 0
    assert len(_rows(tmp_path / "r.csv")) == n
    bag1 = write_bag(ds, tmp_path / "b1", ros1=True)
    cut = tmp_path / "cut.bag"
    raw = bag1.read_bytes()
    cut.write_bytes(raw[: len(raw) * 2 // 3])
    r = _cli(*_import_args(ds, cut, tmp_path / "o1"))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "not a readable ROS bag" in lines[0]
    assert "Traceback" not in r.stderr


def test_time_going_backwards_and_no_images(original: tuple[Path, list[list[str]]],
                                            tmp_path: Path) -> None:
    ds, _ = original
    # image 8 stamped before image 7 (the bag's own times in order)
    bag = write_bag(ds, tmp_path / "bag", stamp_shift={8: -0.06})
    out = tmp_path / "o"
    r = _cli(*_import_args(ds, bag, out))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "time goes backwards on '/camera/image' at message 8" in r.stderr
    # the frames before it were written and replay
    assert len(_rows(out / "frames.csv")) == 8
    assert tileviz_main(["replay", str(out), "--out", str(tmp_path / "r.csv"), "--quiet"]) == 0
    json.loads((out / "meta.json").read_text())
    # a bag whose image topic has no message
    empty = write_bag(ds, tmp_path / "empty", image_limit=0)
    r = _cli(*_import_args(ds, empty, tmp_path / "o2"))
    assert r.returncode == 2 and "no images on '/camera/image'" in r.stderr


def test_a_real_camera_through_a_bag(tmp_path: Path) -> None:
    """record --lens -> ROS 2 bag of the raw images -> import-bag --camera-model (the recording's
    meta.json: its block and view) -> replay: rectified, the truth inside every set. A file with
    the block alone (calibrate's output) gives a view of the raw size."""
    ds = tmp_path / "lens"
    assert tileviz_main(["record", str(ds), "--duration", "2", "--quiet", "--seed", "6",
                         "--lens", "webcam"]) == 0
    orig = tmp_path / "orig.csv"
    assert tileviz_main(["replay", str(ds), "--out", str(orig), "--quiet"]) == 0
    bag = write_bag(ds, tmp_path / "bag", storage="mcap")
    out = tmp_path / "imported"
    assert tileviz_main(_import_args(ds, bag, out, "--camera-model", str(ds / "meta.json"))) == 0
    meta = read_meta(out)
    assert meta.camera_model == read_meta(ds).camera_model
    assert (meta.image_width, meta.image_height) == (320, 240)
    plain = tmp_path / "plain"
    shutil.copytree(ds, plain)
    doc = json.loads((plain / "meta.json").read_text())
    del doc["tileviz_config"]  # the settings an imported dataset gets
    (plain / "meta.json").write_text(json.dumps(doc))
    base = tmp_path / "plain.csv"
    assert tileviz_main(["replay", str(plain), "--out", str(base), "--quiet"]) == 0
    _check_replay(ds, out, _rows(base), slack=1e-6)
    block = tmp_path / "cam.json"
    block.write_text(json.dumps({"camera_model": doc["camera_model"]}))
    out2 = tmp_path / "imported2"
    assert tileviz_main(_import_args(ds, bag, out2, "--camera-model", str(block))) == 0
    assert (read_meta(out2).image_width, read_meta(out2).image_height) == (640, 480)
    frame = next(iter(DatasetSource(out2)))
    assert frame.image.shape == (480, 640)  # the rectified gray view vision reads
