"""The robust extractor's loops over profile samples, compiled with numba (a required
dependency; these kernels are the only implementation): one loop per dip or per part profile
instead of many numpy passes over all of them, and the compile decorator and numpy-exact helpers
the other kernels share. :func:`part_rows` (plateaus, crossings, centroid and midpoints of every
part profile), :func:`part_profiles` (the part profiles from the integral image). The dips'
kernels (each dip on its whole profile, its parts, each line's medians) are in
:mod:`~tileviz.vision.robust.dip_kernel`, the projection's kernels
(spans, profiles, dips, the light-grout test) are in
:mod:`~tileviz.vision.robust.projection_kernel`, the first heading's in
:mod:`~tileviz.vision.robust.heading_kernel`, the common fit of the lines' parts in
:mod:`~tileviz.vision.robust.fit_kernel`, the lattice's missing-line check and line clipping in
:mod:`~tileviz.vision.robust.lattice_kernel`, the foreign-edge search's in
:mod:`~tileviz.vision.robust.foreign_kernel`, the set of lattices the lines allow in
:mod:`~tileviz.vision.robust.feasible_kernel`.

Every operation is the numpy one in the same order: sums over a profile are numpy's pairwise
sums (:func:`_pairwise`, the order ``ndarray.sum`` adds a contiguous row in), medians sort the
finite values, ``argmax`` takes the first maximum, ``np.minimum`` / ``np.maximum`` / ``np.clip``
propagate NaN, float32 stays float32 where numpy keeps it. Division follows numpy's error model
(x / 0 is inf or NaN, no exception), as under the extractor's ``np.errstate``. The tests keep a
numpy reference of every kernel (``tests/numpy_profiles.py``, ``tests/numpy_kernels.py``) and
check the equality bit for bit on every floor family and on random inputs
(``tests/test_vision_speed_paths.py``).

The compiled code is cached next to this module (``cache=True``): only the first robust
extraction after an install (or after a change of this file) compiles the kernels, which takes
seconds of CPU; a later process loads them from the cache.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numba
import numpy as np

__all__ = ["compiled", "part_profiles",
           "part_rows"]


def compiled(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` compiled with numba, cached, without the GIL, with numpy's error model (x / 0 is
    inf or NaN)."""
    return numba.njit(cache=True, error_model="numpy", nogil=True)(fn)


_ROUGH = 1.4826 / math.sqrt(2.0)
_BIG = 1.7976931348623157e308  # np.nan_to_num's replacement of +inf


@compiled
def _block(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of a[lo : lo + n] for n <= 128 (8 accumulators)."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = 8
    end = n - n % 8
    while i < end:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@compiled
def _split(n: int) -> int:
    """Where numpy's pairwise sum splits n > 128 values: half, down to a multiple of 8."""
    n2 = n // 2
    return n2 - n2 % 8


@compiled
def _half(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of a[lo : lo + n] for n up to about 256."""
    if n <= 128:
        return _block(a, lo, n)
    n2 = _split(n)
    return _block(a, lo, n2) + _block(a, lo + n2, n - n2)


@compiled
def _pairwise(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of a[lo : lo + n] (blocks of up to 128 values, split in halves),
    for n up to about 512 (a profile window is at most 2 x 69 + 1 samples); written without
    recursion, which numba's cache does not load reliably."""
    if n <= 128:
        return _block(a, lo, n)
    n2 = _split(n)
    return _half(a, lo, n2) + _half(a, lo + n2, n - n2)


@compiled
def _rowsum(a: np.ndarray) -> float:
    """``a.sum()`` of a contiguous 1-D float64 array (as a row of ``.sum(axis=1)``)."""
    return 0.0 + _pairwise(a, 0, a.size)


@compiled
def _max(a: float, b: float) -> float:
    """np.maximum: NaN if either is NaN."""
    if math.isnan(a) or math.isnan(b):
        return math.nan
    return a if a >= b else b


@compiled
def _min(a: float, b: float) -> float:
    """np.minimum: NaN if either is NaN."""
    if math.isnan(a) or math.isnan(b):
        return math.nan
    return a if a <= b else b


@compiled
def _clip01(x: float) -> float:
    """np.clip(x, 0, 1) (NaN stays NaN)."""
    if math.isnan(x):
        return x
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@compiled
def _plateaus(p: np.ndarray, j: np.ndarray, c: float, half: float,
              buf: np.ndarray) -> tuple[float, float]:
    """One row of :func:`~tileviz.vision.robust.profiles.plateaus`."""
    cl = c - half
    cr = c + half
    n = p.size
    nl = 0
    nr = 0
    for i in range(n):
        ok = not math.isnan(p[i])
        pz = p[i] if ok else 0.0
        ml = (j[i] < cl) and (j[i] >= cl - 4.0) and ok
        buf[i] = pz * (1.0 if ml else 0.0)
        nl += 1 if ml else 0
    left = _rowsum(buf[:n]) / nl
    for i in range(n):
        ok = not math.isnan(p[i])
        pz = p[i] if ok else 0.0
        mr = (j[i] > cr) and (j[i] <= cr + 4.0) and ok
        buf[i] = pz * (1.0 if mr else 0.0)
        nr += 1 if mr else 0
    right = _rowsum(buf[:n]) / nr
    return left, right


@compiled
def _crossings(d: np.ndarray, j: np.ndarray, jp: float, lv: float) -> tuple[float, float]:
    """Where the darkness ``d`` (over sample offsets ``j``) first falls below ``lv`` on the
    left and on the right of its peak ``jp``, interpolated linearly; NaN when it does not (or
    runs into missing data first)."""
    n = j.size
    big = j[n - 1] + 1.0
    jl = -big
    jrt = big
    for i in range(n):
        below = not (d[i] >= lv)
        if below and j[i] < jp and j[i] > jl:
            jl = j[i]
        if below and j[i] > jp and j[i] < jrt:
            jrt = j[i]
    ok = (jl > -big) and (jrt < big)
    r = (n - 1) // 2
    il = int(min(max(jl + r, 0.0), n - 2.0))
    ir = int(min(max(jrt + r, 1.0), n - 1.0))
    xl = jl + (lv - d[il]) / (d[il + 1] - d[il])
    xr = jrt - (lv - d[ir]) / (d[ir - 1] - d[ir])
    if not ok:
        return math.nan, math.nan
    return xl, xr


@compiled
def _centroid(p: np.ndarray, j: np.ndarray, c: float, half: float, ll: float, lr: float,
              q: np.ndarray, qj: np.ndarray) -> float:
    """Centroid of the darkness ``1 - p / level`` over [c - half, c + half] (sample offsets
    ``j``), the level stepping from ``ll`` to ``lr`` at the current centre; each sample weighs
    by its overlap with the window; re-centred 3 times. NaN where the window holds missing data
    or no darkness. ``q``, ``qj``: scratch buffers."""
    dl = lr - ll
    cc = c
    n = j.size
    for _ in range(3):
        for i in range(n):
            w = _clip01(_min(j[i] + 0.5, cc + half) - _max(j[i] - 0.5, cc - half))
            lev = ll + dl * _clip01(j[i] - cc + 0.5)
            v = (1.0 - p[i] / lev) * w
            q[i] = v if w > 0 else 0.0
            qj[i] = q[i] * j[i]
        tot = _rowsum(q[:n])
        cc = _rowsum(qj[:n]) / tot if tot > 0 else math.nan
    return cc


@compiled
def _median_finite(a: np.ndarray, n: int) -> float:
    """Median of the finite values of a[:n] (NaN if none), as
    :func:`~tileviz.vision.robust.profiles.nanmedian` gives it; reorders ``a``."""
    cnt = 0
    for i in range(n):
        if math.isfinite(a[i]):
            a[cnt] = a[i]
            cnt += 1
    if cnt == 0:
        return math.nan
    s = np.sort(a[:cnt])
    return 0.5 * (s[(cnt - 1) // 2] + s[cnt // 2])


@compiled
def _midpoints(p: np.ndarray, j: np.ndarray, start: float, c: float, half: float,
               lev_l: float, lev_r: float, dn: np.ndarray, tmp: np.ndarray,
               mids: np.ndarray) -> float:
    """Where the part profile ``p`` (over sample offsets ``j``, its dip within 3 samples of
    ``start``) crosses 50, 25 and 75 % of its own depth, as the midpoints of its left and right
    crossings (into ``mids[:3]``, NaN where a crossing is missing), and how far its 25 %
    crossings reach from the 50 % midpoint (``mids[3]``: the farther of the two, px, NaN where
    one is missing); returns the predicted standard error of the 50 % midpoint, px.

    Each side's darkness is measured against that side's plateau (``lev_l``, ``lev_r``, taken
    outside the window ``c +- half``) and normalised by that side's depth (plateau - bottom of
    the dip), so a shade step between the tiles does not move the crossings; the level
    switches sides at the midpoint (found twice, from ``start``). The standard error: the
    profile's roughness outside the window (noise and texture at the sample scale) over each
    side's depth, divided by the slope of the normalised edge (from its 25 and 75 %
    crossings), half the root sum of squares of the two sides."""
    n = j.size
    nd = 0
    for i in range(n - 1):
        dif = abs(p[i + 1] - p[i])
        o0 = abs(j[i] - c) > half
        o1 = abs(j[i + 1] - c) > half
        tmp[i] = dif if (o0 and o1 and math.isfinite(dif)) else math.nan
        nd += 1
    rough = _ROUGH * _median_finite(tmp, nd)
    rs = np.rint(start)
    bottom = math.inf
    for i in range(n):
        if abs(j[i] - rs) <= 3.0 and not math.isnan(p[i]) and p[i] < bottom:
            bottom = p[i]
    mc = start
    levels = (0.5, 0.25, 0.75)
    xl0 = xr0 = xl1 = xr1 = xl2 = xr2 = math.nan
    for _ in range(2):
        best = -math.inf
        jp = j[0]
        for i in range(n):
            lev = lev_l + (lev_r - lev_l) * _clip01(j[i] - mc + 0.5)
            den = lev - bottom
            v = (lev - p[i]) / _max(den, 1e-6) if den > 1e-6 else math.nan
            dn[i] = v
            if abs(j[i] - rs) <= 3.0:
                if math.isnan(v):
                    v = -math.inf
                elif v == math.inf:
                    v = _BIG
                elif v == -math.inf:
                    v = -_BIG
            else:
                v = -math.inf
            if v > best:  # np.argmax: the first maximum (index 0 when all are -inf)
                best = v
                jp = j[i]
        xl0, xr0 = _crossings(dn, j, jp, levels[0])
        xl1, xr1 = _crossings(dn, j, jp, levels[1])
        xl2, xr2 = _crossings(dn, j, jp, levels[2])
        mids[0] = 0.5 * (xl0 + xr0)
        mids[1] = 0.5 * (xl1 + xr1)
        mids[2] = 0.5 * (xl2 + xr2)
        if math.isfinite(mids[0]):
            mc = mids[0]
    mids[3] = _max(mids[0] - xl1, xr1 - mids[0])
    sl = rough / _max(lev_l - bottom, 1e-6) * abs(xl2 - xl1) / 0.5
    sr = rough / _max(lev_r - bottom, 1e-6) * abs(xr2 - xr1) / 0.5
    return 0.5 * math.sqrt(sl * sl + sr * sr)


@compiled
def part_rows(pp: np.ndarray, jf: np.ndarray, cj: np.ndarray, hj: np.ndarray, r: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                         np.ndarray]:
    """Every part profile's measurement (rows of ``pp`` over sample offsets ``jf`` = -r..r,
    the dip's centre ``cj`` and half window ``hj`` per row): half-depth width and 20-80 % rise
    (NaN where the profile shows no dip: none darker than its plateaus), contrast (depth /
    brighter plateau), centroid (NaN where its window leaves the profile or it strays beyond
    the half window), the 50/25/75 % midpoints and the reach of the 25 %
    crossings from the 50 % midpoint (4, rows), and the 50 % midpoint's standard error
    (:func:`_midpoints`).

    The position is the midpoint of the dip's 50 % crossings, each side against its own
    plateau and depth (texture beside the grout, a slope of the light or a shade step between
    the tiles pull the centroid, much less the edges); measured where the centroid's window is
    inside the profile."""
    rows, n = pp.shape
    width = np.empty(rows)
    rise = np.empty(rows)
    contrast = np.empty(rows)
    cen = np.empty(rows)
    mids = np.empty((4, rows))
    msig = np.empty(rows)
    dp = np.empty(n)
    buf = np.empty(n)
    buf2 = np.empty(n)
    m3 = np.empty(4)
    for k in range(rows):
        p = pp[k]
        c = cj[k]
        h = hj[k]
        ll, lr = _plateaus(p, jf, c, h, buf)
        best = -math.inf
        jp = -3
        for i in range(n):
            dp[i] = (ll + (lr - ll) * _clip01(jf[i] - c + 0.5)) - p[i]
        for i in range(r - 3, r + 4):
            v = dp[i]
            if math.isnan(v):
                v = -math.inf
            if i == r - 3 or v > best:
                best = v
                jp = i - r
        dpk = best
        pk = float(jp)
        xl5, xr5 = _crossings(dp, jf, pk, 0.5 * dpk)
        xl2, xr2 = _crossings(dp, jf, pk, 0.2 * dpk)
        xl8, xr8 = _crossings(dp, jf, pk, 0.8 * dpk)
        width[k] = xr5 - xl5
        rise[k] = 0.5 * ((xl8 - xl2) + (xr2 - xr8))
        if not dpk > 0.0:  # no dip: no band to measure the width or rise of
            width[k] = math.nan
            rise[k] = math.nan
        contrast[k] = dpk / _max(ll, lr)
        inside = (c - h - 4.0 >= -r) and (c + h + 4.0 <= r)
        ce = _centroid(p, jf, c, h, ll, lr, buf, buf2)
        ce = ce if (inside and abs(ce - c) <= h) else math.nan
        cen[k] = ce
        start = ce if math.isfinite(ce) else c
        msig[k] = _midpoints(p, jf, start, c, h, ll, lr, buf, buf2, m3)
        mids[0, k] = m3[0]
        mids[1, k] = m3[1]
        mids[2, k] = m3[2]
        mids[3, k] = m3[3]
    return width, rise, contrast, cen, mids, msig


@compiled
def part_profiles(flat: np.ndarray, stride: int, fam: np.ndarray, line: np.ndarray,
                  idx: np.ndarray, mean: float, p0: np.ndarray) -> np.ndarray:
    """The part profiles of m dips (m PARTS, W): row i * PARTS + j is part j of dip i, the mean
    gray level of each warp row (family 1) or column (family 2) ``line[i]`` (m, W) over the
    stretch [idx[i, j], idx[i, j + 1]) of the tangent axis, from the integral image ``flat``
    (rows of ``stride`` values), plus ``mean``; NaN where the whole profile ``p0`` (m, W) is."""
    m, nw = line.shape
    parts = idx.shape[1] - 1
    rows_i = flat.size // stride
    hmax = rows_i - 1
    wmax = stride - 1
    pp = np.empty((m * parts, nw))
    for i in range(m):
        f1 = fam[i] == 0
        umax = wmax if f1 else hmax
        for w in range(nw):
            qv = min(line[i, w], hmax - 1 if f1 else wmax - 1)
            missing = math.isnan(p0[i, w])
            for j in range(parts):
                ua = min(idx[i, j], umax)
                ub = min(idx[i, j + 1], umax)
                if f1:
                    lin0 = qv * stride
                    lin1 = (qv + 1) * stride
                    ka = ua
                    kb = ub
                else:
                    lin0 = qv
                    lin1 = qv + 1
                    ka = ua * stride
                    kb = ub * stride
                s = flat[lin1 + kb] - flat[lin0 + kb] - flat[lin1 + ka] + flat[lin0 + ka]
                v = s / (idx[i, j + 1] - idx[i, j]) + mean
                pp[i * parts + j, w] = math.nan if missing else v
    return pp


