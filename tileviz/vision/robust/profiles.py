"""The gray profiles across the grout lines: the dips of both families (:mod:`.projection`
gives the warp and the profiles) and their measurement in parts (position, depth, width, rise,
levels), and the choice of the lines among them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tileviz.vision.robust import checks, dip_kernel, kernel
from tileviz.vision.robust.projection import Projection, project
from tileviz.vision.robust.state import PARTS, Line, ReadingState
from tileviz.vision.robust.statistics import list_median

__all__ = ["DipGroup", "beside_dip", "dips", "grout_contrast", "measure", "measure_parts",
           "nanmedian", "plateaus", "select_lines"]


def measure(
    run: ReadingState, y3: float, attempt: int = 1, *, reuse: bool = True, every: bool = False
) -> list[list[Line]]:
    """The dips of both families at heading y3, measured with their windows
    (``run.window_of``). The warp and the profiles are computed once per heading (a second
    call with the same y3 on a later attempt, with a wider window, reuses them unless
    ``reuse`` is false); on the first attempt, this also decides the grout's polarity.
    ``every``: see :func:`dips`."""
    proj = run.projection if reuse else None
    if attempt == 0 or proj is None or proj.y3 != y3:
        proj = project(run, y3, attempt)
        run.projection = proj
    return dips(run, proj, every=every)


def dips(run: ReadingState, proj: Projection, *, every: bool = False) -> list[list[Line]]:
    """The lines of both families from the dips of their profiles (:func:`profiles`): each
    dip is measured in PARTS equal stretches of the part of its line that every sample of its
    window (``run.window_of(k)`` samples each side, family k) sees (so all samples of a part
    average the same stretch of floor), from the integral image. The dips of a window are
    measured at once (vectorised). Only the dips that :func:`select_lines` can keep are
    measured in parts (at least ``rel_depth`` of the deepest dip's depth; every usable dip
    when the deepest gave no line): the others give no line; with ``every``, every usable dip
    is (the same lines once :func:`select_lines` has run). Sets ``run.unmeasured_width`` and
    ``run.unmeasured_family`` (the bands too wide for their window, which a wider one may
    measure).

    Missing data is NaN throughout: the caller silences numpy's warnings on it
    (:func:`~tileviz.vision.robust.extractor.extract_robust` does)."""
    run.unmeasured_width = math.nan
    run.unmeasured_family = (math.nan, math.nan)
    if proj.peak.size == 0:
        return [[], []]
    windows = (run.window_of(0), run.window_of(1))
    if windows[0] == windows[1]:
        groups = [_dip_group(run, proj, np.arange(proj.peak.size), windows[0])]
    else:  # a family measured in a wider window of its own
        groups = [_dip_group(run, proj, np.flatnonzero(proj.fam == k), windows[k])
                  for k in range(2)]
    groups = [g for g in groups if g.usable.size]
    if not groups:
        return [[], []]
    # every row is measured on its own: a subset of the rows gives the same lines
    top = max(float(g.depth[g.usable].max()) for g in groups)
    strong = [g.usable if every else g.usable[g.depth[g.usable] >= (
        run.st.selection.rel_depth * top)] for g in groups]
    measured = [measure_parts(run, proj, g, rows) for g, rows in zip(groups, strong, strict=True)]
    if not any(got[g.depth[rows] == top].any()
               for g, rows, (_, got) in zip(groups, strong, measured, strict=True)):
        # the deepest dip gave no line: shallower ones may pass select_lines; its own
        # half-depth width on the whole profile (half = 1.5 width + 1.5) tells the caller
        # whether a wider window would measure it (a grout band wider than the window
        # allows, beside a texture's thin lines)
        g = next(g for g in groups if float(g.depth[g.usable].max()) == top)
        deepest = g.usable[int(np.argmax(g.depth[g.usable]))]
        run.unmeasured_width = float((g.half[deepest] - 1.5) / 1.5)
        strong = [g.usable for g in groups]
        measured = [measure_parts(run, proj, g, g.usable) for g in groups]
    out: list[list[Line]] = [[], []]
    unmeasured: list[list[float]] = [[], []]
    least = checks.CONTRAST_DEPTH.limit(run)
    for g, rows, (lines, got) in zip(groups, strong, measured, strict=True):
        # the strong bands, as deep as a grout line must be (contrast.depth), that gave no
        # line and whose band and plateaus (4 samples beyond it) reach past the window
        # (kernel.part_rows): a wider window may measure them
        depth = g.depth[rows]
        wide = rows[~got & (depth >= run.st.selection.rel_depth * top) & (depth >= least)
                    & (np.abs(g.c0[rows]) + g.half[rows] + 4.0 > g.r)]
        fam, width = proj.fam[g.rows[wide]], (g.half[wide] - 1.5) / 1.5
        for k in range(2):
            unmeasured[k].extend(width[fam == k].tolist())
            out[k].extend(lines[k])
    # a family with profiles.wide_family such bands or more (its grout, not one wide stain or
    # shadow): their median half-depth width (px)
    median = [list_median(u) if len(u) >= run.st.profiles.wide_family else math.nan
              for u in unmeasured]
    run.unmeasured_family = (median[0], median[1])
    return out


class DipGroup(NamedTuple):
    """Dips of one projection measured in one window ``r`` on their whole profiles: ``rows``
    (indices into the projection's dips), the sample offsets ``jf`` (-r..r), each dip's
    padded profile indices ``cols``, the :func:`~tileviz.vision.robust.dip_kernel.dip_rows`
    arrays (index i: the dip ``rows[i]``) and the ``usable`` ones (indices into ``rows``)."""

    rows: np.ndarray
    r: int
    jf: np.ndarray
    cols: np.ndarray
    p0: np.ndarray
    depth: np.ndarray
    c0: np.ndarray
    half: np.ndarray
    u_lo: np.ndarray
    step: np.ndarray
    lev_l: np.ndarray
    lev_r: np.ndarray
    usable: np.ndarray


def _dip_group(run: ReadingState, proj: Projection, rows: np.ndarray, r: int) -> DipGroup:
    """The dips ``rows`` of ``proj`` measured on their whole profiles in a window of ``r``
    samples each side."""
    jj = np.arange(-r, r + 1)
    fam, pk = proj.fam[rows], proj.peak[rows]
    p0, depth, c0, half, u_lo, step, lev_l, lev_r = dip_kernel.dip_rows(
        proj.prof, proj.dark, proj.lo, proj.hi, fam, pk, r)
    # The deepest sample of a wide, flat-bottomed band may lie at either of its edges, half
    # the band off its centre, where the band's far edge and plateau fall outside the window
    # (its parts could not be measured, kernel.part_rows): such a dip is measured again
    # centred on its half-depth crossings (kept within the profile's data, so the window
    # stays within its padding).
    pk, moved = dip_kernel.dip_recentre(c0, half, pk, r, proj.pad,
                                        proj.prof.shape[1] - 1 - proj.pad)
    if moved:
        p0, depth, c0, half, u_lo, step, lev_l, lev_r = dip_kernel.dip_rows(
            proj.prof, proj.dark, proj.lo, proj.hi, fam, pk, r)
    usable = np.flatnonzero(np.isfinite(c0) & (step >= run.st.profiles.min_part / 2.0))
    return DipGroup(rows, r, jj.astype(np.float64), pk[:, None] + jj[None, :], p0, depth, c0,
                    half, u_lo, step, lev_l, lev_r, usable)


def measure_parts(run: ReadingState, proj: Projection, g: DipGroup, sel: np.ndarray
                  ) -> tuple[list[list[Line]], np.ndarray]:
    """The lines of the dips ``sel`` (indices into the group ``g``), measured in parts (see
    :func:`dips`), and for each of ``sel`` whether it gave a line."""
    r = g.r
    jf = g.jf
    mean = run.mean
    integ = proj.integ
    rows = sel
    fam = proj.fam[g.rows[sel]]
    cols = g.cols[sel]
    pk = cols[:, r]  # each dip's centre sample (padded index)
    p0, c0, half, depth = g.p0[sel], g.c0[sel], g.half[sel], g.depth[sel]
    u_lo, step = g.u_lo[sel], g.step[sel]
    lev_l, lev_r = g.lev_l[sel], g.lev_r[sel]
    x0, y0 = run.centre
    idx, count, tpart, line, cj, hj = dip_kernel.part_layout(
        fam, u_lo, step, x0, y0, cols, proj.pad, integ.shape[0] + integ.shape[1], c0, half)
    pp = kernel.part_profiles(integ.ravel(), integ.shape[1], fam, line, idx, mean, p0)
    width, rise, contrast, cen, mids, msig = kernel.part_rows(pp, jf, cj, hj, r)
    wmed, rmed, cmed, stepr, parts, wpart, sigma, spread, reach = dip_kernel.part_summary(
        width, rise, contrast, cen, mids, msig, count, pk - proj.pad, lev_l, lev_r)
    gmed = np.full(rows.size, np.nan)
    if run.inverted:
        gmed = nanmedian(grout_contrast(pp, jf, cj, hj, contrast).reshape(rows.size, PARTS).T)
    out: list[list[Line]] = [[], []]
    # (Python floats and ints of the arrays in one conversion each)
    fam_l, depth_l, chord_l = fam.tolist(), depth.tolist(), proj.total[fam, pk].tolist()
    wmed_l, rmed_l, stepr_l = wmed.tolist(), rmed.tolist(), stepr.tolist()
    cmed_l, gmed_l = cmed.tolist(), gmed.tolist()
    part_contrast = contrast.reshape(rows.size, PARTS)
    got = np.isfinite(parts).any(axis=1)
    for i in np.flatnonzero(got).tolist():
        out[fam_l[i]].append(
            Line(
                depth=depth_l[i],
                width=wmed_l[i],
                rise=rmed_l[i],
                step=stepr_l[i],
                contrast=cmed_l[i],
                contrast_grout=gmed_l[i],
                part_contrast=part_contrast[i],
                chord=chord_l[i],
                parts=parts[i],
                tpart=tpart[i],
                wpart=wpart[i],
                sigma=sigma[i],
                spread=spread[i],
                reach=reach[i],
            )
        )
    return out, got


def grout_contrast(pp: np.ndarray, jf: np.ndarray, cj: np.ndarray, hj: np.ndarray,
                   contrast: np.ndarray) -> np.ndarray:
    """Each part's depth over the grout's own level in the gray image, for an inverted view
    (lighter grout; rows of ``pp`` are 255 - gray over sample offsets ``jf``, the dip's centre
    ``cj`` and half window ``hj`` per row, ``contrast`` its depth / brighter plateau as
    :func:`~tileviz.vision.robust.kernel.part_rows` gives it). Light falling off across the
    view (vignetting, a gradient) scales the grout's level and the depth alike, so this ratio
    is the same for
    every line of one grout colour wherever the light is; the depth over the plateau of the
    inverted image (the tiles' 255 - gray) is not, but is less moved by tiles of strongly
    different shades."""
    ll, lr = plateaus(pp, jf, cj, hj)
    depth = contrast * np.maximum(ll, lr)
    core = np.abs(jf[None, :] - cj[:, None]) <= 3.0
    bottom = np.where(core & ~np.isnan(pp), pp, np.inf).min(axis=1)
    return depth / np.maximum(255.0 - bottom, 1.0)


def select_lines(run: ReadingState, lines: list[list[Line]]) -> list[list[Line]]:
    """Keep the dips that look like grout lines: deep enough against the deepest, and not
    much wider than the strong ones (a broad shadow or stain is not a line)."""
    st = run.st.selection
    every = lines[0] + lines[1]
    if not every:
        return [[], []]
    deepest = max(ln.depth for ln in every)
    wref = list_median([ln.width for ln in every if ln.depth >= st.strong_share * deepest])
    run.details["depth"] = deepest
    run.details["width"] = wref
    return [
        distinct([
            ln
            for ln in fam
            if ln.depth >= st.rel_depth * deepest
            and ln.width <= st.wide_ratio * wref + st.wide_slack
        ])
        for fam in lines
    ]


def beside_dip(run: ReadingState, k: int, line: Line, reach: float = math.inf,
               share: float = math.inf) -> tuple[float, list[int]]:
    """The dips of family ``k``'s whole profile (the last projection) apart from ``line``'s
    own within its measurement window (``run.window_of(k)`` samples each side of the line's
    centre, at most ``reach``): the deepest one's darkness over the line's depth (0.0 when
    there is none), and the signed offsets (samples = px, from the line's own deepest sample)
    of those samples whose darkness is at least ``share`` of the line's depth. Apart: every
    sample between the line's own deepest
    sample (within half its width + 2 of its centre) and that dip's is lighter than
    ``lines.beside_apart`` of that dip's darkness (a valley between two bands). A grout line
    is one band; a cable or a seam along it, a few px beside it, is a second band that every
    part of the line shows (a texture's dip beside one part of it is a quarter as deep in the
    whole profile), and the line's measurement window, whose plateaus it darkens, cannot
    tell which band is the grout."""
    proj = run.projection
    at = list_median([p for p in line.parts.tolist() if p == p] or [math.nan])
    if proj is None or not math.isfinite(at) or not line.depth > 0.0:
        return 0.0, []
    d = np.where(np.isnan(proj.prof[k]), -np.inf, proj.dark[k])
    c = int(round(at)) + proj.pad
    r = run.window_of(k) if reach >= run.window_of(k) else int(reach)
    lo, hi = max(c - r, 0), min(c + r + 1, d.size)
    near = max(int(math.ceil(0.5 * line.width)) + 2, 1) if math.isfinite(line.width) else 2
    a, b = max(c - near, lo), min(c + near + 1, hi)
    if a >= b:
        return 0.0, []
    own = a + int(np.argmax(d[a:b]))
    apart = run.st.lines.beside_apart
    least = share * line.depth
    best = 0.0
    offsets: list[int] = []
    for step, end in ((-1, lo - 1), (1, hi)):
        col = math.inf
        for i in range(own + step, end, step):
            v = float(d[i])
            if col < apart * v:
                best = max(best, v)
                if v >= least:
                    offsets.append(i - own)
            col = min(col, v)
    return best / line.depth, offsets


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


