"""Where the two line families cross: the grout's depth across each line just beside each
crossing, compared between the two lines (:func:`crossing_spread`).

Grout of one colour is one band wherever it runs, but its contrast over the tiles beside it is
not one number on a floor whose tiles differ in shade: lighter grout between two dark tiles is
deeper (on the inverted image) than between two light ones, and uneven light scales both. Beside
a crossing, though, both lines run between the same four tiles under the same light: read on
both sides of the crossing (the four tiles alike), the two bands must show the same depth. A
line that is not grout (a cable, a seam of another colour lying along one family) shows a
different depth from the grout it crosses."""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust import checks
from tileviz.vision.robust.state import Line, ReadingState

__all__ = ["crossing_depths", "crossing_spread", "crossings_agree"]

def crossings_agree(run: ReadingState, lines: list[list[Line]]) -> bool:
    """Whether the lines of lighter grout (an inverted view) are one grout by their depths
    beside the crossings (:func:`crossing_spread`): some line is read beside a crossing
    (check ``foreign_line.crossings_read``), the two lines of every crossing read agree within
    ``lines.crossing_ratio`` (``foreign_line.crossings``), and every line not read at a
    crossing (both near the border of the view) agrees in contrast (depth over the tiles'
    inverted level, or over the grout's own level) within ``lines.contrast_ratio`` with one
    that was (``foreign_line.unread``). Records ``crossing_spread`` and ``crossing_lines``
    (how many lines were read) in the details, and the checks in ``run.record``."""
    st = run.st.lines
    worst, read = crossing_spread(run, lines)
    run.details["crossing_spread"] = worst
    run.details["crossing_lines"] = float(len(read))
    rec = run.record
    if not (rec.check(checks.CROSSINGS_READ, run, len(read))
            and rec.check(checks.CROSSINGS, run, worst)):
        return False
    unlike = sum(
        1 for ln in lines[0] + lines[1]
        if not any(ln is r for r in read)
        and not any(ratio(ln.contrast, r.contrast) <= st.contrast_ratio
                    or ratio(ln.contrast_grout, r.contrast_grout) <= st.contrast_ratio
                    for r in read))
    return rec.check(checks.CROSSINGS_UNREAD, run, unlike)


def crossing_spread(run: ReadingState, lines: list[list[Line]]) -> tuple[float, list[Line]]:
    """The largest ratio (>= 1) of the two lines' depths over the crossings of a line of
    each family that the view lets read (inf when a depth is not positive; 1 when none is
    read), and the lines read at one crossing at least. ``run.projection`` must hold the
    warped view the lines were measured on and ``run.y3`` the heading after the lines'
    common tilt fit."""
    worst = 1.0
    read: dict[int, Line] = {}
    for a in lines[0]:
        for b in lines[1]:
            got = crossing_depths(run, a, b)
            if got is None:
                continue
            worst = max(worst, ratio(*got))
            read[id(a)] = a
            read[id(b)] = b
    return worst, list(read.values())


def crossing_depths(run: ReadingState, a: Line, b: Line) -> tuple[float, float] | None:
    """The depths (levels of the warped view, as the profiles read them) of line ``a``
    (family 1, a warp row) and line ``b`` (family 2, a warp column) beside their crossing, read
    between the same tiles: each band's profile averaged along its line over up to
    ``lines.crossing_reach`` px (as far as the view allows, alike) on both sides of the crossing,
    beyond the other band's window, its depth the mean of the 4 samples beyond its own window on
    each side minus the band's lowest sample. Where the view holds only one side of the crossing for
    either line (near its border), each line is read on one side and its depth taken over the
    plateau of the one tile both readings share (of the quarters the view holds, the one where the
    two depths agree best). None when no quarter can be read."""
    proj = run.projection
    if proj is None or run.y3 is None:
        return None
    eps = run.y3 - proj.y3
    x0, y0 = run.centre
    # family-1 rows drift by +eps per px of X, family-2 columns by -eps per px of Y
    xc, yc = b.pos, a.pos
    for _ in range(2):
        yc = a.pos + eps * (xc - x0)
        xc = b.pos - eps * (yc - y0)
    ha = 1.5 * a.width + 1.5
    hb = 1.5 * b.width + 1.5
    if not (math.isfinite(ha) and math.isfinite(hb) and ha > 0.0 and hb > 0.0):
        return None
    pa = band_profiles(run, 0, yc, xc, ha, hb)
    pb = band_profiles(run, 1, xc, yc, hb, ha)
    if pa is None or pb is None:
        return None
    if pa[0] is not None and pb[0] is not None:
        return pa[0][0], pb[0][0]
    best: tuple[float, float] | None = None
    for sx in (1, 2):  # the side of the crossing line a is read on (its tangent, X)
        for sy in (1, 2):  # the side line b is read on (Y)
            ra, rb = pa[sx], pb[sy]
            if ra is None or rb is None:
                continue
            # the tile of this quarter: beyond a on b's side, beyond b on a's side
            da, db = ra[sy], rb[sx]
            if best is None or ratio(da, db) < ratio(*best):
                best = (da, db)
    return best


def ratio(a: float, b: float) -> float:
    """max / min of two depths (inf unless both are positive)."""
    return max(a, b) / min(a, b) if a > 0.0 and b > 0.0 else math.inf


def band_profiles(run: ReadingState, k: int, at: float, along: float, half: float,
                  other: float) -> list[tuple[float, float, float] | None] | None:
    """The family-``k`` band centred at profile coordinate ``at`` (a warp row for k = 0, a
    column for k = 1), read along the band beside the tangent position ``along`` (warp column for k
    = 0, row for k = 1), beyond ``other`` px (the crossing band's half window) + 2; ``half``: this
    band's own half window. Three readings: on both sides alike, on the lower side only, on the
    higher side only; each (depth over both plateaus, depth over the lower-side plateau, depth over
    the higher-side plateau), or None where the view does not hold ``lines.crossing_min_reach`` px
    of it. None when the band's window leaves the warped view."""
    proj = run.projection
    integ = proj.integ
    r0 = int(math.ceil(other + 2.0))
    n = int(math.ceil(half)) + 4
    c = int(round(at))
    idx = np.arange(c - n, c + n + 1)
    size = integ.shape[0] - 1 if k == 0 else integ.shape[1] - 1
    if idx[0] < 0 or idx[-1] >= size:
        return None
    # within the in-view stretch of every row (column) read (tangent coordinates relative to
    # the warp centre)
    base = run.centre[0] if k == 0 else run.centre[1]
    lo = float(proj.lo[k, idx + proj.pad].max()) + base
    hi = float(proj.hi[k, idx + proj.pad].min()) + base
    mid = int(math.floor(along))
    gap_lo = mid - r0
    gap_hi = mid + r0 + 1  # exclusive
    # (a side whose start lies beyond the view has no room)
    reach, least = run.st.lines.crossing_reach, run.st.lines.crossing_min_reach
    room_lo = min(reach, int(math.floor(gap_lo - lo))) if gap_lo <= hi + 1.0 else 0
    room_hi = min(reach, int(math.floor(hi + 1.0 - gap_hi))) if gap_hi >= lo else 0
    cum = integ[idx + 1] - integ[idx] if k == 0 else (integ[:, idx + 1] - integ[:, idx]).T
    j = idx - at
    core = np.abs(j) <= max(1.0, 0.5 * (half - 1.5) / 1.5 + 1.0)
    side = (np.abs(j) > half) & (np.abs(j) <= half + 4.0)
    left = side & (j < 0)
    right = side & (j > 0)
    if not (core.any() and left.any() and right.any()):
        return None

    def read(lo_n: int, hi_n: int) -> tuple[float, float, float] | None:
        if min(r for r in (lo_n, hi_n) if r) < least:
            return None
        tot = np.zeros(idx.size)
        if lo_n:
            tot += cum[:, gap_lo] - cum[:, gap_lo - lo_n]
        if hi_n:
            tot += cum[:, gap_hi + hi_n] - cum[:, gap_hi]
        prof = tot / float(lo_n + hi_n)
        bottom = float(prof[core].min())
        pl, pr = float(prof[left].mean()), float(prof[right].mean())
        return 0.5 * (pl + pr) - bottom, pl - bottom, pr - bottom

    both = min(room_lo, room_hi)
    return [read(both, both) if both >= least else None,
            read(room_lo, 0) if room_lo >= least else None,
            read(0, room_hi) if room_hi >= least else None]
