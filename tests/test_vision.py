"""The vision API shared by both extractors: the docs/method.md convention (checked against the
exact observation of ``tileviz.core.tiles``), the result's fields, stage images and bad input."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.config import CameraConfig, VisionConfig, preset
from tileviz.core import tiles
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision import REASONS, VisionResult, extract, observation_error
from tileviz.vision.geometry import circular_median, family_normals, wrap_quarter
from tileviz.vision.robust import DEFAULT_SETTINGS

CFG = preset("default")
EXTRACTORS = ("faithful", "robust")


def _vision(ext: str) -> VisionConfig:
    return replace(CFG.vision, extractor=ext)


@pytest.fixture(scope="module")
def renderer() -> FloorRenderer:
    return FloorRenderer(CFG.floor, CFG.camera)


@pytest.fixture(scope="module")
def views(renderer: FloorRenderer) -> list[tuple[Pose, np.ndarray]]:
    rng = np.random.default_rng(11)
    out = []
    for _ in range(24):
        pose = Pose(rng.uniform(-8, 8), rng.uniform(-8, 8), rng.uniform(-7, 7))
        out.append((pose, renderer.render(pose, rng)))
    return out


def _same_branch_error(y: tuple[float, float, float], pose: Pose) -> tuple[float, float, float]:
    """Differences to ``tiles.observe`` itself (no symmetry allowed): y1, y2 modulo L."""
    t = tiles.observe(pose, CFG.floor.tile_size, CFG.camera.offset)
    lsize = CFG.floor.tile_size
    return (
        math.remainder(y[0] - t[0], lsize),
        math.remainder(y[1] - t[1], lsize),
        y[2] - t[2],
    )


@pytest.mark.parametrize("ext", EXTRACTORS)
def test_observation_is_the_exact_one_of_design_md(ext: str, views: list) -> None:
    """Away from the branch edge y3 = -pi/4 the extracted (y1, y2, y3) is tiles.observe(pose)
    itself (same m), not merely an equivalent vector; errors within a few pixels."""
    tol_px = 0.5 if ext == "robust" else 3.0
    tol_rad = 0.005 if ext == "robust" else 0.04
    checked = 0
    for pose, img in views:
        res = extract(img, camera=CFG.camera, tile_size=CFG.floor.tile_size, vision=_vision(ext))
        if not res.accepted:
            continue
        obs = res.observation
        assert 0.0 <= obs.y1 < CFG.floor.tile_size and 0.0 <= obs.y2 < CFG.floor.tile_size
        assert -math.pi / 4 <= obs.y3 < math.pi / 4
        true_y3 = tiles.observe(pose, CFG.floor.tile_size, CFG.camera.offset)[2]
        if abs(abs(true_y3) - math.pi / 4) < 0.05:
            continue
        e1, e2, e3 = _same_branch_error((obs.y1, obs.y2, obs.y3), pose)
        assert abs(e1) * CFG.camera.ppm < tol_px and abs(e2) * CFG.camera.ppm < tol_px
        assert abs(e3) < tol_rad
        checked += 1
    assert checked >= 15


@pytest.mark.parametrize("ext", EXTRACTORS)
@pytest.mark.parametrize("m", [0, 1, 2, 3])
@pytest.mark.parametrize("edge", [-1e-3, 0.0, 1e-3])
def test_branch_edge_gives_an_equivalent_observation(
    ext: str, m: int, edge: float, renderer: FloorRenderer
) -> None:
    """At headings m pi/2 + pi/4 (+- a hair) the branch m may flip with the measurement noise;
    the output must still be in range and equivalent to the truth (camera centre and heading
    modulo the floor's symmetries)."""
    pose = Pose(1.37 + 0.1 * m, -2.21, m * math.pi / 2 + math.pi / 4 + edge)
    img = renderer.render(pose, np.random.default_rng(m))
    res = extract(img, camera=CFG.camera, tile_size=CFG.floor.tile_size, vision=_vision(ext))
    assert res.accepted, res.reason
    obs = res.observation
    assert -math.pi / 4 <= obs.y3 < math.pi / 4
    e1, e2, e3 = observation_error(obs, pose, CFG.floor.tile_size, CFG.camera.offset)
    tol_px = 0.5 if ext == "robust" else 3.0
    assert max(abs(e1), abs(e2)) * CFG.camera.ppm < tol_px
    assert abs(e3) < (0.005 if ext == "robust" else 0.04)


@pytest.mark.parametrize("ext", EXTRACTORS)
def test_result_fields_describe_the_lines(ext: str, views: list) -> None:
    """Segments, angles, bags, (cos 4a, sin 4a) and offsets agree with each other and with the
    observation: a bag-1 line runs along y3, a bag-2 line along y3 + pi/2, and each sits where
    y_k + offset is a multiple of L."""
    lsize = CFG.floor.tile_size
    for _, img in views[:8]:
        res = extract(img, camera=CFG.camera, tile_size=lsize, vision=_vision(ext))
        n = len(res.segments)
        assert res.segments.shape == (n, 4) and res.angles.shape == (n,)
        assert res.bags.shape == (n,) and res.bags.dtype == np.int8
        assert res.disambiguation.shape == (n, 2) and res.offsets.shape == (n,)
        np.testing.assert_allclose(res.disambiguation[:, 0], np.cos(4 * res.angles), atol=1e-9)
        np.testing.assert_allclose(res.disambiguation[:, 1], np.sin(4 * res.angles), atol=1e-9)
        assert res.lines == int(np.count_nonzero(res.bags))
        if not res.accepted:
            continue
        obs = res.observation
        for k, yk in ((1, obs.y1), (2, obs.y2)):
            sel = res.bags == k
            assert sel.any()
            along = obs.y3 + (0.0 if k == 1 else math.pi / 2)
            dev = np.remainder(res.angles[sel] - along + math.pi / 2, math.pi) - math.pi / 2
            assert np.abs(dev).max() < (0.01 if ext == "robust" else 0.06)
            resid = np.remainder(yk + res.offsets[sel] + lsize / 2, lsize) - lsize / 2
            assert np.abs(resid).max() * CFG.camera.ppm < (1.0 if ext == "robust" else 6.0)
        assert np.isnan(res.offsets[res.bags == 0]).all()


@pytest.mark.parametrize("ext", EXTRACTORS)
def test_stage_images_only_when_asked(ext: str, views: list) -> None:
    img = views[0][1]
    plain = extract(img, camera=CFG.camera, tile_size=1.0, vision=_vision(ext))
    assert plain.stages == {}
    res = extract(img, camera=CFG.camera, tile_size=1.0, vision=_vision(ext), keep_stages=True)
    expected = {
        "faithful": ["input", "gray", "laplacian", "canny", "morphology", "hough", "bags",
                     "distances", "lattice", "disambiguation"],
        "robust": ["input", "gray", "edges", "warped", "lines", "distances", "lattice",
                   "foreign", "disambiguation"],
    }[ext]
    assert list(res.stages) == expected
    for name, stage in res.stages.items():
        assert stage.dtype == np.uint8 and stage.ndim == 3 and stage.shape[2] == 3, name
        if name != "disambiguation":
            assert stage.shape[:2] == img.shape[:2], name
    assert res.observation == plain.observation
    assert "stages" in res.timings and all(v >= 0 for v in res.timings.values())


@pytest.mark.parametrize("ext", EXTRACTORS)
def test_gray_input_gives_the_same_result(ext: str, views: list) -> None:
    import cv2

    img = views[1][1]
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    a = extract(img, camera=CFG.camera, tile_size=1.0, vision=_vision(ext))
    b = extract(gray, camera=CFG.camera, tile_size=1.0, vision=_vision(ext))
    c = extract(gray[..., None], camera=CFG.camera, tile_size=1.0, vision=_vision(ext))
    assert a.observation == b.observation == c.observation


@pytest.mark.parametrize("ext", EXTRACTORS)
def test_bad_input_is_a_clear_error_or_a_refusal(ext: str) -> None:
    cam, vis = CFG.camera, _vision(ext)
    ok = np.full((cam.height, cam.width, 3), 128, np.uint8)
    with pytest.raises(ValueError, match="image is 100x50 but the camera is 320x240"):
        extract(np.zeros((50, 100, 3), np.uint8), camera=cam, tile_size=1.0, vision=vis)
    with pytest.raises(ValueError, match="uint8"):
        extract(ok.astype(np.float32), camera=cam, tile_size=1.0, vision=vis)
    with pytest.raises(ValueError, match="shape"):
        extract(np.zeros((240, 320, 2), np.uint8), camera=cam, tile_size=1.0, vision=vis)
    with pytest.raises(ValueError, match="empty"):
        extract(np.zeros((0, 320, 3), np.uint8), camera=cam, tile_size=1.0, vision=vis)
    with pytest.raises(ValueError, match="numpy array"):
        extract([[1, 2]], camera=cam, tile_size=1.0, vision=vis)  # type: ignore[arg-type]
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="tile_size"):
            extract(ok, camera=cam, tile_size=bad, vision=vis)
    with pytest.raises(ValueError, match="camera"):
        extract(ok, camera=None, tile_size=1.0, vision=vis)  # type: ignore[arg-type]
    # a constant frame is a refusal, not an error
    res = extract(ok, camera=cam, tile_size=1.0, vision=vis)
    assert not res.accepted and res.observation is None
    assert res.reason == ("constant image" if ext == "robust" else "no lines")
    assert res.reason in REASONS


def test_reasons_are_ok_exactly_when_accepted(views: list) -> None:
    for ext in EXTRACTORS:
        for _, img in views:
            res = extract(img, camera=CFG.camera, tile_size=1.0, vision=_vision(ext))
            assert isinstance(res, VisionResult)
            assert (res.reason == "ok") == res.accepted == (res.observation is not None)
            assert res.reason in REASONS
            if res.accepted and ext == "faithful":
                assert res.observation.position_error == pytest.approx(
                    CFG.vision.position_error_px / CFG.camera.ppm)
                assert res.observation.heading_error == CFG.vision.heading_error
            elif res.accepted:  # the view's own bound, within the largest it may declare
                caps = DEFAULT_SETTINGS
                assert 0 < res.observation.position_error <= (
                    max(CFG.vision.position_error_px, caps.bound.max_px) / CFG.camera.ppm)
                assert 0 < res.observation.heading_error <= max(CFG.vision.heading_error,
                                                                caps.bound.max_rad)


def test_geometry_helpers() -> None:
    assert wrap_quarter(math.pi / 4) == pytest.approx(-math.pi / 4)
    assert wrap_quarter(-math.pi / 4) == pytest.approx(-math.pi / 4)
    assert wrap_quarter(1.0 + 3 * math.pi / 2) == pytest.approx(1.0 - math.pi / 2)
    # a cluster straddling 0 (mod L) has its median near 0, not near L/2
    med = circular_median(np.array([0.98, 0.99, 0.01, 0.02, 0.03]), 1.0)
    assert min(med, 1.0 - med) == pytest.approx(0.01, abs=1e-12)
    with pytest.raises(ValueError):
        circular_median(np.array([]), 1.0)
    n1, n2 = family_normals(0.0)
    assert n1 == pytest.approx((0.0, -1.0)) and n2 == pytest.approx((-1.0, 0.0))


def test_observation_error_is_modulo_the_symmetries() -> None:
    cam = CameraConfig()
    pose = Pose(3.3, -1.2, 2.0)
    y = tiles.observe(pose, 1.0, cam.offset)
    assert max(map(abs, observation_error(y, pose, 1.0, cam.offset))) < 1e-9
    # the same view described with another quarter turn
    for m in range(1, 4):
        y1, y2 = tiles.quarter_turn(m, y[0], y[1])
        z = (y1 % 1.0, y2 % 1.0, y[2] + m * math.pi / 2)
        assert max(map(abs, observation_error(z, pose, 1.0, cam.offset))) < 1e-9
    # a wrong offset shows up in metres
    e = observation_error((y[0] + 0.01, y[1], y[2]), pose, 1.0, cam.offset)
    assert max(abs(e[0]), abs(e[1])) == pytest.approx(0.01)


@settings(max_examples=60, deadline=None)
@given(
    data=st.data(),
    w=st.integers(16, 96),
    h=st.integers(16, 96),
    ppm=st.floats(5.0, 2000.0),
    tile=st.floats(0.01, 5.0),
    kind=st.sampled_from(["noise", "blocks", "stripes", "flat"]),
)
def test_any_image_gives_a_result_never_an_exception(
    data: st.DataObject, w: int, h: int, ppm: float, tile: float, kind: str
) -> None:
    """Arbitrary content, sizes and scales: both extractors answer (a refusal with a reason,
    or an observation in range), they never raise."""
    seed = data.draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    if kind == "noise":
        img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    elif kind == "blocks":
        img = np.kron(rng.integers(0, 256, (h // 8 + 1, w // 8 + 1, 3)),
                      np.ones((8, 8, 1)))[:h, :w].astype(np.uint8)
    elif kind == "stripes":
        img = np.zeros((h, w, 3), np.uint8)
        img[:, ::5] = 255
    else:
        img = np.full((h, w, 3), data.draw(st.integers(0, 255)), np.uint8)
    cam = CameraConfig(ppm=ppm, width=w, height=h)
    if not 4.0 <= ppm * tile <= 1e5:
        # a tile period outside 4..1e5 px is a bad argument, named at once
        with pytest.raises(ValueError, match="a tile must span"):
            extract(img, camera=cam, tile_size=tile, vision=_vision("robust"))
        return
    for ext in EXTRACTORS:
        res = extract(img, camera=cam, tile_size=tile, vision=_vision(ext), keep_stages=True)
        assert res.reason in REASONS
        if res.accepted:
            assert 0 <= res.observation.y1 < tile and 0 <= res.observation.y2 < tile
            assert -math.pi / 4 <= res.observation.y3 < math.pi / 4
