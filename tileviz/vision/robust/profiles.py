"""The gray profiles across the grout lines: the dips of both families (:mod:`.projection`
gives the warp and the profiles) and their measurement in parts (position, depth, width, rise,
levels), and the choice of the lines among them.
"""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust import kernel
from tileviz.vision.robust.projection import Projection, project
from tileviz.vision.robust.state import PARTS, Line, RobustRun
from tileviz.vision.robust.statistics import list_median

__all__ = ["beside_dip", "centroid", "crossings", "dip_recentre_numpy", "dip_rows_numpy", "dips",
           "grout_contrast", "measure", "measure_parts", "midpoints", "nanmedian",
           "part_layout_numpy", "part_profiles_numpy", "part_rows_numpy", "part_summary_numpy",
           "plateaus", "select_lines"]


def measure(
    run: RobustRun, y3: float, attempt: int = 1, *, reuse: bool = True, every: bool = False
) -> list[list[Line]]:
    """The dips of both families at heading y3, measured with the window ``run.window``. The
    warp and the profiles are computed once per heading (a second call with the same y3 on a
    later attempt, with a wider window, reuses them unless ``reuse`` is false); on the first
    attempt, this also decides the grout's polarity. ``every``: see :func:`dips`."""
    proj = run.projection if reuse else None
    if attempt == 0 or proj is None or proj.y3 != y3:
        proj = project(run, y3, attempt)
        run.projection = proj
    return dips(run, proj, every=every)


def dips(run: RobustRun, proj: Projection, *, every: bool = False) -> list[list[Line]]:
    """The lines of both families from the dips of their profiles (:func:`profiles`): each
    dip is measured in PARTS equal stretches of the part of its line that every sample of its
    window (``run.window`` samples each side) sees (so all samples of a part average the same
    stretch of floor), from the integral image. Every dip of both families is measured at
    once (vectorised). Only the dips that :func:`select_lines` can keep are measured in parts
    (at least ``rel_depth`` of the deepest line's depth): the others give no line; with
    ``every``, every usable dip is (the same lines once :func:`select_lines` has run).

    Missing data is NaN throughout: the caller silences numpy's warnings on it
    (:func:`~tileviz.vision.robust.extractor.extract_robust` does)."""
    run.unmeasured_width = math.nan
    if proj.peak.size == 0:
        return [[], []]
    r = run.window
    pk = proj.peak
    jj = np.arange(-r, r + 1)
    jf = jj.astype(np.float64)
    rows_of = kernel.dip_rows if kernel.AVAILABLE else dip_rows_numpy
    recentre = kernel.dip_recentre if kernel.AVAILABLE else dip_recentre_numpy
    p0, depth, c0, half, u_lo, step, lev_l, lev_r = rows_of(
        proj.prof, proj.dark, proj.lo, proj.hi, proj.fam, pk, r)
    # The deepest sample of a wide, flat-bottomed band may lie at either of its edges, half
    # the band off its centre, where the band's far edge and plateau fall outside the window
    # (its parts could not be measured, :func:`part_rows_numpy`): such a dip is measured
    # again centred on its half-depth crossings (kept within the profile's data, so the
    # window stays within its padding).
    pk, moved = recentre(c0, half, pk, r, proj.pad, proj.prof.shape[1] - 1 - proj.pad)
    if moved:
        p0, depth, c0, half, u_lo, step, lev_l, lev_r = rows_of(
            proj.prof, proj.dark, proj.lo, proj.hi, proj.fam, pk, r)
    cols = pk[:, None] + jj[None, :]  # padded profile index
    usable = np.flatnonzero(np.isfinite(c0) & (step >= run.st.min_part / 2.0))
    if usable.size == 0:
        return [[], []]
    # every row is measured on its own: a subset of the rows gives the same lines
    top = float(depth[usable].max())
    strong = usable if every else usable[depth[usable] >= run.st.rel_depth * top]
    meas = (p0, c0, half, depth, u_lo, step, lev_l, lev_r)
    out = measure_parts(run, proj, strong, cols, jf, *meas)
    if not any(ln.depth == top for fam_lines in out for ln in fam_lines):
        # the deepest dip gave no line: shallower ones may pass select_lines; its own
        # half-depth width on the whole profile (half = 1.5 width + 1.5) tells the caller
        # whether a wider window would measure it (a grout band wider than the window
        # allows, beside a texture's thin lines)
        deepest = usable[int(np.argmax(depth[usable]))]
        run.unmeasured_width = float((half[deepest] - 1.5) / 1.5)
        out = measure_parts(run, proj, usable, cols, jf, *meas)
    return out


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
    kernel.dip_rows` is the same computation compiled (bit-identical)."""
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
    kernel.dip_recentre` is the same computation compiled (bit-identical)."""
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
    :func:`~tileviz.vision.robust.kernel.part_layout` is the same computation compiled
    (bit-identical)."""
    along = np.where(fam == 0, x0, y0)  # warp coordinate of u = 0
    edges_u = u_lo[:, None] + step[:, None] * np.arange(PARTS + 1)[None, :]
    idx = np.ceil(along[:, None] + edges_u).astype(np.intp)
    count = np.diff(idx, axis=1)  # samples in each part, (m, PARTS)
    tpart = 0.5 * (idx[:, :-1] + idx[:, 1:] - 1) - along[:, None]
    line = np.clip(cols - pad, 0, lim)  # warp row / column
    return idx, count, tpart, line, np.repeat(c0, PARTS), np.repeat(half, PARTS)


def measure_parts(
    run: RobustRun,
    proj: Projection,
    rows: np.ndarray,
    cols: np.ndarray,
    jf: np.ndarray,
    p0: np.ndarray,
    c0: np.ndarray,
    half: np.ndarray,
    depth: np.ndarray,
    u_lo: np.ndarray,
    step: np.ndarray,
    lev_l: np.ndarray,
    lev_r: np.ndarray,
) -> list[list[Line]]:
    """The lines of the dips ``rows`` (indices into the dips of ``proj``), measured in parts
    (see :func:`dips`; the per-dip arrays are those :func:`dips` computed for every dip)."""
    r = run.window
    mean = run.mean
    integ = proj.integ
    fam = proj.fam[rows]
    cols = cols[rows]
    pk = cols[:, r]  # each dip's centre sample (padded index)
    p0, c0, half, depth = p0[rows], c0[rows], half[rows], depth[rows]
    u_lo, step = u_lo[rows], step[rows]
    lev_l, lev_r = lev_l[rows], lev_r[rows]
    x0, y0 = run.centre
    layout = kernel.part_layout if kernel.AVAILABLE else part_layout_numpy
    idx, count, tpart, line, cj, hj = layout(fam, u_lo, step, x0, y0, cols, proj.pad,
                                             integ.shape[0] + integ.shape[1], c0, half)
    if kernel.AVAILABLE:
        pp = kernel.part_profiles(integ.ravel(), integ.shape[1], fam, line, idx, mean, p0)
    else:
        pp = part_profiles_numpy(integ, fam, line, idx, mean, p0)
    meas_rows = kernel.part_rows if kernel.AVAILABLE else part_rows_numpy
    width, rise, contrast, cen, mids, msig = meas_rows(pp, jf, cj, hj, r)
    summary = kernel.part_summary if kernel.AVAILABLE else part_summary_numpy
    wmed, rmed, cmed, stepr, parts, wpart, sigma, spread = summary(
        width, rise, contrast, cen, mids, msig, count, pk - proj.pad, lev_l, lev_r)
    gmed = np.full(rows.size, np.nan)
    if run.inverted:
        gmed = nanmedian(grout_contrast(pp, jf, cj, hj, contrast).reshape(rows.size, PARTS).T)
    out: list[list[Line]] = [[], []]
    # (Python floats and ints of the arrays in one conversion each)
    fam_l, depth_l, chord_l = fam.tolist(), depth.tolist(), proj.total[fam, pk].tolist()
    wmed_l, rmed_l, stepr_l = wmed.tolist(), rmed.tolist(), stepr.tolist()
    cmed_l, gmed_l = cmed.tolist(), gmed.tolist()
    for i in np.flatnonzero(np.isfinite(parts).any(axis=1)).tolist():
        out[fam_l[i]].append(
            Line(
                depth=depth_l[i],
                width=wmed_l[i],
                rise=rmed_l[i],
                step=stepr_l[i],
                contrast=cmed_l[i],
                contrast_grout=gmed_l[i],
                chord=chord_l[i],
                parts=parts[i],
                tpart=tpart[i],
                wpart=wpart[i],
                sigma=sigma[i],
                spread=spread[i],
            )
        )
    return out


def part_summary_numpy(
    width: np.ndarray, rise: np.ndarray, contrast: np.ndarray, cen: np.ndarray,
    mids: np.ndarray, msig: np.ndarray, count: np.ndarray, base: np.ndarray,
    lev_l: np.ndarray, lev_r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
           np.ndarray]:
    """m dips' lines from their part measurements (:func:`part_rows_numpy`, row i * PARTS + j
    is part j of dip i; ``count`` (m, PARTS) samples per part, ``base`` each dip's peak in
    profile coordinates, ``lev_l``, ``lev_r`` its plateau levels): the medians over the parts
    of width, rise and contrast, the step between the plateaus, and per part (m, PARTS) the
    position (NaN where not measured), the length (0 there), the standard error and the
    spread of the 25 / 75 % midpoints (0 there). :func:`~tileviz.vision.robust.kernel.
    part_summary` is the same computation compiled (bit-identical)."""
    m = count.shape[0]
    width = width.reshape(m, PARTS)
    rise = rise.reshape(m, PARTS)
    cen = cen.reshape(m, PARTS)
    mids = mids.reshape(3, m, PARTS)
    msig = msig.reshape(m, PARTS)
    pos50 = np.where(np.isfinite(cen), mids[0], np.nan)
    spread = np.maximum(np.abs(mids[1] - mids[0]), np.abs(mids[2] - mids[0]))
    # a thin or shallow dip may miss its 25 or 75 % crossings: its position is then only
    # known to be within its half-depth width (from the 50 % crossings)
    sp_ok = np.where(np.isfinite(spread) & np.isfinite(msig), spread, 0.5 * width + 0.5)
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
    return wmed, rmed, cmed, stepr, parts, wpart, sigma, spread


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
    the dip's centre ``cj`` and half window ``hj`` per row): half-depth width, 20-80 % rise,
    contrast (depth / brighter plateau), centroid (NaN where its window leaves the profile or
    it strays beyond the half window), the 50/25/75 % midpoints (3, rows) and the 50 %
    midpoint's standard error (:func:`midpoints`). :func:`~tileviz.vision.robust.kernel.
    part_rows` is the same computation compiled (bit-identical); this one is used without
    numba."""
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
    inside = (cj - hj - 4.0 >= -r) & (cj + hj + 4.0 <= r)
    cen = centroid(pp, jf, cj, hj, ll, lr)
    cen = np.where(inside & (np.abs(cen - cj) <= hj), cen, np.nan)
    # the position: the midpoint of the dip's 50 % crossings, each side against its own
    # plateau and depth (texture beside the grout, a slope of the light or a shade step
    # between the tiles pull the centroid, much less the edges); measured where the
    # centroid's window is inside the profile
    mids, msig = midpoints(pp, jf, np.where(np.isfinite(cen), cen, cj), cj, hj, ll, lr)
    return width, rise, dpk / np.maximum(ll, lr), cen, mids, msig


def grout_contrast(pp: np.ndarray, jf: np.ndarray, cj: np.ndarray, hj: np.ndarray,
                   contrast: np.ndarray) -> np.ndarray:
    """Each part's depth over the grout's own level in the gray image, for an inverted view
    (lighter grout; rows of ``pp`` are 255 - gray over sample offsets ``jf``, the dip's centre
    ``cj`` and half window ``hj`` per row, ``contrast`` its depth / brighter plateau as
    :func:`part_rows_numpy` gives it). Light falling off across the view (vignetting, a
    gradient) scales the grout's level and the depth alike, so this ratio is the same for
    every line of one grout colour wherever the light is; the depth over the plateau of the
    inverted image (the tiles' 255 - gray) is not, but is less moved by tiles of strongly
    different shades."""
    ll, lr = plateaus(pp, jf, cj, hj)
    depth = contrast * np.maximum(ll, lr)
    core = np.abs(jf[None, :] - cj[:, None]) <= 3.0
    bottom = np.where(core & ~np.isnan(pp), pp, np.inf).min(axis=1)
    return depth / np.maximum(255.0 - bottom, 1.0)


def select_lines(run: RobustRun, lines: list[list[Line]]) -> list[list[Line]]:
    """Keep the dips that look like grout lines: deep enough against the deepest, and not
    much wider than the strong ones (a broad shadow or stain is not a line)."""
    every = lines[0] + lines[1]
    if not every:
        return [[], []]
    deepest = max(ln.depth for ln in every)
    wref = list_median([ln.width for ln in every if ln.depth >= 0.5 * deepest])
    run.details["depth"] = deepest
    run.details["width"] = wref
    return [
        distinct([
            ln
            for ln in fam
            if ln.depth >= run.st.rel_depth * deepest and ln.width <= 2.0 * wref + 2.0
        ])
        for fam in lines
    ]


def beside_dip(run: RobustRun, k: int, line: Line) -> float:
    """The darkness of the deepest dip of family ``k``'s whole profile (the last projection)
    apart from ``line``'s own within its measurement window (``run.window`` samples each side
    of the line's centre), over the line's depth (0.0 when there is none). Apart: every
    sample between the line's own deepest sample (within half its width + 2 of its centre)
    and that dip's is lighter than half that dip's darkness, so their half-depth bands do not
    touch. A grout line is one band; a cable or a seam along it, a few px beside it, is a
    second band that every part of the line shows (a texture's dip beside one part of it is
    a quarter as deep in the whole profile), and the line's measurement window, whose
    plateaus it darkens, cannot tell which band is the grout."""
    proj = run.projection
    at = list_median([p for p in line.parts.tolist() if p == p] or [math.nan])
    if proj is None or not math.isfinite(at) or not line.depth > 0.0:
        return 0.0
    d = np.where(np.isnan(proj.prof[k]), -np.inf, proj.dark[k])
    c = int(round(at)) + proj.pad
    r = run.window
    lo, hi = max(c - r, 0), min(c + r + 1, d.size)
    near = max(int(math.ceil(0.5 * line.width)) + 2, 1) if math.isfinite(line.width) else 2
    a, b = max(c - near, lo), min(c + near + 1, hi)
    if a >= b:
        return 0.0
    own = a + int(np.argmax(d[a:b]))
    best = 0.0
    for step, end in ((-1, lo - 1), (1, hi)):
        col = math.inf
        for i in range(own + step, end, step):
            v = float(d[i])
            if col < 0.5 * v:
                best = max(best, v)
            col = min(col, v)
    return best / line.depth


def distinct(fam: list[Line]) -> list[Line]:
    """The lines of one family, each band once: a shallower dip beside a grout band (a
    texture's, within its window) can be measured onto that band; of two lines whose parts'
    median positions are within the wider one's half-depth width, the deeper is kept (in the
    family's order)."""
    if len(fam) < 2:
        return fam
    at = [list_median([p for p in ln.parts.tolist() if p == p] or [math.nan]) for ln in fam]
    keep = [True] * len(fam)
    for i in sorted(range(len(fam)), key=lambda i: -fam[i].depth):
        if not keep[i]:
            continue
        for j in range(len(fam)):
            if j != i and keep[j] and fam[j].depth <= fam[i].depth and (
                    abs(at[j] - at[i]) <= max(fam[i].width, fam[j].width)):
                keep[j] = False
    return [ln for ln, k in zip(fam, keep, strict=True) if k]


def nanmedian(a: np.ndarray) -> np.ndarray:
    """Median over axis 0 of the finite entries of a small (k, m) array (NaN if none)."""
    srt = np.sort(np.where(np.isfinite(a), a, np.inf), axis=0)
    cnt = np.isfinite(a).sum(axis=0)
    lo = np.clip((cnt - 1) // 2, 0, a.shape[0] - 1)
    hi = np.clip(cnt // 2, 0, a.shape[0] - 1)
    cols = np.arange(a.shape[1])
    out = 0.5 * (srt[lo, cols] + srt[hi, cols])
    return np.where(cnt > 0, out, np.nan)


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
    left and right crossings (shape (3, rows), NaN where a crossing is missing), and the
    predicted standard error of the 50 % midpoint (rows,), px.

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
    sl = rough / np.maximum(lev_l - bottom, 1e-6) * np.abs(xl3[2] - xl3[1]) / 0.5
    sr = rough / np.maximum(lev_r - bottom, 1e-6) * np.abs(xr3[2] - xr3[1]) / 0.5
    return mids, 0.5 * np.sqrt(sl * sl + sr * sr)


def plateaus(
    p: np.ndarray, j: np.ndarray, c: np.ndarray, half: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Mean level of each row of ``p`` (sample offsets ``j``) over the 4 samples just outside
    its window [c - half, c + half], on the left and on the right (NaN if none)."""
    cl = (c - half)[:, None]
    cr = (c + half)[:, None]
    jr = j[None, :]
    ok = ~np.isnan(p)
    ml = (jr < cl) & (jr >= cl - 4.0) & ok
    mr = (jr > cr) & (jr <= cr + 4.0) & ok
    pz = np.where(ok, p, 0.0)
    with np.errstate(invalid="ignore"):  # no sample on a side: NaN
        left = (pz * ml).sum(axis=1) / ml.sum(axis=1)
        right = (pz * mr).sum(axis=1) / mr.sum(axis=1)
    return left, right


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
