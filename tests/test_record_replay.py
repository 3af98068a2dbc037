"""record -> replay: a replay gives the very sets of the live run; CLI errors are one line."""

from __future__ import annotations

import csv
import itertools
import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from tileviz.__main__ import main as tileviz_main
from tileviz.config import preset
from tileviz.datasets import DatasetMeta, DatasetWriter, dataset_mb
from tileviz.pipeline import FrameLoop
from tileviz.pipeline.outputs import REPLAY_COLUMNS, RESIDUAL_COLUMNS, replay_row
from tileviz.sim.source import SimSource
from tileviz.summary import FAITHFUL_NOTE

FRAMES = 60


def _small_cfg():
    cfg = preset("default")
    return replace(cfg, sim=replace(cfg.sim, seed=7))


def _read_csv(path: Path) -> list[list[str]]:
    with open(path, newline="") as f:
        return list(csv.reader(f))


@pytest.fixture(scope="module")
def live_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[list[str]]]:
    """Simulate FRAMES frames, localize them live and record them as a dataset."""
    cfg = _small_cfg()
    folder = tmp_path_factory.mktemp("rec") / "ds"
    runner = FrameLoop(cfg)
    rows = []
    with DatasetWriter(folder, DatasetMeta.from_config(cfg)) as writer:
        for frame in itertools.islice(SimSource(cfg), FRAMES):
            writer.write(frame)
            rows.append([str(v) for v in replay_row(runner.process(frame))])
    return folder, rows


@pytest.mark.parametrize("jobs", ["1", "2", "default"])
def test_replay_reproduces_live_sets(live_run: tuple[Path, list[list[str]]],
                                     tmp_path: Path, jobs: str,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    """The same sets as the live run, with vision in this process or in worker processes (2, or
    the default: one per core); the progress bar knows the frame count."""
    folder, live_rows = live_run
    out = tmp_path / "result.csv"
    eq = tmp_path / "eq.csv"
    flags = ["--quiet", "--jobs", jobs] if jobs != "default" else []
    code = tileviz_main(["replay", str(folder), "--mode", "autonomous", "--out", str(out),
                         "--output-file", str(eq), *flags])
    assert code == 0
    printed = capsys.readouterr()
    if jobs == "default":
        assert f"{FRAMES}/{FRAMES}" in printed.err
    rows = _read_csv(out)
    assert tuple(rows[0]) == REPLAY_COLUMNS
    assert rows[1:] == live_rows
    # the localizer localized: most frames contracted, and the truth is inside every vouched set
    statuses = [r[2] for r in rows[1:]]
    assert statuses.count("contracted") > FRAMES // 2
    # one summary line: frames, statuses as written, median set, containment (the truth is known)
    summary = printed.out.strip().splitlines()[-1]
    assert f"replayed {FRAMES} frames" in summary
    assert f"{statuses.count('contracted')} contracted" in summary and "median set" in summary
    vouched = sum(1 for r in rows[1:] if r[2] != "lost")
    assert f"truth inside the set in 100.0 % of the {vouched} frames" in summary
    eq_rows = _read_csv(eq)
    assert tuple(eq_rows[0]) == RESIDUAL_COLUMNS and len(eq_rows) == FRAMES + 1


def test_replay_modes_and_truth_inside(live_run: tuple[Path, list[list[str]]],
                                       tmp_path: Path) -> None:
    folder, _ = live_run
    truths = _read_csv(folder / "frames.csv")[1:]
    widths = {}
    for mode in ("autonomous", "truth", "odometry"):
        out = tmp_path / f"{mode}.csv"
        assert tileviz_main(["replay", str(folder), "--mode", mode, "--out", str(out),
                             "--quiet"]) == 0
        rows = _read_csv(out)[1:]
        assert len(rows) == FRAMES
        for row, truth in zip(rows, truths, strict=True):
            if row[2] == "lost":
                continue
            x, y = float(truth[6]), float(truth[7])
            assert float(row[3]) <= x <= float(row[4]) and float(row[5]) <= y <= float(row[6])
        widths[mode] = float(rows[-1][4]) - float(rows[-1][3])
        if mode == "odometry":
            assert {r[2] for r in rows} == {"predicted"}
    # prediction alone grows; the view keeps the set small
    assert widths["odometry"] > widths["autonomous"]


def test_record_cli_writes_a_dataset_and_says_its_size(tmp_path: Path) -> None:
    out = tmp_path / "rec"
    r = _cli("record", str(out), "--duration", "0.5", "--quiet", "--seed", "3")
    assert r.returncode == 0, r.stderr
    mb = dataset_mb(out)
    assert mb > 11 * 0.05  # eleven 320x240 colour images
    assert r.stdout.strip() == f"wrote 11 frames ({mb:.1f} MB) to {out}"
    meta = json.loads((out / "meta.json").read_text())
    assert meta["format"] == "tileviz-dataset/1"
    rows = _read_csv(out / "frames.csv")
    assert rows[0] == ["index", "t", "image", "speed", "yaw_rate", "compass", "x", "y", "theta"]
    assert len(rows) == 1 + 11
    assert all((out / r[2]).is_file() for r in rows[1:])


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tileviz", *args], capture_output=True,
                          text=True, timeout=600)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["replay", "nowhere", "--out", "x.csv"], "nowhere: no such directory"),
        (["replay", "notes.txt", "--out", "x.csv"], "notes.txt: not a directory"),
        (["replay", "nowhere", "--mode", "fly", "--out", "x.csv"], "invalid choice"),
        (["record", "x", "--duration", "-1"], "--duration must be a finite number > 0"),
        (["record", "x", "--duration", "1", "--ppm", "nan"], "--ppm must be a finite number"),
        (["record", "x", "--duration", "1", "--png-level", "10"], "--png-level: invalid choice"),
        (["frobnicate"], "unknown command"),
    ],
)
def test_cli_errors_are_one_line(args: list[str], needle: str, tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("a file, not a dataset folder\n")
    r = subprocess.run([sys.executable, "-m", "tileviz", *args], capture_output=True, text=True,
                       timeout=600, cwd=tmp_path)
    assert r.returncode != 0
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], r.stderr
    assert "Traceback" not in r.stderr


def test_replay_without_out_prints_the_summary_alone(live_run: tuple[Path, list[list[str]]],
                                                     tmp_path: Path) -> None:
    folder, _ = live_run
    r = subprocess.run([sys.executable, "-m", "tileviz", "replay", str(folder), "--quiet",
                        "--jobs", "1"], capture_output=True, text=True, timeout=600,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"replayed {FRAMES} frames; statuses: ")
    assert "truth inside the set in 100.0 %" in lines[0]
    assert list(tmp_path.iterdir()) == []  # no CSV anywhere


@pytest.mark.parametrize("extractor", ["faithful", "robust"])
def test_the_faithful_summary_says_its_views_break_their_bounds(
        live_run: tuple[Path, list[list[str]]], tmp_path: Path, extractor: str) -> None:
    folder, _ = live_run
    r = _cli("replay", str(folder), "--extractor", extractor, "--quiet", "--jobs", "1")
    assert r.returncode == 0, r.stderr
    (line,) = r.stdout.strip().splitlines()
    assert (FAITHFUL_NOTE in line) == (extractor == "faithful"), line
    if extractor == "faithful":  # said beside the containment it explains
        assert f"vouched for; {FAITHFUL_NOTE}" in line


@pytest.mark.parametrize(("jobs", "damage"), [("1", "row"), ("2", "row"), ("2", "image")])
def test_replay_stops_at_bad_row_keeping_rows_written(
        live_run: tuple[Path, list[list[str]]], tmp_path: Path, jobs: str, damage: str) -> None:
    src, live_rows = live_run
    import shutil

    folder = tmp_path / "broken"
    shutil.copytree(src, folder)
    lines = (folder / "frames.csv").read_text().splitlines()
    cells = lines[11].split(",")
    if damage == "row":
        cells[3] = "fast"
        needle = "frames.csv line 12 (frame 10): speed is not a number ('fast')"
    else:
        (folder / cells[2]).unlink()
        needle = f"frames.csv line 12 (frame 10): image '{cells[2]}' is missing"
    lines[11] = ",".join(cells)
    (folder / "frames.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "partial.csv"
    r = _cli("replay", str(folder), "--out", str(out), "--quiet", "--jobs", jobs)
    assert r.returncode != 0
    assert r.stderr.strip().count("\n") == 0
    assert needle in r.stderr, r.stderr
    rows = _read_csv(out)
    # every frame before the bad row was written, complete and identical to the live run
    assert rows[1:] == live_rows[: len(rows) - 1] and len(rows) - 1 == 10
