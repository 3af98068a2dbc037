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

_DECIDERS = 12
"""Parts that decide a set's extent: a pair for each end of the tilt's range and of each
family's offset range."""


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
def _extent(a: np.ndarray, lo: np.ndarray, hi: np.ndarray, fam: np.ndarray, keep: np.ndarray,
            out: np.ndarray, who: np.ndarray) -> int:
    """The extent of the lattices that the kept parts allow (part i: ``-o_fam + a_i eps`` in
    [lo_i, hi_i]) into ``out`` (rows eps, o_1, o_2; columns lower, upper) and the parts that
    decide it into ``who`` (-1: none); the status of :func:`feasible_ranges`.

    The tilt: two parts of one family allow one offset only where ``a_i eps - hi_i <= a_j eps
    - lo_j``, a half-line of eps for each pair. Each offset's least: the least over the tilt
    range of the convex ``max_i (a_i eps - hi_i)``, which on an interval of one variable is that
    of its worst pair (two constraints decide a linear programme in one variable, Helly), each
    pair's in closed form; its greatest likewise."""
    out[:] = np.nan
    who[:] = -1
    n = a.size
    e_lo = -np.inf
    e_hi = np.inf
    for i in range(n):
        if not keep[i]:
            continue
        for j in range(n):
            if j == i or not keep[j] or fam[j] != fam[i]:
                continue
            da = a[i] - a[j]
            c = hi[i] - lo[j]
            if da > 0.0:
                if c / da < e_hi:
                    e_hi = c / da
                    who[2] = i
                    who[3] = j
            elif da < 0.0:
                if c / da > e_lo:
                    e_lo = c / da
                    who[0] = i
                    who[1] = j
            elif c < 0.0:  # parallel slabs that do not meet
                who[:] = -1
                who[0] = i
                who[1] = j
                return 1
    if e_lo > e_hi:
        return 1
    if not (np.isfinite(e_lo) and np.isfinite(e_hi)):
        return 2
    out[0, 0] = e_lo
    out[0, 1] = e_hi
    for k in range(2):
        for end in range(2):
            # lower end: o_k >= a_i eps - hi_i for every part; upper end: -o_k >= -(a_i eps -
            # lo_i), the same with the signs turned
            sign = 1.0 if end == 0 else -1.0
            c = hi if end == 0 else lo
            best = -np.inf
            slot = 4 + 4 * k + 2 * end
            for i in range(n):
                if not keep[i] or fam[i] != k:
                    continue
                for j in range(i, n):
                    if not keep[j] or fam[j] != k:
                        continue
                    v = _pair_least(sign * a[i], sign * c[i], sign * a[j], sign * c[j],
                                    e_lo, e_hi)
                    if v > best:
                        best = v
                        who[slot] = i
                        who[slot + 1] = j
            out[1 + k, end] = sign * best
    return 0


@compiled
def _finite(a: np.ndarray, q: np.ndarray, b: np.ndarray) -> bool:
    """Whether every part's tangent coordinate, position and bound is finite."""
    for i in range(a.size):
        if not (np.isfinite(a[i]) and np.isfinite(q[i]) and np.isfinite(b[i])):
            return False
    return True


@compiled
def _bounded(row: np.ndarray) -> bool:
    """Whether a range (lower, upper) is finite at both ends."""
    return bool(np.isfinite(row[0]) and np.isfinite(row[1]))


@compiled
def feasible_ranges(a: np.ndarray, q: np.ndarray, b: np.ndarray,
                    fam: np.ndarray) -> tuple[int, np.ndarray]:
    """The extent of the lattices (eps, o_1, o_2) that the parts allow, each part i of family
    ``fam[i]`` (0 or 1) saying ``-o_fam + a_i eps`` is within ``b_i`` of ``q_i``: a status
    (0: the ranges; 1: no lattice allows every part; 2: the tilt's range is unbounded or an
    input not finite) and the ranges as rows [eps, o_1, o_2] x [lower, upper] (a family with
    no part: its offset's range is infinite)."""
    out = np.full((3, 2), np.nan)
    if not _finite(a, q, b):
        return 2, out
    who = np.empty(_DECIDERS, np.intp)
    status = _extent(a, q - b, q + b, fam, np.ones(a.size, np.bool_), out, who)
    return status, out


@compiled
def relaxed_ranges(a: np.ndarray, q: np.ndarray, b: np.ndarray, fam: np.ndarray,
                   group: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """:func:`feasible_ranges` allowing one group of constraints (``group[i]``: one line's) to
    be wrong: the union over each group left out in turn of the ranges the others allow. A
    status 0 and the ranges when some group left out leaves a set and none leaves the tilt
    unbounded; 2 when one does (or an input is not finite); 1 when every group left out leaves
    none. Only the groups of the parts that decide the whole set's extent are left out: leaving
    out any other leaves the same extent (a constraint not active at a linear programme's
    optimum does not move it), which every set of all groups but one holds.

    A group whose leaving out leaves a family's offset unbounded (the family's only line) does
    not widen that offset's range, which is the union over the other groups left out (NaN when
    there is none); ``opened[k]`` (the third result) says that family k's offset is bounded
    only with that group right: the caller bounds it otherwise."""
    out = np.full((3, 2), np.nan)
    opened = np.zeros(2, np.bool_)
    if not _finite(a, q, b):
        return 2, out, opened
    lo = q - b
    hi = q + b
    who = np.empty(_DECIDERS, np.intp)
    status = _extent(a, lo, hi, fam, np.ones(a.size, np.bool_), out, who)
    if status == 2:
        return 2, out, opened
    found = status == 0
    if not found:
        out[:] = np.nan  # no lattice allows every part: the ranges are the left-out sets' only
    for k in range(2):
        if found and not _bounded(out[1 + k]):
            opened[k] = True  # a family without parts
            out[1 + k] = np.nan
    deciders = np.unique(np.array([group[i] for i in who if i >= 0]))
    r = np.empty((3, 2))
    who_g = np.empty(_DECIDERS, np.intp)
    for g in deciders:
        s_g = _extent(a, lo, hi, fam, group != g, r, who_g)
        if s_g == 2:
            return 2, out, opened
        if s_g == 1:
            continue
        found = True
        for v in range(3):
            if v > 0 and not _bounded(r[v]):
                opened[v - 1] = True
                continue
            out[v, 0] = np.fmin(out[v, 0], r[v, 0])  # a NaN end (none yet) takes r's
            out[v, 1] = np.fmax(out[v, 1], r[v, 1])
    return (0 if found else 1), out, opened
