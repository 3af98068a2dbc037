"""Contraction of a box with a tile observation (docs/method.md, "Contraction", "Lever arm"): per
rotation branch, the camera-centre interval cut by the lattice exactly, each cell pushed back
through the lever arm to the fixpoint of its projections; every bound outward rounded."""

from __future__ import annotations

import math

from tileviz.core.intervals import (
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
)
from tileviz.types import Box, Observation

__all__ = [
    "FIXPOINT_TOL", "Lever", "Window", "contract_box", "contract_branch", "contract_view",
    "lever_enclosure", "observation_windows", "view_window",
]

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

_QUARTER_LO = (0.0, HALF_PI_LO, _nextafter(2.0 * HALF_PI_LO, -_INF),
               _nextafter(3.0 * HALF_PI_LO, -_INF))
_QUARTER_HI = (0.0, HALF_PI_HI, _nextafter(2.0 * HALF_PI_HI, _INF),
               _nextafter(3.0 * HALF_PI_HI, _INF))
"""Rigorous bounds of m pi/2, m = 0..3."""
_EIGHTH_TURN = 0.5 * HALF_PI
"""pi/4 (rounded): heading windows this wide or wider may overlap (contract_box)."""



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


def observation_windows(obs: Observation) -> tuple[Window, Window, Window, Window]:
    """The four rotation branches of an observation (docs/method.md, "The corrected equivalence"):
    for m = 0..3, [u] = R(m pi/2) ([y1 +- e], [y2 +- e]) and [h] = [y3 +- e3] + m pi/2, so the pose
    is consistent with branch m iff c in [u] + L Z^2 and theta in [h] + 2 pi Z."""
    w0 = view_window(obs)
    return (w0, _branch_window(w0, 1), _branch_window(w0, 2), _branch_window(w0, 3))


def view_window(obs: Observation) -> Window:
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
) -> tuple[Box | None, int]:
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
    return Box(x_lo, x_hi, y_lo, y_hi, t_lo, t_hi), p


def _contract_cells(
    b: Box,
    a_lo: float,
    a_hi: float,
    win: Window,
    tile_size: float,
    lever: Lever | None,
    max_passes: int,
    max_cells: int,
    out: list[Box],
) -> tuple[int, bool]:
    """Contract box ``b`` whose heading is already cut to one piece [a_lo, a_hi] of branch
    ``win``: the camera-centre interval [c] = [x] + rho cos([t] + phi) (resp. y, sin) is cut
    exactly by the lattice [u] + L Z (``lattice_intersect``) and every (x piece, y piece) cell
    becomes one box, pushed back through the lever arm (:func:`_refine_cell`). Appends the boxes
    to ``out``; returns (largest number of passes, whether pieces were hulled)."""
    x_lo, x_hi, y_lo, y_hi = b[0], b[1], b[2], b[3]
    if lever is None:  # the camera centre is the robot point
        g = (0.0, 0.0, 0.0, 0.0)
        c: tuple[float, ...] = b
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
                out.append(Box(px_lo, px_hi, py_lo, py_hi, a_lo, a_hi))
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
    b: Box,
    win: Window,
    tile_size: float,
    lever: Lever | None,
    max_passes: int,
    max_cells: int,
) -> tuple[list[Box], int, bool]:
    """Contract box ``b`` with one rotation branch ``win`` of an observation (docs/method.md).

    The heading is cut to [h] + 2 pi Z, then each heading piece is contracted by
    :func:`_contract_cells`: one box per lattice cell of the camera centre, pushed back through
    the lever arm; with no lever arm the cut is final (one pass). When a heading piece has more
    than ``max_cells`` cells, the x and y pieces are replaced by their hulls (one box).
    Returns (boxes, largest number of passes, whether a hull replaced pieces).
    """
    out: list[Box] = []
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
    b: Box,
    windows: tuple[Window, Window, Window, Window],
    tile_size: float,
    lever: Lever | None,
    max_passes: int,
    max_cells: int,
) -> tuple[list[Box], int, bool]:
    """Union over the four rotation branches of :func:`contract_branch`.

    The branches' heading windows are [h0] + m pi/2 + 2 pi Z = [h0] + k pi/2 with m = k mod 4, so
    one pass over the pi/2-lattice finds every branch piece the box heading meets (when the
    windows are disjoint, e3 < pi/4; otherwise each branch is cut on its own)."""
    return contract_view(b, windows[0], windows, tile_size, lever, max_passes, max_cells)


def contract_view(
    b: Box,
    w0: Window,
    windows: tuple[Window, Window, Window, Window] | None,
    tile_size: float,
    lever: Lever | None,
    max_passes: int,
    max_cells: int,
) -> tuple[list[Box], int, bool]:
    """:func:`contract_box` with ``windows`` built on demand from branch 0 ``w0`` when None
    (only the branches the heading meets are needed)."""
    out: list[Box] = []
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
