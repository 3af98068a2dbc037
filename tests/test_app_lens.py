"""A real camera in the demo: ``serve --lens webcam`` and datasets with a ``camera_model`` show
the raw image and its rectification as the first stages; the boxes are those ``replay`` writes."""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path

import pytest

from tileviz.app import commands as C
from tileviz.app.panels import decode_jpeg
from tileviz.app.serve_cli import options_from_args, parser, serve_config
from tileviz.app.session import Session, SessionOptions
from tileviz.cliutil import CliError
from tileviz.config import preset
from tileviz.datasets import read_meta, replay_config
from tileviz.pipeline.replay import replay


def _images(s: Session) -> dict[str, tuple[int, ...]]:
    entry = s.shown_entry()
    assert entry is not None
    return {name: decode_jpeg(data).shape for name, data in entry.images}


@pytest.fixture(scope="module")
def lens_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Session, Path]]:
    out = tmp_path_factory.mktemp("lens")
    s = Session(preset("default"), SessionOptions(out_dir=out, interactive=True, lens="webcam"))
    s.apply(C.Step())
    s.apply(C.StartRecording("lens"))
    for _ in range(8):
        s.apply(C.Step())
    s.apply(C.StopRecording())
    yield s, out / "lens"
    s.close()


def test_the_lens_camera_shows_raw_and_rectified_images_first(lens_run) -> None:
    s, _ = lens_run
    cam = s.cfg.camera
    model = s.source.rectifier.model
    shapes = _images(s)
    names = list(shapes)
    assert names[:3] == ["camera", "raw", "rectified"] and len(names) > 4  # then the extractor's
    assert shapes["raw"][:2] == (model.raw_height, model.raw_width)
    assert shapes["rectified"][:2] == shapes["camera"][:2] == (cam.height, cam.width)
    rec = s.shown_entry().record
    assert rec.truth_inside() and rec.status == "contracted"
    # shown: the colour view (vision read the gray one); the extractor's input is gray
    images = {name: decode_jpeg(data).astype(int) for name, data in s.shown_entry().images}
    for name in ("camera", "rectified"):
        assert abs(images[name][..., 0] - images[name][..., 2]).mean() > 10
    assert abs(images["input"][..., 0] - images["input"][..., 2]).mean() < 2
    # without the stage images, none of them is kept
    s.apply(C.SetDisplay(False))
    s.apply(C.Step())
    assert list(_images(s)) == ["camera"]
    s.apply(C.SetDisplay(True))


def test_the_lens_recording_stores_raw_images_that_replay_rectifies(lens_run, tmp_path) -> None:
    s, folder = lens_run
    meta = read_meta(folder)
    assert meta.camera_model == s.source.rectifier.model
    table = tmp_path / "r.csv"
    assert replay(folder, out=table, jobs=1) == 8
    rows = list(csv.DictReader(table.open()))
    assert all(r["status"] == "contracted" for r in rows)
    # the live run's localizer had the bound the replay derives from the camera model
    assert s.runner.cfg.vision == replay_config(meta).vision


def test_camera_faults_are_refused_through_a_lens(lens_run) -> None:
    s, _ = lens_run
    with pytest.raises(ValueError, match="not drawn through a lens"):
        s.apply(C.Inject("cable", 5))


def test_a_dataset_with_a_camera_model_shows_both_and_gives_the_replay_boxes(lens_run,
                                                                             tmp_path) -> None:
    _, folder = lens_run
    cfg = replay_config(read_meta(folder))
    s = Session(cfg, SessionOptions(out_dir=tmp_path, interactive=True, dataset=folder))
    table = tmp_path / "r.csv"
    replay(folder, out=table, jobs=1)
    rows = list(csv.DictReader(table.open()))
    for row in rows[:4]:
        s.apply(C.Step())
        rec = s.shown_entry().record
        hull = rec.updated.hull()
        assert rec.status == row["status"]
        assert (hull.x_lo, hull.x_hi) == (float(row["x_lo"]), float(row["x_hi"]))
    assert list(_images(s))[:3] == ["camera", "raw", "rectified"]
    s.close()


def test_serve_lens_option() -> None:
    args = parser().parse_args(["--lens", "webcam"])
    assert options_from_args(args).lens == "webcam"
    with pytest.raises(SystemExit):
        parser().parse_args(["--lens", "fisheye"])
    args = parser().parse_args(["--lens", "webcam", "--dataset", "somewhere"])
    with pytest.raises(CliError, match="--lens cannot be used with --dataset"):
        serve_config(args)
