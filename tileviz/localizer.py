"""The guaranteed interval localizer: a set of robot poses kept as a few disjoint boxes.

Each frame: predict the set with the bounded odometry, intersect its heading with the compass,
then contract it with the tile observation (design.md). Frames and units as in
``shared/dataset-format.md``: metres, radians, heading continuous (not wrapped).

What is guaranteed, and when
----------------------------
Hypotheses: (H1) the initial box (and every box given to :meth:`Localizer.reset`) contains the
true pose; (H2) over every step the true speed and yaw rate stay within ``speed_error`` and
``yaw_rate_error`` of the measured ones (they may vary within the bounds); ``odometry=None`` is
passed only when the robot did not move since the previous step (frame 0, after a reset);
(H3) every compass reading is within ``compass_error`` of the true heading, modulo 2 pi; (H4) every
observation that the localizer *uses* is within its declared ``position_error`` /
``heading_error`` of the exact observation of the true pose (``tiles.observe``, modulo L and
modulo the quarter turns of design.md).

Then, at every frame whose status is not ``lost``, the true pose is inside ``predicted`` and
inside ``updated`` (heading modulo 2 pi). All bounds are outward rounded, so this holds for the
real numbers, not only up to rounding.

Statuses (dataset-format.md):

- ``contracted``: an observation was used and the contracted set is non-empty.
- ``predicted``: no observation (or mode ``odometry``): the prediction is kept.
- ``rejected``: the contraction with the observation is empty, so the observation cannot satisfy
  H4 if H1-H3 hold: it is judged an outlier, not used, and the prediction is kept (with recovery
  on, the slip candidates are kept too: see "Recovery"). A rejected view never weakens the
  guarantee. (An outlier that happens to be consistent with the set *is* used and can break H4
  without being noticed: that is the method's residual risk.)
- ``lost``: ``max_rejections`` consecutive rejections (frames without an observation neither
  count nor reset the streak; a successful contraction resets it). So many inconsistent views mean
  H1-H3 probably failed (a kidnap, a wheel slip beyond the bounds): the method no longer vouches for
  its set. It keeps predicting and outputs the hull of the set as one box, ignores views
  (with a periodic floor any view fits a wide enough set, so a contraction would only look
  confident), and stays ``lost`` until :meth:`Localizer.reset`.

Fault model (``LocalizerConfig.fault_speed`` m/s, ``fault_yaw_rate`` rad/s; off when both are 0)
---------------------------------------------------------------------------------------------------
Mode ``autonomous`` only; it replaces the ``max_slip`` recovery below. The localizer keeps a second
set beside its own, the fault set F: predicted with the odometry bounds widened by the fault model
(``speed_error + fault_speed``, ``yaw_rate_error + fault_yaw_rate``), cut by the compass when the
compass meets it, and contracted by every view, exactly as the set itself is. When a view or the
compass rejects the set, the set becomes F's contraction (``reinflated``, status ``contracted``)
and the two sets agree again; a view that fits F no more either counts as a rejection, and
:data:`FAULT_MAX_REJECTIONS` of those in a row make the status ``lost``.

Hypothesis (H2'): over every step the true speed and yaw rate stay within the bounds widened by
the fault model. Under H1, H2', H3 and H4, F holds the truth at every frame (the induction of the
plain guarantee, with wider bounds), so every frame that takes F holds the truth: a slip within the
model is followed, the set tight (F is contracted by every view). The set itself may miss the truth
while a fault is not yet noticed (as without the model). Beyond the model (a kidnap) views stop
fitting F and the status is ``lost`` after at most FAULT_MAX_REJECTIONS frames. Cost: a second
prediction and contraction per frame.

Recovery (``LocalizerConfig.max_slip = (d, a)``, metres and radians; off when both are 0)
-------------------------------------------------------------------------------------------
Mode ``autonomous`` only (mode ``truth`` starts afresh every frame).
An empty contraction has two explanations: the view is an outlier (H4 broken), or the prediction
is (H2 broken: a wheel slip beyond the bounds, an odometry outlier, a push). With recovery on, a
rejected frame keeps *both*: the prediction P, and the slip candidates -- the poses within
(d, d, a) of P (P inflated by d in x and y and a in heading, before the compass) that the compass
(unless it misses them all) and the view allow, one box per lattice cell. A compass reading that
misses P is treated the same way (P is kept, plus the candidates the compass allows). The next
views then remove whichever explanation was wrong: a contraction of the union is the union of the
contractions, so the status returns to ``contracted`` as soon as a view fits either.

Hypothesis (H5): at a frame that re-inflates (a rejected view, or a compass that misses P), the
true pose is within (d, d, a) of P. P is the localizer's own prediction, so H5 reads: the odometry
error beyond its declared bounds, accumulated since the set last held the truth, moved the pose by
at most d in x and in y and a in heading. (For scale: an excess speed s held for T seconds moves
it by s T; an excess heading e held over a path of length D moves it by about e D.)

Guarantee, by induction over the frames: if H1 and H3 hold, the truth is in the set at every frame
that is not ``lost`` as long as every frame is of one of two kinds:

(a) H2 held for its step, and its view, if it contracted the set, satisfies H4 (a rejected view
    may be anything) -- the guarantee without recovery;
(b) it re-inflated, H5 holds, and its view, if any, satisfies H4. Such a frame repairs the set:
    the truth is back in it whatever happened before.

Not covered, because no method can notice it from these inputs: an odometry error beyond its bound
that leaves the prediction overlapping the view. The contraction is then non-empty but may exclude
the truth, and it stays so (status ``contracted``) until the drift makes a view miss the set: a
frame of kind (b) with recovery on, a step towards ``lost`` without. ``bench/faults.py`` counts
those frames.

Limits of recovery, by the geometry of a periodic floor:

- Two poses one tile apart (same heading) give the same views and the same odometry forever: a
  push by a whole tile is never noticed, and slip candidates one tile apart are never told apart
  by views. The candidates of one re-inflation lie in a single lattice cell when the camera-centre
  range of the inflated prediction (P's width + 2 d + the lever arm times P's heading width + 2 a)
  is less than L minus the view's cell width (2 ``position_error``) on each axis; so choose
  d below about L / 2 minus the tracking set's width. A larger d can leave several boxes a tile
  apart, all vouched for (the truth is in one of them), for good.
- A kidnap beyond (d, a) breaks H5. Usually no candidate fits (and the compass removes those
  whose heading it rules out): the frames are ``rejected`` -- vouching for a set that misses the
  truth, since H5 is broken -- until ``max_rejections`` makes the status ``lost``, which stays
  until :meth:`Localizer.reset`. Views cannot recover from ``lost``: every candidate within d of the
  prediction has just been ruled out, and farther away a periodic floor offers a candidate in
  every tile. A kidnap that lands within (d, d, a) of a *lattice translate* of P is accepted as a
  slip of the translate: a wrong set, vouched for, exactly as if the robot had been pushed by
  whole tiles.

Cost: nothing on frames that contract (the hot path is unchanged); a rejected frame contracts the
inflated boxes once more.

How tight the contraction is
----------------------------
Per rotation branch m (design.md, corrected Theorem 1) the camera-centre interval is cut by the
lattice exactly, and every (heading piece, x piece, y piece) cell is kept as its own box
(``LocalizerConfig.max_boxes`` caps the count: past it, the hull, flagged ``hulled``). With the
camera on the robot point the cells are the exact solution set. With a lever arm each cell is
contracted to the fixpoint of the exact projections of its constraint onto x, y and the heading
(hull consistency): that is the exact hull of the cell's solutions unless the heading preimage
of one axis alone has a gap inside the cell (the lever arm swinging past an extremum of cos or
sin), where the hull of that preimage is kept -- as any forward-backward contractor (codac's
``CtcInverse`` included) does. The fixpoint is reached after at most 2 passes in tracking (one
when the lever arm cannot narrow the heading, the usual case; ``bench/bench_localizer.py`` prints
the distribution), so ``LocalizerConfig.passes = 3`` is enough.

A compass reading that misses the predicted set entirely (H1-H3 cannot all hold) is ignored for
that frame and flagged in ``LocalizerStep.compass_rejected`` (with recovery on, the slip
candidates it allows are added: see "Recovery").

Modes (``LocalizerConfig.mode``): ``autonomous``; ``truth`` (report 7.1: every frame the set is
reset to the true pose inflated by ``truth_inflation``, then the compass and the view contract it;
never ``lost``); ``odometry`` (prediction and compass only, views ignored, status ``predicted``).

The hot path works on plain 6-tuples ``(x_lo, x_hi, y_lo, y_hi, t_lo, t_hi)``; the public API
speaks :class:`tileviz.types.Box` / :class:`tileviz.types.BoxSet`. It is written for a pure-Python
step of a few hundred lines: one-box shortcuts, cos and sin ranges in one call, lattice walks that
reuse their piece bounds, only the rotation branches the heading meets, result objects built
without the frozen dataclass __init__. Every such shortcut computes the very same floats as the
general code: ``tests/test_localizer_golden.py`` replays recorded sequences and compares every
output bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tileviz.config import LocalizerConfig
from tileviz.intervals import (
    HALF_PI,
    HALF_PI_ERROR,
    HALF_PI_HI,
    HALF_PI_LO,
    TWO_PI,
    TWO_PI_ERROR,
    acos_preimage,
    asin_preimage,
    cos_sin_range,
    lattice_cut,
    lattice_hull,
    lattice_intersect,
    lattice_pieces_indexed,
    mul,
    turn_shift,
)
from tileviz.types import Box, BoxSet, Observation, Odometry, Pose, SensorBounds

__all__ = [
    "Lever",
    "Localizer",
    "LocalizerStep",
    "Tuple6",
    "compass_pieces",
    "contract_box",
    "contract_branch",
    "inflate_box",
    "lever_enclosure",
    "observation_windows",
    "predict_box",
]

Tuple6 = tuple[float, float, float, float, float, float]
"""A box as (x_lo, x_hi, y_lo, y_hi, t_lo, t_hi): metres, metres, radians (continuous)."""
Lever = tuple[float, float, float, float]
"""Enclosures (rho_lo, rho_hi, phi_lo, phi_hi) of the lever arm in polar form: forward * cos t -
left * sin t = rho cos(t + phi) and forward * sin t + left * cos t = rho sin(t + phi)."""
Window = tuple[float, float, float, float, float, float]
"""Per rotation branch m: (u1_lo, u1_hi, u2_lo, u2_hi, h_lo, h_hi) with
[u] = R(m pi/2)([y1 +- e], [y2 +- e]) and [h] = [y3 +- e3] + m pi/2."""

_INF = math.inf
_nextafter = math.nextafter
FIXPOINT_TOL = 1e-12
"""A contraction pass that moves the heading bounds by less than this (rad, in total) ends the
fixpoint iteration."""

FAULT_MAX_REJECTIONS = 5
"""With the fault model on, a view that fits neither the set nor the fault set means the motion
went beyond the fault model (a kidnap) or the view is an outlier; this many in a row and the
status is ``lost`` (``max_rejections`` if smaller): never more frames vouching for a set that
may have lost the truth."""

_QUARTER_LO = (0.0, HALF_PI_LO, _nextafter(2.0 * HALF_PI_LO, -_INF),
               _nextafter(3.0 * HALF_PI_LO, -_INF))
_QUARTER_HI = (0.0, HALF_PI_HI, _nextafter(2.0 * HALF_PI_HI, _INF),
               _nextafter(3.0 * HALF_PI_HI, _INF))
"""Rigorous bounds of m pi/2, m = 0..3."""
_EIGHTH_TURN = 0.5 * HALF_PI
"""pi/4 (rounded): heading windows this wide or wider may overlap (contract_box)."""


@dataclass(frozen=True)
class LocalizerStep:
    """What one :meth:`Localizer.step` did.

    ``predicted``: the set after prediction and compass (before the view). ``updated``: the set
    after this frame's update. ``status``: see the module docstring. ``passes``: the largest
    number of contraction passes run on one cell (0 when nothing was contracted). ``hulled``: the
    box cap (or a lattice split too fine to keep) replaced some set by its hull this frame.
    ``compass_rejected``: the compass reading missed the predicted set and was ignored.
    ``rejections``: the current streak of consecutive rejected views. ``reinflated``: recovery
    added the slip candidates to the set this frame (module docstring, "Recovery").
    """

    predicted: BoxSet
    updated: BoxSet
    status: str
    passes: int
    hulled: bool = False
    compass_rejected: bool = False
    rejections: int = 0
    reinflated: bool = False


# --- validation ---------------------------------------------------------------------------------


LIMIT = 1e9
"""Largest magnitude of any input number and of any bound of the set (metres, radians, m/s,
rad/s, seconds). Beyond it the lattice arithmetic would need more than float64's 52 bits to tell
one tile (or one turn) from the next; no real robot comes near it. Inputs past it raise
ValueError, and so does a prediction that would leave it."""
MIN_TILE = 1e-4
"""Smallest tile size L, metres (with LIMIT: at most 1e13 tiles across the representable floor)."""
_TURN = _nextafter(TWO_PI + 2.0 * TWO_PI_ERROR, _INF)
"""A heading interval wider than this holds every heading: it is cut to one turn."""


def _finite(name: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"{name} must be a finite number, got {v!r}")
    if not -LIMIT <= v <= LIMIT:
        raise ValueError(f"{name} must be within +-{LIMIT:g}, got {v!r}")
    return float(v)


def _nonneg(name: str, v: object) -> float:
    f = _finite(name, v)
    if f < 0:
        raise ValueError(f"{name} must be >= 0, got {v!r}")
    return f


def _check_box(name: str, box: Box) -> Tuple6:
    if not isinstance(box, Box):
        raise ValueError(f"{name} must be a Box, got {type(box).__name__}")
    t = tuple(_finite(f"{name}.{k}", getattr(box, k)) for k in
              ("x_lo", "x_hi", "y_lo", "y_hi", "t_lo", "t_hi"))
    for axis, (lo, hi) in zip("xyt", (t[0:2], t[2:4], t[4:6]), strict=True):
        if lo > hi:
            raise ValueError(f"{name} is empty: {axis}_lo = {lo} > {axis}_hi = {hi}")
    return _one_turn(t)  # type: ignore[arg-type]


def _one_turn(b: Tuple6) -> Tuple6:
    """``b`` with a heading interval wider than a turn cut to one turn from its low end (the
    same poses, heading modulo 2 pi)."""
    if b[5] - b[4] <= _TURN:
        return b
    return (b[0], b[1], b[2], b[3], b[4],
            _nextafter(_nextafter(b[4] + TWO_PI, _INF) + TWO_PI_ERROR, _INF))


def _in_range(boxes: list[Tuple6]) -> list[Tuple6]:
    """The boxes, headings cut to one turn; ValueError when a bound leaves +-LIMIT."""
    out = boxes
    for i, b in enumerate(boxes):
        if not (-LIMIT <= b[0] and b[1] <= LIMIT and -LIMIT <= b[2] and b[3] <= LIMIT
                and -LIMIT <= b[4] and b[5] <= LIMIT):
            raise ValueError(f"the set left +-{LIMIT:g} (m, rad): {b}; the odometry or the "
                             f"bounds are too large")
        if b[5] - b[4] > _TURN:
            if out is boxes:
                out = list(boxes)
            out[i] = _one_turn(b)
    return out


# --- building blocks on 6-tuples ----------------------------------------------------------------


def lever_enclosure(offset: tuple[float, float]) -> Lever | None:
    """Rigorous (rho, phi) enclosures of the camera lever arm (forward, left), or None when the
    camera sits on the robot point. rho = hypot(f, l) (< 1 ulp), phi = atan2(l, f) (a few ulp).

    rho_lo > 0 whenever the arm is not zero, for every float offset, subnormals included: a
    relative margin of a few ulps is no margin at all where an ulp is the number itself (5e-324),
    so rho_lo is also at least max(|f|, |l|), which hypot(f, l) can never be below."""
    f, left = offset
    if f == 0.0 and left == 0.0:
        return None
    if left == 0.0 and f > 0.0:
        return (f, f, 0.0, 0.0)
    rho = math.hypot(f, left)
    phi = math.atan2(left, f)
    rho_lo = _nextafter(_nextafter(rho, -_INF), -_INF)
    leg = max(abs(f), abs(left))
    if rho_lo < leg:
        rho_lo = leg
    rho_hi = _nextafter(_nextafter(rho, _INF), _INF)
    dphi = 4.0 * math.ulp(phi)
    return (rho_lo, rho_hi, _nextafter(phi - dphi, -_INF), _nextafter(phi + dphi, _INF))


def predict_box(
    b: Tuple6, v_lo: float, v_hi: float, w_lo: float, w_hi: float, dt: float
) -> Tuple6:
    """Enclosure of every pose reachable from box ``b`` in ``dt`` s (design.md, "Prediction").

    The true speed v(s) in [v_lo, v_hi] (m/s) and yaw rate w(s) in [w_lo, w_hi] (rad/s) may vary
    over the step. The heading theta(s) = theta0 + int_0^s w stays in
    H = hull([t], [t] + dt [w]); the displacement int_0^dt v(s) (cos, sin)(theta(s)) ds lies in
    dt * hull{v cos h : v in [v], h in H} (resp. sin) because the integrand never leaves that
    interval; the final heading is in [t] + dt [w]. Every bound is outward rounded.
    """
    x_lo, x_hi, y_lo, y_hi, t_lo, t_hi = b
    n = _nextafter
    tn_lo = n(t_lo + n(dt * w_lo, -_INF), -_INF)
    tn_hi = n(t_hi + n(dt * w_hi, _INF), _INF)
    h_lo = t_lo if t_lo < tn_lo else tn_lo
    h_hi = t_hi if t_hi > tn_hi else tn_hi
    c_lo, c_hi, s_lo, s_hi = cos_sin_range(h_lo, h_hi)
    d_lo = n(dt * v_lo, -_INF)
    d_hi = n(dt * v_hi, _INF)
    if d_lo >= 0.0:
        # moving forward: which of the four products is the least / greatest follows from the
        # signs (rounding is monotone, so these are mul's min and max, up to the sign of a zero,
        # which the outward step removes)
        dx_lo = n((d_lo if c_lo >= 0.0 else d_hi) * c_lo, -_INF)
        dx_hi = n((d_hi if c_hi >= 0.0 else d_lo) * c_hi, _INF)
        dy_lo = n((d_lo if s_lo >= 0.0 else d_hi) * s_lo, -_INF)
        dy_hi = n((d_hi if s_hi >= 0.0 else d_lo) * s_hi, _INF)
    else:
        dx_lo, dx_hi = mul(d_lo, d_hi, c_lo, c_hi)
        dy_lo, dy_hi = mul(d_lo, d_hi, s_lo, s_hi)
    return (
        n(x_lo + dx_lo, -_INF),
        n(x_hi + dx_hi, _INF),
        n(y_lo + dy_lo, -_INF),
        n(y_hi + dy_hi, _INF),
        tn_lo,
        tn_hi,
    )


def compass_pieces(b: Tuple6, h_lo: float, h_hi: float) -> list[Tuple6]:
    """Box ``b`` with its heading intersected with [h_lo, h_hi] + 2 pi Z (the compass reading
    +- its bound, any 2 pi shift): zero, one or (for a wide heading) several boxes."""
    pieces = lattice_intersect(b[4], b[5], h_lo, h_hi, TWO_PI, period_error=TWO_PI_ERROR)
    if len(pieces) == 1:  # the usual case, without a comprehension's frame
        lo, hi = pieces[0]
        return [(b[0], b[1], b[2], b[3], lo, hi)]
    return [(b[0], b[1], b[2], b[3], lo, hi) for lo, hi in pieces]


def observation_windows(obs: Observation) -> tuple[Window, Window, Window, Window]:
    """The four rotation branches of an observation (design.md, corrected Theorem 1):
    for m = 0..3, [u] = R(m pi/2) ([y1 +- e], [y2 +- e]) and [h] = [y3 +- e3] + m pi/2, so the pose
    is consistent with branch m iff c in [u] + L Z^2 and theta in [h] + 2 pi Z."""
    w0 = _view_window(obs)
    return (w0, _branch_window(w0, 1), _branch_window(w0, 2), _branch_window(w0, 3))


def _view_window(obs: Observation) -> Window:
    """Branch m = 0 of :func:`observation_windows`: ([y1 +- e], [y2 +- e], [y3 +- e3]), outward."""
    n = _nextafter
    e = obs.position_error
    e3 = obs.heading_error
    return (n(obs.y1 - e, -_INF), n(obs.y1 + e, _INF), n(obs.y2 - e, -_INF), n(obs.y2 + e, _INF),
            n(obs.y3 - e3, -_INF), n(obs.y3 + e3, _INF))


def _branch_window(w0: Window, m: int) -> Window:
    """Branch m (0..3) of :func:`observation_windows` from branch 0: [u] = R(m pi/2)([a], [b])
    (m=1 (-b, a), m=2 (-a, -b), m=3 (b, -a): negation is exact) and [h] = [h0] + m pi/2 with the
    rigorous bounds of m pi/2. The localizer builds only the branches the heading meets."""
    if m == 0:
        return w0
    a_lo, a_hi, b_lo, b_hi, t_lo, t_hi = w0
    h_lo = _nextafter(t_lo + _QUARTER_LO[m], -_INF)
    h_hi = _nextafter(t_hi + _QUARTER_HI[m], _INF)
    if m == 1:
        return (-b_hi, -b_lo, a_lo, a_hi, h_lo, h_hi)
    if m == 2:
        return (-a_hi, -a_lo, -b_hi, -b_lo, h_lo, h_hi)
    return (b_lo, b_hi, -a_hi, -a_lo, h_lo, h_hi)


def _lever_ranges(
    s_lo: float, s_hi: float, rho_lo: float, rho_hi: float
) -> tuple[float, float, float, float]:
    """Enclosures (gx_lo, gx_hi, gy_lo, gy_hi) of the lever arm rho (cos, sin)(s) over
    s in [s_lo, s_hi] (s = heading + phi)."""
    n = _nextafter
    c_lo, c_hi, d_lo, d_hi = cos_sin_range(s_lo, s_hi)
    # min(p, q) / max(p, q) of the two products, written out (same ties: p wins)
    p = rho_lo * c_lo
    q = rho_hi * c_lo
    gx_lo = q if q < p else p
    p = rho_lo * c_hi
    q = rho_hi * c_hi
    gx_hi = q if q > p else p
    p = rho_lo * d_lo
    q = rho_hi * d_lo
    gy_lo = q if q < p else p
    p = rho_lo * d_hi
    q = rho_hi * d_hi
    gy_hi = q if q > p else p
    return (n(gx_lo, -_INF), n(gx_hi, _INF), n(gy_lo, -_INF), n(gy_hi, _INF))


def _lever_axis(
    v_lo: float,
    v_hi: float,
    g_lo: float,
    g_hi: float,
    p_lo: float,
    p_hi: float,
    rho_lo: float,
    rho_hi: float,
) -> tuple[float, float, tuple[float, float] | None] | None:
    """One axis of the lever-arm constraint v + g(t) in [p] (v the robot x or y, g(t) in [g] the
    lever arm's x or y, [p] the camera's lattice piece). The camera is in [c] = ([v] + [g]) ∩ [p],
    so v in [c] - [g] and g(t) in [c] - [v]. Returns None when empty, else (v_lo, v_hi, w) where
    w encloses g(t) / rho, or None when it says nothing new ([c] - [v] holds [g])."""
    n = _nextafter
    c_lo = n(v_lo + g_lo, -_INF)
    c_hi = n(v_hi + g_hi, _INF)
    if c_lo < p_lo:
        c_lo = p_lo
    if c_hi > p_hi:
        c_hi = p_hi
    if c_lo > c_hi:
        return None
    w = n(c_lo - g_hi, -_INF)
    if w > v_lo:
        v_lo = w
    w = n(c_hi - g_lo, _INF)
    if w < v_hi:
        v_hi = w
    if v_lo > v_hi:
        return None
    a_lo = n(c_lo - v_hi, -_INF)
    a_hi = n(c_hi - v_lo, _INF)
    if a_lo <= g_lo and a_hi >= g_hi:
        return v_lo, v_hi, None
    return v_lo, v_hi, (
        n(a_lo / (rho_hi if a_lo >= 0.0 else rho_lo), -_INF),
        n(a_hi / (rho_lo if a_hi >= 0.0 else rho_hi), _INF),
    )


def _recut(
    v_lo: float,
    v_hi: float,
    g_lo: float,
    g_hi: float,
    p_lo: float,
    p_hi: float,
    u_lo: float,
    u_hi: float,
    tile_size: float,
) -> tuple[float, float] | None:
    """The hull of the lattice pieces [u] + L Z within [p] that the camera range [v] + [g] meets
    (outward), or None when none does: one axis of a hulled cell, cut again."""
    c_lo = _nextafter(v_lo + g_lo, -_INF)
    c_hi = _nextafter(v_hi + g_hi, _INF)
    if c_lo < p_lo:
        c_lo = p_lo
    if c_hi > p_hi:
        c_hi = p_hi
    if c_lo > c_hi:
        return None
    return lattice_hull(c_lo, c_hi, u_lo, u_hi, tile_size)


def _refine_cell(
    x_lo: float,
    x_hi: float,
    y_lo: float,
    y_hi: float,
    t_lo: float,
    t_hi: float,
    px_lo: float,
    px_hi: float,
    py_lo: float,
    py_hi: float,
    lever: Lever,
    max_passes: int,
    s_lo: float,
    s_hi: float,
    g: tuple[float, float, float, float],
    recut: Window | None = None,
) -> tuple[Tuple6 | None, int]:
    """Contract one cell: the camera centre c = (x, y) + rho (cos, sin)(t + phi) must lie in the
    lattice piece [px] x [py]. Alternates the exact projections of that constraint onto x, y and
    the heading (the latter the hull of the arccos / arcsin preimage) until the heading stops
    moving (FIXPOINT_TOL) or ``max_passes`` passes. ``s_lo, s_hi``: [t] + phi (outward) and ``g``
    the lever-arm ranges (gx_lo, gx_hi, gy_lo, gy_hi) over it, as the caller computed them for
    the first pass (:func:`_contract_cells`: the same for every cell). ``recut``: when the cell
    is the hull of several lattice pieces (the cap fired), ``(u1_lo, u1_hi, u2_lo, u2_hi, L, _)``:
    every pass then cuts the camera-centre range by the lattice again (its hull), as a
    forward-backward contractor would, instead of keeping the hull of the first pass's pieces.
    Returns (box or None when empty, passes)."""
    n = _nextafter
    rho_lo, rho_hi, phi_lo, phi_hi = lever
    gx_lo, gx_hi, gy_lo, gy_hi = g
    p = 0
    while True:
        p += 1
        if p > 1:
            s_lo = n(t_lo + phi_lo, -_INF)
            s_hi = n(t_hi + phi_hi, _INF)
            gx_lo, gx_hi, gy_lo, gy_hi = _lever_ranges(s_lo, s_hi, rho_lo, rho_hi)
        if recut is not None:  # a hulled cell: its pieces that the camera range still meets
            r = _recut(x_lo, x_hi, gx_lo, gx_hi, px_lo, px_hi, recut[0], recut[1], recut[4])
            if r is None:
                return None, p
            px_lo, px_hi = r
            r = _recut(y_lo, y_hi, gy_lo, gy_hi, py_lo, py_hi, recut[2], recut[3], recut[4])
            if r is None:
                return None, p
            py_lo, py_hi = r
        # x and y through the lever arm, then the heading: rho cos(t + phi) in ([c] - [x]) etc.
        rx = _lever_axis(x_lo, x_hi, gx_lo, gx_hi, px_lo, px_hi, rho_lo, rho_hi)
        if rx is None:
            return None, p
        ry = _lever_axis(y_lo, y_hi, gy_lo, gy_hi, py_lo, py_hi, rho_lo, rho_hi)
        if ry is None:
            return None, p
        x_lo, x_hi, wx = rx
        y_lo, y_hi, wy = ry
        s0_lo = s_lo
        s0_hi = s_hi
        if wx is not None:
            r = acos_preimage(s_lo, s_hi, wx[0], wx[1])
            if r is None:
                return None, p
            s_lo, s_hi = r
        if wy is not None:
            r = asin_preimage(s_lo, s_hi, wy[0], wy[1])
            if r is None:
                return None, p
            s_lo, s_hi = r
        if s_lo == s0_lo and s_hi == s0_hi:
            break
        moved = 0.0
        v = n(s_lo - phi_hi, -_INF)
        if v > t_lo:
            moved += v - t_lo
            t_lo = v
        v = n(s_hi - phi_lo, _INF)
        if v < t_hi:
            moved += t_hi - v
            t_hi = v
        if t_lo > t_hi:
            return None, p
        if moved <= FIXPOINT_TOL or p >= max_passes:
            break
    return (x_lo, x_hi, y_lo, y_hi, t_lo, t_hi), p


def _contract_cells(
    b: Tuple6,
    a_lo: float,
    a_hi: float,
    win: Window,
    tile_size: float,
    lever: Lever | None,
    max_passes: int,
    max_cells: int,
    out: list[Tuple6],
) -> tuple[int, bool]:
    """Contract box ``b`` whose heading is already cut to one piece [a_lo, a_hi] of branch
    ``win``: the camera-centre interval [c] = [x] + rho cos([t] + phi) (resp. y, sin) is cut
    exactly by the lattice [u] + L Z (``lattice_intersect``) and every (x piece, y piece) cell
    becomes one box, pushed back through the lever arm (:func:`_refine_cell`). Appends the boxes
    to ``out``; returns (largest number of passes, whether pieces were hulled)."""
    x_lo, x_hi, y_lo, y_hi = b[0], b[1], b[2], b[3]
    if lever is None:  # the camera centre is the robot point
        g = (0.0, 0.0, 0.0, 0.0)
        c = b
    else:
        rho_lo, rho_hi, phi_lo, phi_hi = lever
        s_lo = _nextafter(a_lo + phi_lo, -_INF)
        s_hi = _nextafter(a_hi + phi_hi, _INF)
        g = _lever_ranges(s_lo, s_hi, rho_lo, rho_hi)
        c = (_nextafter(x_lo + g[0], -_INF), _nextafter(x_hi + g[1], _INF),
             _nextafter(y_lo + g[2], -_INF), _nextafter(y_hi + g[3], _INF))
    xs, hx = lattice_cut(c[0], c[1], win[0], win[1], tile_size, max_pieces=max_cells)
    if not xs:
        return 1, False
    ys, hy = lattice_cut(c[2], c[3], win[2], win[3], tile_size, max_pieces=max_cells)
    if not ys:
        return 1, False
    hulled = hx or hy
    if len(xs) * len(ys) > max_cells:
        xs = [(xs[0][0], xs[-1][1])]
        ys = [(ys[0][0], ys[-1][1])]
        hulled = True
    if lever is None:  # the camera is the robot point: the cut is exact and final
        for px_lo, px_hi in xs:
            for py_lo, py_hi in ys:
                out.append((px_lo, px_hi, py_lo, py_hi, a_lo, a_hi))
        return 1, hulled
    passes = 0
    for px_lo, px_hi in xs:
        for py_lo, py_hi in ys:
            box, p = _refine_cell(
                x_lo, x_hi, y_lo, y_hi, a_lo, a_hi,
                px_lo, px_hi, py_lo, py_hi, lever, max_passes, s_lo, s_hi, g,
                (win[0], win[1], win[2], win[3], tile_size, 0.0) if hulled else None,
            )
            if p > passes:
                passes = p
            if box is not None:
                out.append(box)
    return passes, hulled


def contract_branch(
    b: Tuple6,
    win: Window,
    tile_size: float,
    lever: Lever | None,
    max_passes: int,
    max_cells: int,
) -> tuple[list[Tuple6], int, bool]:
    """Contract box ``b`` with one rotation branch ``win`` of an observation (design.md).

    The heading is cut to [h] + 2 pi Z, then each heading piece is contracted by
    :func:`_contract_cells`: one box per lattice cell of the camera centre, pushed back through
    the lever arm; with no lever arm the cut is final (one pass). When a heading piece has more
    than ``max_cells`` cells, the x and y pieces are replaced by their hulls (one box).
    Returns (boxes, largest number of passes, whether a hull replaced pieces).
    """
    out: list[Tuple6] = []
    passes = 0
    hulled = False
    for a_lo, a_hi in lattice_intersect(
        b[4], b[5], win[4], win[5], TWO_PI, period_error=TWO_PI_ERROR
    ):
        p, h = _contract_cells(b, a_lo, a_hi, win, tile_size, lever, max_passes, max_cells, out)
        if p > passes:
            passes = p
        hulled = hulled or h
    return out, passes, hulled


def contract_box(
    b: Tuple6,
    windows: tuple[Window, Window, Window, Window],
    tile_size: float,
    lever: Lever | None,
    max_passes: int,
    max_cells: int,
) -> tuple[list[Tuple6], int, bool]:
    """Union over the four rotation branches of :func:`contract_branch`.

    The branches' heading windows are [h0] + m pi/2 + 2 pi Z = [h0] + k pi/2 with m = k mod 4, so
    one pass over the pi/2-lattice finds every branch piece the box heading meets (when the
    windows are disjoint, e3 < pi/4; otherwise each branch is cut on its own)."""
    return _contract_view(b, windows[0], windows, tile_size, lever, max_passes, max_cells)


def _contract_view(
    b: Tuple6,
    w0: Window,
    windows: tuple[Window, Window, Window, Window] | None,
    tile_size: float,
    lever: Lever | None,
    max_passes: int,
    max_cells: int,
) -> tuple[list[Tuple6], int, bool]:
    """:func:`contract_box` with ``windows`` built on demand from branch 0 ``w0`` when None
    (only the branches the heading meets are needed)."""
    out: list[Tuple6] = []
    passes = 0
    hulled = False
    h_lo, h_hi = w0[4], w0[5]
    if h_hi - h_lo >= _EIGHTH_TURN:
        for m in range(4):
            win = _branch_window(w0, m) if windows is None else windows[m]
            boxes, p, h = contract_branch(b, win, tile_size, lever, max_passes, max_cells)
            out.extend(boxes)
            passes = max(passes, p)
            hulled = hulled or h
        return out, passes, hulled
    for k, a_lo, a_hi in lattice_pieces_indexed(b[4], b[5], h_lo, h_hi, HALF_PI, HALF_PI_ERROR):
        win = _branch_window(w0, k & 3) if windows is None else windows[k & 3]
        p, h = _contract_cells(b, a_lo, a_hi, win, tile_size, lever, max_passes, max_cells, out)
        if p > passes:
            passes = p
        hulled = hulled or h
    return out, passes, hulled


# --- box-set housekeeping -------------------------------------------------------------------------


def _shift_heading(b: Tuple6, ref: float) -> Tuple6:
    """``b`` with its heading moved by the multiple of 2 pi that brings its centre nearest
    ``ref`` (outward rounded: :func:`tileviz.intervals.turn_shift`)."""
    k = round((ref - 0.5 * (b[4] + b[5])) / TWO_PI)
    if k == 0:
        return b
    t_lo, t_hi = turn_shift(b[4], b[5], k)
    return (b[0], b[1], b[2], b[3], t_lo, t_hi)


def _hull_all(boxes: list[Tuple6]) -> Tuple6:
    """The bounding box; headings shifted next to the first box's first."""
    ref = 0.5 * (boxes[0][4] + boxes[0][5])
    x_lo, x_hi, y_lo, y_hi, t_lo, t_hi = boxes[0]
    for raw in boxes[1:]:
        b = _shift_heading(raw, ref)
        x_lo = min(x_lo, b[0])
        x_hi = max(x_hi, b[1])
        y_lo = min(y_lo, b[2])
        y_hi = max(y_hi, b[3])
        t_lo = min(t_lo, b[4])
        t_hi = max(t_hi, b[5])
    return (x_lo, x_hi, y_lo, y_hi, t_lo, t_hi)


def _meet(a: Tuple6, b: Tuple6) -> bool:
    """Whether two boxes share a point (heading modulo 2 pi)."""
    return (
        a[0] <= b[1] and b[0] <= a[1] and a[2] <= b[3] and b[2] <= a[3]
        and lattice_hull(a[4], a[5], b[4], b[5], TWO_PI, TWO_PI_ERROR) is not None
    )


def _tidy(boxes: list[Tuple6], cap: int) -> tuple[list[Tuple6], bool]:
    """Make the boxes disjoint (boxes that meet are replaced by their hull, repeatedly) and apply
    the cap (more than ``cap`` boxes: the hull of all). Returns (boxes, whether the cap fired).
    Boxes are swept in order of x_lo, so only pairs whose x ranges overlap are compared."""
    if len(boxes) > cap:
        return [_hull_all(boxes)], True
    if len(boxes) < 2:
        return boxes, False
    out = sorted(boxes)
    i = 0
    while i < len(out):
        a = out[i]
        j = i + 1
        while j < len(out) and out[j][0] <= a[1]:
            if _meet(a, out[j]):
                out[i] = _hull_all([a, out[j]])
                del out[j]
                out.sort()
                i = -1  # a hull can meet boxes already passed: sweep again
                break
            j += 1
        i += 1
    return out, False


# Building the frozen result objects through their dataclass __init__ (one object.__setattr__
# per field) cost as much as the whole prediction; the hot path fills the same slots directly.
# The objects are the same as Box(*b) / BoxSet(boxes) (tests/test_localizer_golden.py checks).
_new = object.__new__
_BOX_SLOTS = tuple(Box.__dict__[k].__set__
                   for k in ("x_lo", "x_hi", "y_lo", "y_hi", "t_lo", "t_hi"))
_BOXSET_SLOT = BoxSet.__dict__["boxes"].__set__


def _box(b: Tuple6) -> Box:
    """``Box(*b)``, built without the frozen dataclass __init__."""
    s0, s1, s2, s3, s4, s5 = _BOX_SLOTS
    x_lo, x_hi, y_lo, y_hi, t_lo, t_hi = b
    o = _new(Box)
    s0(o, x_lo)
    s1(o, x_hi)
    s2(o, y_lo)
    s3(o, y_hi)
    s4(o, t_lo)
    s5(o, t_hi)
    return o


def _to_boxset(boxes: list[Tuple6]) -> BoxSet:
    """``BoxSet(tuple(Box(*b) for b in boxes))``, built without the dataclass __init__s."""
    o = _new(BoxSet)
    _BOXSET_SLOT(o, (_box(boxes[0]),) if len(boxes) == 1 else tuple(map(_box, boxes)))
    return o


def inflate_box(b: Tuple6, d: float, dt: float) -> Tuple6:
    """Box ``b`` widened by ``d`` metres on each side in x and y and ``dt`` rad in heading
    (outward rounded): every pose within (d, d, dt) of a pose of ``b``."""
    n = _nextafter
    return (n(b[0] - d, -_INF), n(b[1] + d, _INF), n(b[2] - d, -_INF), n(b[3] + d, _INF),
            n(b[4] - dt, -_INF), n(b[5] + dt, _INF))


# --- the localizer ------------------------------------------------------------------------------


class Localizer:
    """Guaranteed localization on a tiled floor (see the module docstring for the guarantee).

    ``tile_size``: L, metres. ``camera_offset``: (forward, left) of the camera centre in the robot
    frame, metres. ``bounds``: odometry and compass error bounds. ``config``: mode, box cap,
    passes, truth inflation, rejection limit. ``initial``: a box known to contain the true pose.
    """

    def __init__(
        self,
        *,
        tile_size: float,
        camera_offset: tuple[float, float],
        bounds: SensorBounds,
        config: LocalizerConfig,
        initial: Box,
    ) -> None:
        self._L = _finite("tile_size", tile_size)
        if self._L < MIN_TILE:
            raise ValueError(f"tile_size must be >= {MIN_TILE:g} m, got {tile_size!r}")
        if len(camera_offset) != 2:
            raise ValueError(f"camera_offset must be (forward, left), got {camera_offset!r}")
        off = (
            _finite("camera_offset[0]", camera_offset[0]),
            _finite("camera_offset[1]", camera_offset[1]),
        )
        self._lever = lever_enclosure(off)
        self._ev = _nonneg("speed_error", bounds.speed_error)
        self._ew = _nonneg("yaw_rate_error", bounds.yaw_rate_error)
        self._ec = _nonneg("compass_error", bounds.compass_error)
        if not isinstance(config, LocalizerConfig):
            raise ValueError(f"config must be a LocalizerConfig, got {type(config).__name__}")
        self._cfg = config
        self._inflation = tuple(
            _nonneg(f"truth_inflation[{i}]", v) for i, v in enumerate(config.truth_inflation)
        )
        if len(self._inflation) != 3:
            raise ValueError(f"truth_inflation needs 3 values, got {config.truth_inflation!r}")
        if len(config.max_slip) != 2:
            raise ValueError(f"max_slip must be (metres, radians), got {config.max_slip!r}")
        self._slip = (_nonneg("max_slip[0]", config.max_slip[0]),
                      _nonneg("max_slip[1]", config.max_slip[1]))
        self._recover = config.mode == "autonomous" and (self._slip[0] > 0 or self._slip[1] > 0)
        fv = _nonneg("fault_speed", config.fault_speed)
        fw = _nonneg("fault_yaw_rate", config.fault_yaw_rate)
        self._faulty = config.mode == "autonomous" and (fv > 0 or fw > 0)
        """The fault model is on: the fault set is kept (module docstring, "Fault model"); it
        replaces the ``max_slip`` recovery."""
        self._recover = self._recover and not self._faulty
        n = _nextafter
        self._fault_bounds = (n(self._ev + fv, _INF), n(self._ew + fw, _INF))
        self._fault: list[Tuple6] = []
        self._boxes: list[Tuple6] = []
        self._rejections = 0
        self._lost = False
        self._window = 0
        self.reset(initial)

    def reset(self, box: Box) -> None:
        """Start again from ``box`` (it must contain the true pose): clears the rejection streak
        and the ``lost`` state."""
        self._boxes = [_check_box("initial box", box)]
        self._fault = list(self._boxes)
        self._rejections = 0
        self._lost = False
        self._window = 0

    @property
    def current(self) -> BoxSet:
        """The set after the last step (or the initial box)."""
        return _to_boxset(self._boxes)

    @property
    def lost(self) -> bool:
        """True once the localizer declared itself lost (until :meth:`reset`)."""
        return self._lost

    def step(
        self,
        odometry: Odometry | None,
        compass: float | None,
        observation: Observation | None,
        truth: Pose | None = None,
    ) -> LocalizerStep:
        """One frame: predict with ``odometry`` (the motion since the previous step; None = no
        motion, e.g. frame 0), intersect with ``compass`` (rad, wrapped to (-pi, pi], or None),
        contract with ``observation`` (or None). ``truth`` is needed in mode ``truth`` only.
        Raises ValueError naming the quantity on NaN/inf, negative dt, negative bounds."""
        cfg = self._cfg
        mode = cfg.mode
        cap = cfg.max_boxes
        hulled = False
        # validate every input first, so a bad frame changes nothing. The fast test: every value
        # within +-LIMIT (written as literals; NaN fails, a non-number raises TypeError); on
        # failure the checks that name the culprit run.
        if odometry is not None:
            v, w, dt = odometry.speed, odometry.yaw_rate, odometry.dt
            try:
                ok = -1e9 <= v <= 1e9 and -1e9 <= w <= 1e9 and 0 <= dt <= 1e9
            except TypeError:
                ok = False
            if not ok:
                _finite("odometry.speed", v)
                _finite("odometry.yaw_rate", w)
                _nonneg("odometry.dt", dt)
        if compass is not None:
            try:
                ok = -1e9 <= compass <= 1e9
            except TypeError:
                ok = False
            if not ok:
                _finite("compass", compass)
        if observation is not None:
            o = observation
            e, e3 = o.position_error, o.heading_error
            try:
                ok = (-1e9 <= o.y1 <= 1e9 and -1e9 <= o.y2 <= 1e9 and -1e9 <= o.y3 <= 1e9
                      and 0 <= e <= 1e9 and 0 <= e3 <= 1e9)
            except TypeError:
                ok = False
            if not ok:
                _finite("observation.y1", o.y1)
                _finite("observation.y2", o.y2)
                _finite("observation.y3", o.y3)
                _nonneg("observation.position_error", e)
                _nonneg("observation.heading_error", e3)
        if truth is not None:
            tx, ty, tt = truth.x, truth.y, truth.theta
            try:
                ok = -1e9 <= tx <= 1e9 and -1e9 <= ty <= 1e9 and -1e9 <= tt <= 1e9
            except TypeError:
                ok = False
            if not ok:
                _finite("truth.x", tx)
                _finite("truth.y", ty)
                _finite("truth.theta", tt)
        elif mode == "truth":
            raise ValueError("truth: mode 'truth' needs the true pose every frame, got None")

        # prediction
        if mode == "truth":
            ix, iy, it = self._inflation
            n = _nextafter
            boxes = _in_range([(n(tx - ix, -_INF), n(tx + ix, _INF), n(ty - iy, -_INF),
                                n(ty + iy, _INF), n(tt - it, -_INF), n(tt + it, _INF))])
        elif odometry is not None:
            n = _nextafter
            v_lo, v_hi = n(v - self._ev, -_INF), n(v + self._ev, _INF)
            w_lo, w_hi = n(w - self._ew, -_INF), n(w + self._ew, _INF)
            prior = self._boxes
            boxes = ([predict_box(prior[0], v_lo, v_hi, w_lo, w_hi, dt)] if len(prior) == 1 else
                     [predict_box(b, v_lo, v_hi, w_lo, w_hi, dt) for b in prior])
            for b in boxes:
                if not (-1e9 <= b[0] and b[1] <= 1e9 and -1e9 <= b[2] and b[3] <= 1e9
                        and -1e9 <= b[4] and b[5] <= 1e9 and b[5] - b[4] <= _TURN):
                    boxes = _in_range(boxes)  # raises, or cuts a heading to one turn
                    break
            if len(boxes) > 1:  # (one box is tidy: cap >= 1, LocalizerConfig checks it)
                boxes, hulled = _tidy(boxes, cap)
        else:
            boxes = list(self._boxes)

        fault: list[Tuple6] | None = None  # the fault set's prediction (fault model on)
        if self._faulty and not self._lost:
            fault = self._fault
            if odometry is not None:
                n = _nextafter
                ev, ew = self._fault_bounds
                fault = _in_range([predict_box(b, n(v - ev, -_INF), n(v + ev, _INF),
                                               n(w - ew, -_INF), n(w + ew, _INF), dt)
                                   for b in fault])
                if len(fault) > 1:
                    fault, h = _tidy(fault, cap)
                    hulled = hulled or h
            if compass is not None:
                cut = self._compass_cut(fault, compass)
                if cut:  # (a compass that misses the fault set too is ignored)
                    fault, h = _tidy(cut, cap)
                    hulled = hulled or h
        compass_rejected = False
        reinflated = False
        raw = boxes  # the prediction before the compass: what recovery inflates
        recover = self._recover and not self._lost
        following = recover and self._window > 0  # a fault noticed lately: follow it
        if following:
            self._window -= 1
        if compass is not None:
            c_lo = _nextafter(compass - self._ec, -_INF)
            c_hi = _nextafter(compass + self._ec, _INF)
            cut = (compass_pieces(boxes[0], c_lo, c_hi) if len(boxes) == 1 else
                   [p for b in boxes for p in compass_pieces(b, c_lo, c_hi)])
            if len(cut) == 1:
                boxes = cut
            elif cut:
                boxes, h = _tidy(cut, cap)
                hulled = hulled or h
            else:
                compass_rejected = True
                if fault is not None:
                    # the compass misses the prediction: the fault set holds what a fault allows
                    boxes = fault
                    reinflated = True
                elif recover:
                    # the prediction misses the compass: keep it (the compass may be the outlier)
                    # and add the slip candidates the compass allows (the odometry may be)
                    self._window = cfg.slip_window
                    extra, _, h = self._slip_candidates(raw, compass, None)
                    if extra:
                        boxes, h2 = _tidy(boxes + extra, cap)
                        hulled = hulled or h or h2
                        reinflated = True
        predicted = _to_boxset(boxes)

        passes = 0
        if self._lost and mode != "truth":
            status = "lost"
            updated_boxes = [_hull_all(boxes)]
        elif mode == "odometry" or observation is None:
            status = "predicted"
            updated_boxes = boxes
        else:
            view = _view_window(observation)
            out: list[Tuple6] = []
            view_hulled = False
            if following:
                # within slip_window frames of a noticed fault: the view contracts the prediction
                # inflated by max_slip (it holds the plain prediction)
                out, passes, h = self._slip_candidates(raw, compass, view)
                hulled = hulled or h
                reinflated = bool(out)
            else:
                for b in boxes:
                    got, p, h = _contract_view(b, view, None, self._L, self._lever, cfg.passes,
                                               cap)
                    out.extend(got)
                    if p > passes:
                        passes = p
                    view_hulled = view_hulled or h
                hulled = hulled or view_hulled
            if fault is not None:
                # the set is taken from the fault set only when the view cuts it to a few
                # disjoint boxes: a hull (more cells than max_boxes) would be a wide box called
                # contracted, so such a frame counts as a rejection instead
                if reinflated:  # (boxes is the fault set already: contracted above)
                    if out:
                        fault = out
                    if view_hulled or len(out) > cap:
                        out = []
                else:
                    got_f: list[Tuple6] = []
                    f_hulled = False
                    for b in fault:
                        got, p, h = _contract_view(b, view, None, self._L, self._lever,
                                                   cfg.passes, cap)
                        got_f.extend(got)
                        f_hulled = f_hulled or h
                    hulled = hulled or f_hulled
                    if got_f:
                        fault = got_f
                        if not out and not f_hulled and len(got_f) <= cap:
                            # the view rejects the prediction, not the fault set
                            out = got_f
                            reinflated = True
            if out:
                status = "contracted"
                self._rejections = 0
                if len(out) == 1:
                    updated_boxes = out
                else:
                    updated_boxes, h = _tidy(out, cap)
                    hulled = hulled or h
            else:
                self._rejections += 1
                status = "rejected"
                updated_boxes = boxes
                if recover:
                    # the view misses the prediction: either the view is the outlier (keep the
                    # prediction) or the odometry is (keep what the view allows within max_slip)
                    self._window = cfg.slip_window
                    if not following:  # (when following, that set was just found empty)
                        extra, p, h = self._slip_candidates(raw, compass, view)
                        passes = max(passes, p)
                        hulled = hulled or h
                        if extra:
                            updated_boxes, h = _tidy(boxes + extra, cap)
                            hulled = hulled or h
                            reinflated = True
                limit = cfg.max_rejections
                if self._faulty and limit > FAULT_MAX_REJECTIONS:
                    limit = FAULT_MAX_REJECTIONS
                if mode == "autonomous" and self._rejections >= limit:
                    status = "lost"
                    self._lost = True
                    self._window = 0
                    updated_boxes = [_hull_all(updated_boxes)]
        self._boxes = updated_boxes
        if fault is not None:
            if reinflated:  # the set was taken from the fault set: they agree again
                fault = updated_boxes
            elif len(fault) > 1:
                fault, h = _tidy(fault, cap)
                hulled = hulled or h
            self._fault = fault
        result = _new(LocalizerStep)  # LocalizerStep(...) without its frozen __init__
        result.__dict__.update(
            predicted=predicted,
            updated=predicted if updated_boxes is boxes else _to_boxset(updated_boxes),
            status=status,
            passes=passes,
            hulled=hulled,
            compass_rejected=compass_rejected,
            rejections=self._rejections,
            reinflated=reinflated,
        )
        return result

    def _compass_cut(self, boxes: list[Tuple6], compass: float) -> list[Tuple6]:
        """The boxes' poses whose heading is within ``compass_error`` of ``compass`` (mod 2 pi)."""
        c_lo = _nextafter(compass - self._ec, -_INF)
        c_hi = _nextafter(compass + self._ec, _INF)
        return [p for b in boxes for p in compass_pieces(b, c_lo, c_hi)]

    def _slip_candidates(
        self,
        raw: list[Tuple6],
        compass: float | None,
        view: Window | None,
    ) -> tuple[list[Tuple6], int, bool]:
        """Recovery: the poses within ``max_slip`` of the prediction ``raw`` (before the compass)
        that the compass and the view allow (``view``: branch 0 of its windows, or None), as
        disjoint boxes (one per lattice cell).
        Without a view, only the part the compass meets (none when it misses them all); with a
        view, a compass that misses every candidate is ignored, as in :meth:`step`.
        Returns (boxes, largest number of contraction passes, hulled)."""
        cfg = self._cfg
        cap = cfg.max_boxes
        d, dt = self._slip
        grown, hulled = _tidy([_one_turn(inflate_box(b, d, dt)) for b in raw], cap)
        if compass is not None:
            cut = self._compass_cut(grown, compass)
            if cut:
                grown, h = _tidy(cut, cap)
                hulled = hulled or h
            elif view is None:
                return [], 0, hulled  # the compass misses the slip candidates too
        if view is None:
            return grown, 0, hulled
        out: list[Tuple6] = []
        passes = 0
        for b in grown:
            got, p, h = _contract_view(b, view, None, self._L, self._lever, cfg.passes, cap)
            out.extend(got)
            passes = max(passes, p)
            hulled = hulled or h
        return out, passes, hulled
