"""The interval localizer: soundness (the truth never leaves the set when the bounds hold),
tightness (the contraction is the exact answer computed another way), statuses, modes, the box
cap and bad input."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.config import LocalizerConfig
from tileviz.core.contraction import (
    contract_box,
    contract_branch,
    lever_enclosure,
    observation_windows,
)
from tileviz.core.localizer import Localizer
from tileviz.core.prediction import compass_pieces, predict_box
from tileviz.core.tiles import camera_centre, observe, quarter_turn
from tileviz.types import Box, BoxSet, Observation, Odometry, Pose, SensorBounds

FAST = settings(max_examples=80, deadline=None)
BOUNDS = SensorBounds(speed_error=0.02, yaw_rate_error=0.01, compass_error=0.02)
TWO_PI = 2 * math.pi

unit = st.floats(-1.0, 1.0)
frac = st.floats(0.0, 1.0)
tiles = st.sampled_from([0.166, 0.5, 1.0])
offsets = st.sampled_from([(0.0, 0.0), (0.3, 0.0), (0.875, 0.0), (0.25, -0.1), (-0.2, 0.15)])


def _loc(config: LocalizerConfig | None = None, *, tile: float = 1.0,
         offset: tuple[float, float] = (0.3, 0.0), box: Box | None = None,
         bounds: SensorBounds = BOUNDS) -> Localizer:
    return Localizer(
        tile_size=tile,
        camera_offset=offset,
        bounds=bounds,
        config=config or LocalizerConfig(),
        initial=box or Box(-0.1, 0.1, -0.1, 0.1, -0.05, 0.05),
    )


def _box_around(p: Pose, half: tuple[float, float, float], where: tuple[float, float, float]):
    """A box of half-widths ``half`` containing ``p``; ``where`` in [-1, 1]^3 places p in it."""
    cx = p.x - where[0] * half[0]
    cy = p.y - where[1] * half[1]
    ct = p.theta - where[2] * half[2]
    # min/max: the box must hold p exactly, whatever the rounding of the centre
    return Box(min(cx - half[0], p.x), max(cx + half[0], p.x), min(cy - half[1], p.y),
               max(cy + half[1], p.y), min(ct - half[2], p.theta), max(ct + half[2], p.theta))


def _inside(box: Box | tuple, p: Pose, tol: float = 0.0) -> bool:
    b = box.as_tuple() if isinstance(box, Box) else box
    k = math.floor((p.theta - b[4] + tol) / TWO_PI)
    th = p.theta - k * TWO_PI
    return (b[0] - tol <= p.x <= b[1] + tol and b[2] - tol <= p.y <= b[3] + tol
            and b[4] - tol <= th <= b[5] + tol)


# --- prediction ---------------------------------------------------------------------------------


def _arc(p: Pose, v: float, w: float, h: float) -> Pose:
    """Exact motion with constant speed v and yaw rate w for h seconds (unicycle)."""
    half = 0.5 * w * h
    sinc = math.sin(half) / half if half else 1.0
    mid = p.theta + half
    return Pose(p.x + v * h * sinc * math.cos(mid), p.y + v * h * sinc * math.sin(mid),
                p.theta + w * h)


def _simulate(p: Pose, vs: list[float], ws: list[float], dt: float) -> Pose:
    """The true path: piecewise-constant (v, w) over len(vs) equal sub-steps of dt, each an exact
    arc."""
    h = dt / len(vs)
    for v, w in zip(vs, ws, strict=True):
        p = _arc(p, v, w, h)
    return p


SIM_TOL = 1e-11
"""The float simulation of the truth itself rounds (a few hundred operations): the true end pose
may be off by ~1e-13 m; the check allows 1e-11. Outward rounding of the prediction is checked
exactly (rationals) in test_prediction_bounds_are_outward_rounded."""


@FAST
@given(
    st.floats(-5, 5), st.floats(-5, 5), st.floats(-10, 10),
    st.tuples(st.floats(0, 0.3), st.floats(0, 0.3), st.floats(0, 0.5)),
    st.tuples(unit, unit, unit),
    st.floats(-1.0, 1.5), st.floats(-1.5, 1.5), st.floats(0.0, 1.0),
    st.tuples(frac, frac), st.tuples(unit, unit),
)
def test_prediction_contains_the_true_arc_constant_inputs(
    x, y, th, half, where, v_meas, w_meas, dt, errs, pick
) -> None:
    ev, ew = 0.1 * errs[0], 0.2 * errs[1]
    p0 = Pose(x, y, th)
    box = _box_around(p0, half, where)
    v_true = v_meas + pick[0] * ev
    w_true = w_meas + pick[1] * ew
    end = _simulate(p0, [v_true] * 50, [w_true] * 50, dt)
    pred = predict_box(box.as_tuple(), v_meas - ev, v_meas + ev, w_meas - ew, w_meas + ew, dt)
    assert _inside(pred, end, SIM_TOL)
    # the same through the Localizer (bounds outward-rounded there too)
    loc = _loc(box=box, bounds=SensorBounds(ev, ew, 0.1))
    step = loc.step(Odometry(v_meas, w_meas, dt), None, None)
    assert step.status == "predicted"
    assert step.updated.contains(end.x, end.y, end.theta) or _inside(
        step.updated.boxes[0], end, SIM_TOL
    )


@FAST
@given(st.integers(0, 2**32 - 1), st.floats(0.05, 1.0), st.floats(0.0, 0.3), st.floats(0, 0.5))
def test_prediction_contains_the_true_arc_varying_inputs(seed, dt, ev, ew) -> None:
    """Speed and yaw rate change 64 times within the step, each within its bound."""
    rng = np.random.default_rng(seed)
    p0 = Pose(*rng.uniform(-3, 3, 2), rng.uniform(-7, 7))
    box = _box_around(p0, tuple(rng.uniform(0, 0.2, 3)), tuple(rng.uniform(-1, 1, 3)))
    v_meas, w_meas = rng.uniform(-0.5, 1.5), rng.uniform(-2, 2)
    vs = list(v_meas + ev * rng.uniform(-1, 1, 64))
    ws = list(w_meas + ew * rng.choice([-1.0, 1.0, 0.3], 64))
    end = _simulate(p0, vs, ws, dt)
    pred = predict_box(box.as_tuple(), v_meas - ev, v_meas + ev, w_meas - ew, w_meas + ew, dt)
    assert _inside(pred, end, SIM_TOL)


@FAST
@given(st.floats(-100, 100), st.floats(-100, 100), st.floats(-3, 3), st.floats(0, 2))
def test_prediction_bounds_are_outward_rounded(x, y, v, dt) -> None:
    # heading exactly 0, no yaw, no error: the exact end is (x + v dt, y), in rationals
    lo_x, hi_x, lo_y, hi_y, lo_t, hi_t = predict_box((x, x, y, y, 0.0, 0.0), v, v, 0.0, 0.0, dt)
    exact = Fraction(x) + Fraction(v) * Fraction(dt)
    assert Fraction(lo_x) < exact < Fraction(hi_x)
    assert lo_y < y < hi_y and lo_t <= 0.0 <= hi_t
    assert hi_x - lo_x < 1e-12 * (1 + abs(x))


def test_prediction_is_not_an_euler_step() -> None:
    # a half turn in one step: Euler would move along the initial heading only; the enclosure
    # must contain the arc's end, which lies to the side
    p0 = Pose(0.0, 0.0, 0.0)
    end = _simulate(p0, [1.0] * 100, [math.pi] * 100, 1.0)
    pred = predict_box((0.0, 0.0, 0.0, 0.0, 0.0, 0.0), 1.0, 1.0, math.pi, math.pi, 1.0)
    assert end.y == pytest.approx(2 / math.pi)
    assert _inside(pred, end, SIM_TOL)
    assert pred[3] >= 1.0 - 1e-12  # the box reaches dt * v * max sin over the turn


# --- compass ------------------------------------------------------------------------------------


def test_compass_wraps_across_pi() -> None:
    # the box heading [3.0, 3.3] crosses pi; the compass says -3.1 (= 3.183 - 2 pi)
    (b,) = compass_pieces((0, 1, 0, 1, 3.0, 3.3), -3.1 - 0.05, -3.1 + 0.05)
    assert b[4] == pytest.approx(TWO_PI - 3.15) and b[5] == pytest.approx(TWO_PI - 3.05)


def test_compass_meets_a_heading_many_turns_away() -> None:
    # a continuous heading after two turns: [12.5, 12.7]; compass wrap(12.6) = 12.6 - 4 pi
    c = math.remainder(12.6, TWO_PI)
    (b,) = compass_pieces((0, 1, 0, 1, 12.5, 12.7), c - 0.02, c + 0.02)
    assert b[4] == pytest.approx(12.58) and b[5] == pytest.approx(12.62)


def test_compass_can_split_a_wide_heading_in_two() -> None:
    pieces = compass_pieces((0, 1, 0, 1, -4.0, 4.0), 2.9, 3.1)
    assert [(round(p[4], 9), round(p[5], 9)) for p in pieces] == [
        (round(2.9 - TWO_PI, 9), round(3.1 - TWO_PI, 9)), (2.9, 3.1)
    ]
    # the two pieces are the same headings modulo 2 pi: the localizer keeps one box
    loc = _loc(box=Box(0, 1, 0, 1, -4.0, 4.0), bounds=SensorBounds(0.0, 0.0, 0.1))
    (b,) = loc.step(None, 3.0, None).updated.boxes
    assert b.t_hi - b.t_lo == pytest.approx(0.2)
    assert b.contains(0.5, 0.5, 3.0) and not b.contains(0.5, 0.5, 3.2)


def test_a_compass_that_misses_the_set_is_ignored_and_flagged() -> None:
    loc = _loc(box=Box(0, 1, 0, 1, 0.0, 0.2))
    step = loc.step(None, 2.0, None)
    assert step.compass_rejected
    assert step.updated.boxes[0].as_tuple() == (0, 1, 0, 1, 0.0, 0.2)


@FAST
@given(st.floats(-30, 30), st.floats(0, 1), st.floats(-1, 1), st.floats(0.001, 0.3),
       st.floats(0.0, 3.0))
def test_compass_keeps_the_true_heading(theta, where, err, ec, half) -> None:
    truth = Pose(0.5, 0.5, theta)
    box = _box_around(truth, (0.1, 0.1, half), (0.0, 0.0, 2 * where - 1))
    # the error stays (1 - 1e-6) inside its bound so the float sum cannot round past it
    reading = math.remainder(theta + err * (1 - 1e-6) * ec, TWO_PI)  # wrapped to [-pi, pi]
    loc = _loc(box=box, bounds=SensorBounds(0.0, 0.0, ec))
    step = loc.step(None, reading, None)
    assert not step.compass_rejected
    assert step.updated.contains(*truth.as_tuple())
    for b in step.updated.boxes:
        assert b.t_hi - b.t_lo <= 2 * ec + 1e-9


# --- contraction: soundness ---------------------------------------------------------------------

cases = st.tuples(
    tiles, offsets,
    st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-10, 10)),
    st.tuples(st.floats(0.001, 0.2), st.floats(0.001, 0.15)),  # e / L, e3
    st.tuples(unit, unit, unit),  # observation error, as a fraction of its bound
    st.tuples(st.floats(0.0, 1.5), st.floats(0.0, 1.5), st.floats(0.0, 1.0)),  # half widths
    st.tuples(unit, unit, unit),  # where the truth sits in the box
)


def _case(c, offset_override: tuple[float, float] | None = None):
    L, offset, p, (e_rel, e3), err, half, where = c
    if offset_override is not None:
        offset = offset_override
    truth = Pose(*p)
    e = e_rel * L
    y1, y2, y3 = observe(truth, L, offset)
    # errors up to (1 - 1e-6) of the bound, so that rounding y + error in floats cannot push the
    # observation a hair outside its declared bound
    err = [v * (1 - 1e-6) for v in err]
    obs = Observation(y1 + err[0] * e, y2 + err[1] * e, y3 + err[2] * e3, e, e3)
    box = _box_around(truth, (half[0] * L, half[1] * L, half[2]), where)
    return L, offset, truth, obs, box


@FAST
@given(cases)
def test_contraction_keeps_the_truth(c) -> None:
    L, offset, truth, obs, box = _case(c)
    loc = _loc(LocalizerConfig(max_boxes=64, passes=10), tile=L, offset=offset, box=box)
    step = loc.step(None, None, obs)
    assert step.status == "contracted"
    assert step.updated.contains(*truth.as_tuple())
    hull = step.updated.hull()
    for a, b in zip(hull.widths, box.widths, strict=True):
        assert a <= b + 1e-12
    # boxes of the set are disjoint
    bs = step.updated.boxes
    for i, a in enumerate(bs):
        for b in bs[i + 1:]:
            assert (a.x_hi < b.x_lo or b.x_hi < a.x_lo or a.y_hi < b.y_lo or b.y_hi < a.y_lo
                    or not _headings_meet(a, b))


def _headings_meet(a: Box, b: Box) -> bool:
    k = math.floor((a.t_lo - b.t_hi) / TWO_PI)
    return any(a.t_lo <= b.t_hi + j * TWO_PI and b.t_lo + j * TWO_PI <= a.t_hi
               for j in range(k - 1, k + 3))


@FAST
@given(cases, st.tuples(unit, unit, unit), st.floats(-0.5, 1.0), st.floats(-1.0, 1.0))
def test_a_full_step_keeps_the_truth(c, errs, v_true, w_true) -> None:
    """Predict from the previous frame with bounded odometry, cut with the compass, contract with
    the view: the true pose stays in both sets. The previous pose is the truth driven back along
    the true arc (v_true, w_true) for dt; the sensors read within their bounds."""
    L, offset, truth, obs, _ = _case(c)
    dt = 0.05
    prev = _simulate(truth, [-v_true] * 20, [-w_true] * 20, dt)  # time reversal of the arc
    box = _box_around(prev, (0.05, 0.05, 0.03), (0.3, -0.2, 0.5))
    bounds = SensorBounds(0.1, 0.05, 0.02)
    errs = [v * (1 - 1e-6) for v in errs]  # strictly within the bounds (float rounding)
    loc = _loc(tile=L, offset=offset, box=box, bounds=bounds)
    odo = Odometry(v_true + errs[0] * 0.1, w_true + errs[1] * 0.05, dt)
    step = loc.step(odo, math.remainder(truth.theta + errs[2] * 0.02, TWO_PI), obs)
    assert step.status == "contracted"
    assert _inside(step.predicted.hull(), truth, SIM_TOL)
    assert any(_inside(b, truth, SIM_TOL) for b in step.updated.boxes)


# --- contraction: tightness ---------------------------------------------------------------------


def _branch_pieces(box: tuple, obs: Observation):
    """For every branch m and heading turn j whose window [y3 +- e3] + m pi/2 + 2 pi j meets the
    box heading: (m, j, (u1_lo, u1_hi, u2_lo, u2_hi), heading piece), where
    [u] = R(m pi/2) ([y1 +- e], [y2 +- e]). Plain floats, by enumeration."""
    e, e3 = obs.position_error, obs.heading_error
    for m in range(4):
        u1_lo, u2_lo = quarter_turn(m, obs.y1 - e, obs.y2 - e)
        u1_hi, u2_hi = quarter_turn(m, obs.y1 + e, obs.y2 + e)
        u1_lo, u1_hi = sorted((u1_lo, u1_hi))
        u2_lo, u2_hi = sorted((u2_lo, u2_hi))
        for j in range(-6, 7):
            h = obs.y3 + m * math.pi / 2 + j * TWO_PI
            a, b = max(box[4], h - e3), min(box[5], h + e3)
            if a <= b:
                yield m, j, (u1_lo, u1_hi, u2_lo, u2_hi), (a, b)


def _brute_force_no_lever(box: tuple, obs: Observation, L: float) -> list[tuple]:
    """The exact contracted set with the camera on the robot point, by enumerating lattice
    indices: for every branch m, heading turn j and tile (kx, ky), the box
    [x] ∩ [u1 + kx L] x [y] ∩ [u2 + ky L] x [t] ∩ [y3 +- e3 + m pi/2 + 2 pi j] when non-empty.
    Plain float arithmetic (no outward rounding), compared to 1e-9."""
    x_lo, x_hi, y_lo, y_hi, _, _ = box
    out = []
    for _m, _j, (u1_lo, u1_hi, u2_lo, u2_hi), (a, b) in _branch_pieces(box, obs):
        xs = [(max(x_lo, u1_lo + k * L), min(x_hi, u1_hi + k * L)) for k in range(-60, 61)]
        ys = [(max(y_lo, u2_lo + k * L), min(y_hi, u2_hi + k * L)) for k in range(-60, 61)]
        for px in xs:
            for py in ys:
                if px[0] <= px[1] and py[0] <= py[1]:
                    out.append((*px, *py, a, b))
    return sorted(out)


@FAST
@given(cases)
def test_contraction_without_lever_arm_is_exact(c) -> None:
    L, _, truth, obs, box = _case(c, (0.0, 0.0))
    got, passes, hulled = contract_box(
        box.as_tuple(), observation_windows(obs), L, lever_enclosure((0.0, 0.0)), 5, 10**6
    )
    exact = _brute_force_no_lever(box.as_tuple(), obs, L)
    assert not hulled and passes == 1  # the truth's cell is always there; one pass is final
    assert len(got) == len(exact)
    for g, x in zip(sorted(got), exact, strict=True):
        assert max(abs(a - b) for a, b in zip(g, x, strict=True)) < 1e-9
        assert g[0] <= x[0] and g[1] >= x[1] and g[2] <= x[2] and g[3] >= x[3]


@FAST
@given(cases, st.floats(0.001, 1.0))
def test_contract_box_is_the_union_of_the_four_branches(c, e3) -> None:
    """contract_box finds the branch pieces in one pass over the pi/2-lattice of headings (or
    branch by branch when e3 >= pi/4, where the windows overlap); contract_branch cuts each branch
    on its own 2 pi-lattice. Same boxes."""
    L, offset, _, obs, box = _case(c)
    obs = Observation(obs.y1, obs.y2, obs.y3, obs.position_error, e3)
    win = observation_windows(obs)
    lever = lever_enclosure(offset)
    got, _, _ = contract_box(box.as_tuple(), win, L, lever, 5, 10**6)
    ref = [b for m in range(4) for b in contract_branch(box.as_tuple(), win[m], L, lever, 5,
                                                        10**6)[0]]
    assert len(got) == len(ref)
    for g, r in zip(sorted(got), sorted(ref), strict=True):
        assert max(abs(a - b) for a, b in zip(g, r, strict=True)) < 1e-12


N_THETA = 3001


def _sampled_cells(box: tuple, obs: Observation, L: float, offset: tuple[float, float]):
    """The exact solution set, cell by cell, by dense sampling of the heading.

    For a heading t the camera sits at (x, y) + g(t) with g(t) = R(t) @ offset, so the robot x is
    exactly X(t) = [x] ∩ ([u1 + kx L] - g_x(t)) (an interval), likewise Y(t). A cell
    (m, j, kx, ky) is feasible at t iff X(t) and Y(t) are non-empty. Returns, per feasible cell,
    (hull of the feasible samples: x, y, t), plus the hull of the headings where the x constraint
    alone (resp. y alone) is feasible, and the sampling step."""
    x_lo, x_hi, y_lo, y_hi, _, _ = box
    f, left = offset
    cells = {}
    for m, j, (u1_lo, u1_hi, u2_lo, u2_hi), (a, b) in _branch_pieces(box, obs):
        t = np.linspace(a, b, N_THETA)
        gx = f * np.cos(t) - left * np.sin(t)
        gy = f * np.sin(t) + left * np.cos(t)
        step = (b - a) / (N_THETA - 1)
        kx_all = range(math.floor((x_lo + gx.min() - u1_hi) / L) - 1,
                       math.ceil((x_hi + gx.max() - u1_lo) / L) + 2)
        ky_all = range(math.floor((y_lo + gy.min() - u2_hi) / L) - 1,
                       math.ceil((y_hi + gy.max() - u2_lo) / L) + 2)
        for kx in kx_all:
            xl = np.maximum(x_lo, u1_lo + kx * L - gx)
            xh = np.minimum(x_hi, u1_hi + kx * L - gx)
            okx = xl <= xh
            if not okx.any():
                continue
            for ky in ky_all:
                yl = np.maximum(y_lo, u2_lo + ky * L - gy)
                yh = np.minimum(y_hi, u2_hi + ky * L - gy)
                oky = yl <= yh
                ok = okx & oky
                if not ok.any() and not oky.any():
                    continue
                cells[(m, j, kx, ky)] = {
                    "hull": None if not ok.any() else (
                        xl[ok].min(), xh[ok].max(), yl[ok].min(), yh[ok].max(),
                        t[ok].min(), t[ok].max()),
                    "tx": (t[okx].min(), t[okx].max()),
                    "ty": (t[oky].min(), t[oky].max()) if oky.any() else None,
                    "gap": _has_gap(okx) or _has_gap(oky),
                    "step": step,
                }
    return cells


def _has_gap(ok: np.ndarray) -> bool:
    idx = np.flatnonzero(ok)
    return idx.size > 0 and idx[-1] - idx[0] + 1 != idx.size


@settings(max_examples=40, deadline=None)
@given(cases, st.sampled_from([(0.3, 0.0), (0.875, 0.0), (0.25, -0.1), (-0.2, 0.15)]))
def test_contraction_with_lever_arm_is_the_sampled_hull(c, offset) -> None:
    """Soundness: every feasible sampled pose is in the result. Tightness: each box of the result
    is the exact hull of its cell's solution set within the sampling slack (heading: 2 steps;
    position: rho * 2 steps + 1e-9) -- except where the heading preimage of one constraint alone
    has a gap inside the cell (the lever arm swings the camera past an extremum of cos / sin):
    there a forward-backward contraction keeps the hull of that preimage (as codac does), so the
    box is only checked against hull(t_x) ∩ hull(t_y)."""
    L, _, truth, obs, box = _case(c)
    obs = Observation(*observe(truth, L, offset), obs.position_error, obs.heading_error)
    got, _, _ = contract_box(
        box.as_tuple(), observation_windows(obs), L, lever_enclosure(offset), 50, 10**6
    )
    cells = _sampled_cells(box.as_tuple(), obs, L, offset)
    rho = math.hypot(*offset)
    exact_cells = [v for v in cells.values() if v["hull"] is not None]
    assert exact_cells and got
    for cell in exact_cells:  # soundness
        assert any(_contains(g, cell["hull"], 1e-12) for g in got)
    for g in got:  # tightness
        match = [v for v in exact_cells if _contains(g, v["hull"], 1e-12)]
        if not match:  # a sliver the sampling missed
            assert g[5] - g[4] <= 2 * max(v["step"] for v in cells.values())
            continue
        # cells overlap in robot coordinates (the lever arm): take the nearest one
        v = min(match, key=lambda m: max(abs(a - b) for a, b in zip(g, m["hull"], strict=True)))
        s = 2 * v["step"]
        if not v["gap"]:
            ref = v["hull"]
            slack = (rho * s + 1e-9, rho * s + 1e-9, s + 1e-9)
        else:
            ty = v["ty"]
            ref = (*v["hull"][:4], max(v["tx"][0], ty[0]), min(v["tx"][1], ty[1]))
            slack = (np.inf, np.inf, s + 1e-9)
        for d in range(3):
            assert g[2 * d] >= ref[2 * d] - slack[d]
            assert g[2 * d + 1] <= ref[2 * d + 1] + slack[d]


def _contains(outer: tuple, inner: tuple, tol: float) -> bool:
    return all(outer[2 * d] <= inner[2 * d] + tol and inner[2 * d + 1] <= outer[2 * d + 1] + tol
               for d in range(3))


def test_contraction_needs_at_most_two_passes_in_tracking() -> None:
    """With a lever arm a pass can narrow the heading, and then the next pass narrows x and y:
    measured here, the fixpoint is reached after at most 2 passes in a typical tracking box
    (bench/bench_localizer.py reports the distribution)."""
    rng = np.random.default_rng(3)
    seen = set()
    for _ in range(300):
        truth = Pose(*rng.uniform(-3, 3, 2), rng.uniform(-4, 4))
        y = observe(truth, 1.0, (0.3, 0.0))
        obs = Observation(*y, 0.01, 0.02)
        box = _box_around(truth, (0.03, 0.03, 0.03), tuple(rng.uniform(-1, 1, 3)))
        _, passes, _ = contract_box(box.as_tuple(), observation_windows(obs), 1.0,
                                    lever_enclosure((0.3, 0.0)), 50, 16)
        seen.add(passes)
    assert max(seen) <= 2 and 1 in seen


# --- statuses and modes -------------------------------------------------------------------------


def _obs_for(p: Pose, L: float = 1.0, offset: tuple[float, float] = (0.3, 0.0)) -> Observation:
    return Observation(*observe(p, L, offset), 0.01, 0.02)


def test_statuses_contracted_predicted_rejected() -> None:
    truth = Pose(0.02, -0.03, 0.01)
    loc = _loc()
    assert loc.step(None, None, _obs_for(truth)).status == "contracted"
    assert loc.step(Odometry(0.0, 0.0, 0.05), None, None).status == "predicted"
    # a view that fits no pose of the set: 0.4 m off in x (the set is a few cm wide now)
    bad = Observation(*observe(Pose(0.42, -0.03, 0.01), 1.0, (0.3, 0.0)), 0.01, 0.02)
    before = loc.current
    step = loc.step(None, None, bad)
    assert step.status == "rejected" and step.rejections == 1
    assert step.updated == before  # the prediction is kept
    assert loc.step(None, None, _obs_for(truth)).status == "contracted"
    assert loc.step(None, None, None).rejections == 0


def test_lost_after_max_rejections_and_sticky_until_reset() -> None:
    truth = Pose(0.0, 0.0, 0.0)
    loc = _loc(LocalizerConfig(max_rejections=3))
    bad = Observation(0.5, 0.5, 0.3, 0.01, 0.02)  # a view 0.5 m and 17 deg off
    statuses = [loc.step(Odometry(0.0, 0.0, 0.05), None, bad).status for _ in range(3)]
    assert statuses == ["rejected", "rejected", "lost"]
    # still lost even with a good view; output is one box (the hull of the prediction)
    step = loc.step(Odometry(0.0, 0.0, 0.05), None, _obs_for(truth))
    assert step.status == "lost" and len(step.updated) == 1
    assert loc.lost
    loc.reset(Box(-0.05, 0.05, -0.05, 0.05, -0.02, 0.02))
    assert not loc.lost
    assert loc.step(None, None, _obs_for(truth)).status == "contracted"


def test_frames_without_a_view_do_not_reset_the_rejection_streak() -> None:
    loc = _loc(LocalizerConfig(max_rejections=2))
    bad = Observation(0.5, 0.5, 0.3, 0.01, 0.02)
    assert loc.step(None, None, bad).status == "rejected"
    assert loc.step(None, None, None).status == "predicted"
    assert loc.step(None, None, bad).status == "lost"


def test_truth_mode_resets_to_the_inflated_truth_every_frame() -> None:
    cfg = LocalizerConfig(mode="truth", truth_inflation=(0.3, 0.3, 0.2))
    truth = Pose(5.0, -2.0, 1.0)
    loc = _loc(cfg)  # the initial box is far from the truth: truth mode ignores it
    step = loc.step(Odometry(1.0, 0.0, 0.05), None, None, truth=truth)
    assert step.status == "predicted"
    assert step.updated.hull().as_tuple() == pytest.approx((4.7, 5.3, -2.3, -1.7, 0.8, 1.2))
    step = loc.step(None, None, _obs_for(truth), truth=truth)
    assert step.status == "contracted" and step.updated.contains(*truth.as_tuple())
    assert max(step.updated.hull().widths[:2]) < 0.1
    with pytest.raises(ValueError, match="truth"):
        loc.step(None, None, None)
    # many rejections never make truth mode lost
    bad = Observation(0.5, 0.5, 0.3, 0.001, 0.001)
    for _ in range(25):
        assert loc.step(None, None, bad, truth=truth).status in ("rejected", "contracted")


def test_odometry_mode_ignores_the_view() -> None:
    loc = _loc(LocalizerConfig(mode="odometry"))
    step = loc.step(Odometry(0.5, 0.0, 0.1), 0.0, _obs_for(Pose(0.05, 0.0, 0.0)))
    assert step.status == "predicted" and step.passes == 0
    assert step.updated == step.predicted


def test_frame_zero_does_no_prediction() -> None:
    box = Box(-0.1, 0.1, -0.1, 0.1, -0.05, 0.05)
    loc = _loc(box=box)
    step = loc.step(None, None, None)
    assert step.updated == BoxSet((box,)) == loc.current


# --- the box cap --------------------------------------------------------------------------------


def test_box_cap_hulls_and_says_so() -> None:
    # a 3.4 m x 3.2 m initial box on 1 m tiles, no lever arm: the view leaves 4 x 4 = 16 cells
    # (x in -1.63, -0.63, 0.37, 1.37 and y in -1.48, -0.48, 0.52, 1.52, +- 0.01)
    truth = Pose(0.37, 0.52, 0.1)
    obs = Observation(*observe(truth, 1.0, (0.0, 0.0)), 0.01, 0.02)
    box = Box(-1.7, 1.7, -1.5, 1.7, 0.0, 0.2)
    many = _loc(LocalizerConfig(max_boxes=16), offset=(0.0, 0.0), box=box).step(None, None, obs)
    assert len(many.updated) == 16 and not many.hulled
    assert many.updated.contains(*truth.as_tuple())
    capped = _loc(LocalizerConfig(max_boxes=8), offset=(0.0, 0.0), box=box).step(None, None, obs)
    assert capped.hulled and len(capped.updated) == 1
    assert capped.updated.boxes[0].as_tuple() == pytest.approx(many.updated.hull().as_tuple())
    assert capped.updated.contains(*truth.as_tuple())


# --- bad input ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"odometry": Odometry(math.nan, 0.0, 0.05)}, "odometry.speed"),
        ({"odometry": Odometry(0.0, math.inf, 0.05)}, "odometry.yaw_rate"),
        ({"odometry": Odometry(0.0, 0.0, -0.05)}, "odometry.dt"),
        ({"compass": math.nan}, "compass"),
        ({"observation": Observation(math.nan, 0.0, 0.0, 0.01, 0.01)}, "observation.y1"),
        ({"observation": Observation(0.0, 0.0, math.inf, 0.01, 0.01)}, "observation.y3"),
        ({"observation": Observation(0.0, 0.0, 0.0, -0.01, 0.01)}, "observation.position_error"),
        ({"observation": Observation(0.0, 0.0, 0.0, 0.01, math.nan)}, "observation.heading_error"),
        ({"truth": Pose(0.0, math.nan, 0.0)}, "truth.y"),
    ],
)
def test_bad_step_input_names_the_quantity(kwargs, name) -> None:
    loc = _loc()
    before = loc.current
    args = {"odometry": None, "compass": None, "observation": None} | kwargs
    with pytest.raises(ValueError, match=name.replace(".", r"\.")):
        loc.step(**args)
    assert loc.current == before  # nothing changed


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"tile_size": 0.0}, "tile_size"),
        ({"tile_size": math.nan}, "tile_size"),
        ({"camera_offset": (math.inf, 0.0)}, r"camera_offset\[0\]"),
        ({"bounds": SensorBounds(-0.1, 0.0, 0.0)}, "speed_error"),
        ({"bounds": SensorBounds(0.0, math.nan, 0.0)}, "yaw_rate_error"),
        ({"bounds": SensorBounds(0.0, 0.0, -1.0)}, "compass_error"),
        ({"initial": Box(1.0, 0.0, 0.0, 1.0, 0.0, 1.0)}, "x_lo"),
        ({"initial": Box(0.0, 1.0, 0.0, math.nan, 0.0, 1.0)}, "y_hi"),
    ],
)
def test_bad_construction_names_the_quantity(kwargs, name) -> None:
    args = {
        "tile_size": 1.0,
        "camera_offset": (0.3, 0.0),
        "bounds": BOUNDS,
        "config": LocalizerConfig(),
        "initial": Box(0, 1, 0, 1, 0, 1),
    } | kwargs
    with pytest.raises(ValueError, match=name):
        Localizer(**args)


def test_camera_centre_consistency_with_lever_enclosure() -> None:
    # rho cos(t + phi), rho sin(t + phi) encloses the lever arm's R(t) @ offset
    for off in [(0.3, 0.0), (0.25, -0.1), (-0.2, 0.15), (0.0, 0.4)]:
        r_lo, r_hi, p_lo, p_hi = lever_enclosure(off)
        for t in np.linspace(-7, 7, 29):
            cx, cy = camera_centre(Pose(0.0, 0.0, float(t)), off)
            for r in (r_lo, r_hi):
                for p in (p_lo, p_hi):
                    assert abs(r * math.cos(t + p) - cx) < 1e-14
                    assert abs(r * math.sin(t + p) - cy) < 1e-14
