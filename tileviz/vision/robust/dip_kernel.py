"""The robust extractor's loops over dips, compiled with numba: every dip's measurement on its
whole profile (:func:`dip_rows`), a wide band's dips moved onto their centres
(:func:`dip_recentre`), where each dip's parts lie (:func:`part_layout`) and each line's medians
and parts from its part measurements (:func:`part_summary`), with the conventions and the
numpy-exact helpers of :mod:`~tileviz.vision.robust.kernel`. The tests check them bit for bit
against a numpy reference (``tests/numpy_profiles.py``)."""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust.kernel import (
    _crossings,
    _max,
    _median_finite,
    _min,
    _plateaus,
    compiled,
)
from tileviz.vision.robust.state import PARTS

__all__ = ["dip_recentre", "dip_rows", "part_layout", "part_summary"]


@compiled
def dip_rows(prof: np.ndarray, dark: np.ndarray, lo: np.ndarray, hi: np.ndarray,
             fam: np.ndarray, peak: np.ndarray, r: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                        np.ndarray, np.ndarray, np.ndarray]:
    """Every dip's measurement on its whole profile (the (2, size) arrays of a
    :class:`~tileviz.vision.robust.projection.Projection`; dip i of family ``fam[i]`` at padded
    index ``peak[i]``, sample offsets -r..r): the profile ``p0`` (m, 2 r + 1), its depth
    (deepest darkness within 2 samples of the peak), its half-depth centre ``c0`` and half
    window ``half`` (1.5 x the half-depth width + 1.5), the start ``u_lo`` and the length
    ``step`` of each of its PARTS parts (the in-view stretch that every sample within ``half``
    + 5 of the centre sees, 1 px in from each end), and its plateau levels on both sides."""
    size = prof.shape[1]
    pf = prof.ravel()
    df = dark.ravel()
    lf = lo.ravel()
    hf = hi.ravel()
    m = fam.size
    n = 2 * r + 1
    jf = np.empty(n)
    for t in range(n):
        jf[t] = float(t - r)
    p0 = np.empty((m, n))
    depth = np.empty(m)
    c0 = np.empty(m)
    half = np.empty(m)
    u_lo = np.empty(m)
    step = np.empty(m)
    lev_l = np.empty(m)
    lev_r = np.empty(m)
    d0 = np.empty(n)
    buf = np.empty(n)
    for i in range(m):
        at = fam[i] * size + peak[i] - r  # flat index of the window's first sample
        for t in range(n):
            p0[i, t] = pf[at + t]
            d0[t] = df[at + t]
        best = -math.inf
        jp = -2
        for t in range(r - 2, r + 3):
            v = d0[t]
            if math.isnan(v):
                v = -math.inf
            if t == r - 2 or v > best:  # np.argmax: the first maximum
                best = v
                jp = t - r
        depth[i] = best
        hl, hr = _crossings(d0, jf, float(jp), 0.5 * best)
        c = 0.5 * (hl + hr)
        h = 1.5 * (hr - hl) + 1.5
        c0[i] = c
        half[i] = h
        cu = 0.0 if math.isnan(c) else c
        hu = (0.0 if math.isnan(h) else h) + 5.0
        a = -math.inf
        b = math.inf
        for t in range(n):
            if abs(jf[t] - cu) <= hu:
                if lf[at + t] > a:
                    a = lf[at + t]
                if hf[at + t] < b:
                    b = hf[at + t]
        u_lo[i] = a + 1.0
        step[i] = ((b - 1.0) - (a + 1.0)) / PARTS
        lev_l[i], lev_r[i] = _plateaus(p0[i], jf, c, h, buf)
    return p0, depth, c0, half, u_lo, step, lev_l, lev_r


@compiled
def part_summary(width: np.ndarray, rise: np.ndarray, contrast: np.ndarray, cen: np.ndarray,
                 mids: np.ndarray, msig: np.ndarray, count: np.ndarray, base: np.ndarray,
                 lev_l: np.ndarray, lev_r: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                            np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """m dips' lines from their part measurements (:func:`part_rows`, row i * PARTS + j is
    part j of dip i; ``count`` (m, PARTS) samples per part, ``base`` each dip's peak in profile
    coordinates, ``lev_l``, ``lev_r`` its plateau levels): the medians over the parts of
    width, rise and contrast, the step between the plateaus (over the brighter), and per part
    (m, PARTS) the position (NaN where not measured), the length (0 there), the standard error,
    the spread of the 25 / 75 % midpoints and the reach of the 25 % crossings from the 50 %
    midpoint, at least the spread (both 0 there; a part that misses its 25 or 75 % crossings
    is known to within its half-depth width)."""
    m = count.shape[0]
    wmed = np.empty(m)
    rmed = np.empty(m)
    cmed = np.empty(m)
    stepr = np.empty(m)
    parts = np.empty((m, PARTS))
    wpart = np.empty((m, PARTS))
    sigma = np.empty((m, PARTS))
    spread = np.empty((m, PARTS))
    reach = np.empty((m, PARTS))
    buf = np.empty(PARTS)
    for i in range(m):
        for j in range(PARTS):
            k = i * PARTS + j
            m0 = mids[0, k]
            pos = m0 if math.isfinite(cen[k]) else math.nan
            sp = _max(abs(mids[1, k] - m0), abs(mids[2, k] - m0))
            if not (math.isfinite(sp) and math.isfinite(msig[k])):
                sp = 0.5 * width[k] + 0.5
            rc = _max(mids[3, k], sp)
            if not math.isfinite(rc):
                rc = sp
            ok = math.isfinite(pos)
            wpart[i, j] = float(count[i, j]) if ok else 0.0
            parts[i, j] = float(base[i]) + pos if ok else math.nan
            sigma[i, j] = msig[k] if (ok and math.isfinite(msig[k])) else 0.0
            spread[i, j] = sp if ok else 0.0
            reach[i, j] = rc if ok else 0.0
        for j in range(PARTS):
            buf[j] = width[i * PARTS + j]
        wmed[i] = _median_finite(buf, PARTS)
        for j in range(PARTS):
            buf[j] = rise[i * PARTS + j]
        rmed[i] = _median_finite(buf, PARTS)
        for j in range(PARTS):
            buf[j] = contrast[i * PARTS + j]
        cmed[i] = _median_finite(buf, PARTS)
        lo_lev = _min(lev_l[i], lev_r[i])
        hi_lev = _max(lev_l[i], lev_r[i])
        stepr[i] = (hi_lev - lo_lev) / _max(hi_lev, 1e-9)
    return wmed, rmed, cmed, stepr, parts, wpart, sigma, spread, reach


@compiled
def dip_recentre(c0: np.ndarray, half: np.ndarray, peak: np.ndarray, r: int, first: int,
                 last: int) -> tuple[np.ndarray, bool]:
    """The dips' peaks moved onto their half-depth centres where the window of ``r`` samples
    does not reach the plateaus (``|c0| + half + 4 > r``), kept within [``first``, ``last``],
    and whether any moved (:func:`~tileviz.vision.robust.profiles.dips`)."""
    m = c0.size
    out = peak.copy()
    moved = False
    for i in range(m):
        reach = abs(c0[i]) + half[i] + 4.0
        if math.isfinite(reach) and reach > r:
            off = np.intp(np.rint(c0[i]))
            if off != 0:
                moved = True
            out[i] = peak[i] + off
    if moved:
        for i in range(m):
            out[i] = min(max(out[i], first), last)
    return out, moved


@compiled
def part_layout(fam: np.ndarray, u_lo: np.ndarray, step: np.ndarray, x0: float, y0: float,
                cols: np.ndarray, pad: int, lim: int, c0: np.ndarray, half: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                           np.ndarray]:
    """Where the PARTS parts of m dips lie (family ``fam``, parts from ``u_lo`` in steps of
    ``step`` along the tangent axis, whose u = 0 is warp column ``x0`` (family 1) or row
    ``y0``): each part's sample bounds ``idx`` (m, PARTS + 1; part j is [idx[j], idx[j + 1])),
    its length ``count`` and mean tangent coordinate ``tpart`` (m, PARTS), the warp row or
    column of every window sample (padded profile indices ``cols`` less ``pad``, within
    [0, ``lim``]), and per part row the dip's centre ``c0`` and half window ``half``."""
    m = fam.size
    n = cols.shape[1]
    idx = np.empty((m, PARTS + 1), np.intp)
    count = np.empty((m, PARTS), np.intp)
    tpart = np.empty((m, PARTS))
    line = np.empty((m, n), np.intp)
    cj = np.empty(m * PARTS)
    hj = np.empty(m * PARTS)
    for i in range(m):
        along = x0 if fam[i] == 0 else y0
        for k in range(PARTS + 1):
            idx[i, k] = np.intp(np.ceil(along + (u_lo[i] + step[i] * float(k))))
        for k in range(PARTS):
            count[i, k] = idx[i, k + 1] - idx[i, k]
            tpart[i, k] = 0.5 * float(idx[i, k] + idx[i, k + 1] - 1) - along
            cj[i * PARTS + k] = c0[i]
            hj[i * PARTS + k] = half[i]
        for t in range(n):
            line[i, t] = min(max(cols[i, t] - pad, 0), lim)
    return idx, count, tpart, line, cj, hj

