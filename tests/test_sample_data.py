"""``python -m tileviz sample-data DIR``: the commands it prints work as printed, end to end
(calibrate the sample camera, import the sample bag, replay it with the truth inside every set);
without the ros extra the board images are written and one line says what the bag needs."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from tileviz.testing.extras import WITHOUT_ROS as BLOCK


def _shell(line: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run a printed ``python -m tileviz ...`` line in bash (its glob expanded) with this
    Python."""
    assert line.startswith("python -m tileviz "), line
    return subprocess.run(["bash", "-c", f"{sys.executable}{line[len('python'):]}"], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def _commands(stdout: str) -> list[str]:
    lines = stdout.splitlines()
    assert lines[1] == "next:", stdout
    return [line.strip() for line in lines[2:]]


def test_the_printed_commands_calibrate_import_and_replay_the_sample(tmp_path: Path) -> None:
    pytest.importorskip("rosbags", reason="the [ros] extra (pip install -e '.[ros]')")
    r = subprocess.run([sys.executable, "-m", "tileviz", "sample-data", "sample"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[0] == ("wrote 6 checkerboard images to sample/board, a 41-frame "
                                        "ROS 1 bag sample/run.bag (true poses in "
                                        "sample/truth.csv)")
    calibrate, import_bag, replay = _commands(r.stdout)
    assert calibrate.startswith("python -m tileviz calibrate sample/board/*.png ")
    c = _shell(calibrate, tmp_path)
    assert c.returncode == 0, c.stderr
    mm = float(c.stdout.splitlines()[1].split(",")[1].split()[0])
    assert mm < 1.0  # the floor fit, mm RMS
    assert list(json.loads((tmp_path / "sample" / "camera.json").read_text())) == ["camera_model"]
    i = _shell(import_bag, tmp_path)
    assert i.returncode == 0, i.stderr
    assert i.stdout.startswith("imported 41 frames into sample/robot")
    s = _shell(replay, tmp_path)
    assert s.returncode == 0, s.stderr
    assert s.stdout.startswith("replayed 41 frames; statuses: ")
    # every set holds the true pose (the bag's world frame is the simulator's: the start is
    # within half a tile of the grout crossing at the origin)
    o = _shell(f"{replay} --out boxes.csv --quiet", tmp_path)
    assert o.returncode == 0, o.stderr
    with open(tmp_path / "boxes.csv", newline="") as f:
        boxes = list(csv.DictReader(f))
    with open(tmp_path / "sample" / "truth.csv", newline="") as f:
        truth = list(csv.DictReader(f))
    assert len(boxes) == len(truth) == 41
    assert sum(b["status"] == "contracted" for b in boxes) >= 30
    for b, t in zip(boxes, truth, strict=True):
        x, y, th = float(t["x"]), float(t["y"]), float(t["theta"])
        lo, hi = float(b["theta_lo"]), float(b["theta_hi"])
        th += 2 * math.pi * round(((lo + hi) / 2 - th) / (2 * math.pi))
        assert float(b["x_lo"]) <= x <= float(b["x_hi"]), (b, t)
        assert float(b["y_lo"]) <= y <= float(b["y_hi"]), (b, t)
        assert lo <= th <= hi, (b, t)


def test_without_the_ros_extra_the_images_are_written_and_one_line_says_why_no_bag(
        tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, "-c", BLOCK, "sample-data", "s"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "wrote 6 checkerboard images to s/board"
    assert lines[1] == "the sample bag needs the rosbags package: pip install -e '.[ros]'"
    assert len(list((tmp_path / "s" / "board").glob("*.png"))) == 6
    assert not (tmp_path / "s" / "run.bag").exists()
    (calibrate,) = _commands("\n".join(lines[1:]))
    c = _shell(calibrate, tmp_path)
    assert c.returncode == 0, c.stderr


def test_a_file_in_the_way_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "taken").write_text("a file\n")
    r = subprocess.run([sys.executable, "-m", "tileviz", "sample-data", "taken"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=600)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and lines == ["tileviz sample-data: error: taken: exists and is not "
                                           "a folder"]
