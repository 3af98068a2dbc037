"""The faithful pipeline: the original's constants and stages, and its corrections (signed
offsets, circular medians modulo L, refusals instead of NaN)."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from tileviz.config import CameraConfig, VisionConfig, preset
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision import extract, faithful, observation_error

SEED = preset("seed")
FAITHFUL = replace(SEED.vision, extractor="faithful")


def test_defaults_are_the_original_constants() -> None:
    """docs/seed-code.md: Laplacian ksize 1, Canny 50/255/3, close 1x1, dilate 3x3 once,
    HoughLinesP(1, pi/180, 60, 100, 50), L1 0.15, bags at 0.2, more than one good segment."""
    v = VisionConfig()
    assert (v.laplacian_ksize, v.canny_low, v.canny_high, v.canny_aperture) == (1, 50, 255, 3)
    assert (v.close_kernel, v.dilate_kernel, v.dilate_iterations) == (1, 3, 1)
    assert (v.hough_rho, v.hough_theta, v.hough_threshold) == (1.0, math.pi / 180, 60)
    assert (v.hough_min_line_length, v.hough_max_line_gap) == (100, 50)
    assert (v.l1_threshold, v.bag_threshold, v.min_segments) == (0.15, 0.2, 2)
    assert (SEED.floor.tile_size, SEED.camera.ppm) == (0.166, 620.48)
    assert (SEED.camera.width, SEED.camera.height) == (256, 384)


@pytest.fixture(scope="module")
def seed_views() -> list[tuple[Pose, np.ndarray]]:
    r = FloorRenderer(SEED.floor, SEED.camera)
    rng = np.random.default_rng(5)
    out = []
    for _ in range(16):
        pose = Pose(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4))
        out.append((pose, r.render(pose, rng)))
    return out


def test_seed_preset_views_are_read_within_two_pixels(seed_views: list) -> None:
    for pose, img in seed_views:
        res = extract(img, camera=SEED.camera, tile_size=SEED.floor.tile_size, vision=FAITHFUL)
        assert res.accepted, res.reason
        e1, e2, e3 = observation_error(res.observation, pose, SEED.floor.tile_size,
                                       SEED.camera.offset)
        assert max(abs(e1), abs(e2)) * SEED.camera.ppm < 2.0
        assert abs(e3) < 0.03


def test_stages_are_the_original_operations(seed_views: list) -> None:
    """Each stage image is what the corresponding OpenCV call gives with the seed constants."""
    img = seed_views[0][1]
    res = extract(img, camera=SEED.camera, tile_size=SEED.floor.tile_size, vision=FAITHFUL,
                  keep_stages=True)
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    lap = cv2.Laplacian(gray, cv2.CV_8U, ksize=1)
    edges = cv2.Canny(lap, 50, 255, apertureSize=3)
    morph = cv2.dilate(cv2.morphologyEx(edges, cv2.MORPH_CLOSE, np.ones((1, 1), np.uint8)), None)
    assert np.array_equal(res.stages["gray"][..., 0], gray)
    assert np.array_equal(res.stages["canny"][..., 0], edges)
    assert np.array_equal(res.stages["morphology"][..., 0], morph)
    lines = cv2.HoughLinesP(morph, 1, math.pi / 180, 60, minLineLength=100, maxLineGap=50)
    assert np.array_equal(res.segments, np.asarray(lines, np.float64).reshape(-1, 4))


@pytest.mark.parametrize("shape", ["n4", "n14"])
def test_hough_output_shape_of_any_opencv(shape: str, seed_views: list,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """OpenCV 5 returns HoughLinesP as (N, 4), older versions as (N, 1, 4): same result."""
    img = seed_views[1][1]
    ref = extract(img, camera=SEED.camera, tile_size=SEED.floor.tile_size, vision=FAITHFUL)
    real = cv2.HoughLinesP

    def fake(*args: object, **kw: object) -> np.ndarray:
        out = np.asarray(real(*args, **kw)).reshape(-1, 4)
        return out.reshape(-1, 1, 4) if shape == "n14" else out

    monkeypatch.setattr(faithful.cv2, "HoughLinesP", fake)
    res = extract(img, camera=SEED.camera, tile_size=SEED.floor.tile_size, vision=FAITHFUL)
    assert res.observation == ref.observation
    assert np.array_equal(res.segments, ref.segments)


def _lines_image(cam: CameraConfig, rows: list[float], cols: list[float]) -> np.ndarray:
    """White image with 3 px dark lines at the given rows and columns (full length)."""
    img = np.full((cam.height, cam.width, 3), 210, np.uint8)
    for r in rows:
        cv2.line(img, (0, int(r)), (cam.width - 1, int(r)), (60, 60, 60), 3)
    for c in cols:
        cv2.line(img, (int(c), 0), (int(c), cam.height - 1), (60, 60, 60), 3)
    return img


def test_a_family_straddling_the_centre_keeps_its_offset() -> None:
    """Lines just above and just below the centre row (offsets near +0 and near L-0) must give
    y1 near 0 (mod L), where the original's unsigned distances and a plain median gave L/2."""
    cam = CameraConfig(ppm=200.0, width=320, height=240)
    cy = (cam.height - 1) / 2.0
    lsize = 0.05  # 10 px tiles: each line's two edges sit on both sides of a lattice offset
    lp = lsize * cam.ppm
    rows = [cy + 0.5 + k * lp for k in range(-11, 12) if 0 < cy + 0.5 + k * lp < cam.height - 1]
    cols = [100.0, 200.0]
    img = _lines_image(cam, rows, cols)
    vis = VisionConfig(extractor="faithful", hough_threshold=40)
    res = extract(img, camera=cam, tile_size=lsize, vision=vis)
    assert res.accepted, res.reason
    # the lines sit 0.5 px below the centre: s1 = -0.5 px -> y1 = 0.5 px (mod L)
    y1_px = res.observation.y1 * cam.ppm
    assert min(y1_px, lp - y1_px) < 1.5


def test_refusals_instead_of_nan() -> None:
    cam = CameraConfig(ppm=200.0, width=320, height=240)
    vis = VisionConfig(extractor="faithful")
    only_rows = extract(_lines_image(cam, [60.0, 180.0], []), camera=cam, tile_size=0.6,
                        vision=vis)
    assert (only_rows.accepted, only_rows.reason) == (False, "one family")
    assert set(only_rows.bags.tolist()) == {1}
    # min_segments is an option: one line gives fewer Hough segments than 30
    one = extract(_lines_image(cam, [60.0], []), camera=cam, tile_size=0.6,
                  vision=replace(vis, min_segments=30))
    assert one.reason == "too few segments" and 0 < len(one.segments) < 30
    none = extract(np.full((240, 320, 3), 200, np.uint8), camera=cam, tile_size=0.6,
                   vision=vis)
    assert none.reason == "no lines" and len(none.segments) == 0
