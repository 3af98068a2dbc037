"""The robust extractor on floors rendered independently of tileviz
(``tileviz/testing/floorgen.py``): every floor family is read, and no accepted view (clean or
corrupted) lies outside the bound it declares. Fixed seeds of the study's splits
(``bench/vision_study.py``; none held out)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import cv2
import numpy as np
import pytest

from tileviz.config import CameraConfig, VisionConfig
from tileviz.testing import floorgen
from tileviz.testing.views import (
    FAMILY_SALT,
    cable_view,
    crossing_cable_view,
    motion_view,
    study_view,
)
from tileviz.types import Pose
from tileviz.vision import extract, observation_error

SEEDS = range(5)


@pytest.mark.parametrize("family", floorgen.FAMILIES)
def test_each_floor_family_is_read_within_its_declared_bound(family: str) -> None:
    rows = [study_view(seed, family, None) for seed in SEEDS]
    for r in rows:
        assert r["inside"], r
    readable = [r for r in rows if r["readable"]]
    accepted = [r for r in readable if r["accepted"]]
    assert len(accepted) == len(readable), rows


def test_a_channel_that_is_the_luma_again_is_not_read_a_second_time() -> None:
    """``bench/cable_along.py``'s seed 22 terrazzo view: a dark cable 7.8 px off a grout line;
    the luma is refused (one family), and its red channel, the same gray pixels under the
    floor's tint, was read with the cable as the line (7.8 px off a bound of 0.96 px). A
    projection as correlated with the luma as that is not read."""
    r = cable_view(22, "terrazzo")
    assert r["inside"], r


def test_a_motion_blurred_grout_floor_is_not_read_from_its_edge_image() -> None:
    """Tuning seed 4's corrupted degraded view (motion blur): its luma is refused (one
    family); its edge image, where the blur moved each grout band's ridge toward one edge, was
    read 6.6 px off against a bound of 1.9 px. The edge image is read on a declared
    checkerboard, or where every piece of its lines is one step between two tiles' levels
    (a grout band is not one)."""
    r = study_view(4, "degraded", "motion_blur")
    assert r["inside"], r
    assert not r["accepted"], r


def test_a_checkerboard_of_two_hues_of_one_luma_is_read_from_a_difference_of_channels(
) -> None:
    """Tiles of two hues and one luma, edge to edge: the luma shows no edge, and the floor
    undeclared is read as a recognised checkerboard. Declared ``checker`` or recognised, the
    edge images are read strongest first: a colour projection's (``details["projection"]`` -2
    or below, not the luma's -1) reads the view, within its bound."""
    luma = np.array([0.299, 0.587, 0.114])
    grey = np.array([150.0, 150.0, 150.0])
    hue = np.array([1.0, -0.3, 0.0])
    hue -= hue.dot(luma) / luma.dot(luma) * luma
    hued = grey + hue * 70.0 / float(np.abs(hue).max())
    spec = floorgen.FloorSpec(family="checker", kind="checker", tile_size=0.3, ppm=400.0,
                              grout_px=0.0, grout_shade=float(hued.dot(luma)),
                              tile_shade=150.0, shade_spread=0.0, surface="flat",
                              surface_amp=0.0, seed=4,
                              tint=(tuple(grey.tolist()), tuple(hued.tolist())))
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    for cx, cy, th in ((0.41, 0.23, 0.3), (1.1, 0.7, -0.6)):
        img = floorgen.render(spec, cx, cy, th, np.random.default_rng(2))
        undeclared = extract(img, camera=cam, tile_size=spec.tile_size,
                             vision=VisionConfig(extractor="robust"))
        assert undeclared.details.get("checker", 0.0) >= 2.0, undeclared.reason
        res = extract(img, camera=cam, tile_size=spec.tile_size,
                      vision=VisionConfig(extractor="robust"), floor=spec.model)
        for got in (res, undeclared):
            assert got.accepted and got.observation is not None, got.reason
            assert got.details["projection"] <= -2.0
            e1, e2, e3 = observation_error(got.observation, Pose(cx, cy, th), spec.tile_size,
                                           (0.0, 0.0))
            assert max(abs(e1), abs(e2)) <= got.observation.position_error
            assert abs(e3) <= got.observation.heading_error


@pytest.mark.parametrize("seed", [0, 2, 5])
def test_an_undeclared_checkerboard_is_recognised_from_its_tile_edges(seed: int) -> None:
    """The study's checkerboards (tuning seeds: marble-like, and seed 5 two hues of one luma)
    extracted with nothing declared: the grout reading is refused, the edge images read as on
    a declared checkerboard, and the reading kept because every piece of its lines is one step
    between two tiles' levels and the tiles beside each line swap shades at its crossings; the
    decision shows the three checks in the reading kept; within its bound."""
    rng = np.random.default_rng([seed, FAMILY_SALT["checker"], 0])
    spec = floorgen.draw_floor("checker", rng)
    cx, cy, th = floorgen.draw_view(rng)
    img = floorgen.render(spec, cx, cy, th, rng)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"))
    assert res.accepted and res.observation is not None and res.decision is not None
    assert res.details["checker"] >= 2 and res.details["projection"] <= -1
    assert res.decision.shown is not None
    shown = {c.check for c in res.decision.readings[res.decision.shown].checks}
    assert shown >= {"checker.pieces", "checker.steps", "checker.sides"}
    # recognised: the joints image, read last, is not read
    assert not any(i.startswith("joints image") for i in res.decision.images)
    e1, e2, e3 = observation_error(res.observation, Pose(cx, cy, th), spec.tile_size,
                                   (0.0, 0.0))
    assert max(abs(e1), abs(e2)) <= res.observation.position_error
    assert abs(e3) <= res.observation.heading_error


def test_an_undeclared_checkerboard_with_a_thin_grout_is_recognised_and_bounded_by_its_reach(
) -> None:
    """Marble-like squares of two shades with a thin grout (1.5 px, darker than both) along
    their edges, nothing declared: the grout reading is refused, the edge image is recognised
    as a checkerboard whose tile edges carry a band; the decision shows ``checker.band``, the
    bound covers the reach of the band (``details["checker_band"]``, px), and the truth is
    inside it."""
    rng = np.random.default_rng([24, 5])
    dark = float(rng.uniform(40, 90))
    spec = floorgen.FloorSpec(family="checker", kind="checker", tile_size=0.3,
                              ppm=float(rng.uniform(300, 500)), grout_px=1.5,
                              grout_shade=float(rng.uniform(150, 200)), tile_shade=dark,
                              shade_spread=4.0, surface="terrazzo", surface_amp=0.12, seed=24,
                              band_shade=dark - 30.0, noise=1.5, blur=0.6)
    cx, cy, th = (float(rng.uniform(0, 3)), float(rng.uniform(0, 3)),
                  float(rng.uniform(-3, 3)))
    img = floorgen.render(spec, cx, cy, th, rng)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"))
    assert res.accepted and res.observation is not None and res.decision is not None
    assert res.details["projection"] <= -1 and res.details["checker_band"] > 0.0
    assert res.decision.shown is not None
    shown = {c.check for c in res.decision.readings[res.decision.shown].checks}
    assert shown >= {"checker.pieces", "checker.steps", "checker.band", "checker.sides"}
    assert res.details["checker_band"] >= 1.0  # the band's far side, beside the edge
    assert res.observation.position_error * spec.ppm >= res.details["checker_band"]
    e1, e2, e3 = observation_error(res.observation, Pose(cx, cy, th), spec.tile_size,
                                   (0.0, 0.0))
    assert max(abs(e1), abs(e2)) <= res.observation.position_error
    assert abs(e3) <= res.observation.heading_error


def test_a_recognised_reading_keeps_its_estimate_and_covers_the_widened_reading() -> None:
    """The reading kept after a checkerboard's tile edges showed a reach: its own estimate, its
    bounds widened to cover the second reading's (made with the tolerance widened), in the
    lattice's quarter-turn symmetry; never narrower than its own."""
    from tileviz.types import Observation
    from tileviz.vision.views import _covering

    first = Observation(0.10, 0.20, 0.05, 0.004, 0.010)
    other = Observation(0.200, 0.197, 0.05 + 0.002 - 0.5 * math.pi, 0.006, 0.015)
    got = _covering(first, other, 0.3)
    # a quarter turn of (0.200, 0.197) is (-0.197, 0.200) = (0.103, 0.200) mod 0.3: 3 mm off
    assert got.y1 == first.y1 and got.y3 == first.y3
    assert got.position_error == pytest.approx(0.006 + 0.003)
    assert got.heading_error == pytest.approx(0.015 + 0.002)
    tight = _covering(first, Observation(0.10, 0.20, 0.05, 0.001, 0.001), 0.3)
    assert (tight.position_error, tight.heading_error) == (0.004, 0.010)


def test_one_step_between_two_levels_is_a_tile_edge_and_its_reach_covers_a_thin_band() -> None:
    """The profile across a line of a checkerboard (offsets from the line read) is one blurred
    step, its reach (how far from the line its edge and any edge the other way lie) the
    step's own offset; a thin grout band darker than both tiles along the edge reaches to its
    far side, which covers the band's centre; a line read on a band's far side reaches to the
    step's edge; a band's far side beyond the limit (even a faint one of 20 % of the step's
    edge), a band of a third level between the tiles (two edges the step's way) and a step
    under the noise are no tile edge; a tile's level drifting gently beside the edge (worn
    marble) is no band."""
    from tileviz.vision.robust.checker import step_band
    from tileviz.vision.robust.settings import DEFAULT_SETTINGS

    st = DEFAULT_SETTINGS.checker
    u = np.arange(-10.0, 10.25, 0.5)
    outer = np.abs(u) >= 10.0 - st.plateau
    erf = np.vectorize(math.erf)

    def edge(at: float, height: float) -> np.ndarray:
        return height * 0.5 * (1.0 + erf((u - at) / (1.2 * math.sqrt(2.0))))

    def reach(prof: np.ndarray) -> float | None:
        return step_band(prof, u, outer, 0.5, 4.0, st)

    clean = reach(60.0 + edge(0.0, 100.0))
    assert clean is not None and clean <= 0.5
    # dark grout from -2 to 0 px (60 levels below the darker tile): its centre at -1
    thin = reach(60.0 + edge(0.0, 100.0) - edge(-2.0, 60.0) + edge(0.0, 60.0))
    assert thin is not None and 1.0 <= thin <= 4.0
    # the same grout, the line read on its far side: the step's edge 2 px off
    far = reach(60.0 + edge(2.0, 100.0) - edge(0.0, 60.0) + edge(2.0, 60.0))
    assert far is not None and far >= 1.5
    faint_wide = 60.0 + edge(0.0, 100.0) - edge(-6.0, 25.0) + edge(0.0, 25.0)
    assert reach(faint_wide) is None  # a far side of 20 % of the edge, 6 px off
    assert reach(60.0 + edge(0.0, 100.0) - 100.0 * np.exp(-u * u / 18.0)) is None  # wide dip
    assert reach(60.0 + edge(-3.0, 50.0) + edge(3.0, 50.0)) is None
    assert reach(60.0 + edge(0.0, 4.0)) is None
    drift = 60.0 + edge(0.0, 100.0) - np.where(u > 0, 12.0 * np.exp(-u / 6.0), 0.0)
    drifted = reach(drift)
    assert drifted is not None and drifted <= 0.5


def _checker_view(light: np.ndarray, dark: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                  np.ndarray]:
    """A 240x320 checkerboard of 100 px tiles (corners at x = 60 + 100 i, y = 20 + 100 j),
    tile (i, j) of shade ``light[i, j]`` or ``dark[i, j]`` by parity, blurred 1 px and noisy
    (3 levels): the view, and the segments and families of its lines read exactly."""
    ys, xs = np.mgrid[0:240, 0:320].astype(np.float64)
    i = np.floor((xs - 60.0) / 100.0).astype(int) + 1
    j = np.floor((ys - 20.0) / 100.0).astype(int) + 1
    img = np.where((i + j) % 2 == 0, light[i, j], dark[i, j])
    img = cv2.GaussianBlur(img, (0, 0), 1.0) + np.random.default_rng(1).normal(0, 3, img.shape)
    segments = np.array([[60, 0, 60, 239], [160, 0, 160, 239], [260, 0, 260, 239],
                         [0, 20, 319, 20], [0, 120, 319, 120], [0, 220, 319, 220]], float)
    bags = np.array([2, 2, 2, 1, 1, 1], np.int8)
    return np.clip(img, 0, 255).astype(np.uint8), segments, bags


def test_the_tiles_beside_a_checkerboard_line_swap_shades_at_each_crossing() -> None:
    """On a checkerboard both tiles beside a line change shade at each crossing, even where
    tiles of one shade differ (worn marble: 140..210 and 40..100); the edge of a gray box lying
    on the floor, read where a line of the lattice would be, has the box on one side, which
    keeps its level: the swap is under 1, and a reading with that edge is refused
    (``checker.sides``, a foreign line) with the check in its decision."""
    from dataclasses import replace

    from tileviz.vision.decision import CheckResult, Decision, Reading, Tried
    from tileviz.vision.result import VisionResult
    from tileviz.vision.robust.checker import sides_alternate
    from tileviz.vision.robust.settings import DEFAULT_SETTINGS
    from tileviz.vision.views import _sides_swap

    st = DEFAULT_SETTINGS.checker
    rng = np.random.default_rng(3)
    light, dark = rng.uniform(140, 210, (6, 6)), rng.uniform(40, 100, (6, 6))
    img, segments, bags = _checker_view(light, dark)
    crossings, swap = sides_alternate(img, segments, bags, 100.0, st)
    assert crossings >= 6 and swap >= 1.0, swap
    boxed = img.copy()
    boxed[:, :110] = 120  # a box's gray face; its edge at x = 110, half a tile off the lattice
    moved = segments.copy()
    moved[0] = [110, 0, 110, 239]
    crossings, swap = sides_alternate(boxed, moved[[0, 3, 4, 5]], bags[[0, 3, 4, 5]], 100.0, st)
    assert crossings >= 2 and swap < 1.0, swap

    tried = Tried(Reading(0.0, "votes"), (CheckResult("lines.found", 4, 1, ">=", True),), "ok")
    got = VisionResult(observation=None, accepted=True, reason="ok", segments=moved[[0, 3, 4, 5]],
                       bags=bags[[0, 3, 4, 5]],
                       decision=Decision((), (tried,), 0, "ok", None, None))
    refused = _sides_swap(boxed, got, 100.0)
    assert not refused.accepted and refused.reason == "foreign line"
    assert refused.decision is not None and refused.decision.refusal is not None
    assert refused.decision.refusal.check == "checker.sides"
    assert refused.decision.readings[0].checks[-1].check == "checker.sides"
    kept = _sides_swap(img, replace(got, segments=segments, bags=bags), 100.0)
    assert kept.accepted and kept.details["checker_sides"] >= 1.0


def _lattice_lines(y: tuple[float, float, float], ppm: float, lp: float,
                   centre: tuple[float, float], along: float) -> tuple[np.ndarray, np.ndarray]:
    """Two lines of each family of the lattice ``y`` (m, m, rad) as segments 200 px long whose
    midpoints lie ``along`` px from the foot of the view centre's normal on them, and their
    bags (1: the family of y1, 2: of y2); lines where n_k . (p - centre) = (j L - y_k) ppm."""
    from tileviz.vision.geometry import family_normals

    segs, bags = [], []
    for k, n in enumerate(family_normals(y[2])):
        t = (-n[1], n[0])
        for j in (0, 1):
            s = j * lp - y[k] * ppm
            mx, my = centre[0] + s * n[0] + along * t[0], centre[1] + s * n[1] + along * t[1]
            segs.append([mx - 100 * t[0], my - 100 * t[1], mx + 100 * t[0], my + 100 * t[1]])
            bags.append(k + 1)
    return np.array(segs), np.array(bags, np.int8)


def test_a_reading_of_another_image_must_explain_the_lines_the_first_read() -> None:
    """When the luma's reading is refused for a missing line (the edge of a box hides one) and
    a colour projection's reading is accepted, the lines the luma read must lie on the lattice
    accepted, within its bound plus the largest a view may declare, more far from the view's
    centre along a line (its heading bound turns it): the same lattice passes, one turned within
    the bounds passes, one turned 25 degrees (the box's edge read as a line in the tiles' edges'
    place) or moved half a tile along one family is refused as a foreign line, the check
    ``first.lines`` in its decision; through the readings of a view in turn, that refusal is the
    one reported."""
    from dataclasses import replace

    from tileviz.config import FloorModel
    from tileviz.types import Observation
    from tileviz.vision.decision import CheckResult, Decision, Reading, Tried
    from tileviz.vision.result import VisionResult
    from tileviz.vision.views import _explains_first, _first_accepted

    shape, ppm, lp = (480, 640), 100.0 / 0.3, 100.0
    centre = (319.5, 239.5)
    true = Observation(30.0 / ppm, 70.0 / ppm, 0.2, 2.0 / ppm, 0.01)
    segments, bags = _lattice_lines((true.y1, true.y2, true.y3), ppm, lp, centre, 200.0)
    first = VisionResult(observation=None, accepted=False, reason="inconsistent spacing",
                         segments=segments, bags=bags,
                         angles=np.arctan2(segments[:, 3] - segments[:, 1],
                                           segments[:, 2] - segments[:, 0]))
    bounds = (CheckResult("bound.position", 2.0, 5.0, "<=", True),
              CheckResult("bound.heading", 0.01, 0.05, "<=", True))
    tried = Tried(Reading(0.0, "votes"), bounds, "ok")
    got = VisionResult(observation=true, accepted=True, reason="ok",
                       decision=Decision((), (tried,), 0, "ok", None, None))
    floor = FloorModel("grout", 0.0)

    def check(obs: Observation) -> VisionResult:
        return _explains_first(first, replace(got, observation=obs), shape, ppm, lp, floor)

    kept = check(true)
    assert kept.accepted and kept.decision is not None
    assert kept.decision.readings[0].checks[-1].check == "first.lines"
    assert kept.decision.readings[0].checks[-1].value < 0.01
    # turned 0.05 rad: 10 px off at 200 px along, under 7 px + 200 px x 0.06 rad
    turned = check(replace(true, y3=true.y3 + 0.05))
    assert turned.accepted, turned.decision
    for wrong in (replace(true, y3=true.y3 + math.radians(25.0)),
                  replace(true, y1=true.y1 + 50.0 / ppm),
                  replace(true, y2=true.y2 + 50.0 / ppm)):
        refused = check(wrong)
        assert not refused.accepted and refused.reason == "foreign line"
        assert refused.decision is not None and refused.decision.refusal is not None
        assert refused.decision.refusal.check == "first.lines"

    wrong_read = replace(got, observation=replace(true, y1=true.y1 + 50.0 / ppm))
    answers = {0.0: first, 1.0: wrong_read}
    gray = np.random.default_rng(5).integers(0, 256, shape, dtype=np.uint8)
    ramp = np.tile((np.arange(640) // 3).astype(np.uint8), (480, 1))  # unlike the luma

    def read(view: np.ndarray, tm: dict[str, float], as_floor: FloorModel,
             number: float) -> VisionResult:
        return answers[number]

    accepted, reported = _first_accepted([(0.0, lambda: gray), (1.0, lambda: ramp)], gray, {},
                                         floor, read, ppm, lp)
    assert accepted is None and reported.decision is not None
    assert reported.decision.refusal is not None
    assert reported.decision.refusal.check == "first.lines"


def faint_thin_grout_view(seed: int) -> tuple[np.ndarray, floorgen.FloorSpec, Pose]:
    """A view of thin (2 px) light grout 14 gray levels above plain tiles, through a camera
    with noise of 4 levels, a 0.9 px blur and vignetting (a real white ceramic floor seen by a
    plain camera is like it): the image, its floor and the camera's pose."""
    rng = np.random.default_rng([seed, 5150])
    spec = dataclasses.replace(
        floorgen.draw_floor("light_grout", rng), grout_px=2.0, tile_shade=185.0,
        grout_shade=199.0, shade_spread=3.0, noise=4.0, blur=0.9, vignetting=0.3,
        surface="flat", surface_amp=0.0, ppm=106 / 0.3, tile_size=0.3, jpeg=0, gradient=0.0)
    cx, cy, th = floorgen.draw_view(rng)
    return floorgen.render(spec, cx, cy, th, rng), spec, Pose(cx, cy, th)


@pytest.mark.parametrize("seed", [32, 47])
def test_faint_thin_grout_whose_gradients_point_anywhere_is_read_at_its_sharpest_heading(
        seed: int) -> None:
    """On such a view every heading from the gradients and the tile period is a degree or two
    off, which smears a 2 px line into the noise (no lines); the headings near them at which the
    lines are sharpest are read, and read the view (the sharpest heading with the grout's
    polarity imposed, or the lattice heading so, before it), within its bound."""
    img, spec, pose = faint_thin_grout_view(seed)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"))
    assert res.accepted and res.observation is not None and res.decision is not None
    tried = [t.reading.source for t in res.decision.readings]
    assert "sharpened heading" in tried and "first heading" in tried, tried
    e1, e2, e3 = observation_error(res.observation, pose, spec.tile_size, (0.0, 0.0))
    assert max(abs(e1), abs(e2)) <= res.observation.position_error
    assert abs(e3) <= res.observation.heading_error


@pytest.mark.parametrize("family", floorgen.DECLARED_FAMILIES)
def test_each_declared_floor_family_is_read_within_its_bound(family: str) -> None:
    """Checkerboards, hand-laid tiles, mosaic panels and faint coloured grout, each declared as
    its meta.json would (kind, lattice tolerance): no accepted view outside its bound of the
    ideal lattice, and most readable views accepted."""
    rows = [study_view(seed, family, None) for seed in SEEDS]
    for r in rows:
        assert r["inside"], r
    readable = [r for r in rows if r["readable"]]
    assert sum(r["accepted"] for r in readable) >= len(readable) - 1 >= 3, rows


@pytest.mark.parametrize(
    ("family", "seed", "why"),
    [
        ("wood", 15, "a chance alignment of the wavy grain's edges along a straight band"),
        ("photo", 63, "a chance alignment of the gravel photograph's edges"),
        ("photo", 65, "straight edges of the gravel photograph inside the tiles"),
        ("photo", 12, "the brick photograph's mortar lines run into the grout and stop there "
                      "(was a step edge)"),
        ("photo", 54, "the brick photograph's mortar lines run into the grout and stop there "
                      "(was a step edge)"),
        ("photo", 5_000_024, "mortar lines that run on along another tile's mortar beyond "
                             "the grout, which they leave alike (was a foreign line)"),
        ("photo", 5_000_093, "the same, the mortar's edge a step (was a step edge)"),
        ("photo", 5_000_311, "mortar lines that meet the grout at under 0.15 rad (was a "
                             "foreign line)"),
        ("terrazzo", 5, "chips outvote the grout in the gradient directions"),
        ("wood", 24, "the grain outvotes the grout in the gradient directions"),
        ("degraded", 39, "blur, JPEG and a strong lighting gradient: the first heading is 0.75 "
                         "rad off"),
        ("degraded", 33, "blur of 1.6 px: grout edges rise over 3.4 px"),
        ("degraded", 30, "light grout under vignetting and a lighting gradient: the lines' "
                         "depth over the inverted tiles' level differs by 1.9 x"),
        ("shade_steps", 54, "a bright tile cut by the border reads as a narrow peak: the "
                            "dark grout was taken for lighter grout"),
        ("shade_steps", 24, "a line next to a dark tile at the border: the level beyond the "
                            "view (the image mean) hid its edge"),
        ("wide_grout", 92, "a flat-bottomed 19 px band whose deepest sample is at its edge"),
        ("photo", 5_000_258, "a 10 px grout band beside the brick photograph's thin mortar "
                             "lines: the first window could not measure the band, only the "
                             "mortar (was low contrast)"),
        ("photo", 5_000_421, "light grout on a grass photograph: its deepest dip did not "
                             "fit the first window, only shallower ones were measured (was "
                             "low contrast)"),
        ("photo", 5_000_058, "the light stones of a gravel photograph saturate 7 % of the "
                             "pixels in scattered specks (was glare)"),
        ("photo", 5_000_345, "bright grass blades saturate 10 % of the pixels (was glare)"),
        ("degraded", 5_000_253, "a 13 px band of light grout under 1.8 px of blur: its edges "
                                "rise 5.1 px (was blurred)"),
        ("photo", 6_000_079, "the brick photograph's mortar lines give dips off the tile "
                             "period, narrower and weaker than the grout's (was a foreign "
                             "line)"),
        ("photo", 6_000_306, "a mortar dip 12 px off the tile period (was inconsistent "
                             "spacing)"),
        ("photo", 6_000_441, "mortar dips off the tile period, 2.7 x narrower than the grout "
                             "(was a foreign line)"),
        ("photo", 6_000_004, "a mortar edge running into the grout band at the border of the "
                             "view, the grout's centre line beyond it (was a foreign line)"),
        ("photo", 6_000_183, "a mortar edge leaving the grout band near the border, the "
                             "grout's centre line beside it out of view (was a step edge)"),
        ("photo", 174, "2 px grout that the brick photograph's light mortar brightens where "
                       "it meets it, there as all along the line (was a step edge)"),
        ("photo", 127, "the same on 2.9 px grout (was a step edge)"),
        ("degraded", 4_000_442, "the same under noise and JPEG (was a foreign line)"),
        ("degraded", 49, "light grout on tiles 150 levels apart under a lighting gradient: "
                         "the lines' contrasts differ by more than 1.7 x, their depths "
                         "beside the crossings agree (was foreign line)"),
        ("degraded", 6_000_299, "the same, a short line between two light tiles at the "
                                "border (was foreign line)"),
        ("degraded", 6_000_116, "noise 9.3 and JPEG 55 outvote 1.6 px grout on terrazzo in "
                                "the gradient directions: the smoothed view's votes find the "
                                "heading (was one family)"),
        ("degraded", 38, "a grout line between two dark tiles, too shallow to be kept as a "
                         "line, shows as a dip where the lattice puts it (was inconsistent "
                         "spacing)"),
        ("shade_steps", 6_000_051, "light grout beside a light tile at the border: a dip, no "
                                   "line (was inconsistent spacing)"),
        ("coarse", 7_000_311, "0.9 px grout on 1.5 m tiles covers about 1.4 % of the view: "
                              "its 2-98 % gray range was a blank floor's (was constant "
                              "image)"),
        ("photo", 7_000_098, "a light mortar line meets the grout between bricks of nearly "
                             "the grout's gray, its line running on along another tile's "
                             "mortar: the object there is the light ridge, which would have "
                             "brightened the grout (was a foreign line)"),
        ("photo", 6_000_069, "a mortar edge with a 16 % step over dark grout, its line running "
                             "on along another tile's mortar where the tiles show no such "
                             "step: no shadow goes on across the grout (was a foreign line)"),
        ("photo", 7_000_286, "the same, a 13 % step (was a foreign line)"),
        ("photo", 7_000_123, "a mortar edge running along the grout band for 115 px under "
                             "vignetting: the grout's level falls by 18 levels along it, "
                             "smoothly (was a foreign line)"),
        ("photo", 6_000_046, "the same, 17 levels over 133 px (was a foreign line)"),
        ("photo", 6_000_349, "its own bound, 3.04 px, exceeds the 3 px configured (was "
                             "imprecise)"),
        ("photo", 6_000_106, "a mortar edge meets the light grout at 0.1 rad, where its short "
                             "line in view gives no reading of the grout's own variation: "
                             "the grout's level rises by 16 levels over the 180 px read, "
                             "smoothly, about its straight trend (was a step edge)"),
        ("photo", 6_000_370, "the same at 0.085 rad, 20 levels (was a step edge)"),
        ("photo", 121, "the same on dark bricks, 15 levels at 0.14 rad (was a foreign line)"),
        ("photo", 240, "the same, 15 levels falling at 0.1 rad (was a foreign line)"),
        ("photo", 5_000_269, "the same, two mortar edges at 0.06 rad (was a foreign line)"),
        ("photo", 7_000_095, "the same, 9 levels over a 7.6 limit at 0.17 rad (was a foreign "
                             "line)"),
        ("photo", 116, "one part of a short line at the border measured on a mortar joint "
                       "7 px beside the grout, its other three parts within 0.5 px of the "
                       "fit: that part is left out (was inconsistent angle)"),
        ("photo", 6_000_267, "the same on a grass photograph, 7.9 px (was inconsistent "
                             "angle)"),
        ("photo", 5_000_379, "the same, 6.6 px (was inconsistent angle)"),
        ("photo", 6_000_395, "the same on a gravel photograph, 6.6 px (was inconsistent "
                             "angle)"),
        ("photo", 4_000_312, "a light mortar line between bricks of two shades (a 10 % step) "
                             "meets the grout at the border of the view: the levels at the "
                             "edge rise above both sides, a ridge no shadow edge makes (was a "
                             "foreign line)"),
        ("photo", 5_000_488, "the same, an 11 % step (was a step edge)"),
        ("photo", 7_000_325, "the same (was a foreign line)"),
        ("photo", 6_000_351, "the same, the mortar edge passing the grout band near the border "
                             "(was a foreign line)"),
        ("photo", 37, "a light mortar edge running into the grout at the corner of the view, "
                      "one side out of the view beside its last 15 px: its sides read beside "
                      "its last 47 px (was a foreign line)"),
        ("photo", 51, "the same (was a step edge)"),
        ("photo", 8_000_268, "a light mortar ridge at the edge, the next mortar line 8 px "
                             "beside it: the ridge the edge bounds is the one at the edge, "
                             "unlike the grout (was a foreign line)"),
    ],
)
def test_views_once_refused_are_read_within_their_bound(family: str, seed: int, why: str) -> None:
    """Readable clean views the extractor used to refuse (``foreign line``, ``step edge``, ``low
    contrast``, ``no lines``, ``blurred``, ``inconsistent spacing``, ``one family``, ``glare``,
    ``imprecise``; ``why``): texture is told from a foreign object's edge (an edge that stops
    at the grout leaves the grout alike on both sides; when its line runs on beyond the grout,
    what is seen beside it would have changed the grout's level had it crossed), the heading
    is sought from
    the view's periodicity when the lines at the first heading fail their checks, and then the
    other polarity of the grout; a blurred view is read with the wider bound its softer edges
    give; lighter grout's lines are compared in depth over the grout's own level too, and
    beside their crossings; the heading is also sought from the gradient votes of the
    smoothed view; a lattice line that shows as a dip but gives no line is not missing; the
    profile beyond the view continues its last level; a wide band is measured centred on
    itself, and with a window that fits it when only shallower dips could be measured;
    saturated specks of a light texture are not glare; a view may declare a bound wider than
    the configured one, up to the robust extractor's own limit."""
    r = study_view(seed, family, None)
    assert r["readable"] and r["accepted"], (why, r)
    assert r["err_px"] <= r["bound_px"] and r["err_rad"] <= r["bound_rad"], (why, r)


@pytest.mark.parametrize(("seed", "reason"), [
    (148, "foreign line"), (7_000_183, "foreign line"), (4_000_121, "foreign line"),
    (5_000_030, "inconsistent angle")])
def test_a_mortar_line_beside_a_familys_lone_grout_line_is_refused_as_a_cable_would_be(
        seed: int, reason: str) -> None:
    """Brick photographs on the tiles whose mortar runs beside the one grout line of a family
    in view, deeper than 0.3 of it and apart from it (a valley between): one view cannot tell
    that mortar from a cable laid there (``bench/cable_along.py`` seeds 93 mosaic, 106
    light_grout and 378 degraded, read at the cable 9.7, 11.6 and 8.8 px off), so the view is
    refused, as the cable's is (with its first reading's reason)."""
    r = study_view(seed, "photo", None)
    assert r["readable"] and not r["accepted"] and r["reason"] == reason, r


def test_a_trend_of_part_errors_along_a_line_stays_inside_the_heading_bound() -> None:
    """A terrazzo view (chips beside the grout, one line per family) whose part positions once
    erred in a linear trend along the line, which the fit took for a tilt: 7.6 of the tilt's
    standard errors, outside the bound it declared. Its heading error must be inside its own
    bound (the part positions come from the dips' edges, and each part's own bound is carried
    through the fit)."""
    r = study_view(1_000_098, "terrazzo", None)
    assert r["accepted"], r
    assert r["err_rad"] <= r["bound_rad"] and r["err_px"] <= r["bound_px"], r


def test_a_cable_of_the_grouts_own_gray_on_brick_floors_is_never_read_outside_its_bound(
) -> None:
    """Brick photographs whose mortar lines the foreign-edge search lets pass (they run on
    along other tiles' mortar beyond the grout, which they leave alike): a 5 px cable of the
    grout's own gray level, which the grout's level cannot show where it crosses it, laid
    across each view at eight angles, must be refused or read within the declared bound, and
    mostly refused (at least 10 of the 16 views; the exact count moves with rounding-level
    changes of the heading, and with the texture's own edges: the search finds the cable's
    edge in none of the views it reads, and one more view whose mortar step used to refuse it
    by chance is read since that step is seen not to go on beyond the grout)."""
    refused = 0
    for seed in (5_000_024, 5_000_093):
        rng = np.random.default_rng([seed, FAMILY_SALT["photo"], 0])
        spec = floorgen.draw_floor("photo", rng)
        cx, cy, th = floorgen.draw_view(rng)
        img = floorgen.render(spec, cx, cy, th, rng).astype(np.float32)
        cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height,
                           offset=(0.0, 0.0))
        h, w = img.shape[:2]
        for ang in np.linspace(0.1, 3.0, 8):
            d = _offsets(img.shape, ang, (w - 1) / 2, (h - 1) / 2) - 15.0
            cov = np.clip(3.0 - np.abs(d), 0.0, 1.0)[..., None]
            view = np.clip(np.rint(img + cov * (spec.grout_shade - img)), 0, 255)
            res = extract(view.astype(np.uint8), camera=cam, tile_size=spec.tile_size,
                          vision=VisionConfig(extractor="robust"))
            if not res.accepted:
                refused += 1
                continue
            assert res.observation is not None
            e1, e2, e3 = observation_error(res.observation, Pose(cx, cy, th),
                                           spec.tile_size, (0.0, 0.0))
            assert max(abs(e1), abs(e2)) <= res.observation.position_error, (seed, ang)
            assert abs(e3) <= res.observation.heading_error, (seed, ang)
    assert refused >= 10


def _photo_view(seed: int) -> tuple[floorgen.FloorSpec, np.ndarray, CameraConfig, Pose]:
    """The clean photo-family view of ``seed`` (float32 RGB), its camera and true pose."""
    rng = np.random.default_rng([seed, FAMILY_SALT["photo"], 0])
    spec = floorgen.draw_floor("photo", rng)
    cx, cy, th = floorgen.draw_view(rng)
    img = floorgen.render(spec, cx, cy, th, rng).astype(np.float32)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    return spec, img, cam, Pose(cx, cy, th)


def _read(view: np.ndarray, spec: floorgen.FloorSpec, cam: CameraConfig, pose: Pose) -> bool:
    """Extract ``view`` (float RGB); True when accepted, after asserting the observation lies
    within its own declared bound."""
    res = extract(np.clip(np.rint(view), 0, 255).astype(np.uint8), camera=cam,
                  tile_size=spec.tile_size, vision=VisionConfig(extractor="robust"))
    if not res.accepted:
        return False
    assert res.observation is not None
    e1, e2, e3 = observation_error(res.observation, pose, spec.tile_size, (0.0, 0.0))
    assert max(abs(e1), abs(e2)) <= res.observation.position_error, res.details
    assert abs(e3) <= res.observation.heading_error, res.details
    return True


def _clean_lines(img: np.ndarray, spec: floorgen.FloorSpec, cam: CameraConfig) -> np.ndarray:
    """The measured grout lines (segments, px) of the clean view ``img`` (float RGB), which
    must be accepted."""
    clean = extract(np.clip(np.rint(img), 0, 255).astype(np.uint8), camera=cam,
                    tile_size=spec.tile_size, vision=VisionConfig(extractor="robust"))
    assert clean.accepted, clean.reason
    return clean.segments


def _offsets(shape: tuple[int, ...], ang: float, x0: float, y0: float) -> np.ndarray:
    """Each pixel's signed offset (px) from the line through (x0, y0) at angle ``ang`` (rad,
    image axes), for a view of ``shape``."""
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float32)
    return -(xx - x0) * math.sin(ang) + (yy - y0) * math.cos(ang)


def _box_edge_refused(img: np.ndarray, d: np.ndarray, spec: floorgen.FloorSpec,
                      cam: CameraConfig, pose: Pose) -> None:
    """A box (as dark or as light as the renderer's boxes) covering the view where the offset
    ``d`` > 0 is refused."""
    cov = np.clip(d + 0.5, 0.0, 1.0)[..., None]
    for level in (70.0, 190.0):
        assert not _read(img + cov * (level - img), spec, cam, pose), level


@pytest.mark.parametrize(("seed", "min_refused"), [(7_000_098, 8), (7_000_183, 8), (8_000_268, 0)])
def test_a_grout_gray_cable_on_views_read_by_their_light_mortar_ridge_stays_in_bound(
        seed: int, min_refused: int) -> None:
    """Views whose mortar edges the foreign-edge search lets pass because the object beside
    them is a light ridge unlike the grout (the bricks beside it nearly the grout's gray): a
    cable of the grout's own gray, 3 or 8 px wide, laid across at eight angles, is a dark
    ridge of the grout's level and must be refused or read within the declared bound (on
    the first two views mostly refused; on 8 000 268, whose ridge is told from the next
    mortar line 8 px beside it, 11 of the 16 are read, each within its bound)."""
    spec, img, cam, pose = _photo_view(seed)
    h, w = img.shape[:2]
    refused = 0
    for width in (3.0, 8.0):
        for ang in np.linspace(0.1, 3.0, 8):
            d = _offsets(img.shape, ang, (w - 1) / 2, (h - 1) / 2) + 20.0
            cov = np.clip(0.5 * width + 0.5 - np.abs(d), 0.0, 1.0)[..., None]
            refused += not _read(img + cov * (spec.grout_shade - img), spec, cam, pose)
    assert refused >= min_refused


@pytest.mark.parametrize("seed", [6_000_069, 7_000_286])
def test_a_shadow_edge_on_views_read_by_the_far_sides_ratio_stays_in_bound(seed: int) -> None:
    """Views whose mortar steps pass because the tiles beyond the grout show no such step: a
    straight shadow edge across the view, 15 % or 45 % dark (2 px penumbra), at eight angles,
    must be refused or read within the declared bound; the darker one (as the renderer's
    shadows, 35-60 %) nearly always refused."""
    spec, img, cam, pose = _photo_view(seed)
    h, w = img.shape[:2]
    refused = {0.15: 0, 0.45: 0}
    for k in refused:
        for ang in np.linspace(0.1, 3.0, 8):
            d = _offsets(img.shape, ang, (w - 1) / 2, (h - 1) / 2) + 30.0
            t = np.clip(d / 2.0 + 0.5, 0.0, 1.0)[..., None]
            refused[k] += not _read(img * (1.0 - k * t), spec, cam, pose)
    assert refused[0.45] >= 6


@pytest.mark.parametrize("seed", [7_000_123, 6_000_046])
@pytest.mark.parametrize("tilt", [-0.03, 0.03])
def test_a_box_edge_along_the_grout_on_views_read_through_a_trend_stays_in_bound(
        seed: int, tilt: float) -> None:
    """Views whose mortar edge runs along the grout band where the light's gradient changes
    the grout's level smoothly: a box edge laid along a measured grout line, ``tilt`` rad off
    it and crossing it in the middle of the view, the box as dark or as light as the
    renderer's boxes, covers the grout on one side of the crossing and must be refused."""
    spec, img, cam, pose = _photo_view(seed)
    x1, y1, x2, y2 = _clean_lines(img, spec, cam)[0]
    d = _offsets(img.shape, math.atan2(y2 - y1, x2 - x1) + tilt, 0.5 * (x1 + x2),
                 0.5 * (y1 + y2))
    _box_edge_refused(img, d, spec, cam, pose)


@pytest.mark.parametrize("seed", [6_000_106, 240])
@pytest.mark.parametrize("tilt", [-0.1, 0.1])
def test_a_box_edge_crossing_the_grout_shallowly_on_views_read_about_the_trend_is_refused(
        seed: int, tilt: float) -> None:
    """Views whose mortar edges pass because the grout's level, read over a long stretch where
    they meet it at a shallow angle, changes smoothly (the light's trend): a box edge laid
    ``tilt`` rad off a measured grout line, crossing it in the middle of the view, covers the
    grout from the crossing on (a jump the trend leaves whole) and must be refused; a shadow
    edge (45 % dark) or a cable (5 px, the grout's gray or dark) laid the same way must be
    refused or read within the declared bound."""
    spec, img, cam, pose = _photo_view(seed)
    x1, y1, x2, y2 = _clean_lines(img, spec, cam)[0]
    d = _offsets(img.shape, math.atan2(y2 - y1, x2 - x1) + tilt, 0.5 * (x1 + x2),
                 0.5 * (y1 + y2))
    _box_edge_refused(img, d, spec, cam, pose)
    _read(img * (1.0 - 0.45 * np.clip(d / 2.0 + 0.5, 0.0, 1.0)[..., None]), spec, cam, pose)
    for shade in (spec.grout_shade, 30.0):
        cable = np.clip(3.0 - np.abs(d - 3.0), 0.0, 1.0)[..., None]
        _read(img + cable * (shade - img), spec, cam, pose)


@pytest.mark.parametrize(
    ("seed", "edge"),
    [(4_000_312, (191.0, 11.0, 0.3348, -0.9423)), (5_000_488, (282.0, 19.0, 0.7557, -0.6549))],
)
def test_a_shadow_edge_along_a_mortar_ridge_read_as_texture_stays_in_bound(
        seed: int, edge: tuple[float, float, float, float]) -> None:
    """Views whose mortar edges (a light ridge between bricks of two shades, meeting the
    grout at the border of the view) pass because the levels at the edge go beyond both
    sides, which a shadow's edge never does: a straight shadow edge laid along that very
    edge (``edge``: its end, px, and unit direction), 0 or 2 px off it, 15 % to 45 % dark on
    either side, keeps or hides the ridge and must be refused or read within the declared
    bound."""
    spec, img, cam, pose = _photo_view(seed)
    px, py, dx, dy = edge
    h, w = img.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    for off in (-2.0, 0.0, 2.0):
        d = -(xx - px) * dy + (yy - py) * dx - off
        for k in (0.15, 0.3, 0.45):
            for side in (1.0, -1.0):
                t = np.clip(side * d / 2.0 + 0.5, 0.0, 1.0)[..., None]
                _read(img * (1.0 - k * t), spec, cam, pose)


@pytest.mark.parametrize("seed", [116, 6_000_267])
def test_a_short_cable_beside_the_grout_on_views_read_without_a_stray_part_stays_in_bound(
        seed: int) -> None:
    """Views read after leaving out the one part of a line that a texture's dip moved: a
    cable stub (3 px dark or 5 px of the grout's gray) laid beside a measured grout line,
    3 or 4 px off it, along a third of its length (moving the parts it lies beside), or along
    the whole line (moving every part alike: no single part to leave out), must be refused
    or read within the declared bound."""
    spec, img, cam, pose = _photo_view(seed)
    h, w = img.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    for x1, y1, x2, y2 in _clean_lines(img, spec, cam)[:2]:
        length = math.hypot(x2 - x1, y2 - y1)
        ux, uy = (x2 - x1) / length, (y2 - y1) / length
        across = -(xx - x1) * uy + (yy - y1) * ux
        along = (xx - x1) * ux + (yy - y1) * uy
        for f0, f1 in ((0.0, 0.33), (0.33, 0.67), (0.67, 1.0), (-1.0, 2.0)):
            stub = np.clip(np.minimum(along - f0 * length, f1 * length - along) + 0.5, 0, 1)
            for off in (3.0, -4.0):
                for width, shade in ((3.0, 30.0), (5.0, spec.grout_shade)):
                    cov = np.clip(0.5 * width + 0.5 - np.abs(across - off), 0.0, 1.0) * stub
                    _read(img + cov[..., None] * (shade - img), spec, cam, pose)


@pytest.mark.parametrize("seed", [6_000_079, 6_000_441])
@pytest.mark.parametrize("bag", [1, 2])
@pytest.mark.parametrize("width", [3, 5])
def test_a_cable_along_the_grout_off_the_tile_period_is_refused(seed: int, bag: int,
                                                                 width: int) -> None:
    """Brick photographs whose weak mortar dips off the tile period are dropped at the line
    selection (the lattice's periodicity): a cable of the grout's own gray, ``width`` px wide,
    laid across the whole view along one grout family half a tile period off its lines, is as
    strong as the grout and must still be refused."""
    rng = np.random.default_rng([seed, FAMILY_SALT["photo"], 0])
    spec = floorgen.draw_floor("photo", rng)
    cx, cy, th = floorgen.draw_view(rng)
    img = floorgen.render(spec, cx, cy, th, rng)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    vision = VisionConfig(extractor="robust")
    clean = extract(img, camera=cam, tile_size=spec.tile_size, vision=vision)
    assert clean.accepted, clean.reason
    x1, y1, x2, y2 = clean.segments[clean.bags.tolist().index(bag)]
    along = np.array([x2 - x1, y2 - y1])
    normal = np.array([-along[1], along[0]]) / math.hypot(*along)
    mid = np.array([x1, y1]) + 0.5 * spec.tile_size * spec.ppm * normal
    a = tuple(int(v) for v in np.rint(mid - along))
    b = tuple(int(v) for v in np.rint(mid + 2.0 * along))
    view = img.copy()
    cv2.line(view, a, b, (int(spec.grout_shade),) * 3, width, cv2.LINE_AA)
    res = extract(view, camera=cam, tile_size=spec.tile_size, vision=vision)
    assert not res.accepted, res.reason


def unlike_contrast_floor(period_px: float | None = None) -> tuple[
        floorgen.FloorSpec, tuple[float, float, float], Callable[[np.ndarray], np.ndarray]]:
    """A floor whose grout lines are drawn as 4 px bands: one family's of shade 160, the
    other's of shade 80, on tiles of 200 (``period_px``: the tile period in the view, px,
    instead of the drawn floor's); the floor, the view (x, y, heading) and the overlay that
    draws the lines."""
    rng = np.random.default_rng([3, 77])
    spec = dataclasses.replace(floorgen.draw_floor("plain", rng), grout_shade=200.0,
                               tile_shade=200.0, shade_spread=2.0, noise=2.0)
    if period_px is not None:
        spec = dataclasses.replace(spec, tile_size=period_px / spec.ppm)
    cx, cy, th = floorgen.draw_view(rng)
    lp = spec.tile_size * spec.ppm
    bands = []
    for k, shade in ((0, 160.0), (1, 80.0)):
        normal, s0 = floorgen.line_offset(spec, cx, cy, th, k)
        bands += [floorgen.band(spec, normal, s0 + m * lp, 4.0, shade) for m in range(-3, 4)]

    def lines(img: np.ndarray) -> np.ndarray:
        for band in bands:
            img = band(img)
        return img

    return spec, (cx, cy, th), lines


def test_two_families_of_unlike_contrast_are_one_lattice() -> None:
    """Recessed joints under light from one side: every line of one family has twice the
    contrast of every line of the other (a paver mosaic's photoscan shows this), which is no
    foreign line: each family agrees with itself. A cable along one of the fainter lines, as
    dark as the others, is unlike its own family: the view is read without that line, from
    the others, within its bound."""
    spec, (cx, cy, th), lines = unlike_contrast_floor()

    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    pose = Pose(cx, cy, th)
    img = floorgen.render(spec, cx, cy, th, np.random.default_rng(1), overlay=lines)
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"))
    assert res.accepted and res.observation is not None, res.reason
    e1, e2, _ = observation_error(res.observation, pose, spec.tile_size, (0.0, 0.0))
    assert max(abs(e1), abs(e2)) <= res.observation.position_error
    n_lines = res.lines
    normal, s0 = floorgen.line_offset(spec, cx, cy, th, 0)
    # a cable as dark as the other family's lines, along a line and 3 px off its centre
    for off in (0.0, 3.0):
        cable = floorgen.band(spec, normal, s0 + off, 4.0, 80.0)
        img = floorgen.render(spec, cx, cy, th, np.random.default_rng(1),
                              overlay=lambda im, c=cable: c(lines(im)))
        res = extract(img, camera=cam, tile_size=spec.tile_size,
                      vision=VisionConfig(extractor="robust"))
        assert res.accepted and res.observation is not None and res.decision is not None, off
        assert res.decision.readings[0].reason == "foreign line"
        shown = res.decision.readings[res.decision.shown or 0].reading
        assert shown.unlike and shown.kind == "unlike", shown
        assert res.lines == n_lines - 1, (res.lines, n_lines)
        e1, e2, _ = observation_error(res.observation, pose, spec.tile_size, (0.0, 0.0))
        assert max(abs(e1), abs(e2)) <= res.observation.position_error


def test_a_line_unlike_the_only_other_of_its_family_is_not_left_out() -> None:
    """With two lines of each family in view (a tile period of 120 px in a 320 x 240 view), a
    cable along one leaves no majority to tell which is the grout: the reading that would
    leave one out refuses (``foreign_line.left_out``), and so does the view."""
    spec, (cx, cy, th), lines = unlike_contrast_floor(120.0)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    img = floorgen.render(spec, cx, cy, th, np.random.default_rng(1), overlay=lines)
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"))
    assert res.accepted, res.reason
    assert np.count_nonzero(res.bags == 1) == 2 and np.count_nonzero(res.bags == 2) == 2
    normal, s0 = floorgen.line_offset(spec, cx, cy, th, 0)
    cable = floorgen.band(spec, normal, s0, 4.0, 80.0)
    img = floorgen.render(spec, cx, cy, th, np.random.default_rng(1),
                          overlay=lambda im: cable(lines(im)))
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"))
    assert not res.accepted and res.decision is not None, res.reason
    left = [c for t in res.decision.readings if t.reading.unlike for c in t.checks
            if c.check == "foreign_line.left_out"]
    assert left and not any(c.passed for c in left), res.decision.readings


@pytest.mark.parametrize("seed", [49, 74, 81, 149])
def test_a_mosaic_panel_laid_off_the_lattice_within_the_tolerance_is_no_foreign_edge(
        seed: int) -> None:
    """Tuning views of the study's mosaic: each panel is laid up to the declared tolerance off
    the lattice, so a joint's edges may lie that far beyond the band the foreign-edge search
    leaves out around each predicted line; with the band widened by the tolerance each side,
    the joints are no foreign edge, and the view is read within its bound."""
    r = study_view(seed, "mosaic", None)
    assert r["accepted"] and r["inside"], r


def test_a_heading_bound_the_declared_tolerance_widens_past_the_limit_is_no_reason_to_refuse(
) -> None:
    """A tuning view of the study's mosaic (few lines, each laid up to the declared tolerance
    off the lattice): the set of lattices its parts allow reaches 0.199 rad in heading, of which
    the tolerance adds 0.167 (the same set with every part's bound less the tolerance reaches
    0.032), while the tolerance adds only 0.039 rad to the fit's sum. The limit allows each
    bound what the tolerance adds to it, so the view is accepted (it was refused as imprecise
    when the set's reach got the fit's allowance), with the truth inside its bound."""
    from tileviz.vision.robust.settings import DEFAULT_SETTINGS

    r = study_view(163, "mosaic", None)
    assert r["accepted"], r
    assert r["inside"], r
    # past the largest a view may declare plus what the tolerance adds to the fit's sum
    assert r["bound_rad"] > DEFAULT_SETTINGS.bound.max_rad + 0.039, r


@pytest.mark.parametrize(
    ("seed", "family", "refused", "why"),
    [
        (16, "light_grout", True, "a light cable 3 px beside a light grout line: two bands"),
        (41, "photo", True, "a dark cable 3 px beside the grout of a gravel photograph"),
        (1065, "light_grout", True, "a bright cable 20 px off a light grout line, three times "
                                    "as deep: the grout, measured in every part, is no "
                                    "texture to drop off the tile period"),
        (2063, "wood", True, "a dark cable touching the grout, which is a shoulder below half "
                             "the cable's depth in every part"),
        (2091, "degraded", True, "the same under blur and noise"),
        (7, "wide_grout", None, "a cable overlapping an 18 px band widens it by 5 px on one "
                                "side (read within the bound, or refused: the noise-relative "
                                "depth lets the cable's shallower edge through as a dip)"),
        (33, "terrazzo", False, "a 3 px cable touching a 6 px grout line widens it to 10 px"),
        (37, "plain", False, "a 6 px cable 1 px off a 6 px grout line widens it by 1 px"),
        (95, "mosaic", True, "a dark cable 23 px off the one grout line of its family, the "
                             "thin joint a second dip of 0.33 of the cable's darkness"),
        (93, "mosaic", True, "a dark cable 4 px beside a joint whose dip the panels' offsets "
                             "smear: a second dip of 0.4 of the cable's darkness"),
        (106, "light_grout", True, "a light cable 4 px beside a light grout line"),
        (200, "mosaic", True, "a 3 px cable 11 px beside a joint"),
        (368, "checker", True, "an 8 px dark cable over a checkerboard's edge"),
        (343, "mosaic", False, "a 3.6 px cable 4.6 px beside a seam, two lines of the family "
                               "in view: the declared tolerance widens the spacing check past "
                               "the cable, so the band beside it is in the line's bound"),
        (244, "hand_laid", False, "a 5 px cable 6 px off a grout line among others"),
        (113, "mosaic", True, "a 6 px cable 17 px off a thin joint, read for it: 17 px in the "
                              "bound is more than a view may declare"),
        (265, "checker", True, "a light 2.4 px cable 15 px off a checkerboard's edge: the edge "
                               "image refused it; the luma, read next, took the cable for a "
                               "line of lighter grout (on a floor of no grout, a dip of the "
                               "luma is no line)"),
        (378, "degraded", True, "a light cable 3.6 px beside light grout under blur: half the "
                                "grout's darkness stays between the two bands"),
        (261, "light_grout", None, "a cable merged with its family's one line, as wide and "
                                   "deep as the other family's: the band at a quarter of its "
                                   "depth, less half the grout's width, is in the bound"),
        (294, "degraded", None, "the same under blur and noise"),
        (321, "shade_steps", None, "the same between tiles of unlike shades"),
        (431, "light_grout", None, "the same (a cable touching the lone line)"),
        (669, "shade_steps", None, "the same"),
        (739, "checker", None, "a cable over a checkerboard's only edge of its family"),
        (207, "checker", None, "the same, its one segment past a corner left out as stray: "
                               "the bound reaches that segment too"),
        (778, "degraded", None, "the same as 294"),
        (835, "hand_laid", None, "the same on a declared hand-laid floor"),
    ],
)
def test_a_cable_along_a_grout_line_is_refused_or_read_within_its_bound(
        seed: int, family: str, refused: bool | None, why: str) -> None:
    """``bench/cable_along.py``'s views that were accepted outside their bound: a cable
    beside the grout (a second band in the window of its family's one line, a line off the
    lattice spacing, or a shoulder on one side of it) is refused; a cable lying on the grout
    line's edge makes it wider than the view's other lines, and half that excess is in the
    bound; merged with a family's only line in view, the band's reach at a quarter of its depth
    less half the grout's width is. Where that only line is read without a stray part, the part
    left out may be the right one (on a checkerboard the cable moves the edge of each segment
    toward its lighter side, so the segments past a corner disagree), and the bound reaches it.
    """
    r = cable_view(seed, family)
    assert r["inside"], (why, r)
    if refused:
        assert not r["accepted"], (why, r)
    elif refused is not None:
        assert r["accepted"], (why, r)


@pytest.mark.parametrize(("seed", "family", "accepted"), [
    (49, "hand_laid", True), (3, "hand_laid", True), (17, "hand_laid", True),
    (12, "hand_laid", False), (19, "plain", False)])
def test_a_cable_crossing_a_grout_line_at_a_small_angle_is_refused_or_read_within_its_bound(
        seed: int, family: str, accepted: bool) -> None:
    """A cable of the grout's shade crossing a grout line at a few degrees
    (``crossing_cable_view``) is read with the line as one band that turns off it: its parts
    pull the heading off. The fit's sums assume every line right: on hand_laid seed 49 they
    allowed 0.026 rad and the view lay 0.040 rad off. The bound the view declares is the set of
    lattices that the parts of every line but one allow, which holds the truth with that line
    wrong; where that bound exceeds the largest a view may declare (hand_laid 12: 0.090 rad,
    plain 19: 0.054 rad), the view is refused as imprecise, never declared beyond it."""
    r = crossing_cable_view(seed, family)
    assert r["accepted"] == accepted, r
    assert r["inside"], r
    if not accepted:
        assert r["reason"] == "imprecise", r


def test_grout_with_a_bevel_along_every_line_is_read_with_the_band_at_a_quarter_depth_bound(
) -> None:
    """A real floor's joints are not always a symmetric band: a bevel beside each grout line
    (a shadowed edge of the tile) puts a shoulder on every line, which the line checks refuse
    as a cable touching the grout. The view is then read again with each shouldered line's
    parts bounded by its band at a quarter of its depth (``Reading.shoulder``): accepted,
    within that bound; the bevel's side of the band is in the bound, so the bound is wider than
    the same floor's without bevels."""
    spec = floorgen.FloorSpec(family="plain", tile_size=0.3, ppm=400.0, grout_px=3.0,
                              grout_shade=60.0, tile_shade=190.0, shade_spread=5.0,
                              surface="flat", surface_amp=0.0, seed=3)
    lp = spec.tile_size * spec.ppm
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    read = 0
    for cx, cy, th in ((0.41, 0.23, 0.3), (1.1, 0.7, -0.6), (0.05, 2.3, 1.2),
                       (0.9, 0.1, 2.0), (0.3, 0.3, 0.7)):
        def bevels(img: np.ndarray, cx: float = cx, cy: float = cy, th: float = th
                   ) -> np.ndarray:
            for fam in (0, 1):
                normal, s = floorgen.line_offset(spec, cx, cy, th, fam)
                for k in range(-3, 4):
                    img = floorgen.band(spec, normal, s + k * lp + 3.0, 3.0, 140.0)(img)
            return img

        pose = Pose(cx, cy, th)
        plain = extract(floorgen.render(spec, cx, cy, th, np.random.default_rng(1)),
                        camera=cam, tile_size=spec.tile_size,
                        vision=VisionConfig(extractor="robust"))
        res = extract(floorgen.render(spec, cx, cy, th, np.random.default_rng(1),
                                      overlay=bevels),
                      camera=cam, tile_size=spec.tile_size,
                      vision=VisionConfig(extractor="robust"))
        assert res.decision is not None
        first = res.decision.readings[0]
        assert first.checks[-1].check == "foreign_line.shoulder", first
        assert res.reason in ("ok", "imprecise"), res.reason
        if not res.accepted:
            continue
        read += 1
        shown = res.decision.readings[res.decision.shown or 0].reading
        assert shown.shoulder and shown.kind == "shoulder", shown
        assert res.observation is not None and plain.observation is not None
        e1, e2, e3 = observation_error(res.observation, pose, spec.tile_size, (0.0, 0.0))
        assert max(abs(e1), abs(e2)) <= res.observation.position_error
        assert abs(e3) <= res.observation.heading_error
        assert res.observation.position_error > plain.observation.position_error
    assert read >= 3


def test_the_studys_cable_beside_the_grout_of_a_gravel_photograph_is_refused() -> None:
    """Seed 9 000 015's corrupted photo view (the fresh7 split): a dark cable about 10 px
    from a grout line, one line of that family in view, was read at the cable (10.3 px off,
    bound 1.1 px); the grout is a second dip inside the line's window."""
    r = study_view(9_000_015, "photo", "cable")
    assert r["reason"] == "foreign line", r


@pytest.mark.parametrize("family", floorgen.FAMILIES)
def test_a_short_motion_blur_is_read_within_its_bound_or_refused(family: str) -> None:
    """``bench/cable_along.py --motion``'s views (a motion blur of 2-15 px at any angle,
    smearing one family's lines more than the other's): none accepted outside its bound, and
    the blur does not make every view unreadable."""
    rows = [motion_view(seed, family) for seed in range(4)]
    for r in rows:
        assert r["inside"], r
    assert sum(r["accepted"] for r in rows) >= 1, rows


def test_light_grout_smeared_by_motion_blur_into_a_ramp_is_refused_or_bounded() -> None:
    """Tuning seed 39's corrupted shade-steps view: light grout on tiles of strongly
    different shades, smeared by motion blur across one family, was read 8.2 px off against
    a bound of 3.9 px. The smeared band's 25 / 75 % midpoints lie about 1 px off its 50 %
    one in every part (a shoulder, ``RobustSettings.lines.shoulder_px``): it is refused, or
    read on a shoulder reading with each smeared line bounded by its band at a quarter of its
    depth, which holds the error."""
    r = study_view(39, "shade_steps", "motion_blur")
    assert r["inside"], r
    if r["accepted"]:
        assert r["bound_px"] > r["err_px"] > 3.9, r


@pytest.mark.parametrize("corruption", floorgen.CORRUPTIONS)
def test_corrupted_views_are_never_accepted_outside_their_bound(corruption: str) -> None:
    refused = 0
    for i, family in enumerate(("plain", "light_grout", "shade_steps", "wide_grout")):
        r = study_view(100 + i, family, corruption)
        assert r["inside"], r
        refused += not r["accepted"]
    assert refused >= 2


def test_glare_saturates_the_sensor_and_is_refused_as_glare() -> None:
    """The renderer's colour cast comes before the sensor clips: a glare patch is white (gray
    255) in every view, whichever the tint (``spec.seed`` odd or even), and the extractor
    refuses it as glare."""
    tints = set()
    for seed in range(100, 106):
        rng = np.random.default_rng([seed, FAMILY_SALT["plain"], 1])
        spec = floorgen.draw_floor("plain", rng)
        cx, cy, th = floorgen.draw_view(rng)
        img = floorgen.render(spec, cx, cy, th, rng, "glare")
        tints.add(spec.seed % 2)
        assert int(img.min(axis=2).max()) == 255, seed
        assert study_view(seed, "plain", "glare")["reason"] == "glare", seed
    assert tints == {0, 1}


@pytest.mark.parametrize("sigma", [0.0, 1.0, 1.4])
def test_a_blank_floor_is_a_constant_image_and_one_thin_line_is_not(sigma: float) -> None:
    """A blank frame under camera noise (up to 1.4 gray levels) is refused as ``constant
    image``; the same frame crossed by one 1 px dark line is not (it has structure, and is
    refused for what it lacks: a second family)."""
    rng = np.random.default_rng(7)
    blank = np.clip(180.0 + rng.normal(0.0, sigma, (240, 320)), 0, 255).astype(np.uint8)
    cam = CameraConfig(ppm=120.0, width=320, height=240, offset=(0.0, 0.0))
    vision = VisionConfig(extractor="robust")
    res = extract(blank, camera=cam, tile_size=1.5, vision=vision)
    assert res.reason == "constant image"
    lined = blank.copy()
    lined[:, 150] = 80
    res = extract(lined, camera=cam, tile_size=1.5, vision=vision)
    assert not res.accepted and res.reason != "constant image", res.reason


def test_a_wide_blurred_lone_band_refused_in_the_luma_is_read_in_the_joints_image() -> None:
    """A 16 px band under 1.8 px of blur, JPEG 62 and noise 10 (its edges rise 5.7 px) on
    unevenly lit tiles, its family's only line in view: in the luma its bound holds the band's
    reach at a quarter of its depth, more than a view may declare, so the luma's reading is
    refused as imprecise rather than read with a bound it cannot vouch for. The joints image,
    the band's difference from the tiles' level around it, shows it on an even background:
    read there within its own bound."""
    from tileviz.testing.views import FAMILY_SALT
    from tileviz.vision.views import JOINTS

    rng = np.random.default_rng([4_000_058, FAMILY_SALT["degraded"], 0])
    spec = floorgen.draw_floor("degraded", rng)
    cx, cy, th = floorgen.draw_view(rng)
    img = floorgen.render(spec, cx, cy, th, rng, None)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"), floor=spec.model)
    assert floorgen.readable(spec, cx, cy, th)
    assert res.decision is not None
    luma = res.decision.images[0]
    assert luma.startswith("luma: refused (imprecise) by bound.position"), luma
    assert res.accepted and res.details["projection"] == JOINTS, res.reason
    assert res.decision.images[-1] == "joints image: accepted"
    assert _inside(res, Pose(cx, cy, th), spec.tile_size)


def _inside(res: object, pose: Pose, tile_size: float) -> bool:
    """Whether an accepted result's observation holds ``pose`` within its own bound."""
    obs = getattr(res, "observation", None)
    assert obs is not None
    e1, e2, e3 = observation_error(obs, pose, tile_size, (0.0, 0.0))
    return max(abs(e1), abs(e2)) <= obs.position_error and abs(e3) <= obs.heading_error


def test_joints_of_two_widths_are_each_measured_in_a_window_that_fits_them() -> None:
    """A mosaic whose joints along one direction are twice as wide as the others (14 px and
    7 px, the wide ones shallower), declared with a lattice tolerance: the wide family's
    bands reach past the window that measures the narrow, deeper family, and were left
    unmeasured (the view refused for one family). Each family is measured in a window fitting
    its own bands: every view is read, within its bound."""
    from tileviz.config import FloorModel

    rng = np.random.default_rng(5)
    for seed in range(12):
        spec = floorgen.FloorSpec(family="plain", tile_size=0.1, ppm=1000.0, grout_px=7.0,
                                  grout_shade=70.0, tile_shade=170.0, shade_spread=5.0,
                                  surface="flat", surface_amp=0.0, seed=seed, width=512,
                                  height=384, second=(14.0, 120.0))
        cx, cy, th = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(-3, 3)
        cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height,
                           offset=(0.0, 0.0))
        img = floorgen.render(spec, cx, cy, th, np.random.default_rng(seed))
        res = extract(img, camera=cam, tile_size=spec.tile_size, vision=VisionConfig(),
                      floor=FloorModel("grout", 0.004))
        assert res.accepted, (seed, res.reason)
        assert _inside(res, Pose(cx, cy, th), spec.tile_size), seed


def test_the_joints_image_shows_a_dark_and_a_light_joint_alike() -> None:
    """The joints image: a dark joint and a light one (30 gray levels either way, 6 px wide)
    on tiles lit unevenly (a ramp of 80 levels across the view) are two light bands of the
    same depth and width, centred where the joints are; the tiles are dark."""
    from tileviz.vision.colour import joints_image

    x = np.arange(320, dtype=np.float64)
    row = 90.0 + 80.0 * x / 319.0
    row[77:83] -= 30.0  # a dark joint centred at x = 79.5
    row[237:243] += 30.0  # a light one centred at x = 239.5
    gray = np.tile(np.rint(row).astype(np.uint8), (240, 1))
    out = joints_image(gray, 160.0)[120].astype(np.float64)
    for lo, hi in ((77, 83), (237, 243)):
        band = out[lo - 6:hi + 6]
        assert band.max() >= 29.0 and np.count_nonzero(band >= 15.0) == 6, band
        centre = float(np.dot(np.arange(lo - 6, hi + 6), band) / band.sum())
        assert centre == pytest.approx(0.5 * (lo + hi - 1), abs=0.5)
    tiles = np.r_[out[10:70], out[90:230], out[250:310]]
    assert tiles.max() <= 2.0, tiles.max()


@pytest.mark.parametrize("seed", [1, 56, 135, 195])
def test_a_cable_beside_the_grout_stays_two_bands_in_the_joints_image(seed: int) -> None:
    """A dark cable parallel to a grout line, tiles between them (gaps of 1.3 to 10.6 px): the
    luma's reading is refused for a second dip beside a line (``foreign_line.beside``), after
    which the joints image is read too; there the cable and the grout stay two bands, the
    tiles between them, and the view is refused again."""
    rng = np.random.default_rng([seed, FAMILY_SALT["plain"], 2])  # cable_view's draws
    spec = floorgen.draw_floor("plain", rng)
    cx, cy, th = floorgen.draw_view(rng)
    k = int(rng.integers(2))
    delta, width = float(rng.uniform(-25.0, 25.0)), float(rng.uniform(2.0, 10.0))
    shade = float(rng.uniform(10, 60) if rng.uniform() < 0.7 else rng.uniform(200, 250))
    normal, s0 = floorgen.line_offset(spec, cx, cy, th, k)
    img = floorgen.render(spec, cx, cy, th, rng,
                          overlay=floorgen.band(spec, normal, s0 + delta, width, shade))
    assert shade < 128.0 and abs(delta) - 0.5 * (width + spec.grout_px) > 1.0
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    res = extract(img, camera=cam, tile_size=spec.tile_size, vision=VisionConfig())
    assert not res.accepted and res.decision is not None
    images = res.decision.images
    assert "by foreign_line.beside" in images[0], images
    assert images[-1].startswith("joints image: refused"), images


def test_a_joint_with_a_light_fill_between_dark_edges_is_read_in_the_joints_image() -> None:
    """Dark grout 18 px wide, every third joint filled along its middle (30 % of its width)
    with something lighter than the tiles: that joint shows in the luma as two dark dips side
    by side, refused as a second dip beside a line (``foreign_line.beside``); in the joints
    image its dark edges and its light fill are one band, and the view is read there, within
    its bound."""
    from tileviz.vision.views import JOINTS

    spec = floorgen.FloorSpec(family="plain", tile_size=0.1, ppm=1000.0, grout_px=18.0,
                              grout_shade=100.0, tile_shade=150.0, shade_spread=3.0,
                              surface="flat", surface_amp=0.0, seed=1, width=512, height=384,
                              fill=(3, 0.3, 175.0))
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    rng = np.random.default_rng(5)
    for _ in range(2):
        cx, cy, th = rng.uniform(0, 0.1), rng.uniform(0, 0.1), rng.uniform(-0.7, 0.7)
    res = extract(floorgen.render(spec, cx, cy, th, np.random.default_rng(1)), camera=cam,
                  tile_size=spec.tile_size, vision=VisionConfig())
    assert res.decision is not None
    assert "by foreign_line.beside" in res.decision.images[0], res.decision.images
    assert res.accepted and res.details["projection"] == JOINTS, res.reason
    assert _inside(res, Pose(cx, cy, th), spec.tile_size)


def test_joints_filled_with_light_dirt_are_read_at_the_grouts_own_polarity() -> None:
    """Dark grout, every fifth joint filled along its centre with light dirt: the filled
    joints make the strongest narrow peaks, so the profiles call the grout lighter, and the
    lines read at that polarity (the filled joints) miss the lattice (``spacing.missing``).
    The view is then read once more at the other polarity: accepted there, within its bound.
    When that reading is refused too, the luma's refusal is the first reading's, and the
    joints image, where dirt and grout are alike one light band, reads the view within its
    bound."""
    from tileviz.vision.views import JOINTS

    spec = floorgen.FloorSpec(family="plain", tile_size=0.1, ppm=1000.0, grout_px=8.0,
                              grout_shade=125.0, tile_shade=150.0, shade_spread=3.0,
                              surface="flat", surface_amp=0.0, seed=1, width=512, height=384,
                              fill=(5, 0.6, 240.0))
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    for th, edge, in_luma in ((0.01, 110, True), (-0.01, 70, True), (0.0, 40, False)):
        # the filled joints x = 0 and y = 0 ``edge`` px inside the view's top and left sides
        cx, cy = -(191.5 - edge) / spec.ppm, -(255.5 - edge) / spec.ppm
        res = extract(floorgen.render(spec, cx, cy, th, np.random.default_rng(1)),
                      camera=cam, tile_size=spec.tile_size, vision=VisionConfig())
        dec = res.decision
        assert dec is not None and res.accepted, (th, edge, res.reason)
        assert _inside(res, Pose(cx, cy, th), spec.tile_size), (th, edge)
        if not in_luma:  # refused in the luma: read by the joints image instead
            assert res.details["projection"] == JOINTS
            assert dec.images[0] == ("luma: refused (inconsistent spacing) by spacing.missing "
                                     "(family 1) in reading 1: value 1, must be <= 0"), dec.images
            # the luma's lines passed the line checks: the joints image's lattice explains them
            assert dec.shown is not None
            explained = [c for c in dec.readings[dec.shown].checks if c.check == "first.lines"]
            assert len(explained) == 1 and explained[0].passed, explained
            continue
        first = dec.readings[0]
        assert first.reading.polarity == "auto" and first.reason == "inconsistent spacing"
        assert first.checks[-1].check == "spacing.missing", first
        other = dec.readings[1].reading
        assert other.kind == "polarity" and other.polarity == "dark", other
        assert dec.shown == 1


def test_the_other_polarity_refused_too_leaves_the_first_readings_refusal() -> None:
    """A pass's decision (``extractor._pass``): the other polarity, read after a first reading
    whose lines passed but missed the lattice, decides when accepted; refused too, the first
    reading's refusal is the view's. A polarity reading of the unseen-lines stage (the first
    reading's lines did not pass) still reports its own refusal."""
    from types import SimpleNamespace

    from tileviz.vision.robust.extractor import _pass

    def outcome(kind: str, passed: bool, reason: str) -> SimpleNamespace:
        return SimpleNamespace(reading=SimpleNamespace(kind=kind), lines_passed=passed,
                               reason=reason)

    first = outcome("first", True, "inconsistent spacing")
    done = [first, outcome("polarity", True, "foreign line")]
    assert _pass(done, [0, 1]) == ("inconsistent spacing", 0, 0, [0])  # type: ignore[arg-type]
    done = [first, outcome("polarity", True, "ok")]
    assert _pass(done, [0, 1]) == ("ok", 1, None, [0, 1])  # type: ignore[arg-type]
    done = [outcome("first", False, "no lines"), outcome("polarity", True, "imprecise")]
    assert _pass(done, [0, 1]) == ("imprecise", 1, 1, [0, 1])  # type: ignore[arg-type]


def test_faint_grout_above_the_views_noise_is_read_without_a_fixed_floor() -> None:
    """Dark grout 6 gray levels under plain tiles, 2 px wide, through a camera with noise of 3
    levels, a 0.7 px blur and vignetting: its dips are 3.5-5.5 levels deep, well above a part
    profile's noise (0.7 levels) and under any fixed floor of 6 levels. Most views are read,
    each within its own bound (``contrast.depth`` follows the view's noise alone)."""
    accepted = shallow = 0
    for seed in range(12):
        rng = np.random.default_rng([seed, 4242])
        spec = dataclasses.replace(
            floorgen.draw_floor("plain", rng), grout_px=2.0, tile_shade=100.0, grout_shade=94.0,
            shade_spread=2.0, noise=3.0, blur=0.7, vignetting=0.15, surface="flat",
            surface_amp=0.0, ppm=106 / 0.3, tile_size=0.3, jpeg=0, gradient=0.0)
        cx, cy, th = floorgen.draw_view(rng)
        img = floorgen.render(spec, cx, cy, th, rng)
        cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height,
                           offset=(0.0, 0.0))
        res = extract(img, camera=cam, tile_size=spec.tile_size,
                      vision=VisionConfig(extractor="robust"))
        if not res.accepted:
            continue
        assert res.observation is not None and res.decision is not None
        accepted += 1
        e1, e2, e3 = observation_error(res.observation, Pose(cx, cy, th), spec.tile_size,
                                       (0.0, 0.0))
        assert max(abs(e1), abs(e2)) <= res.observation.position_error
        assert abs(e3) <= res.observation.heading_error
        shown = res.decision.readings[res.decision.shown].checks
        depth = next(c.value for c in shown if c.check == "contrast.depth")
        shallow += depth < 6.0
    assert accepted >= 9 and shallow >= 6, (accepted, shallow)
