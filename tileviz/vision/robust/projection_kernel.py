"""The projection's loops, compiled with numba: the in-view spans of the warp's rows and
columns (:func:`view_spans`), both family profiles (:func:`profile_arrays`), their darkness and
dips (:func:`profile_dips`) and a family's term of the light-grout test (:func:`grout_score`),
with the conventions of :mod:`~tileviz.vision.robust.kernel` (numpy's order of operations, its
NaN propagation and error model, float32 where numpy keeps it; the tests' numpy / OpenCV
references in ``tests/numpy_profiles.py`` give the same bits). The grey morphology is an exact
running extreme (only comparisons), so it gives OpenCV's values whatever the order.
"""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust.kernel import _max, _min, compiled

__all__ = ["grout_score", "profile_arrays", "profile_dips", "view_spans"]


@compiled
def _running(ext: np.ndarray, width: int, bigger: bool, out: np.ndarray) -> None:
    """out[x] = max (``bigger``) or min of ext[x : x + width] for every x < out.size, in O(n)
    (van Herk / Gil-Werman: within blocks of ``width`` samples, running extremes from each
    block's start and from its end; a window spans the end of one block and the start of the
    next). Exact: only comparisons (the extreme of a set does not depend on the order)."""
    n = ext.size
    fwd = np.empty(n, ext.dtype)
    bwd = np.empty(n, ext.dtype)
    # (selections rather than branches: a noisy profile's order is a coin toss)
    for b0 in range(0, n, width):
        b1 = min(b0 + width, n)
        v = ext[b0]
        fwd[b0] = v
        for i in range(b0 + 1, b1):
            u = ext[i]
            v = u if ((u > v) if bigger else (u < v)) else v
            fwd[i] = v
        v = ext[b1 - 1]
        bwd[b1 - 1] = v
        for i in range(b1 - 2, b0 - 1, -1):
            u = ext[i]
            v = u if ((u > v) if bigger else (u < v)) else v
            bwd[i] = v
    for x in range(out.size):
        a = bwd[x]
        b = fwd[x + width - 1]
        out[x] = b if ((b > a) if bigger else (b < a)) else a


@compiled
def _morph(a: np.ndarray, half: int, border: np.float32, bigger: bool) -> np.ndarray:
    """cv2.dilate (``bigger``) or cv2.erode of a float32 row by a 1 x (2 half + 1) window,
    constant ``border`` beyond the ends (exact: only comparisons)."""
    n = a.size
    ext = np.full(n + 2 * half, border, np.float32)
    ext[half : half + n] = a
    out = np.empty(n, np.float32)
    _running(ext, 2 * half + 1, bigger, out)
    return out


@compiled
def grout_score(sums: np.ndarray, length: np.ndarray, closing: int, min_row: float,
                min_row_share: float, min_rows: int) -> tuple[bool, float]:
    """One family's term of :func:`~tileviz.vision.robust.projection.light_grout`: whether
    the family has ``min_rows`` rows long enough (at least ``min_row`` px and ``min_row_share``
    of the longest), and then the
    highest narrow peak of its profile (``sums / length`` over those rows, float32) above a
    grey opening minus the deepest narrow dip below a grey closing, both ``closing`` samples
    wide. Beyond the view the profile reads its median level (the tiles'), so that a stretch
    of tile or a line cut by the border is neither a peak nor a dip."""
    lmax = length[0]
    for v in length:
        if v > lmax:
            lmax = v
    thr = min_row_share * lmax
    thr = thr if thr > min_row else min_row
    n = 0
    for v in length:
        if v >= thr:
            n += 1
    if n < min_rows:
        return False, 0.0
    prof = np.empty(n, np.float32)
    k = 0
    for i in range(length.size):
        if length[i] >= thr:
            prof[k] = np.float32(sums[i] / length[i])
            k += 1
    # the median (np.median's float32 value) from a selection: the middle order statistics
    # are the sorted array's, exactly
    srt = np.partition(prof, n // 2)
    if n % 2 == 1:
        mid = srt[n // 2]
    else:
        below = srt[0]
        for i in range(1, n // 2):
            below = srt[i] if srt[i] > below else below
        mid = np.float32(np.float32(below + srt[n // 2]) / np.float32(2.0))
    half = closing // 2
    close = _morph(_morph(prof, half, mid, True), half, mid, False)
    opening = _morph(_morph(prof, half, mid, False), half, mid, True)
    peak = np.float32(prof[0] - opening[0])
    dip = np.float32(close[0] - prof[0])
    for i in range(1, n):
        v = np.float32(prof[i] - opening[i])
        if v > peak:
            peak = v
        v = np.float32(close[i] - prof[i])
        if v > dip:
            dip = v
    return True, np.float64(peak) - np.float64(dip)


@compiled
def profile_dips(prof: np.ndarray, mean: float, closing: int, min_depth: float, min_rows: int,
                 dip_noise: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The dips of both family profiles (rows of ``prof``, NaN where there is no data): the
    darkness ``dark`` below a grey closing of ``closing`` samples (max then min filter along
    each row, removing dips narrower than its window; a missing sample reads as the nearest
    valid sample of its row before it, else after it, ``mean`` in a row with none: a level
    beyond the view unlike the tiles at its border would make a dip of that tile's border),
    each family's profile noise (robust std of its sample-to-sample steps; NaN when the family
    has fewer than ``min_rows`` samples), and the dips: the deepest sample of every run of
    samples darker than ``dip_noise`` x the noise (at least ``min_depth`` / 2), as (family,
    padded index) arrays."""
    fams, size = prof.shape
    half = closing // 2
    dark = np.empty((fams, size))
    noise = np.full(fams, math.nan)
    fam_out = np.empty(fams * size, np.intp)
    peak_out = np.empty(fams * size, np.intp)
    found = 0
    filled = np.empty(size, np.float32)
    dil = np.empty(size, np.float32)
    ero = np.empty(size, np.float32)
    closing_w = 2 * half + 1
    ext = np.empty(size + 2 * half, np.float32)
    diffs = np.empty(size)
    for k in range(fams):
        row = prof[k]
        # missing samples: the nearest valid one before, else after (profiles.fill_ends)
        last = math.nan
        for x in range(size):
            if not math.isnan(row[x]):
                last = row[x]
                break
        if math.isnan(last):
            last = mean
        for x in range(size):
            if not math.isnan(row[x]):
                last = row[x]
            filled[x] = np.float32(last)
        # grey dilation then erosion, the ends replicated
        for x in range(half):
            ext[x] = filled[0]
            ext[half + size + x] = filled[size - 1]
        ext[half : half + size] = filled
        _running(ext, closing_w, True, dil)
        for x in range(half):
            ext[x] = dil[0]
            ext[half + size + x] = dil[size - 1]
        ext[half : half + size] = dil
        _running(ext, closing_w, False, ero)
        for x in range(size):
            dark[k, x] = np.float64(ero[x]) - row[x]
        nok = 0
        nd = 0
        prev = 0.0
        for x in range(size):
            if not math.isnan(row[x]):
                if nok > 0:
                    diffs[nd] = abs(row[x] - prev)
                    nd += 1
                prev = row[x]
                nok += 1
        if nok < min_rows:
            continue
        srt = np.partition(diffs[:nd], nd // 2)  # the middle order statistic, exactly
        sig = 1.4826 * srt[nd // 2] / math.sqrt(2.0)
        noise[k] = sig
        thr = dip_noise * sig
        if not thr > 0.5 * min_depth:
            thr = 0.5 * min_depth
        x = 0
        while x < size:
            dk = dark[k, x] if not math.isnan(row[x]) else -math.inf
            if not dk > thr:
                x += 1
                continue
            best = dk
            at = x
            x += 1
            while x < size:
                dk = dark[k, x] if not math.isnan(row[x]) else -math.inf
                if not dk > thr:
                    break
                if dk > best:
                    best = dk
                    at = x
                x += 1
            fam_out[found] = k
            peak_out[found] = at
            found += 1
    return dark, noise, fam_out[:found].copy(), peak_out[:found].copy()


@compiled
def view_spans(n: int, off: float, c: float, s: float, w: int, h: int, along_rows: bool
               ) -> tuple[np.ndarray, np.ndarray]:
    """The in-view stretch [lo, hi] of each of the ``n`` warp rows (``along_rows``) or columns
    at offsets ``i - off`` from the warp centre, in the tangent coordinate u (relative to the
    centre), of a ``w`` x ``h`` view turned by (cos, sin) = (``c``, ``s``); empty where
    hi <= lo."""
    cx = (w - 1) / 2.0
    cy = (h - 1) / 2.0
    if along_rows:
        a, b, e, f = c, -s, s, c
    else:
        a, b, e, f = -s, c, c, s
    lo = np.empty(n)
    hi = np.empty(n)
    for i in range(n):
        q = float(i) - off
        vlo = -math.inf
        vhi = math.inf
        for axis in range(2):
            coef = a if axis == 0 else e
            base = (cx + b * q) if axis == 0 else (cy + f * q)
            size = w if axis == 0 else h
            if abs(coef) < 1e-12:
                if not ((base >= -0.5) and (base <= size - 0.5)):
                    vlo = math.inf
                continue
            u1 = (-0.5 - base) / coef
            u2 = (size - 0.5 - base) / coef
            vlo = _max(vlo, _min(u1, u2))
            vhi = _min(vhi, _max(u1, u2))
        lo[i] = vlo
        hi[i] = vhi
    return lo, hi


@compiled
def profile_arrays(sums0: np.ndarray, sums1: np.ndarray, lo0: np.ndarray, hi0: np.ndarray,
                   lo1: np.ndarray, hi1: np.ndarray, r: int, mean: float, min_row: float,
                   min_row_share: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The (2, size) arrays of a :class:`~tileviz.vision.robust.projection.Projection`
    (family k in row k, samples shifted by ``r``): the profile (``sums`` / in-view length +
    ``mean``, NaN beyond the data and where a row or column is shorter than ``min_row`` px or
    ``min_row_share`` of the family's longest), the in-view spans ``lo``, ``hi`` (inf, -inf beyond
    the data) and their length."""
    size = max(sums0.size, sums1.size) + 2 * r
    prof = np.full((2, size), math.nan)
    lo = np.full((2, size), math.inf)
    hi = np.full((2, size), -math.inf)
    total = np.zeros((2, size))
    for k in range(2):
        sums = sums0 if k == 0 else sums1
        slo = lo0 if k == 0 else lo1
        shi = hi0 if k == 0 else hi1
        n = sums.size
        lmax = -math.inf
        for i in range(n):
            lo[k, r + i] = slo[i]
            hi[k, r + i] = shi[i]
            length = _max(shi[i] - slo[i], 0.0)
            total[k, r + i] = length
            if math.isnan(length) or math.isnan(lmax):
                lmax = math.nan
            elif length > lmax:
                lmax = length
        v = min_row_share * lmax
        thr = v if v > min_row else min_row  # Python's max(min_row, v): NaN gives min_row
        for i in range(n):
            length = total[k, r + i]
            if length >= thr:
                prof[k, r + i] = sums[i] / length + mean
    return prof, lo, hi, total
