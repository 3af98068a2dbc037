"""The foreign-edge search's loops over the points of a straight edge, compiled with numba,
with the conventions of :mod:`~tileviz.vision.robust.kernel` (numpy's order of operations,
``np.rint``'s rounding half to even, ``argmax`` / ``argmin`` taking the first extreme):

- :func:`edge_shares`: each straight edge's share of points seen as an edge with its normal;
- :func:`end_steps`: the steps from an edge's end to the border of the view, where they meet
  the grout bands and whether the edge is seen before and beyond them;
- :func:`stretch_range`: the grout's own variation along its line.

A photograph's view has dozens of such edges, each followed from both ends: one compiled loop
each instead of some forty numpy calls on arrays of a few dozen points.
``tests/test_vision_speed_paths.py`` checks them bit for bit against a numpy reference
(``tests/numpy_kernels.py``) on random edges and gradients.
"""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust.kernel import compiled

__all__ = ["edge_shares", "end_steps", "stretch_range"]


@compiled
def _hit(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, x: int, y: int, nx: float,
         ny: float, cos_tol: float) -> bool:
    """Whether pixel (x, y) lies within 1 px (its 3 x 3 neighbourhood, clipped to the view) of
    an edge pixel of ``edges`` whose gradient (``dx``, ``dy``) is within the tolerance
    (``cos_tol``: its cosine) of the unit normal (nx, ny), of either sign: one entry of
    :func:`~tileviz.vision.robust.foreign.oriented_points`."""
    h, w = edges.shape
    for ox in range(-1, 2):
        xx = min(max(x + ox, 0), w - 1)
        for oy in range(-1, 2):
            yy = min(max(y + oy, 0), h - 1)
            if edges[yy, xx] == 0:
                continue
            gx = float(dx[yy, xx])
            gy = float(dy[yy, xx])
            g = math.hypot(gx, gy)
            if abs(gx * nx + gy * ny) >= cos_tol * g and g > 0:
                return True
    return False


@compiled
def _count_hits(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, xs: np.ndarray,
                ys: np.ndarray, lo: int, hi: int, nx: float, ny: float, cos_tol: float) -> int:
    """How many of the pixels (xs, ys)[lo:hi] :func:`_hit` sees (as
    :func:`~tileviz.vision.robust.foreign.oriented_points` does)."""
    n = 0
    for i in range(lo, hi):
        if _hit(dx, dy, edges, xs[i], ys[i], nx, ny, cos_tol):
            n += 1
    return n


@compiled
def edge_shares(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, seg: np.ndarray,
                cos_tol: float) -> np.ndarray:
    """For each straight edge (rows of ``seg``: x1, y1, x2, y2, px), the share of its points (1 px
    apart) that :func:`_hit` sees with its normal; 0 for an edge under 1 px."""
    out = np.zeros(seg.shape[0])
    for i in range(seg.shape[0]):
        x1 = seg[i, 0]
        y1 = seg[i, 1]
        x2 = seg[i, 2]
        y2 = seg[i, 3]
        ln = math.hypot(x2 - x1, y2 - y1)
        if ln < 1.0:
            continue
        n = int(math.ceil(ln + 0.5))  # np.arange(0.0, ln + 0.5, 1.0)'s length
        nx = -(y2 - y1) / ln
        ny = (x2 - x1) / ln
        hits = 0
        for j in range(n):
            t = float(j) / ln
            x = int(np.rint(x1 + t * (x2 - x1)))
            y = int(np.rint(y1 + t * (y2 - y1)))
            if _hit(dx, dy, edges, x, y, nx, ny, cos_tol):
                hits += 1
        out[i] = hits / n
    return out


@compiled
def end_steps(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, px: float, py: float,
              ux: float, uy: float, band: float, n00: float, n01: float, n10: float,
              n11: float, sh0: float, sh1: float, lp: float, cos_tol: float,
              inside_steps: int, far_steps: int, seen_share: float
              ) -> tuple[int, np.ndarray, np.ndarray, int, int, int, bool, int, float]:
    """The steps of :func:`~tileviz.vision.robust.foreign.ends` from a straight edge's end
    (px, py) along the unit vector (ux, uy), 1 px apart, to the border of the view (``edges``:
    the edge pixels, HxW; ``dx``, ``dy``: the gradients), and where they meet the grout bands
    (half-width ``band``, px; the families' unit normals (n00, n01), (n10, n11) and offsets
    sh0, sh1, px, so that a line lies where ``n . (p - centre) + sh`` is a multiple of the
    period ``lp``, px).

    Returns (done, xs, ys, i0, i1, i2, far, k, dmin): ``done`` (1) when the border of the view
    comes before any band, or at least ``inside_steps`` steps lead to the first band and at
    most ``seen_share`` of them see the edge (:func:`_hit` with tolerance cosine ``cos_tol``);
    else the steps (xs, ys, pixels), the first step in a band ``i0``, the first after it out of
    the bands ``i1``, the first in a band again ``i2`` (the number of steps when none), whether
    at least ``far_steps`` steps lie between and at least ``seen_share`` of them see the edge
    (``far``), the family ``k`` whose lines
    come nearest in ``i0..i1`` and that distance ``dmin`` (px)."""
    h, w = edges.shape
    empty = np.zeros(0, np.intp)
    lim = math.inf
    have = False
    for axis in range(2):
        p = px if axis == 0 else py
        d = ux if axis == 0 else uy
        size = w if axis == 0 else h
        if d > 1e-12:
            v = (size - 0.5 - p) / d
        elif d < -1e-12:
            v = (-0.5 - p) / d
        else:
            continue
        if not have or v < lim:
            lim = v
        have = True
    tmax = int(math.floor(lim - 1e-9)) if have else 0
    if tmax < 1:
        return 1, empty, empty, 0, 0, 0, False, 0, 0.0
    xs = np.empty(tmax, np.intp)
    ys = np.empty(tmax, np.intp)
    m = 0
    for i in range(tmax):
        t = 1.0 + i
        x = int(np.rint(px + t * ux))
        y = int(np.rint(py + t * uy))
        if 0 <= x < w and 0 <= y < h:
            xs[m] = x
            ys[m] = y
            m += 1
    if m == 0:
        return 1, empty, empty, 0, 0, 0, False, 0, 0.0
    xs = xs[:m]
    ys = ys[:m]
    cx = (w - 1) / 2.0
    cy = (h - 1) / 2.0
    dk0 = np.empty(m)
    dk1 = np.empty(m)
    i0 = m
    for i in range(m):
        fx = float(xs[i]) - cx
        fy = float(ys[i]) - cy
        o = n00 * fx + n01 * fy + sh0
        dk0[i] = abs(o - lp * np.rint(o / lp))
        o = n10 * fx + n11 * fy + sh1
        dk1[i] = abs(o - lp * np.rint(o / lp))
        if i0 == m and min(dk0[i], dk1[i]) < band:
            i0 = i
    if i0 == m:
        return 1, xs, ys, i0, m, m, False, 0, 0.0  # the border comes first
    nx = -uy
    ny = ux
    if (i0 >= inside_steps
            and _count_hits(dx, dy, edges, xs, ys, 0, i0, nx, ny, cos_tol) <= seen_share * i0):
        return 1, xs, ys, i0, m, m, False, 0, 0.0  # it ends inside the tile
    i1 = m
    for i in range(i0, m):
        if not min(dk0[i], dk1[i]) < band:
            i1 = i
            break
    i2 = m
    for i in range(i1, m):
        if min(dk0[i], dk1[i]) < band:
            i2 = i
            break
    n2 = i2 - i1
    far = n2 >= far_steps and (
        _count_hits(dx, dy, edges, xs, ys, i1, i2, nx, ny, cos_tol) >= seen_share * n2)
    m0 = dk0[i0]
    m1 = dk1[i0]
    for i in range(i0 + 1, i1):
        m0 = min(m0, dk0[i])
        m1 = min(m1, dk1[i])
    k = 0 if m0 <= m1 else 1
    return 0, xs, ys, i0, i1, i2, far, k, m0 if k == 0 else m1


@compiled
def stretch_range(lv: np.ndarray, idx: np.ndarray, u: np.ndarray, clear: int,
                  stretches: int) -> float:
    """The largest range of 19 consecutive levels ``lv`` (at the samples ``idx[1:-1]`` of the
    positions ``u`` along the line) among the stretches ``clear`` samples clear of the
    crossing's own (u = 0 +- 9), NaN when fewer than ``stretches`` are."""
    zero = 0
    for i in range(1, u.size):
        if abs(u[i]) < abs(u[zero]):
            zero = i
    lim = 9 + clear
    count = 0
    best = -math.inf
    for j in range(lv.size - 18):
        first = idx[1 + j]
        if not (first + 18 < zero - lim or first > zero + lim):
            continue
        count += 1
        lo = lv[j]
        hi = lv[j]
        for q in range(j + 1, j + 19):
            lo = min(lo, lv[q])
            hi = max(hi, lv[q])
        best = max(best, hi - lo)
    if count < stretches:
        return math.nan
    return best
