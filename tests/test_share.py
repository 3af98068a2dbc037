"""Sharing a run: export-html, figure (and its movie), tileviz.show / tileviz.replay, the
demo's Export page, and the example script; the same boxes as ``replay --out``; bad input in
one line with nothing half-written."""

from __future__ import annotations

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tileviz.testing.extras import SHARE_MODULES, without
from tileviz.testing.pages import page_recording, recorded_hulls

ROOT = Path(__file__).resolve().parents[1]


def _tileviz(*args: str, program: str | None = None) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "tileviz", *args] if program is None else \
        [sys.executable, "-c", program, *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=ROOT)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tileviz.cli import record

    ds = tmp_path_factory.mktemp("share") / "run"
    assert record([str(ds), "--duration", "1.5", "--quiet"]) == 0  # 31 frames
    return ds


@pytest.fixture(scope="module")
def table(dataset: Path) -> list[dict[str, str]]:
    out = dataset.with_name("replay.csv")
    r = _tileviz("replay", str(dataset), "--out", str(out), "--quiet", "--jobs", "1")
    assert r.returncode == 0, r.stderr
    return list(csv.DictReader(out.open()))


def _hull(row: dict[str, str]) -> tuple[float, ...]:
    return tuple(float(row[k]) for k in ("x_lo", "x_hi", "y_lo", "y_hi"))


def test_the_page_plays_the_boxes_replay_writes(dataset, table, tmp_path) -> None:
    out = tmp_path / "page.html"
    r = _tileviz("export-html", str(dataset), str(out), "--start", "4", "--end", "20",
                 "--every", "3", "--quiet")
    assert r.returncode == 0, r.stderr
    assert f"to {out}" in r.stdout and "statuses:" in r.stdout
    html = out.read_text()
    rec = page_recording(html)
    shown = list(range(4, 20, 3))
    hulls = recorded_hulls(rec, "boxes")
    assert len(hulls) == len(shown)
    for i, hull in zip(shown, hulls, strict=True):
        assert hull == pytest.approx(_hull(table[i]), abs=1e-6)
    # real time: every 3rd frame, each shown for 3 frame periods
    assert rec["durationSeconds"] == pytest.approx(len(shown) * 3 * 0.05)
    texts = [m["props"]["text"] for _, m in rec["messages"] if m["type"] == "LabelMessage"]
    assert any(t.startswith("tileviz default seed 0: frames 4 to 19; statuses: 16 ")
               for t in texts)
    images = {m["name"] for _, m in rec["messages"] if m["type"] == "ImageMessage"}
    assert {"/panels/camera", "/panels/stage", "/panels/inset"} <= images


def test_the_figure_draws_the_boxes_replay_writes(dataset, table, tmp_path) -> None:
    from tileviz.share.figure import drawn_sets, render_figure
    from tileviz.share.run import load_run

    run = load_run(dataset, start=2, end=25, jobs=1)
    sets = drawn_sets(run, 5)
    assert [i for i, _, _ in sets] == [2, 7, 12, 17, 22, 24]  # every 5th, then the final set
    for i, _, updated in sets:
        h = updated.hull()
        assert (h.x_lo, h.x_hi, h.y_lo, h.y_hi) == pytest.approx(_hull(table[i]), abs=1e-9)
    fig = render_figure(run, 5)
    blue = fig.axes[0].collections[1]  # the contracted sets drawn
    drawn = [p.vertices for p in blue.get_paths()]
    x = [(v[:, 0].min(), v[:, 0].max()) for v in drawn]
    np.testing.assert_allclose(x, [(float(table[i]["x_lo"]), float(table[i]["x_hi"]))
                                   for i, _, _ in sets], rtol=0, atol=1e-9)
    for suffix in (".png", ".svg", ".pdf"):
        out = tmp_path / f"fig{suffix}"
        r = _tileviz("figure", str(dataset), str(out), "--frames", "2:25", "--every", "5",
                     "--quiet")
        assert r.returncode == 0, r.stderr
        assert out.stat().st_size > 10_000
    import cv2

    img = cv2.imread(str(tmp_path / "fig.png"))
    assert img.shape[1] >= 1000 and len(np.unique(img.reshape(-1, 3), axis=0)) > 100


def test_the_figure_from_the_replay_csv_draws_the_boxes_the_replay_draws(dataset, table,
                                                                          tmp_path) -> None:
    from tileviz.share.figure import drawn_sets, render_figure
    from tileviz.share.run import load_boxes, load_run

    csv_path = dataset.with_name("replay.csv")
    replayed = load_run(dataset, start=2, end=25, jobs=1)
    read = load_boxes(dataset, csv_path, start=2, end=25)
    # the replay CSV keeps no view: its summary is the replay's less the views refused
    kept = [p for p in replayed.summary().split("; ") if not p.startswith("views refused")]
    assert read.summary() == "; ".join(kept)
    assert [r.status for r in read.records] == [r.status for r in replayed.records]

    def blue(run) -> list[np.ndarray]:  # the contracted sets drawn, as (x, y) extents
        paths = render_figure(run, 5).axes[0].collections[1].get_paths()
        return [np.r_[p.vertices.min(axis=0), p.vertices.max(axis=0)] for p in paths]

    assert [i for i, _, _ in drawn_sets(read, 5)] == [2, 7, 12, 17, 22, 24]
    # exactly the replay's sets (one box a frame here), to the last bit the CSV keeps
    np.testing.assert_array_equal(blue(read), blue(replayed))
    np.testing.assert_array_equal(
        blue(read), [[float(table[i][k]) for k in ("x_lo", "y_lo", "x_hi", "y_hi")]
                     for i in (2, 7, 12, 17, 22, 24)])
    out = tmp_path / "fig.png"
    r = _tileviz("figure", str(dataset), str(out), "--boxes", str(csv_path), "--frames",
                 "2:25", "--every", "5", "--quiet")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().endswith(replayed.summary()) and out.stat().st_size > 10_000


def test_a_replay_csv_of_another_run_is_one_line(dataset, table, tmp_path) -> None:
    good = dataset.with_name("replay.csv").read_text().splitlines()
    short = tmp_path / "short.csv"
    short.write_text("\n".join(good[:-3]) + "\n")  # a replay stopped early, or another run
    shifted = tmp_path / "shifted.csv"
    shifted.write_text("\n".join([good[0], *("9" + line if i == 7 else line
                                             for i, line in enumerate(good[1:]))]) + "\n")
    other_t = tmp_path / "t.csv"
    cells = good[5].split(",")
    cells[1] = "7.5"
    other_t.write_text("\n".join([*good[:5], ",".join(cells), *good[6:]]) + "\n")
    frames = tmp_path / "frames.csv"
    frames.write_text((dataset / "frames.csv").read_text())
    out = tmp_path / "f.png"
    cases = [
        (short, "28 frame rows, but"), (shifted, "line 9: frame index '97'"),
        (other_t, "line 6: t = 7.5"), (frames, "not a replay CSV (no column status"),
        (tmp_path / "none.csv", "cannot be read"),
    ]
    for csv_path, words in cases:
        r = _tileviz("figure", str(dataset), str(out), "--boxes", str(csv_path), "--quiet")
        err = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(err) == 1, (csv_path, r.stderr)
        assert words in err[0] and f"--boxes {csv_path}" in err[0], err
    r = _tileviz("figure", str(dataset), str(tmp_path / "m.mp4"), "--boxes",
                 str(dataset.with_name("replay.csv")), "--quiet")
    assert r.returncode == 2 and "not a movie" in r.stderr
    assert not out.exists() and _leftovers(tmp_path) == []


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_the_movie_has_one_frame_every_n_beside_the_camera(dataset, tmp_path, suffix) -> None:
    import imageio.v3 as iio

    out = tmp_path / f"movie{suffix}"
    r = _tileviz("figure", str(dataset), str(out), "--frames", "0:12", "--every", "2",
                 "--width", "640", "--quiet")
    assert r.returncode == 0, r.stderr
    frames = iio.imread(out, index=None)
    assert frames.shape[0] == 6 and frames.shape[1:3] == (320, 640)
    assert not np.array_equal(frames[0], frames[-1])  # time goes on
    assert frames[0][:, 320:].std() > 10  # the camera view on the right


def test_without_the_share_extra_a_movie_is_one_line_naming_the_install(dataset,
                                                                         tmp_path) -> None:
    out = tmp_path / "m.mp4"
    r = _tileviz("figure", str(dataset), str(out), "--quiet", program=without(SHARE_MODULES))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "pip install -e '.[share]'" in lines[0] and not out.exists()
    png = tmp_path / "f.png"  # a figure needs no extra
    assert _tileviz("figure", str(dataset), str(png), "--quiet",
                    program=without(SHARE_MODULES)).returncode == 0


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if ".part" in p.name)


def test_bad_input_is_one_line_and_nothing_half_written(dataset, tmp_path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "meta.json").write_text((dataset / "meta.json").read_text())
    (empty / "frames.csv").write_text((dataset / "frames.csv").read_text().splitlines()[0] + "\n")
    broken = tmp_path / "broken"
    shutil.copytree(dataset, broken)
    lines = (broken / "frames.csv").read_text().splitlines()
    lines[12] = lines[12].replace(",", ",x", 1)
    (broken / "frames.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    out.mkdir()
    cases = [
        (["export-html", str(tmp_path), str(out / "a.html")], "not a dataset"),
        (["export-html", str(tmp_path / "nowhere"), str(out / "a.html")], "nowhere"),
        (["export-html", str(empty), str(out / "a.html")], "no frames"),
        (["export-html", str(dataset), str(out / "a.html"), "--start", "40"], "--start 40"),
        (["export-html", str(dataset), str(out / "a.html"), "--start", "9", "--end", "9"],
         "--end 9"),
        (["export-html", str(dataset), str(out / "a.txt")], "must end with .html"),
        (["export-html", str(dataset), str(tmp_path / "no" / "a.html")], "does not exist"),
        (["export-html", str(dataset), str(out)], "must end with"),
        (["export-html", str(dataset), "--site", str(dataset)], "not an empty folder"),
        (["export-html", str(broken), str(out / "a.html")], "frames.csv"),
        (["figure", str(dataset), str(out / "f.jpg")], "must end with .png"),
        (["figure", str(dataset), str(out / "f.png"), "--frames", "5:100"], "past the run"),
        (["figure", str(dataset), str(out / "f.png"), "--frames", "a:b"], "--frames"),
        (["figure", str(broken), str(out / "f.png")], "frames.csv"),
        (["figure", str(tmp_path), str(out / "f.svg")], "not a dataset"),
    ]
    (out / "keep.html").write_text("older")
    for args, words in cases:
        r = _tileviz(*args, "--quiet")
        err = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(err) == 1, (args, r.stderr)
        assert words in err[0] and "Traceback" not in r.stderr, (args, err)
    assert sorted(p.name for p in out.iterdir()) == ["keep.html"]
    assert _leftovers(tmp_path) == []
    # a run that fails part-way leaves an older file of that name as it was
    r = _tileviz("export-html", str(broken), str(out / "keep.html"), "--quiet")
    assert r.returncode == 2 and (out / "keep.html").read_text() == "older"


def test_a_site_folder_holds_the_client_and_the_recording(dataset, tmp_path) -> None:
    site = tmp_path / "site"
    r = _tileviz("export-html", str(dataset), "--site", str(site), "--end", "6", "--quiet")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in site.iterdir()) == ["index.html", "run.viser"]
    assert "playbackPath=run.viser" in (site / "index.html").read_text()
    assert (site / "run.viser").stat().st_size > 1000


def test_notebook_replay_and_show(dataset, table, monkeypatch) -> None:
    import types

    import tileviz

    rows = tileviz.replay(dataset, start=3, end=9, jobs=1)
    rows = rows.to_dict("records") if hasattr(rows, "to_dict") else rows
    assert [r["index"] for r in rows] == list(range(3, 9))
    for r in rows:
        assert (r["x_lo"], r["x_hi"], r["y_lo"], r["y_hi"]) == pytest.approx(
            _hull(table[r["index"]]), abs=1e-9)
        assert r["status"] == table[r["index"]]["status"] and r["inside"] is True
    with pytest.raises(ValueError, match="end 99 is past the run's end"):
        tileviz.replay(dataset, end=99)
    # in Jupyter: the page inline, as an iframe holding the whole page
    shown: list[str] = []
    ipython = types.ModuleType("IPython")
    core = types.ModuleType("IPython.core")
    getipython = types.ModuleType("IPython.core.getipython")
    getipython.get_ipython = lambda: object()  # type: ignore[attr-defined]
    display = types.ModuleType("IPython.display")
    display.HTML = lambda text: text  # type: ignore[attr-defined]
    display.display = shown.append  # type: ignore[attr-defined]
    for name, mod in (("IPython", ipython), ("IPython.core", core),
                      ("IPython.core.getipython", getipython), ("IPython.display", display)):
        monkeypatch.setitem(sys.modules, name, mod)
    tileviz.show(dataset, end=5, height=420)
    assert len(shown) == 1 and "<iframe srcdoc=" in shown[0] and 'height="420"' in shown[0]
    assert "__VISER_EMBED_DATA__" in shown[0]


def test_the_example_runs(dataset, tmp_path) -> None:
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "share_a_run.py"), str(dataset),
                        str(tmp_path)], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert "31 frames; set width in x" in r.stdout
    assert (tmp_path / "run.png").stat().st_size > 10_000
    assert page_recording((tmp_path / "run.html").read_text())["durationSeconds"] > 1.0


def test_the_demos_export_page_writes_the_recording_as_export_html_does(tmp_path) -> None:
    from tileviz.app import commands as C
    from tileviz.app.session import Session, SessionOptions
    from tileviz.config import preset

    s = Session(preset("default"), SessionOptions(out_dir=tmp_path / "out", interactive=True))
    s.apply(C.Step())
    with pytest.raises(ValueError, match="^nothing to export: record a run first"):
        s.apply(C.ExportPage())
    s.apply(C.StartRecording("page run"))
    for _ in range(5):
        s.apply(C.Step())
    s.apply(C.StopRecording())
    folder = s.last_recording
    assert folder is not None
    s.apply(C.ExportPage())
    assert s.notes[-1].text.startswith(f"exporting {folder} to ")
    with pytest.raises(ValueError, match="^an export is already running"):
        s.apply(C.ExportMcap())
    assert s.export is not None
    s.export.join(timeout=600)
    s.poll()
    out = folder.with_name(folder.name + ".html")
    assert s.notes[-1].level == "info"
    assert s.notes[-1].text == (f"exported 5 frames to {out} (open it in a browser: it plays "
                                "offline)")
    s.apply(C.Step())  # the run goes on
    s.close()
    rec = page_recording(out.read_text())
    table = tmp_path / "r.csv"
    assert _tileviz("replay", str(folder), "--out", str(table), "--quiet").returncode == 0
    rows = list(csv.DictReader(table.open()))
    np.testing.assert_allclose(recorded_hulls(rec), [_hull(r) for r in rows], rtol=0, atol=1e-6)
