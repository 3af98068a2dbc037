"""The set of lattices that a view's measured parts allow, compiled with numba
(:func:`feasible_ranges`, :func:`relaxed_ranges`; docs/vision.md, "The bound of a view").

Each measured part i of a line of family k says, within its own bound b_i (px),
``-o_k + a_i eps = q_i``: o_k is the family's offset at the view's centre (px), eps the
residual tilt (rad), a_i the part's tangent coordinate signed as the fit's families are, q_i
its position relative to the ideal line it belongs to
(:func:`~tileviz.vision.robust.lattice.feasible_terms`). The lattices that every part allows
form a convex polygon in (eps, o_1, o_2); :func:`feasible_ranges` gives its extent along each
axis exactly, and
:func:`relaxed_ranges` the extent of the lattices that the parts of every line but one allow.
The truth lies in the first whenever every part is within its bound, in the second whenever
every line's but one's are; the distance from the estimate to the set's far ends then bounds
its error (``tests/test_vision_feasible.py`` checks the ranges against linear programmes).
"""

from __future__ import annotations

import numpy as np

from tileviz.vision.robust.kernel import compiled

__all__ = ["feasible_ranges", "relaxed_ranges"]

@compiled
def _tilt_range(a: np.ndarray, lo: np.ndarray, hi: np.ndarray, fam: np.ndarray,
                k: int) -> tuple[float, float]:
    """The tilts eps (rad) at which family ``k``'s parts allow one common offset:
    ``max_i (a_i eps - hi_i) <= min_j (a_j eps - lo_j)`` for every pair of its parts (an
    empty range is returned as lower > upper)."""
    e_lo = -np.inf
    e_hi = np.inf
    n = a.size
    for i in range(n):
        if fam[i] != k:
            continue
        for j in range(n):
            if fam[j] != k or j == i:
                continue
            da = a[i] - a[j]
            c = hi[i] - lo[j]
            if da > 0.0:
                e_hi = min(e_hi, c / da)
            elif da < 0.0:
                e_lo = max(e_lo, c / da)
            elif c < 0.0:
                return np.inf, -np.inf
    return e_lo, e_hi


@compiled
def _pair_least(ai: float, ci: float, aj: float, cj: float, e_lo: float, e_hi: float) -> float:
    """The least over eps in [e_lo, e_hi] of ``max(ai eps - ci, aj eps - cj)``: at an end or
    where the two lines cross (a convex function with one corner)."""
    best = max(ai * e_lo - ci, aj * e_lo - cj)
    best = min(best, max(ai * e_hi - ci, aj * e_hi - cj))
    if ai != aj:
        x = min(max((ci - cj) / (ai - aj), e_lo), e_hi)
        best = min(best, max(ai * x - ci, aj * x - cj))
    return best


@compiled
def _least(a: np.ndarray, c: np.ndarray, fam: np.ndarray, k: int, e_lo: float, e_hi: float,
           sign: float) -> float:
    """The least over eps in [e_lo, e_hi] of the convex ``max_i sign (a_i eps - c_i)`` over
    family ``k``'s parts (-inf when it has none). On an interval of one variable the least of
    a maximum of lines is that of its worst pair (Helly's theorem: two constraints decide a
    linear programme in one variable), each pair's in closed form."""
    best = -np.inf
    n = a.size
    for i in range(n):
        if fam[i] != k:
            continue
        ai = sign * a[i]
        ci = sign * c[i]
        for j in range(i, n):
            if fam[j] != k:
                continue
            best = max(best, _pair_least(ai, ci, sign * a[j], sign * c[j], e_lo, e_hi))
    return best


@compiled
def feasible_ranges(a: np.ndarray, q: np.ndarray, b: np.ndarray,
                    fam: np.ndarray) -> tuple[int, np.ndarray]:
    """The extent of the lattices (eps, o_1, o_2) that the parts allow, each part i of family
    ``fam[i]`` (0 or 1) saying ``-o_fam + a_i eps`` is within ``b_i`` of ``q_i``: a status
    (0: the ranges; 1: no lattice allows every part; 2: the tilt's range is unbounded or an
    input not finite) and the ranges as rows [eps, o_1, o_2] x [lower, upper] (a family with
    no part: its offset's range is infinite)."""
    out = np.full((3, 2), np.nan)
    for i in range(a.size):
        if not (np.isfinite(a[i]) and np.isfinite(q[i]) and np.isfinite(b[i])):
            return 2, out
    lo = q - b
    hi = q + b
    e_lo = -np.inf
    e_hi = np.inf
    for k in range(2):
        r_lo, r_hi = _tilt_range(a, lo, hi, fam, k)
        e_lo = max(e_lo, r_lo)
        e_hi = min(e_hi, r_hi)
    if e_lo > e_hi:
        return 1, out
    if not (np.isfinite(e_lo) and np.isfinite(e_hi)):
        return 2, out
    out[0, 0] = e_lo
    out[0, 1] = e_hi
    for k in range(2):
        # o_k >= a_i eps - hi_i for every part: its least is the least of that upper envelope;
        # o_k <= a_i eps - lo_i: its greatest is minus the least of max_i -(a_i eps - lo_i)
        out[1 + k, 0] = _least(a, hi, fam, k, e_lo, e_hi, 1.0)
        out[1 + k, 1] = -_least(a, lo, fam, k, e_lo, e_hi, -1.0)
    return 0, out


@compiled
def relaxed_ranges(a: np.ndarray, q: np.ndarray, b: np.ndarray, fam: np.ndarray,
                   group: np.ndarray) -> tuple[int, np.ndarray]:
    """:func:`feasible_ranges` allowing one group of constraints (``group[i]``: one line's) to
    be wrong: the union over each group left out in turn of the ranges the others allow. A
    status 0 and the ranges when some group left out leaves a set and none leaves the tilt
    unbounded; 2 when one does (or an input is not finite); 1 when every group left out leaves
    none."""
    out = np.full((3, 2), np.nan)
    found = False
    for g in np.unique(group):
        keep = group != g
        status, r = feasible_ranges(a[keep], q[keep], b[keep], fam[keep])
        if status == 2:
            return 2, out
        if status == 1:
            continue
        if not found:
            out[:] = r
            found = True
        else:
            for v in range(3):
                out[v, 0] = min(out[v, 0], r[v, 0])
                out[v, 1] = max(out[v, 1], r[v, 1])
    return (0 if found else 1), out
