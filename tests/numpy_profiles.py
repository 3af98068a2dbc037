"""numpy references of the robust extractor's compiled profile and projection kernels
(:mod:`tileviz.vision.robust.kernel`, :mod:`tileviz.vision.robust.projection_kernel`): the same
computations written with numpy and OpenCV, operation for operation, which the tests compare
with the kernels bit for bit (``tests/test_vision_speed_paths.py``). The package itself runs
the kernels only."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.robust.profiles import nanmedian, plateaus
from tileviz.vision.robust.state import PARTS


def dip_rows_numpy(
    prof: np.ndarray, dark: np.ndarray, lo: np.ndarray, hi: np.ndarray, fam: np.ndarray,
    peak: np.ndarray, r: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
           np.ndarray, np.ndarray]:
    """Every dip's measurement on its whole profile (the arrays of a :class:`Projection`;
    dip i of family ``fam[i]`` at padded index ``peak[i]``, sample offsets -r..r): the
    profile ``p0`` (m, 2 r + 1), its depth (deepest darkness within 2 samples of the peak),
    its half-depth centre ``c0`` and half window ``half`` (1.5 x the half-depth width + 1.5),
    the start ``u_lo`` and the length ``step`` of each of its PARTS parts (the in-view
    stretch that every sample within ``half`` + 5 of the centre sees, 1 px in from each end),
    and its plateau levels on both sides (:func:`plateaus`). :func:`~tileviz.vision.robust.
    dip_kernel.dip_rows` is the same computation compiled (bit-identical)."""
    jj = np.arange(-r, r + 1)
    jf = jj.astype(np.float64)
    cols = peak[:, None] + jj[None, :]  # padded profile index
    at = fam[:, None] * prof.shape[1] + cols  # flat index into the (2, size) arrays
    # the whole profile: depth, half-depth crossings, width, window and plateau levels
    p0 = prof.ravel()[at]
    d0 = dark.ravel()[at]
    near = d0[:, r - 2 : r + 3]
    near = np.where(np.isnan(near), -np.inf, near)
    depth = near.max(axis=1)
    hl, hr = crossings(d0, jf, np.argmax(near, axis=1) - 2, 0.5 * depth)
    c0 = 0.5 * (hl + hr)
    half = 1.5 * (hr - hl) + 1.5
    # the parts: PARTS equal stretches of the window's common in-view stretch
    # (over the samples a part's centroid and plateaus use: c0 +- (half + 4))
    used = np.abs(jf[None, :] - np.where(np.isnan(c0), 0.0, c0)[:, None]) <= (
        np.where(np.isnan(half), 0.0, half)[:, None] + 5.0
    )
    u_lo = np.where(used, lo.ravel()[at], -np.inf).max(axis=1) + 1.0
    u_hi = np.where(used, hi.ravel()[at], np.inf).min(axis=1) - 1.0
    step = (u_hi - u_lo) / PARTS
    lev_l, lev_r = plateaus(p0, jf, c0, half)
    return p0, depth, c0, half, u_lo, step, lev_l, lev_r


def dip_recentre_numpy(c0: np.ndarray, half: np.ndarray, peak: np.ndarray, r: int, first: int,
                       last: int) -> tuple[np.ndarray, bool]:
    """The dips' peaks (padded indices) moved by their half-depth centres ``c0`` (rounded)
    where the window of ``r`` samples does not reach the plateaus (``|c0| + half + 4 > r``),
    kept within [``first``, ``last``], and whether any moved. :func:`~tileviz.vision.robust.
    dip_kernel.dip_recentre` is the same computation compiled (bit-identical)."""
    reach = np.abs(c0) + half + 4.0
    off = np.where(np.isfinite(reach) & (reach > r), np.rint(c0), 0.0).astype(np.intp)
    if not off.any():
        return peak, False
    return np.clip(peak + off, first, last), True


def part_layout_numpy(
    fam: np.ndarray, u_lo: np.ndarray, step: np.ndarray, x0: float, y0: float,
    cols: np.ndarray, pad: int, lim: int, c0: np.ndarray, half: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where the PARTS parts of m dips lie (family ``fam``, parts from ``u_lo`` in steps of
    ``step`` along the tangent axis, whose u = 0 is warp column ``x0`` (family 1) or row
    ``y0``): each part's sample bounds ``idx`` (m, PARTS + 1; part j is [idx[j], idx[j + 1])),
    its length ``count`` and mean tangent coordinate ``tpart`` (m, PARTS), the warp row or
    column of every window sample (padded profile indices ``cols`` less ``pad``, within
    [0, ``lim``]), and per part row the dip's centre ``c0`` and half window ``half``.
    :func:`~tileviz.vision.robust.dip_kernel.part_layout` is the same computation compiled
    (bit-identical)."""
    along = np.where(fam == 0, x0, y0)  # warp coordinate of u = 0
    edges_u = u_lo[:, None] + step[:, None] * np.arange(PARTS + 1)[None, :]
    idx = np.ceil(along[:, None] + edges_u).astype(np.intp)
    count = np.diff(idx, axis=1)  # samples in each part, (m, PARTS)
    tpart = 0.5 * (idx[:, :-1] + idx[:, 1:] - 1) - along[:, None]
    line = np.clip(cols - pad, 0, lim)  # warp row / column
    return idx, count, tpart, line, np.repeat(c0, PARTS), np.repeat(half, PARTS)


def part_summary_numpy(
    width: np.ndarray, rise: np.ndarray, contrast: np.ndarray, cen: np.ndarray,
    mids: np.ndarray, msig: np.ndarray, count: np.ndarray, base: np.ndarray,
    lev_l: np.ndarray, lev_r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
           np.ndarray, np.ndarray]:
    """m dips' lines from their part measurements (:func:`part_rows_numpy`, row i * PARTS + j
    is part j of dip i; ``count`` (m, PARTS) samples per part, ``base`` each dip's peak in
    profile coordinates, ``lev_l``, ``lev_r`` its plateau levels): the medians over the parts
    of width, rise and contrast, the step between the plateaus, and per part (m, PARTS) the
    position (NaN where not measured), the length (0 there), the standard error, the
    spread of the 25 / 75 % midpoints and the reach of the 25 % crossings from the 50 %
    midpoint, at least the spread (both 0 there). :func:`~tileviz.vision.robust.kernel.
    part_summary` is the same computation compiled (bit-identical)."""
    m = count.shape[0]
    width = width.reshape(m, PARTS)
    rise = rise.reshape(m, PARTS)
    cen = cen.reshape(m, PARTS)
    mids = mids.reshape(4, m, PARTS)
    msig = msig.reshape(m, PARTS)
    pos50 = np.where(np.isfinite(cen), mids[0], np.nan)
    spread = np.maximum(np.abs(mids[1] - mids[0]), np.abs(mids[2] - mids[0]))
    # a thin or shallow dip may miss its 25 or 75 % crossings: its position is then only
    # known to be within its half-depth width (from the 50 % crossings)
    sp_ok = np.where(np.isfinite(spread) & np.isfinite(msig), spread, 0.5 * width + 0.5)
    # the reach of the 25 % crossings, at least the spread
    rc = np.maximum(mids[3], sp_ok)
    rc = np.where(np.isfinite(rc), rc, sp_ok)
    # medians over the parts of each dip's width, rise and contrast, in one sort
    meds = nanmedian(np.concatenate(
        (width.T, rise.T, contrast.reshape(m, PARTS).T), axis=1))
    wmed, rmed, cmed = meds[:m], meds[m : 2 * m], meds[2 * m :]
    lo_lev = np.minimum(lev_l, lev_r)
    hi_lev = np.maximum(lev_l, lev_r)
    stepr = (hi_lev - lo_lev) / np.maximum(hi_lev, 1e-9)
    ok = np.isfinite(pos50)
    wpart = np.where(ok, count, 0).astype(np.float64)
    parts = np.where(ok, base[:, None] + pos50, np.nan)
    sigma = np.where(ok & np.isfinite(msig), msig, 0.0)
    spread = np.where(ok, sp_ok, 0.0)
    reach = np.where(ok, rc, 0.0)
    return wmed, rmed, cmed, stepr, parts, wpart, sigma, spread, reach


def part_profiles_numpy(
    integ: np.ndarray, fam: np.ndarray, line: np.ndarray, idx: np.ndarray, mean: float,
    p0: np.ndarray
) -> np.ndarray:
    """The part profiles of m dips: row i * PARTS + j is part j of dip i, the mean gray level
    of each warp row (family 1) or column (family 2) ``line[i]`` (m, W) over the stretch
    [idx[i, j], idx[i, j + 1]) of the tangent axis, from the integral image ``integ``; NaN
    where the whole profile ``p0`` (m, W) is. :func:`~tileviz.vision.robust.kernel.
    part_profiles` is the same computation compiled (bit-identical)."""
    m = fam.size
    count = np.diff(idx, axis=1)  # samples in each part, (m, PARTS)
    # sums over the parts from the integral image: family 1 along rows (integ[line, idx]),
    # family 2 along columns (integ[idx, line]), as flat indices
    hmax, wmax = integ.shape[0] - 1, integ.shape[1] - 1
    fam1 = (fam == 0)[:, None, None]
    q = np.minimum(line[:, :, None], np.where(fam1, hmax - 1, wmax - 1))  # (m, W, 1)
    umax = np.where(fam1, wmax, hmax)
    ua = np.minimum(idx[:, None, :-1], umax)  # (m, 1, PARTS)
    ub = np.minimum(idx[:, None, 1:], umax)
    stride = integ.shape[1]
    lin0 = np.where(fam1, q * stride, q)  # flat offset of line q and of line q + 1
    lin1 = np.where(fam1, (q + 1) * stride, q + 1)
    ka = np.where(fam1, ua, ua * stride)
    kb = np.where(fam1, ub, ub * stride)
    flat = integ.ravel()
    part_sum = flat[lin1 + kb] - flat[lin0 + kb] - flat[lin1 + ka] + flat[lin0 + ka]
    pp = part_sum / count[:, None, :] + mean  # (m, W, PARTS)
    pp = np.where(np.isnan(p0)[:, :, None], np.nan, pp)
    return pp.transpose(0, 2, 1).reshape(m * PARTS, -1)  # row i * PARTS + j


def part_rows_numpy(
    pp: np.ndarray, jf: np.ndarray, cj: np.ndarray, hj: np.ndarray, r: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every part profile's measurement (rows of ``pp`` over sample offsets ``jf`` = -r..r,
    the dip's centre ``cj`` and half window ``hj`` per row): half-depth width and 20-80 % rise
    (NaN where the profile shows no dip), contrast (depth / brighter plateau), centroid (NaN
    where its window leaves the profile or it strays beyond the half window), the 50/25/75 %
    midpoints (3, rows) and the 50 % midpoint's standard error (:func:`midpoints`).
    :func:`~tileviz.vision.robust.kernel.part_rows` is the same computation compiled
    (bit-identical); this one is used without numba."""
    ll, lr = plateaus(pp, jf, cj, hj)
    lev = ll[:, None] + (lr - ll)[:, None] * np.clip(jf[None, :] - cj[:, None] + 0.5, 0, 1)
    dp = lev - pp
    nearp = dp[:, r - 3 : r + 4]
    nearp = np.where(np.isnan(nearp), -np.inf, nearp)
    dpk = nearp.max(axis=1)
    jp = np.argmax(nearp, axis=1) - 3
    lv = np.concatenate([0.5 * dpk, 0.2 * dpk, 0.8 * dpk])
    xl, xr = crossings(np.tile(dp, (3, 1)), jf, np.tile(jp, 3), lv)
    nr = dp.shape[0]
    width = xr[:nr] - xl[:nr]
    rise = 0.5 * ((xl[2 * nr :] - xl[nr : 2 * nr]) + (xr[nr : 2 * nr] - xr[2 * nr :]))
    nodip = ~(dpk > 0.0)  # no band to measure the width or rise of
    width = np.where(nodip, np.nan, width)
    rise = np.where(nodip, np.nan, rise)
    inside = (cj - hj - 4.0 >= -r) & (cj + hj + 4.0 <= r)
    cen = centroid(pp, jf, cj, hj, ll, lr)
    cen = np.where(inside & (np.abs(cen - cj) <= hj), cen, np.nan)
    # the position: the midpoint of the dip's 50 % crossings, each side against its own
    # plateau and depth (texture beside the grout, a slope of the light or a shade step
    # between the tiles pull the centroid, much less the edges); measured where the
    # centroid's window is inside the profile
    mids, msig = midpoints(pp, jf, np.where(np.isfinite(cen), cen, cj), cj, hj, ll, lr)
    return width, rise, dpk / np.maximum(ll, lr), cen, mids, msig


def crossings(
    d: np.ndarray, j: np.ndarray, jp: np.ndarray, level: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where each row of ``d`` (darkness over sample offsets ``j``) first falls below ``level``
    on the left and on the right of its peak ``jp``, interpolated linearly; NaN when it does
    not (or runs into missing data first)."""
    lv = level[:, None]
    below = ~(d >= lv)  # NaN counts as below: such a crossing interpolates to NaN
    jr = j[None, :]
    pk = jp[:, None].astype(np.float64)
    big = float(j[-1]) + 1.0
    jl = np.where(below & (jr < pk), jr, -big).max(axis=1)
    jrt = np.where(below & (jr > pk), jr, big).min(axis=1)
    ok = (jl > -big) & (jrt < big)
    r = (j.size - 1) // 2
    il = np.clip(jl + r, 0, j.size - 2).astype(np.intp)
    ir = np.clip(jrt + r, 1, j.size - 1).astype(np.intp)
    base = np.arange(0, d.size, j.size)  # flat index of each row's first sample
    flat = d.ravel()
    il += base
    ir += base
    dl0, dl1 = flat[il], flat[il + 1]
    dr0, dr1 = flat[ir], flat[ir - 1]
    xl = jl + (lv[:, 0] - dl0) / (dl1 - dl0)
    xr = jrt - (lv[:, 0] - dr0) / (dr1 - dr0)
    return np.where(ok, xl, np.nan), np.where(ok, xr, np.nan)


def midpoints(
    p: np.ndarray, j: np.ndarray, start: np.ndarray, c: np.ndarray, half: np.ndarray,
    lev_l: np.ndarray, lev_r: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where each row of ``p`` (a part's profile over sample offsets ``j``, its dip within 3
    samples of ``start``) crosses 50, 25 and 75 % of its own depth, as the midpoints of its
    left and right crossings, and the reach of the 25 % crossings from the 50 % midpoint (the
    farther one; shape (4, rows), NaN where a crossing is missing), and the predicted standard
    error of the 50 % midpoint (rows,), px.

    Each side's darkness is measured against that side's plateau (``lev_l``, ``lev_r``, taken
    outside the window ``c +- half``) and normalised by that side's depth (plateau - bottom of
    the dip), so a shade step between the tiles does not move the crossings; the level
    switches sides at the midpoint (found twice, from ``start``). The standard error: the
    row's roughness outside the window (noise and texture at the sample scale) over each
    side's depth, divided by the slope of the normalised edge (from its 25 and 75 %
    crossings), half the root sum of squares of the two sides."""
    outside = np.abs(j[None, :] - c[:, None]) > half[:, None]
    dif = np.abs(np.diff(p, axis=1))
    okd = outside[:, 1:] & outside[:, :-1] & np.isfinite(dif)
    rough = (1.4826 / math.sqrt(2.0)) * nanmedian(np.where(okd, dif, np.nan).T)
    core = np.abs(j[None, :] - np.round(start)[:, None]) <= 3.0
    bottom = np.where(core & ~np.isnan(p), p, np.inf).min(axis=1)
    rows = p.shape[0]
    levels = np.repeat(np.array([0.5, 0.25, 0.75]), rows)
    mc = start.copy()
    mids = np.full((3, rows), np.nan)
    xl = xr = np.full(3 * rows, np.nan)
    for _ in range(2):
        lev = lev_l[:, None] + (lev_r - lev_l)[:, None] * np.clip(
            j[None, :] - mc[:, None] + 0.5, 0.0, 1.0)
        den = lev - bottom[:, None]
        dn = np.where(den > 1e-6, (lev - p) / np.maximum(den, 1e-6), np.nan)
        near = np.where(core, np.nan_to_num(dn, nan=-np.inf), -np.inf)
        jp = j[np.argmax(near, axis=1)]
        xl, xr = crossings(np.tile(dn, (3, 1)), j, np.tile(jp, 3), levels)
        mids = (0.5 * (xl + xr)).reshape(3, rows)
        mc = np.where(np.isfinite(mids[0]), mids[0], mc)
    xl3, xr3 = xl.reshape(3, rows), xr.reshape(3, rows)
    reach = np.maximum(mids[0] - xl3[1], xr3[1] - mids[0])
    sl = rough / np.maximum(lev_l - bottom, 1e-6) * np.abs(xl3[2] - xl3[1]) / 0.5
    sr = rough / np.maximum(lev_r - bottom, 1e-6) * np.abs(xr3[2] - xr3[1]) / 0.5
    return np.vstack([mids, reach[None, :]]), 0.5 * np.sqrt(sl * sl + sr * sr)


def centroid(
    p: np.ndarray,
    j: np.ndarray,
    c: np.ndarray,
    half: np.ndarray,
    lev_l: np.ndarray,
    lev_r: np.ndarray,
    iterations: int = 3,
) -> np.ndarray:
    """Centroid of each row's darkness ``1 - p / level`` over [c - half, c + half] (sample
    offsets ``j``), the level stepping from ``lev_l`` to ``lev_r`` at the current centre; each
    sample weighs by its overlap with the window; re-centred ``iterations`` times. NaN where
    the window holds missing data or no darkness."""
    jr = j[None, :]
    ll = lev_l[:, None]
    dl = lev_r[:, None] - ll
    h = half[:, None]
    j_hi = jr + 0.5
    j_lo = jr - 0.5
    cc = c.copy()
    for _ in range(iterations):
        ccol = cc[:, None]
        w = np.clip(np.minimum(j_hi, ccol + h) - np.maximum(j_lo, ccol - h), 0.0, 1.0)
        lev = ll + dl * np.clip(jr - ccol + 0.5, 0.0, 1.0)
        q = (1.0 - p / lev) * w
        q = np.where(w > 0, q, 0.0)  # NaN inside the window stays NaN
        tot = q.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):  # tot <= 0 or NaN: NaN
            cc = np.where(tot > 0, (q * jr).sum(axis=1) / tot, np.nan)
    return cc



def grout_score_numpy(sums: np.ndarray, length: np.ndarray, closing: int, min_row: float,
                      min_row_share: float, min_rows: int) -> tuple[bool, float]:
    """One family's term of :func:`light_grout`: whether the family has 8 rows long enough
    (at least 8 px and 15 % of the longest), and then the highest narrow peak of its profile
    (``sums / length`` over those rows, float32) above a grey opening minus the deepest
    narrow dip below a grey closing, both ``closing`` samples wide. :func:`~tileviz.vision.
    robust.projection_kernel.grout_score` is the same computation compiled (bit-identical)."""
    ok = length >= max(min_row, min_row_share * float(length.max()))
    if int(ok.sum()) < min_rows:
        return False, 0.0
    prof = (sums[ok] / length[ok]).astype(np.float32)[None, :]
    # beyond the view: the median level (the tiles'), so that a stretch of tile or a line cut
    # by the border is neither a peak nor a dip
    mid = float(np.median(prof))
    kern = np.ones((1, closing), np.uint8)
    bt = cv2.BORDER_CONSTANT
    close = cv2.erode(cv2.dilate(prof, kern, borderType=bt, borderValue=mid), kern,
                      borderType=bt, borderValue=mid)
    opening = cv2.dilate(cv2.erode(prof, kern, borderType=bt, borderValue=mid), kern,
                         borderType=bt, borderValue=mid)
    return True, float((prof - opening).max()) - float((close - prof).max())


def view_spans(
    w: int, h: int, q: np.ndarray, c: float, s: float, *, along_rows: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The in-view stretch [lo, hi] of each warped row (``along_rows``) or column at offset
    ``q`` from the warp centre, in the tangent coordinate u (relative to the centre); empty
    where hi <= lo. :func:`~tileviz.vision.robust.projection_kernel.view_spans` is the same
    computation compiled (bit-identical)."""
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    lo = np.full(q.shape, -np.inf)
    hi = np.full(q.shape, np.inf)
    # src col = cx + a u + b q, row = cy + e u + f q
    a, b, e, f = (c, -s, s, c) if along_rows else (-s, c, c, s)
    for coef, base, size in ((a, cx + b * q, w), (e, cy + f * q, h)):
        if abs(coef) < 1e-12:
            lo = np.where((base >= -0.5) & (base <= size - 0.5), lo, np.inf)
            continue
        u1 = (-0.5 - base) / coef
        u2 = (size - 0.5 - base) / coef
        lo = np.maximum(lo, np.minimum(u1, u2))
        hi = np.minimum(hi, np.maximum(u1, u2))
    return lo, hi


def profile_arrays_numpy(
    sums0: np.ndarray, sums1: np.ndarray, lo0: np.ndarray, hi0: np.ndarray, lo1: np.ndarray,
    hi1: np.ndarray, r: int, mean: float, min_row: float, min_row_share: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The (2, size) arrays of a :class:`Projection` (family k in row k, samples shifted by
    ``r``): the profile (``sums`` / in-view length + ``mean``, NaN beyond the data and where a
    row or column is shorter than 8 px or 15 % of the family's longest), the in-view spans
    ``lo``, ``hi`` (inf, -inf beyond the data) and their length. :func:`~tileviz.vision.
    robust.projection_kernel.profile_arrays` is the same computation compiled (bit-identical)."""
    sums = (sums0, sums1)
    spans = ((lo0, hi0), (lo1, hi1))
    size = max(sums0.size, sums1.size) + 2 * r
    # family k in row k; columns shifted by r; missing data NaN
    prof = np.full((2, size), np.nan)
    lo = np.full((2, size), np.inf)
    hi = np.full((2, size), -np.inf)
    total = np.zeros((2, size))
    for k in range(2):
        n = sums[k].size
        lo[k, r : r + n], hi[k, r : r + n] = spans[k]
        length = np.maximum(hi[k, r : r + n] - lo[k, r : r + n], 0.0)
        total[k, r : r + n] = length
        valid = length >= max(min_row, min_row_share * float(length.max()))
        with np.errstate(invalid="ignore", divide="ignore"):  # length 0: not valid, NaN
            prof[k, r : r + n] = np.where(valid, sums[k] / length + mean, np.nan)
    return prof, lo, hi, total


def profile_dips_numpy(
    prof: np.ndarray, mean: float, closing: int, min_depth: float, min_rows: int,
    dip_noise: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The dips of both family profiles (rows of ``prof``, NaN where there is no data): the
    darkness ``dark`` below a grey closing of ``closing`` samples (max then min filter along
    each row, removing dips narrower than its window; missing data read as the nearest valid
    sample of its row, :func:`fill_ends`), each family's profile noise (robust std of its
    sample-to-sample steps; NaN when the family has fewer than 8 samples), and the dips:
    the deepest sample of every run of samples darker than 5 x the noise (at least
    ``min_depth`` / 2), as (family, padded index) arrays. :func:`~tileviz.vision.robust.
    projection_kernel.profile_dips` is the same computation compiled (bit-identical)."""
    missing = np.isnan(prof)
    filled = fill_ends(prof, mean).astype(np.float32)
    kern = np.ones((1, closing), np.uint8)
    base = cv2.erode(
        cv2.dilate(filled, kern, borderType=cv2.BORDER_REPLICATE),
        kern,
        borderType=cv2.BORDER_REPLICATE,
    )
    dark = base - prof  # NaN where no data
    noise = np.full(prof.shape[0], np.nan)
    peaks: list[tuple[int, int]] = []
    for k in range(prof.shape[0]):
        ok = ~missing[k]
        if int(ok.sum()) < min_rows:
            continue
        diffs = np.abs(np.diff(prof[k][ok]))
        kth = diffs.size // 2
        sig = 1.4826 * float(np.partition(diffs, kth)[kth]) / math.sqrt(2.0)
        noise[k] = sig
        thr = max(0.5 * min_depth, dip_noise * sig)
        dk = np.where(ok, dark[k], -np.inf)
        above = dk > thr
        if not above.any():
            continue
        edges = np.diff(above.astype(np.int8), prepend=0, append=0)
        starts = np.flatnonzero(edges == 1)
        ends = np.flatnonzero(edges == -1)
        for s0, s1 in zip(starts.tolist(), ends.tolist(), strict=True):
            peaks.append((k, s0 + int(np.argmax(dk[s0:s1]))))
    return (dark, noise, np.array([k for k, _ in peaks], np.intp),
            np.array([p for _, p in peaks], np.intp))


def fill_ends(prof: np.ndarray, mean: float) -> np.ndarray:
    """``prof`` (rows of samples, NaN where missing) with each missing sample replaced by the
    nearest valid sample of its row before it, or else after it (``mean`` in a row with none):
    a row's valid data is one stretch, so its ends are replicated outward. A level beyond the
    view unlike the tiles at its border (the image mean next to a dark tile) would make a
    dip of that tile's border, or hide a grout line's edge next to it."""
    out = prof.copy()
    for k in range(prof.shape[0]):
        ok = np.flatnonzero(~np.isnan(prof[k]))
        if ok.size == 0:
            out[k] = mean
            continue
        idx = np.clip(np.searchsorted(ok, np.arange(prof.shape[1]), side="right") - 1, 0,
                      ok.size - 1)
        out[k] = prof[k, ok[idx]]
    return out

