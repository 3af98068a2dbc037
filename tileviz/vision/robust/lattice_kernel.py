"""The lattice's loops, compiled with numba: the check for a missing line
(:func:`missing_line`) and the clipping of many lines to the view (:func:`clip_lines`), with
the conventions of :mod:`~tileviz.vision.robust.kernel` (numpy's order of operations, its NaN
propagation and error model). A family has a few dozen predicted lines: one compiled loop
instead of some twenty numpy calls on arrays that short. ``tests/test_vision_speed_paths.py``
checks them against a numpy reference (``tests/numpy_kernels.py``) and
:func:`~tileviz.vision.robust.lattice.clip_line` on random lattices.
"""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust.kernel import _max, _min, compiled

__all__ = ["clip_lines", "missing_line"]


@compiled
def _chord(n0: float, n1: float, hyp: float, v: float, width: int, height: int) -> float:
    """The length (px) inside the image of the line ``n . (p - centre) = v``: one entry of
    :func:`~tileviz.vision.robust.lattice.chords` (``hyp``: ``math.hypot`` of the normal)."""
    tx = -n1
    ty = n0
    lo = -np.inf
    hi = np.inf
    for axis in range(2):
        if axis == 0:
            p0 = (width - 1) / 2.0 + v * n0
            d = tx
            size = width
        else:
            p0 = (height - 1) / 2.0 + v * n1
            d = ty
            size = height
        if abs(d) < 1e-12:
            if not ((p0 >= -0.5) & (p0 <= size - 0.5)):
                hi = -np.inf
            continue
        a = (-0.5 - p0) / d
        b = (size - 0.5 - p0) / d
        lo = _max(lo, _min(a, b))
        hi = _min(hi, _max(a, b))
    span = hi - lo
    return (span if span > 0 else 0.0) * hyp


@compiled
def _nearest(values: np.ndarray, x: float) -> float:
    """``np.min(np.abs(values - x))`` of a non-empty array (NaN if any is NaN)."""
    out = abs(values[0] - x)
    for i in range(1, values.size):
        out = _min(out, abs(values[i] - x))
    return out


@compiled
def missing_line(n0: float, n1: float, hyp: float, ref: float, lp: float, reach: float,
                 margin: int, width: int, height: int, min_chord: float, found: np.ndarray,
                 peak: np.ndarray, fam: np.ndarray, k: int, pad: int, centre: float,
                 near: float, found_share: float) -> bool:
    """Whether a line of family ``k`` that the lattice predicts at the signed offsets ``ref + j
    lp`` (px; ``(n0, n1)`` the family's unit normal, ``hyp`` its ``math.hypot``) within
    ``reach`` of the centre is missing: visible along at least ``min_chord`` of the longest
    chord at the offset and ``margin`` px each side of it, neither a line ``found`` (offsets,
    px) within ``found_share`` of the period nor a dip of the family (``peak``, ``fam``: the
    projection's dips, padded by ``pad``; ``centre`` the warp centre's profile coordinate)
    within ``near`` px."""
    j0 = math.floor((-reach - ref) / lp)
    j1 = math.ceil((reach - ref) / lp)
    need = min_chord * _chord(n0, n1, hyp, 0.0, width, height)
    ndips = 0
    for i in range(fam.size):
        if fam[i] == k:
            ndips += 1
    dips = np.empty(ndips)
    m = 0
    for i in range(fam.size):
        if fam[i] == k:
            dips[m] = -((peak[i] - pad) - centre)
            m += 1
    for j in range(j0, j1 + 1):
        sj = ref + j * lp
        if not (_chord(n0, n1, hyp, sj - margin, width, height) >= need
                and _chord(n0, n1, hyp, sj, width, height) >= need
                and _chord(n0, n1, hyp, sj + margin, width, height) >= need):
            continue
        if found.size == 0 or _nearest(found, sj) > found_share * lp:
            if ndips and _nearest(dips, sj) <= near:
                continue
            return True
    return False


@compiled
def clip_lines(n0: float, n1: float, s: np.ndarray, width: int, height: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~tileviz.vision.robust.lattice.clip_line` of every offset in ``s`` (px) with the
    unit normal ``(n0, n1)`` (bit-identical; Python's ``min`` and ``max`` keep their first
    argument unless the second is strictly smaller / larger): the endpoints (k, 4) and
    whether each line meets the image (its row is unset otherwise)."""
    k = s.size
    out = np.empty((k, 4))
    hit = np.zeros(k, np.bool_)
    cxp = (width - 1) / 2.0
    cyp = (height - 1) / 2.0
    tx = -n1
    ty = n0
    for i in range(k):
        px = cxp + s[i] * n0
        py = cyp + s[i] * n1
        lo = -math.inf
        hi = math.inf
        inside = True
        for axis in range(2):
            p0 = px if axis == 0 else py
            d = tx if axis == 0 else ty
            size = width if axis == 0 else height
            if abs(d) < 1e-12:
                if not (-0.5 <= p0 <= size - 0.5):
                    inside = False
                continue
            a = (-0.5 - p0) / d
            b = (size - 0.5 - p0) / d
            small = b if b < a else a
            big = b if b > a else a
            lo = small if small > lo else lo
            hi = big if big < hi else hi
        if not inside or hi - lo <= 0:
            continue
        hit[i] = True
        out[i, 0] = px + lo * tx
        out[i, 1] = py + lo * ty
        out[i, 2] = px + hi * tx
        out[i, 3] = py + hi * ty
    return out, hit
