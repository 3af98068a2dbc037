"""The grout's gray levels where a straight edge off the lattice meets a grout line: whether the
grout's level changes there (a crossing object covers or darkens the grout), how much the grout
varies by itself along its line, and whether what is seen beside the edge differs enough from
the grout that an object crossing it would have shown (:func:`conclusive`). Used by
:func:`~tileviz.vision.robust.foreign.ends` to tell an object's edge from texture that stops
at the grout."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.geometry import family_normals
from tileviz.vision.robust import foreign_kernel
from tileviz.vision.robust.state import ReadingState

__all__ = ["alongside", "at_edge", "conclusive", "cross_profile", "gray_levels",
           "grout_variation", "neighbour_medians", "on_grout", "pass_unchanged", "row_medians",
           "side_level", "straddle", "straddle_limit", "trend_range"]


def pass_unchanged(run: ReadingState, xs: np.ndarray, ys: np.ndarray, i0: int, i1: int,
                   px: float, py: float, dx: float, dy: float, n: tuple[float, float],
                   sh: float, beyond: tuple[float, float] | None = None) -> bool:
    """Whether the grout of the family with unit normal ``n`` and offset ``sh`` (px) stays
    alike beside a straight edge's pass through its band (the steps ``xs``, ``ys`` from
    ``i0`` to ``i1``, 10 steps more either side), for the edge ending at (px, py) along the
    unit vector (dx, dy): the grout's core levels beside the pass (:func:`alongside`) vary
    by at most :func:`straddle_limit`, or by that much about their straight trend (a
    least-squares line over the pass: the light's gradient and vignetting change the level
    slowly along a long pass), and the pass is :func:`conclusive` (anything seen beside the edge
    would have changed the grout's level had it covered or shaded the grout; ``beyond``: the
    steps where the edge is seen again past the band, as there). An object reaching the
    grout in that stretch covers or darkens its core from where its edge meets it, a step
    the trend leaves nearly whole; a texture's edge beside the grout leaves it alike."""
    j0, j1 = max(i0 - 10, 0), min(i1 + 10, xs.size)
    core = alongside(run, xs[j0:j1], ys[j0:j1], n, sh)
    if core is None:
        # the grout's centre line beside the pass lies out of view: the object cannot have
        # covered a grout core in view (a line whose core is out of view is not measured)
        return j1 - j0 >= 3
    limit = straddle_limit(run)
    vary = float(core.max() - core.min())
    if vary > limit:  # about the straight trend (fitted only when the levels are not flat)
        vary = min(vary, trend_range(core))
    return (vary <= limit
            and conclusive(run, px, py, dx, dy, float(np.median(core)), limit, beyond))


def straddle(run: ReadingState, px: float, py: float, dx: float, dy: float,
             n: tuple[float, float], sh: float) -> tuple[np.ndarray, bool, float] | None:
    """The grout's gray levels where the line through (px, py) along (dx, dy) crosses the
    grout's centre line (the next line ahead of the family with unit normal ``n`` and offset
    ``sh``, px): the centre line's gray levels (bilinear) at 0..9 px from the line on both
    sides (at most 180 px along the grout), whose range the caller compares with the noise.
    An object crossing the grout covers it (a cable, a box) or darkens it (a shadow) near the
    line; a texture's edge that stops at the grout leaves it alike.

    Returns the samples (median of 3 neighbours), whether both sides were read (3 samples
    or more each; one side is enough when the line crosses the grout at
    ``foreign.straddle_one_sided`` or more) and the grout's own variation over as long a stretch
    elsewhere on its line (:func:`grout_variation`, gray levels, NaN when not read). None
    when the line runs within ``foreign.straddle_parallel`` of the grout or neither side can be
    read."""
    cx, cy = (run.w - 1) / 2.0, (run.h - 1) / 2.0
    nd = n[0] * dx + n[1] * dy
    st = run.st.foreign
    if abs(nd) < st.straddle_parallel:
        return None
    o = n[0] * (px - cx) + n[1] * (py - cy) + sh
    # the next grout centre line ahead: o + t nd = m lp
    m = math.floor(o / run.lp) + (1 if nd > 0 else 0)
    t = (m * run.lp - o) / nd
    qx, qy = px + t * dx, py + t * dy
    g = (-n[1], n[0])
    # distance from the line of a point s px along the grout: s |(segment normal) . g| = s |nd|
    s = np.arange(-9.0, 10.0) / abs(nd)
    xs = qx + s * g[0]
    ys = qy + s * g[1]
    ok = (xs >= 0) & (xs <= run.w - 1) & (ys >= 0) & (ys <= run.h - 1)
    sides = (int(ok[:9].sum()), int(ok[10:].sum()))
    both = min(sides) >= 3
    if not both and (max(sides) < 3 or abs(nd) < st.straddle_one_sided):
        return None
    return gray_levels(run, xs[ok], ys[ok]), both, grout_variation(run, qx, qy, g, 1.0 / abs(nd))


def grout_variation(run: ReadingState, qx: float, qy: float, g: tuple[float, float],
                    step: float) -> float:
    """How much the grout's gray level varies by itself over a stretch as long as a straddle's
    (19 samples ``step`` px apart along the unit direction ``g``) elsewhere on the same grout
    centre line through the crossing (qx, qy): the largest range of the stretches in view that
    keep ``foreign.variation_clear`` samples clear of the crossing's own stretch (an object's
    other edge lies within them), NaN when fewer than ``foreign.variation_stretches``. A thin
    grout band takes in the texture beside it (the mortar of a brick photograph brightens it
    where it meets it) and a lighting gradient runs along it, all along the line; an object
    changes it only where it crosses it (a cable) or on one side of that crossing (a box, a
    shadow)."""
    reach = math.hypot(run.w, run.h)
    u = np.arange(-math.floor(reach / step), math.floor(reach / step) + 1) * step
    xs = qx + u * g[0]
    ys = qy + u * g[1]
    idx = np.flatnonzero((xs >= 0) & (xs <= run.w - 1) & (ys >= 0) & (ys <= run.h - 1))
    if idx.size < 21:
        return math.nan
    lv = gray_levels(run, xs[idx], ys[idx])  # at the samples idx[1:-1]
    st = run.st.foreign
    return float(foreign_kernel.stretch_range(lv, idx, u, st.variation_clear,
                                              st.variation_stretches))


def trend_range(v: np.ndarray) -> float:
    """The range of the values ``v`` (1-D, at least 2, in order along a line, equally
    spaced) about their least-squares straight line (gray levels): a slow change of the
    light along the line leaves it small; a jump (an object's edge) stays nearly whole."""
    x = np.arange(v.size, dtype=np.float64)
    rest = v - np.polyval(np.polyfit(x, v, 1), x)
    return float(rest.max() - rest.min())


def alongside(run: ReadingState, xs: np.ndarray, ys: np.ndarray, n: tuple[float, float],
              sh: float) -> np.ndarray | None:
    """The grout's gray levels beside the pixels (xs, ys): at the foot of each on the nearest
    centre line of the family with unit normal ``n`` and offset ``sh`` (px), bilinear, median
    of 3 neighbours; None when fewer than 3 feet lie in the view."""
    cx, cy = (run.w - 1) / 2.0, (run.h - 1) / 2.0
    o = n[0] * (xs - cx) + n[1] * (ys - cy) + sh
    d = o - run.lp * np.rint(o / run.lp)
    fx = xs - d * n[0]
    fy = ys - d * n[1]
    ok = (fx >= 0) & (fx <= run.w - 1) & (fy >= 0) & (fy <= run.h - 1)
    if int(ok.sum()) < 3:
        return None
    return gray_levels(run, fx[ok], fy[ok])


def gray_levels(run: ReadingState, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """The view's gray levels at the points (xs, ys) (px, in the view, at least 3, in order
    along a line): bilinear, each the median of itself and its 2 neighbours (n - 2 values)."""
    v = cv2.remap(run.gray, xs.astype(np.float32).reshape(1, -1),
                  ys.astype(np.float32).reshape(1, -1), cv2.INTER_LINEAR).ravel()
    return neighbour_medians(v.astype(np.float64))


def neighbour_medians(v: np.ndarray) -> np.ndarray:
    """Each value of ``v`` (1-D, n >= 3, no NaN) but the first and last, the median of itself
    and its 2 neighbours (n - 2 values), as ``np.median`` of the three (the middle one)."""
    a, b, c = v[:-2], v[1:-1], v[2:]
    return np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c))


def straddle_limit(run: ReadingState) -> float:
    """How much the grout's gray level may vary where a texture's edge meets it (gray levels):
    ``foreign.straddle_sigmas`` x the image noise + ``foreign.straddle_levels``."""
    st = run.st.foreign
    return st.straddle_sigmas * run.noise + st.straddle_levels


def cross_profile(run: ReadingState, px: float, py: float, dx: float, dy: float, t0: float,
                  t1: float) -> np.ndarray:
    """The gray levels across a straight edge through (px, py) along the unit vector
    (dx, dy): at each of -8..8 px across it (positive along (-dy, dx)), the median of the
    bilinear samples at t0..t1 px along it (1 px apart). Samples out of the view, and on the
    grout itself (:func:`on_grout`: an edge beside the grout sees it within 8 px), are not
    the edge's and are left out; an offset with fewer than 4 samples left is NaN."""
    t = np.arange(t0, t1 + 0.5)
    if t.size == 0:
        return np.full(17, np.nan)
    o = np.arange(-8.0, 9.0)
    xs = px + t[None, :] * dx - o[:, None] * dy
    ys = py + t[None, :] * dy + o[:, None] * dx
    ok = (xs >= 0) & (xs <= run.w - 1) & (ys >= 0) & (ys <= run.h - 1)
    v = cv2.remap(run.gray, xs.astype(np.float32), ys.astype(np.float32),
                  cv2.INTER_LINEAR).astype(np.float64)
    v[~ok | on_grout(run, xs, ys)] = np.nan
    count = np.isfinite(v).sum(axis=1)
    lv = np.full(o.size, np.nan)
    seen = count >= 4
    lv[seen] = row_medians(v[seen], count[seen])
    return lv


def conclusive(run: ReadingState, px: float, py: float, dx: float, dy: float, grout: float,
               limit: float, beyond: tuple[float, float] | None = None) -> bool:
    """Whether an object whose straight edge ends at (px, py) (a unit vector (dx, dy) pointing
    on along its line) would have changed the grout's gray level ``grout`` by more than
    ``foreign.conclusive`` x ``limit`` had it gone on across the grout, from the levels across
    the edge's last 15 px (:func:`cross_profile`; the two sides' levels by :func:`side_level`,
    5..8 px off). Two kinds of object are ruled out:

    - one covering the grout with its own level (a cable, a box): no level seen beside the
      edge lies within that margin of the grout's; or the two sides agree within ``limit``
      and the edge bounds a ridge (the levels more than ``limit`` off the sides', the run of
      them that reaches the edge: :func:`at_edge`) whose every
      level differs from the grout's by that margin: the object there is the ridge (a mortar
      line, a cable), and the sides are the tile; or, when the edge is seen again beyond the
      band (``beyond``: the steps along its line, t from its end, where it is read there),
      every offset whose level lies near the grout's reads more than ``limit`` differently
      there: nothing of that level goes on along the line;
    - a shadow: the two sides agree within ``limit``, or the grout darkened by their ratio
      would change by more than the margin, or the levels within 4 px of the edge go beyond
      both sides' by more than ``limit`` (a ridge or a trough at the edge, a mortar line's: a
      shadow's edge goes monotonically from one side's level to the other's), or
      (``beyond``) the far side's two levels are not in the near side's ratio within
      ``limit``: a shadow edge darkens the tiles on both sides of the grout alike.

    Only what is seen counts (see :func:`cross_profile`); where one side is not seen beside
    the last 15 px (the edge's end at the border of the view), the levels are read beside
    its last 47 px; False when no level, or no level of a side, is seen."""
    o = np.arange(-8.0, 9.0)
    lv = cross_profile(run, px, py, dx, dy, -16.0, -2.0)
    seen = np.isfinite(lv)
    a, b = side_level(lv, seen, o), side_level(lv, seen, -o)
    if not (math.isfinite(a) and math.isfinite(b)):
        # one side out of the view there (the edge's end at the border): the edge's sides
        # over its last 48 px
        lv = cross_profile(run, px, py, dx, dy, -48.0, -2.0)
        seen = np.isfinite(lv)
        a, b = side_level(lv, seen, o), side_level(lv, seen, -o)
    need = run.st.foreign.conclusive * limit
    if not seen.any():
        return False
    if not (math.isfinite(a) and math.isfinite(b)):
        return False
    far: np.ndarray | None = None

    def far_profile() -> np.ndarray | None:
        # the levels beyond the band, read once and only when a test below needs them
        nonlocal far
        if far is None and beyond is not None:
            far = cross_profile(run, px, py, dx, dy, *beyond)
        return far

    if float(np.abs(lv[seen] - grout).min()) <= need:
        if abs(a - b) > limit:
            covered = True
        else:
            ridge = seen & (np.abs(lv - 0.5 * (a + b)) > limit)
            if at_edge(ridge).any():
                ridge = at_edge(ridge)  # the ridge the edge bounds, not another one beside
            covered = not (bool(ridge.any()) and float(np.abs(lv[ridge] - grout).min()) > need)
        if covered:
            past = far_profile()
            if past is None:
                return False
            g = seen & (np.abs(lv - grout) <= need) & np.isfinite(past)
            if not g.any() or float(np.abs(past[g] - lv[g]).min()) <= limit:
                return False
    if abs(a - b) <= limit or grout * abs(a - b) / max(a, b, 1e-9) > need:
        return True
    # a shadow's edge goes monotonically from one side's level to the other's (its penumbra):
    # levels beyond both sides by more than the limit (a ridge or a trough at the edge, a
    # mortar line's) are not a shadow's
    between = lv[seen & (np.abs(o) <= 4)]
    if between.size and (float(between.max()) > max(a, b) + limit
                         or float(between.min()) < min(a, b) - limit):
        return True
    past = far_profile()
    if past is None:
        return False
    fseen = np.isfinite(past)
    a2, b2 = side_level(past, fseen, o), side_level(past, fseen, -o)
    if not (math.isfinite(a2) and math.isfinite(b2)):
        return False
    # a shadow edge going on across the grout darkens the far tile by the same ratio
    return abs(a2 * b - b2 * a) / max(b, a, 1e-9) > limit


def at_edge(off: np.ndarray) -> np.ndarray:
    """The runs of consecutive True of ``off`` (one per offset -8..8 px across an edge) that
    reach the edge (offsets -1..1): the ridge the edge bounds; levels off the sides farther
    out, apart from it, belong to something else beside the edge (the next mortar line).
    :func:`conclusive` keeps every level off the sides when no run reaches the edge."""
    out = np.zeros_like(off)
    c = off.size // 2
    for i in (c - 1, c, c + 1):
        if not off[i] or out[i]:
            continue
        lo = i
        while lo > 0 and off[lo - 1]:
            lo -= 1
        hi = i
        while hi < off.size - 1 and off[hi + 1]:
            hi += 1
        out[lo : hi + 1] = True
    return out


def row_medians(v: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The median of the finite values of each row of ``v`` (``count`` of them, at least 1),
    as ``np.nanmedian(v, axis=1)`` computes it (the mean of the two middle values of an even
    count, halved after adding) without its masked-array overhead."""
    srt = np.sort(v, axis=1)  # NaN last
    hi = count // 2
    lo = np.where(count % 2 == 1, hi, hi - 1)
    rows = np.arange(v.shape[0])
    return (srt[rows, lo] + srt[rows, hi]) / 2.0


def side_level(lv: np.ndarray, seen: np.ndarray, o: np.ndarray) -> float:
    """The level of one side of an edge (gray levels; NaN when none is seen): the median of
    the levels ``lv`` seen (``seen``) at 5..8 px off (``o``, px, positive on that side), else
    (those lie on the grout or out of view) of those seen at 3..4 px off."""
    for side in (seen & (o >= 5), seen & (o >= 3)):
        if side.any():
            return float(np.median(lv[side]))
    return math.nan


def on_grout(run: ReadingState, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Which points (xs, ys) (px) lie on the grout the observation predicts: within half the
    grout's half-depth width + 2 px (its edges' blur) of a grout line of either family."""
    assert run.y is not None
    cx, cy = (run.w - 1) / 2.0, (run.h - 1) / 2.0
    reach = 0.5 * run.details["width"] + 2.0
    out = np.zeros(xs.shape, bool)
    for n, yk in zip(family_normals(run.y[2]), run.y[:2], strict=True):
        off = n[0] * (xs - cx) + n[1] * (ys - cy) + yk * run.ppm
        out |= np.abs(off - run.lp * np.rint(off / run.lp)) <= reach
    return out


