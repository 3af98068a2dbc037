"""The robust extractor: accepted observations inside their declared bound, sub-pixel on clean
views, and refusals (with a reason) for the frames that would mislead it."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.config import CameraConfig, FloorConfig, VisionConfig, preset
from tileviz.sim.camera import Fault, FloorRenderer, random_camera, random_floor
from tileviz.types import Pose
from tileviz.vision import extract, observation_error
from tileviz.vision.robust import normalise
from tileviz.vision.robust.readings import Outcome
from tileviz.vision.robust.state import View

ROBUST = VisionConfig(extractor="robust")
CFG = preset("default")


def _inside_bound(res: object, pose: Pose, floor: FloorConfig, cam: CameraConfig) -> bool:
    obs = res.observation  # type: ignore[attr-defined]
    e1, e2, e3 = observation_error(obs, pose, floor.tile_size, cam.offset)
    return (
        max(abs(e1), abs(e2)) <= obs.position_error and abs(e3) <= obs.heading_error
    )


@pytest.mark.slow
def test_every_accepted_observation_is_inside_the_declared_bound() -> None:
    """Fixed seeds, random floors and cameras (tile 0.166..1 m, 100..700 px/m, noise, blur,
    vignetting, JPEG, textures, stains), no faults: never an accepted observation outside
    ``VisionConfig.position_error_px / ppm`` and ``heading_error``; and most are accepted."""
    rng = np.random.default_rng(20260)
    accepted = total = 0
    for _ in range(24):
        floor, cam = random_floor(rng), random_camera(rng)
        r = FloorRenderer(floor, cam)
        for _ in range(4):
            pose = Pose(rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(-4, 4))
            res = extract(r.render(pose, rng), camera=cam, tile_size=floor.tile_size,
                          vision=ROBUST)
            total += 1
            if res.accepted:
                accepted += 1
                assert _inside_bound(res, pose, floor, cam), (floor, cam, pose, res.details)
    assert accepted >= 0.5 * total


def test_clean_views_are_read_to_a_fraction_of_a_pixel() -> None:
    r = FloorRenderer(CFG.floor, CFG.camera)
    rng = np.random.default_rng(3)
    worst_px, worst_rad, n = 0.0, 0.0, 0
    for _ in range(30):
        pose = Pose(rng.uniform(-9, 9), rng.uniform(-9, 9), rng.uniform(-4, 4))
        res = extract(r.render(pose, rng), camera=CFG.camera, tile_size=CFG.floor.tile_size,
                      vision=ROBUST)
        if not res.accepted:
            continue
        n += 1
        e1, e2, e3 = observation_error(res.observation, pose, 1.0, CFG.camera.offset)
        worst_px = max(worst_px, abs(e1) * 200.0, abs(e2) * 200.0)
        worst_rad = max(worst_rad, abs(e3))
    assert n >= 27
    assert worst_px < 0.5
    assert worst_rad < 0.004


VIEW = Pose(0.37, 0.61, 0.23)


@pytest.fixture(scope="module")
def renderer() -> FloorRenderer:
    return FloorRenderer(CFG.floor, CFG.camera)


def _run(renderer: FloorRenderer, faults: list | None, seed: int = 0, pose: Pose = VIEW):
    img = renderer.render(pose, np.random.default_rng(seed), faults=faults)
    return extract(img, camera=CFG.camera, tile_size=CFG.floor.tile_size, vision=ROBUST)


def test_the_clean_reference_view_is_accepted(renderer: FloorRenderer) -> None:
    res = _run(renderer, None)
    assert res.accepted, res.reason


@pytest.mark.parametrize(
    ("fault", "reasons"),
    [
        (Fault("cable", {"angle": 1.0, "offset": 10.0, "width": 4.0}), {"foreign line"}),
        (Fault("cable", {"angle": 2.3, "offset": -30.0, "width": 8.0, "gray": 60.0}),
         {"foreign line"}),
        # a box or a shadow: its edge, or the lines it dims, give it away
        (Fault("box", {"angle": 0.9, "offset": 40.0}), {"step edge", "foreign line"}),
        (Fault("shadow", {"angle": 2.0, "offset": -20.0, "strength": 0.4}),
         {"step edge", "foreign line"}),
        (Fault("glare", {"x": 150.0, "y": 110.0, "radius": 50.0}), {"glare"}),
        (Fault("motion_blur", {"angle": 0.23, "length": 30.0}),
         {"blurred", "one family", "no lines"}),
        (Fault("dropout"), {"constant image"}),
    ],
)
def test_faults_across_the_view_are_refused(
    renderer: FloorRenderer, fault: Fault, reasons: set[str]
) -> None:
    from tileviz.vision.colour import RETRY_REASONS
    from tileviz.vision.views import VIEW_REASONS

    res = _run(renderer, [fault])
    assert not res.accepted and res.observation is None
    assert res.reason in reasons, res.details
    # the joints image is read only after a luma whose lines did not show the lattice: a
    # refusal for what the view shows (a cable, a box's or a shadow's edge, blur, glare, a
    # blank view) is final
    read = res.decision.images if res.decision is not None else ()
    joints = any(i.startswith("joints image") for i in read)
    assert joints == (res.reason in RETRY_REASONS - VIEW_REASONS), read


@pytest.mark.parametrize("fault", [
    Fault("cable", {"angle": 1.0, "offset": 10.0, "width": 4.0}),
    Fault("box", {"angle": 0.9, "offset": 40.0}),
    Fault("glare", {"x": 150.0, "y": 110.0, "radius": 50.0}),
    Fault("motion_blur", {"angle": 0.23, "length": 30.0}),
    Fault("dropout"),
    None,
])
def test_a_refusal_names_its_check_with_the_value_that_broke_its_limit(
    renderer: FloorRenderer, fault: Fault | None
) -> None:
    """Every refusal carries the check that refused (a known id whose reason is the result's),
    the value measured and the limit it broke; every check run before it passed or was
    overruled by the next (a rescue), and an accepted view passed every check of the reading
    it shows."""
    from tileviz.vision.robust.checks import CHECKS

    res = _run(renderer, None if fault is None else [fault])
    dec = res.decision
    assert dec is not None and dec.reason == res.reason
    runs = [dec.view_checks] + [t.checks for t in dec.readings]
    assert all(c.check in CHECKS for checks in runs for c in checks)
    if res.accepted:
        assert dec.refusal is None and dec.shown is not None
        assert all(c.passed for c in dec.readings[dec.shown].checks)
        return
    ref = dec.refusal
    assert ref is not None and not ref.passed
    check = CHECKS[ref.check]
    assert check.reason == res.reason or ref.check == "foreign_edge"
    assert not check.relation.passes(ref.value, ref.limit)
    where = dec.view_checks if dec.refused_in is None else dec.readings[dec.refused_in].checks
    assert where[-1] == ref  # the last check run there
    rescued = {"constant.range", "glare.saturated", "foreign_line.contrast"}
    assert all(c.passed or c.check in rescued for c in where[:-1])


def test_the_checks_docstring_lists_every_check_id() -> None:
    from tileviz.vision.robust import checks

    assert all(f"``{cid}``" in checks.__doc__ for cid in checks.CHECKS)


def test_a_cable_along_a_grout_line_direction_off_the_lattice_is_refused(
    renderer: FloorRenderer,
) -> None:
    """A straight cable exactly parallel to the grout lines, between two of them, is a dark
    line in the same profile: the spacing check (or the width check) must catch it."""
    # the grout direction in the image is y3 = theta (mod pi/2) for this view
    res = _run(renderer, [Fault("cable", {"angle": VIEW.theta, "offset": 37.0,
                                          "width": 3.0, "gray": 80.0})])
    assert not res.accepted
    assert res.reason in {"inconsistent spacing", "foreign line"}


@pytest.mark.parametrize("kind", ["cable", "box", "shadow", "glare", "motion_blur"])
def test_random_faults_never_give_an_observation_outside_the_bound(
    renderer: FloorRenderer, kind: str
) -> None:
    refused = 0
    for seed in range(12):
        rng = np.random.default_rng(100 + seed)
        pose = Pose(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4))
        img = renderer.render(pose, rng, faults=[(kind, {})])
        res = extract(img, camera=CFG.camera, tile_size=1.0, vision=ROBUST)
        if res.accepted:
            assert _inside_bound(res, pose, CFG.floor, CFG.camera)
        else:
            refused += 1
    assert refused >= 6


def test_a_wrong_tile_size_is_refused() -> None:
    """Told L = 0.7 m on a 1 m floor, the lines are not multiples of L apart."""
    floor = replace(CFG.floor, tile_size=0.3)
    cam = replace(CFG.camera, ppm=300.0)
    r = FloorRenderer(floor, cam)
    res = extract(r.render(VIEW, np.random.default_rng(0)), camera=cam, tile_size=0.3,
                  vision=ROBUST)
    assert res.accepted, res.reason
    wrong = extract(r.render(VIEW, np.random.default_rng(0)), camera=cam, tile_size=0.21,
                    vision=ROBUST)
    assert not wrong.accepted and wrong.reason == "inconsistent spacing"


def test_low_contrast_and_single_family_views_are_refused() -> None:
    """Grout 8 levels off the tiles under noise of 3 levels: its dips pass the noise-relative
    depth, but not as one lattice's grout (refused); one family of lines: refused."""
    cam = CFG.camera
    faint = replace(CFG.floor, grout_rgb=(205, 198, 184))
    res = extract(FloorRenderer(faint, cam).render(VIEW, np.random.default_rng(0)),
                  camera=cam, tile_size=1.0, vision=ROBUST)
    assert not res.accepted
    assert res.reason in {"low contrast", "no lines", "one family", "foreign line"}
    img = np.full((cam.height, cam.width, 3), 200, np.uint8)
    for r in (40, 140):
        cv2.line(img, (0, r), (cam.width - 1, r), (70, 70, 70), 3, cv2.LINE_AA)
    noise = np.random.default_rng(0).normal(0, 2, img.shape)
    img = np.clip(img + noise, 0, 255).astype(np.uint8)
    res = extract(img, camera=cam, tile_size=0.5, vision=ROBUST)
    assert not res.accepted and res.reason == "one family"
    assert set(res.bags.tolist()) == {1}


def test_a_tighter_declared_bound_refuses_more() -> None:
    """The consistency checks scale with the declared bound: with a bound far below the
    measurement's own scatter the extractor refuses (``imprecise`` or a consistency reason)
    rather than promising it."""
    floor, cam = CFG.floor, replace(CFG.camera, noise_sigma=8.0, jpeg_quality=40)
    r = FloorRenderer(floor, cam)
    tight = replace(ROBUST, position_error_px=0.02, heading_error=0.0002)
    refused = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        pose = Pose(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4))
        img = r.render(pose, rng)
        res = extract(img, camera=cam, tile_size=1.0, vision=tight)
        if res.accepted:
            assert _inside_bound(res, pose, floor, cam)
        else:
            refused += 1
            assert res.reason in {"imprecise", "inconsistent spacing", "inconsistent angle"}
    assert refused >= 4


@settings(max_examples=200, deadline=None)
@given(
    y1=st.floats(0, 0.999),
    y2=st.floats(0, 0.999),
    y3=st.floats(-20, 20),
)
def test_normalise_keeps_the_view(y1: float, y2: float, y3: float) -> None:
    """normalise(y) describes the same view: same camera centres and headings modulo the
    floor's symmetries, with y3 in [-pi/4, pi/4) and y1, y2 in [0, L)."""
    z1, z2, z3 = normalise(y1, y2, y3, 1.0)
    assert -math.pi / 4 <= z3 < math.pi / 4 and 0 <= z1 < 1 and 0 <= z2 < 1
    # a pose whose camera centre is (y1, y2) and heading y3 sees y; it must also see z
    pose = Pose(y1 - 0.3 * math.cos(y3), y2 - 0.3 * math.sin(y3), y3)
    e = observation_error((z1, z2, z3), pose, 1.0, (0.3, 0.0))
    assert max(abs(e[0]), abs(e[1])) < 1e-9 and abs(e[2]) < 1e-9


def test_missing_profile_samples_continue_the_nearest_level() -> None:
    """Beyond the view a profile continues its own last level (not the image mean): a dark
    tile at the border neither becomes a dip nor hides the edge of the grout next to it."""
    from tests.numpy_profiles import fill_ends, profile_dips_numpy
    from tileviz.vision.robust import projection_kernel

    nan = np.nan
    prof = np.array([[nan, nan, 50.0, 50.0, 20.0, 50.0, 60.0, nan, nan],
                     [nan] * 9])
    out = fill_ends(prof, 99.0)
    assert out[0].tolist() == [50, 50, 50, 50, 20, 50, 60, 60, 60]
    assert out[1].tolist() == [99.0] * 9
    # a dark tile (level 60) ends the view right after a grout line (20) between brighter
    # tiles (150): the line is one dip, its darkness measured against the tiles beside it
    row = np.full(80, nan)
    row[10:60] = 150.0
    row[44:48] = 20.0
    row[48:60] = 60.0
    prof = np.vstack([row, row])
    dark, _, fam, peak = profile_dips_numpy(prof, 140.0, 21, 15.0, 8, 5.0)
    assert sorted(set(peak.tolist())) == [44]
    assert np.all(dark[0, 48:60] == 0.0)
    kd, _, kf, kp = projection_kernel.profile_dips(prof, 140.0, 21, 15.0, 8, 5.0)
    assert np.array_equal(kd, dark, equal_nan=True)
    assert kp.tolist() == peak.tolist() and kf.tolist() == fam.tolist()


def test_scattered_saturated_specks_are_not_glare_but_a_saturated_patch_is() -> None:
    """A light texture saturating many scattered specks (light stones, bright blades) leaves
    the floor visible between them; glare washes out one large patch."""
    from tileviz.vision.robust.statistics import glare_share

    rng = np.random.default_rng(3)
    gray = np.full((240, 320), 150, np.uint8)
    for y0 in range(0, 234, 9):  # 3x3 specks, one in every 9x9 cell (11 % of the pixels)
        for x0 in range(0, 315, 9):
            y, x = y0 + int(rng.integers(0, 4)), x0 + int(rng.integers(0, 4))
            gray[y : y + 3, x : x + 3] = 255
    assert float((gray >= 250).mean()) > 0.08
    assert glare_share(gray, 7) == 0.0
    spot = np.full((240, 320), 150, np.uint8)
    cv2.circle(spot, (160, 120), 50, 255, -1)  # 10 % of the pixels, one patch
    assert glare_share(spot, 7) > 0.08


def _drawn_grid(tile_px: int, grout_px: int, angle_deg: float, shift: tuple[float, float],
                *, blur: float) -> np.ndarray:
    """A noise-free 320x240 drawing of flat tiles (gray 200) and dark grout (gray 50), turned
    by ``angle_deg`` about the view centre and shifted by ``shift`` (px) before the turn: most
    of its gradients are exactly zero."""
    big = np.full((720, 720), 200, np.uint8)
    for k in range(0, 720, tile_px):
        big[:, k : k + grout_px] = 50
        big[k : k + grout_px, :] = 50
    m = cv2.getRotationMatrix2D((360.0, 360.0), angle_deg, 1.0)
    m[:, 2] += (shift[0] - 200.0, shift[1] - 240.0)
    view = cv2.warpAffine(big, m, (320, 240), flags=cv2.INTER_LINEAR)
    return cv2.GaussianBlur(view, (0, 0), blur) if blur > 0 else view


@pytest.mark.parametrize("angle", [0.0, 7.0, 23.0, -31.0])
@pytest.mark.parametrize("blur", [0.0, 0.7])
def test_noise_free_drawings_are_read(angle: float, blur: float) -> None:
    """A clean synthetic render or a drawing (no noise, flat tiles: fewer than a fifth of the
    gradients are non-zero) is read, not refused for want of gradients; its heading is the
    drawing's turn (modulo 90 degrees) within the declared bound."""
    img = _drawn_grid(150, 4, angle, (13.0, 29.0), blur=blur)
    cam = CameraConfig(ppm=150.0, width=320, height=240, offset=(0.0, 0.0))
    res = extract(img, camera=cam, tile_size=1.0, vision=ROBUST)
    assert np.count_nonzero(cv2.Scharr(img, cv2.CV_16S, 1, 0)) < 0.2 * img.size
    assert res.accepted, res.reason
    # the drawing turns the floor by +angle on the screen: its lines run at -angle in image
    # coordinates (y down), i.e. y3 = -angle modulo 90 degrees
    turn = math.remainder(res.observation.y3 - math.radians(-angle), math.pi / 2)
    assert abs(turn) <= res.observation.heading_error


@pytest.mark.parametrize("off", [0.02, 0.04])
def test_a_line_read_off_its_heading_widens_no_familys_window(off: float) -> None:
    """Thin grout (about 4 px) read at a heading ``off`` rad from the gradients' first heading:
    a long line read so spreads over its length x off across its profile, a band wider than
    the measurement window. That is the heading's error, not a wide grout: the next warp (at
    the corrected heading) measures every line in the standard window, at the grout's width,
    as a reading at the right heading does."""
    from tileviz.testing import floorgen
    from tileviz.vision import to_gray
    from tileviz.vision.decision import Reading
    from tileviz.vision.robust import extractor, profiles
    from tileviz.vision.robust.readings import read_lines
    from tileviz.vision.robust.settings import DEFAULT_SETTINGS
    from tileviz.vision.robust.state import ReadingState

    rng = np.random.default_rng([0, 99])
    spec = replace(floorgen.draw_floor("plain", rng), width=512, height=384)
    cx, cy, th = floorgen.draw_view(rng)
    img = floorgen.render(spec, cx, cy, th, rng)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    dips = profiles.dips
    flagged: list[tuple[float, float]] = []

    def recording(run, proj, *, every=False):  # type: ignore[no-untyped-def]
        out = dips(run, proj, every=every)
        flagged.append(run.unmeasured_family)
        return out

    widths = []
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        view, refusal = extractor.prepare(to_gray(img), cam, spec.tile_size, ROBUST,
                                          DEFAULT_SETTINGS, {})
        assert refusal is None
        for heading in (view.heading, view.heading + off):
            run = ReadingState(view, Reading(heading, "votes"))
            flagged.clear()
            profiles.dips = recording
            try:
                lines, _, _ = read_lines(run, heading, 0.0)
            finally:
                profiles.dips = dips
            assert run.family_window == (0, 0)
            widths.append(sorted(round(ln.width, 1) for f in lines for ln in f))
    # read off the heading, the first warp saw a family's bands too wide for its window
    assert any(math.isfinite(w) for w in flagged[0]), flagged
    assert widths[1] == pytest.approx(widths[0], abs=0.3)
    assert max(widths[1]) <= spec.grout_px + 1.5


def _shifted(out: Outcome, shift: float, depth: float, turn: int = 0,
             y3: float | None = None) -> Outcome:
    """``out`` as a first reading at the decided polarity that saw one family only: its lines
    ``shift`` px along their normal, its deepest dip ``depth``; read at the heading ``y3``
    (default ``out``'s) plus ``turn`` quarter turns, ``out``'s family 1 then being its family 1
    (``turn`` even) or 2 (odd), the offsets turned with it (a quarter turn maps the offsets
    ``(s1, s2)`` to ``(-s2, s1)``, geometry.family_normals)."""
    from types import MappingProxyType

    assert out.y3 is not None
    cy, cx = out.centre[1], out.centre[0]
    s1 = [-(p - cy) for p in out.positions[0]]  # out's family 1, as lattice_offsets' s
    y = (out.y3 if y3 is None else y3) + turn * 0.5 * math.pi
    if turn % 2 == 0:  # family 1 again (a half turn changes the sign)
        sign = 1.0 if turn % 4 == 0 else -1.0
        positions = (tuple(cy - (sign * s + shift) for s in s1), ())
    else:  # family 2 of the turned heading: s2' = s1 (turn 1) or -s1 (turn 3)
        sign = 1.0 if turn % 4 == 1 else -1.0
        positions = ((), tuple(cx - (sign * s + shift) for s in s1))
    return replace(out, reason="one family", refusal=None, lines_passed=False,
                   positions=positions, y3=y,
                   details=MappingProxyType({**out.details, "depth": depth}))


def _polarity_view(tol_px: float = 0.0) -> tuple[View, Outcome]:
    """A plain synthetic view (``tol_px`` its declared lattice tolerance) and its reading with
    the dark polarity imposed (accepted)."""
    from tileviz.testing import floorgen
    from tileviz.vision import to_gray
    from tileviz.vision.decision import Reading
    from tileviz.vision.robust import extractor
    from tileviz.vision.robust.readings import read
    from tileviz.vision.robust.settings import DEFAULT_SETTINGS

    rng = np.random.default_rng([1, 99])
    spec = floorgen.draw_floor("plain", rng)
    img = floorgen.render(spec, *floorgen.draw_view(rng), rng)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        view, _ = extractor.prepare(to_gray(img), cam, spec.tile_size, ROBUST,
                                    DEFAULT_SETTINGS, {}, tol_px=tol_px)
        out = read(view, Reading(view.heading, "first heading", polarity="dark",
                                 kind="polarity"))
    assert out.reason == "ok"
    return view, out


@pytest.mark.parametrize("turn", [0, 1, 2, 3])
def test_a_reading_of_the_other_polarity_beside_the_decided_ones_deeper_lines_is_refused(
        turn: int) -> None:
    """A first reading at the polarity the profiles decided saw its lines in one family only (a
    motion blur wiped the other), deeper than the lines a reading with the other polarity
    imposed then accepts. Off that reading's lattice, the deeper lines are the grout and the
    accepted ones something beside it (a bevel's shadow along a light ridge): the view is
    refused (``foreign_line.polarity``, their distance from the lattice as value, the
    reading's bound as limit). On it they are the same joints, filled with something of the
    other polarity (light dirt in a mosaic's joints): accepted. Shallower ones are not
    checked. The first reading's heading may be any quarter turn from the other's."""
    from tileviz.vision.robust import extractor
    from tileviz.vision.robust.readings import _deeper_than

    view, out = _polarity_view()
    depth = out.details["depth"]
    third = view.lp / 3.0
    for shift, ratio, refused in ((third, 2.0, True), (0.0, 2.0, False), (third, 0.5, None)):
        first = _shifted(out, shift, ratio * depth, turn)
        got = _deeper_than(view, first, out)
        if refused is None:  # shallower: not checked
            assert got is out
            continue
        check = got.checks[-1]
        assert check.check == "foreign_line.polarity" and check.passed is not refused
        assert check.value == pytest.approx(shift, abs=0.5)
        assert check.limit == pytest.approx(out.details["bound_px"])  # no tolerance declared
        assert (got.reason, got.refusal) == (("foreign line", check) if refused
                                             else ("ok", None))
        end = extractor.conclude(view, None, [first, got])
        assert end.reason == got.reason
        if refused:
            assert end.decision.refusal == check and end.decision.refused_in == 1


def test_deeper_lines_across_the_lattice_or_none_kept_refuse_the_other_polarity() -> None:
    """The decided polarity's deeper lines at a heading farther than the other reading's heading
    bound from both families lie on neither (infinitely far: refused), as when the first reading
    kept no line of its deepest dip; the limit is the reading's bound less the declared
    lattice tolerance (the most a grout line may lie off the lattice)."""
    from tileviz.vision.robust.readings import _deeper_than

    view, out = _polarity_view()
    depth = 2.0 * out.details["depth"]
    assert out.y3 is not None
    across = _shifted(out, 0.0, depth, y3=out.y3 + 2.0 * out.details["bound_rad"])
    none_kept = replace(_shifted(out, 0.0, depth), positions=((), ()))
    within = _shifted(out, 0.0, depth, y3=out.y3 + 0.5 * out.details["bound_rad"])
    for first, refused in ((across, True), (none_kept, True), (within, False)):
        check = _deeper_than(view, first, out).checks[-1]
        assert check.check == "foreign_line.polarity"
        assert check.passed is not refused
        assert math.isinf(check.value) is refused
    tol = 1.5
    view, out = _polarity_view(tol)
    check = _deeper_than(view, _shifted(out, 0.0, 2.0 * out.details["depth"]), out).checks[-1]
    assert check.limit == pytest.approx(out.details["bound_px"] - tol)
    assert check.passed and out.details["bound_px"] > tol


@pytest.mark.parametrize(("third", "ratio", "refused"),
                         [(1.0, 3.0, True), (0.0, 3.0, False), (1.0, 0.5, False)])
def test_the_plan_refuses_an_imposed_polarity_beside_the_decided_ones_deeper_lines(
        monkeypatch: pytest.MonkeyPatch, third: float, ratio: float, refused: bool) -> None:
    """Through :func:`~tileviz.vision.robust.readings.decide`: every reading at the decided
    polarity sees one family only (stubbed: its deepest dip ``ratio`` x the grout's, its lines
    ``third`` x a third of the period off), so the plan reads the other polarity, which reads
    the grout: refused by ``foreign_line.polarity`` when the decided polarity's lines were
    deeper and off its lattice, else accepted."""
    from tileviz.vision.decision import CheckResult
    from tileviz.vision.robust import readings

    view, _ = _polarity_view()
    real = readings.read
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        grout = real(view, readings.Reading(view.heading, "first heading")).details["depth"]
        one_family = CheckResult("lines.families", 0.0, 1.0, ">=", False)

        def decided_sees_one_family(v, reading):  # type: ignore[no-untyped-def]
            out = real(v, reading)
            if reading.polarity != "auto":
                return out
            return replace(_shifted(out, third * v.lp / 3.0, ratio * grout),
                           refusal=one_family,
                           inverted=True)  # read as light grout: the other polarity is dark

        monkeypatch.setattr(readings, "read", decided_sees_one_family)
        done = readings.decide(view, {})
    last = done[-1]
    assert last.reading.polarity == "dark" and last.lines_passed
    polarity = [c for c in last.checks if c.check == "foreign_line.polarity"]
    assert [c.passed for c in polarity] == ([] if ratio < 1.0 else [not refused])
    assert last.reason == ("foreign line" if refused else "ok")
