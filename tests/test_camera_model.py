"""A real camera (meta.json's camera_model): validation, rectification, the widened view bound,
record --lens -> replay (one process and workers), the server's dataset source, extract."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.__main__ import main as tileviz_main
from tileviz.app.sources import DatasetReplay
from tileviz.config import preset
from tileviz.datasets import (
    DatasetError,
    DatasetMeta,
    DatasetSource,
    read_meta,
    replay_config,
)
from tileviz.datasets.camera_model import (
    TABLE_STEP,
    CameraModel,
    Rectifier,
    rectified_floor_points,
    view_margin,
)
from tileviz.sim.camera import FloorRenderer
from tileviz.sim.lens import LensRenderer, mounted_camera, webcam_model
from tileviz.types import Pose
from tileviz.vision import extract, to_gray
from tileviz.vision.geometry import observation_error

CFG = preset("default")
MODEL = webcam_model(CFG.camera)


def _meta_dict(**camera_model: object) -> dict:
    d = DatasetMeta.from_config(CFG).to_json()
    block = MODEL.to_json()
    block.update(camera_model)
    d["camera_model"] = {k: v for k, v in block.items() if v is not None}
    return d


@pytest.mark.parametrize(("change", "needle"), [
    ({"raw_width": 0}, "camera_model.raw_width must be an integer > 0"),
    ({"camera_matrix": [[1, 0], [0, 1]]}, "camera_model.camera_matrix must be a 3x3"),
    ({"camera_matrix": [[500, 0, 320], [0, -500, 240], [0, 0, 1]]}, "with fx, fy > 0"),
    ({"dist_coeffs": [0.1, 0.0, 0.0, 0.0, 0.0, 0.0]}, "dist_coeffs must be a list of 4, 5, 8"),
    ({"dist_coeffs": [0.1, float("nan"), 0, 0]}, "dist_coeffs must be a list"),
    ({"floor_homography": [[1, 2, 3], [2, 4, 6], [0, 0, 1]]}, "floor_homography is singular"),
    ({"floor_homography": [[1, 0, 0], [0, 1, 0], [1 / 319.5, 0, -1]]},
     "principal point does not see the floor"),
    ({"reprojection_error_px": -1}, "reprojection_error_px must be a finite number >= 0"),
])
def test_bad_camera_model_is_one_line_naming_the_key(change: dict, needle: str) -> None:
    with pytest.raises(DatasetError) as e:
        DatasetMeta.from_json(_meta_dict(**change))
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_bad_blocks_missing_key_and_not_object() -> None:
    d = _meta_dict()
    del d["camera_model"]["floor_homography"]
    with pytest.raises(DatasetError, match="camera_model: missing key.*floor_homography"):
        DatasetMeta.from_json(d)
    d["camera_model"] = [1, 2]
    with pytest.raises(DatasetError, match="camera_model must be a JSON object"):
        DatasetMeta.from_json(d)


def test_camera_model_round_trips_through_meta_json() -> None:
    meta = DatasetMeta.from_json(_meta_dict(reprojection_error_px=0.25))
    assert meta.camera_model is not None and "camera_model" not in meta.extra
    again = DatasetMeta.from_json(json.loads(json.dumps(meta.to_json())))
    assert again.camera_model == meta.camera_model
    assert json.dumps(again.to_json()) == json.dumps(meta.to_json())
    assert "camera_model" not in DatasetMeta.from_config(CFG).to_json()


@settings(max_examples=60, deadline=None)
@given(st.floats(-0.55, 0.55), st.floats(-0.75, 0.75))
def test_floor_to_raw_inverts_raw_to_floor(df: float, dl: float) -> None:
    """A floor point seen in the view goes to a raw pixel and back to the same point (micrometres:
    the distortion is inverted iteratively)."""
    p = np.array([[CFG.camera.offset[0] + df, CFG.camera.offset[1] + dl]])
    raw, seen = MODEL.floor_to_raw(p)
    assert seen.all()
    back = MODEL.raw_to_floor(raw)
    assert np.abs(back - p).max() < 1e-6


def test_an_undistorted_straight_down_camera_rectifies_by_a_scale() -> None:
    """No tilt, no distortion: the rectified pixel (col, row) comes from the raw pixel the
    pinhole geometry says (a pure scale about the optical centre)."""
    cam = CFG.camera
    model = mounted_camera(raw_size=(400, 300), focal=160.0, dist=(0.0, 0.0, 0.0, 0.0),
                           target=cam.offset, height=1.0, pitch=0.0, roll=0.0)
    rect = Rectifier(model, ppm=cam.ppm, width=cam.width, height=cam.height,
                     camera_offset=cam.offset)
    yy, xx = np.mgrid[0:300, 0:400]
    raw = (xx * 7 + yy * 3).astype(np.float32)  # a linear ramp: bilinear sampling is exact
    out = rect(raw)
    # raw px per metre = 160 at 1 m; view ppm 200: (c, r) <- raw centre + 0.8 (c - cx)
    col, row = 37, 201
    u = 199.5 + 0.8 * (col - (cam.width - 1) / 2.0)
    v = 149.5 + 0.8 * (row - (cam.height - 1) / 2.0)
    assert out[row, col] == pytest.approx(7 * u + 3 * v, abs=0.05)
    assert rect.seen_fraction == 1.0 and rect.scale == pytest.approx(1.25, rel=1e-3)


def test_unseen_pixels_are_flat() -> None:
    """A view larger than the camera sees: the unseen pixels carry one colour (no edge)."""
    cam = replace(CFG.camera, width=640, height=480)
    rect = Rectifier(MODEL, ppm=cam.ppm, width=cam.width, height=cam.height,
                     camera_offset=cam.offset)
    assert 0.2 < rect.seen_fraction < 1.0
    raw = LensRenderer(CFG.floor, CFG.camera, MODEL).render(Pose(0.3, 0.2, 0.1))
    out = rect(raw)
    assert out.shape == (480, 640, 3)
    unseen = out[~rect.valid]
    assert (unseen == unseen[0]).all()


def test_the_view_bound_grows_with_the_calibration_error() -> None:
    rect = Rectifier(MODEL, ppm=CFG.camera.ppm, width=CFG.camera.width,
                     height=CFG.camera.height, camera_offset=CFG.camera.offset)
    px0, rad0 = view_margin(MODEL, rect)
    px1, rad1 = view_margin(replace(MODEL, reprojection_error_px=0.4), rect)
    assert 0 < px0 < px1 and 0 < rad0 < rad1
    assert px1 - px0 == pytest.approx(rect.scale * 3 * 0.4)
    meta = DatasetMeta.from_json(_meta_dict(reprojection_error_px=0.4))
    cfg = meta.to_config()
    assert cfg.vision.position_error_px == pytest.approx(CFG.vision.position_error_px + px1)
    assert cfg.vision.heading_error == pytest.approx(CFG.vision.heading_error + rad1)


def test_rectified_views_are_within_the_widened_bound() -> None:
    """Through the webcam lens, rectified, the robust extractor's observations are within the
    bound the dataset declares (the preset's plus the rectification's)."""
    meta = replace(DatasetMeta.from_config(CFG), camera_model=MODEL)
    cfg = meta.to_config()
    rect = meta.rectifier()
    renderer = LensRenderer(CFG.floor, CFG.camera, MODEL)
    rng = np.random.default_rng(5)
    used = 0
    for _ in range(25):
        pose = Pose(*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi))
        res = extract(rect.gray(renderer.render(pose, rng=rng)), camera=cfg.camera,
                      tile_size=cfg.floor.tile_size, vision=cfg.vision)
        if res.observation is None:
            continue
        used += 1
        e1, e2, e3 = observation_error(res.observation, pose, cfg.floor.tile_size,
                                       cfg.camera.offset)
        assert max(abs(e1), abs(e2)) <= res.observation.position_error
        assert abs(e3) <= res.observation.heading_error
    assert used >= 20


def test_rectified_image_matches_the_orthographic_render() -> None:
    """Raw through the lens, then rectified: the same floor as the orthographic camera draws."""
    pose = Pose(1.3, -0.4, 0.7)
    raw = LensRenderer(CFG.floor, replace(CFG.camera, noise_sigma=0), MODEL).render(pose)
    rect = DatasetMeta.from_json(_meta_dict()).rectifier()
    ortho = FloorRenderer(CFG.floor, replace(CFG.camera, noise_sigma=0)).render(pose)
    assert raw.shape == (480, 640, 3)
    diff = np.abs(rect(raw).astype(int) - ortho.astype(int))
    assert np.median(diff) <= 3
    diff = np.abs(rect.gray(raw).astype(int) - to_gray(ortho).astype(int))
    assert np.median(diff) <= 3


def _bilinear(gray: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``gray`` at raw points (u, v) in float64, rounded half to
    even; neighbours outside the image count as 0 (OpenCV's constant border)."""
    g = np.pad(gray.astype(np.float64), 1)
    iu, iv = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - iu, v - iv
    iu, iv = iu + 1, iv + 1
    top = g[iv, iu] + fu * (g[iv, iu + 1] - g[iv, iu])
    bottom = g[iv + 1, iu] + fu * (g[iv + 1, iu + 1] - g[iv + 1, iu])
    return np.clip(np.rint(top + fv * (bottom - top)), 0, 255).astype(np.uint8)


def test_the_gray_view_is_the_exact_bilinear_sample_on_every_machine() -> None:
    """Vision's view of a raw image: its gray levels interpolated at the model's source points
    (to 1/512 px), exactly: OpenCV's single-precision remap gives the value of exact arithmetic,
    so no machine (fused multiply-add or not, any vector width) gives other pixels."""
    meta = replace(DatasetMeta.from_config(CFG), camera_model=MODEL)
    rect = meta.rectifier()
    floor = rectified_floor_points(CFG.camera.ppm, CFG.camera.width, CFG.camera.height,
                                   CFG.camera.offset)
    exact, seen = MODEL.floor_to_raw(floor.reshape(-1, 2))
    assert seen.all() and rect.valid.all()
    table = np.dstack([rect.map_x, rect.map_y]).reshape(-1, 2).astype(np.float64)
    assert np.abs(table - exact).max() <= TABLE_STEP / 2 + 1e-9
    renderer = LensRenderer(CFG.floor, CFG.camera, MODEL)
    rng = np.random.default_rng(3)
    for _ in range(3):
        raw = renderer.render(Pose(*rng.uniform(-5, 5, 2), rng.uniform(-3, 3)), rng=rng)
        view = rect.gray(raw)
        assert view.shape == (CFG.camera.height, CFG.camera.width) and view.dtype == np.uint8
        assert np.array_equal(view, rect.gray(to_gray(raw)))  # colour or gray raw: same view
        assert np.array_equal(view, _bilinear(to_gray(raw), rect.map_x.astype(np.float64),
                                              rect.map_y.astype(np.float64)))


def test_gray_then_remap_is_remap_then_gray_up_to_rounding() -> None:
    """Gray conversion and bilinear interpolation are both linear: converting the raw image
    first (what vision reads) or the rectified colour view (what the demo shows) differs by
    rounding only, at most one gray level (docs/dataset-format.md)."""
    meta = replace(DatasetMeta.from_config(CFG), camera_model=MODEL)
    rect = meta.rectifier()
    renderer = LensRenderer(CFG.floor, CFG.camera, MODEL)
    rng = np.random.default_rng(4)
    u, v = rect.map_x.astype(np.float64), rect.map_y.astype(np.float64)
    for _ in range(3):
        raw = renderer.render(Pose(*rng.uniform(-5, 5, 2), rng.uniform(-3, 3)), rng=rng)
        colour = np.dstack([_bilinear(raw[..., c], u, v) for c in range(3)])
        diff = np.abs(rect.gray(raw).astype(int) - to_gray(colour).astype(int))
        assert diff.max() <= 1 and diff.mean() < 0.5


def _rows(path: Path) -> list[list[str]]:
    with open(path, newline="") as f:
        return list(csv.reader(f))[1:]


@pytest.fixture(scope="module")
def lens_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("lens") / "ds"
    assert tileviz_main(["record", str(out), "--duration", "4", "--quiet", "--seed", "2",
                         "--lens", "webcam"]) == 0
    return out


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_record_with_a_lens_replays_with_the_truth_inside(lens_run: Path, tmp_path: Path,
                                                          jobs: str) -> None:
    meta = read_meta(lens_run)
    assert meta.camera_model == CameraModel.from_json(MODEL.to_json())
    truths = _rows(lens_run / "frames.csv")
    out = tmp_path / "r.csv"
    assert tileviz_main(["replay", str(lens_run), "--out", str(out), "--quiet",
                         "--jobs", jobs]) == 0
    rows = _rows(out)
    assert len(rows) == len(truths) == 81
    assert sum(r[2] == "contracted" for r in rows) > 60
    for r, t in zip(rows, truths, strict=True):
        assert r[2] != "lost"
        x, y, th = (float(v) for v in t[6:9])
        lo = [float(v) for v in r[3:9]]
        th += 2 * math.pi * round(((lo[4] + lo[5]) / 2 - th) / (2 * math.pi))
        assert lo[0] <= x <= lo[1] and lo[2] <= y <= lo[3] and lo[4] <= th <= lo[5]
    if jobs == "2":  # workers rectify exactly as the calling process does
        other = tmp_path / "one.csv"
        assert tileviz_main(["replay", str(lens_run), "--out", str(other), "--quiet",
                             "--jobs", "1"]) == 0
        assert _rows(other) == rows


def test_server_dataset_source_rectifies_as_replay_does(lens_run: Path) -> None:
    # the demo's source hands over the raw image (shown as a stage) and its rectifier, which
    # gives the very pixels replay's reader delivers
    source = DatasetReplay(lens_run)
    frame = next(source)
    assert np.array_equal(frame.image, next(iter(DatasetSource(lens_run, rectify=False))).image)
    assert source.rectifier is not None
    view = source.rectifier.gray(frame.image)
    assert view.shape == (CFG.camera.height, CFG.camera.width)
    assert np.array_equal(view, next(iter(DatasetSource(lens_run))).image)


def test_replay_the_server_and_extract_give_the_same_observations(
        lens_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One camera_model dataset through the three entry points: ``replay`` (one process and
    its workers), the server's dataset replay and ``extract --camera-model``: vision reads the
    same gray view everywhere, so every frame's observation is the same to the last bit."""
    from tileviz.app import commands as C
    from tileviz.app.session import Session, SessionOptions
    from tileviz.pipeline.replay import replay

    frames = 6
    by_replay: dict[str, list[dict]] = {}
    for jobs in (1, 2):
        got: list[dict] = []
        replay(lens_run, out=tmp_path / f"r{jobs}.csv", jobs=jobs,
               on_frame=lambda rec, got=got: got.append(rec.vision.as_dict()))
        by_replay[str(jobs)] = got[:frames]
    s = Session(replay_config(read_meta(lens_run)),
                SessionOptions(out_dir=tmp_path, interactive=True, dataset=lens_run))
    served = []
    for _ in range(frames):
        s.apply(C.Step())
        served.append(s.shown_entry().record.vision.as_dict())
    s.close()
    names = [r[2] for r in _rows(lens_run / "frames.csv")[:frames]]
    capsys.readouterr()
    assert tileviz_main(["extract", *(str(lens_run / n) for n in names), "--json",
                         "--camera-model", str(lens_run / "meta.json")]) == 0
    extracted = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    keys = ("y1", "y2", "y3", "accepted", "reason", "lines", "position_error", "heading_error")
    assert sum(d["accepted"] for d in extracted) >= frames - 1
    for results in (by_replay["1"], by_replay["2"], served):
        assert [{k: d[k] for k in keys} for d in results] == [
            {k: d[k] for k in keys} for d in extracted]


def test_a_raw_image_of_the_wrong_size_names_the_row(lens_run: Path, tmp_path: Path) -> None:
    import shutil

    import cv2

    ds = tmp_path / "ds"
    shutil.copytree(lens_run, ds)
    cv2.imwrite(str(ds / "images" / "000003.png"), np.zeros((240, 320, 3), np.uint8))
    frames = iter(DatasetSource(ds))
    for _ in range(3):
        next(frames)
    with pytest.raises(DatasetError, match=r"line 5 \(frame 3\): image .* is 320x240, meta.json "
                       r"says 640x480 \(camera_model raw size\)"):
        next(frames)


def test_extract_with_a_camera_model(lens_run: Path) -> None:
    image = str(lens_run / "images" / "000010.png")
    r = subprocess.run([sys.executable, "-m", "tileviz", "extract", image, "--json",
                        "--camera-model", str(lens_run / "meta.json")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout)
    truth = _rows(lens_run / "frames.csv")[10]
    pose = Pose(*(float(v) for v in truth[6:9]))
    e = observation_error((got["y1"], got["y2"], got["y3"]), pose, CFG.floor.tile_size,
                          CFG.camera.offset)
    bound = (CFG.vision.position_error_px + view_margin(
        MODEL, read_meta(lens_run).rectifier())[0]) / CFG.camera.ppm
    assert max(abs(e[0]), abs(e[1])) <= bound
    r = subprocess.run([sys.executable, "-m", "tileviz", "extract", image, "--camera-model",
                        str(lens_run / "frames.csv")], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "not valid JSON" in r.stderr
