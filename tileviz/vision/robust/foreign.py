"""Foreign objects: long straight edges the predicted grout lines do not explain (a cable, a box
or shadow edge), and what kind of edge the longest one is."""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

from tileviz.vision.geometry import family_normals
from tileviz.vision.robust import foreign_kernel, kernel
from tileviz.vision.robust.lattice import clip_line
from tileviz.vision.robust.state import Fail, RobustRun

__all__ = ["classify_edge", "clear_of_lattice", "draw_lattice_mask", "foreign_edges"]


def foreign_edges(run: RobustRun) -> None:
    """Refuse when a long straight edge is not explained by the predicted grout lines."""
    assert run.y is not None and run.dxy is not None
    # Edges at least ``foreign_contrast`` of the grout's own contrast (in gray levels: a
    # texture's fine edges are not objects) and above the noise. Scharr answers 16 x a unit
    # step; its noise is about 15.4 sigma per component.
    dx, dy = run.dxy
    high = max(240.0, 6.0 * 15.4 * run.details["noise_sigma"],
               16.0 * run.st.foreign_contrast * run.details["depth"])
    run.edges = cv2.Canny(dx, dy, 0.5 * high, high, L2gradient=True)
    free = run.edges.copy()
    wmax = max(ln.width for fam in run.lines for ln in fam)
    thick = int(math.ceil(wmax + 2.0 * max(2.0, 0.5 * wmax) + 2.0))
    draw_lattice_mask(free, run.y, run.ppm, run.tile_size, thick)
    run.free_edges = free
    minlen = max(25.0, run.st.foreign_length * run.side)
    votes = int(0.5 * minlen)
    # a segment needs that many votes, at most one per edge pixel: with fewer free edge
    # pixels (a clean view: every edge lies on the grout) the search finds none
    if cv2.countNonZero(free) < votes:
        return
    seg = cv2.HoughLinesP(
        free, 1.0, math.pi / 180.0, votes, minLineLength=minlen, maxLineGap=3.0
    )
    if seg is None:
        return
    seg = np.asarray(seg, np.float64).reshape(-1, 4)
    clear = clear_of_lattice(run, seg)
    run.details["foreign_clear"] = float(clear.sum())
    seg = seg[~clear]
    if seg.size == 0:
        return
    run.foreign = seg
    run.details["foreign_segments"] = float(len(seg))
    raise Fail(classify_edge(run, seg))


def clear_of_lattice(run: RobustRun, seg: np.ndarray) -> np.ndarray:
    """Which straight edges (rows of ``seg``: x1, y1, x2, y2, px) are no foreign object that
    could have moved a measured grout line. Exempt:

    - a chance alignment of a texture's edges (grains, chips, a wavy grain): fewer than
      :data:`TEXTURE_SHARE` of its points lie on an edge pixel whose gradient is normal to it
      (:func:`edge_share`); the edge of one object has nearly all of them;
    - an edge along one line family (within :data:`PARALLEL`) whose whole line, extended
      across the view, stays between two measurement bands of that family (a dip's position
      reads its profile only within its band, :func:`measurement_band`), where that family's
      profile shows no dip a quarter as deep as the other family's grout (a missed grout
      line would, whatever the lines were taken for): the mortar of a brick photograph, a
      plank's edge, a cable or a shadow along the grout in the middle of a tile;
    - an edge whose object stops, on both sides, before or at the grout lines (:func:`ends`):
      its line, followed from each end, sees the edge on at most half the steps to the next
      band, or runs into the grout without changing the grout's gray level there
      (:func:`straddle`) and either does not go on beyond the band or would have changed that
      level had it crossed (:func:`conclusive`: what is seen beside the edge differs from the
      grout). A straight edge inside a tile (the mortar of a brick photograph, a plank's end)
      touches the grout's plateaus as any texture does, and its line often runs on along
      another tile's texture; an object crossing a grout line (a cable, a box or shadow edge)
      covers or darkens the grout where it crosses it.

    Assumed: an object whose straight edge ends inside a grout band without crossing it, or
    crosses the grout with the grout's own gray level, is not told from texture there
    (:func:`ends`)."""
    assert run.y is not None
    out = np.zeros(len(seg), bool)
    proj = run.projection
    if proj is None or not run.lines[0] or not run.lines[1] or run.edges is None:
        return out
    lp = run.lp
    band = measurement_band(run)
    ppm = run.ppm
    cx, cy = (run.w - 1) / 2.0, (run.h - 1) / 2.0
    normals = family_normals(run.y[2])
    shift = (run.y[0] * ppm, run.y[1] * ppm)

    def free_cell(a: float, b: float) -> bool:
        # offsets a, b (px, relative to the family's lattice lines) within one band-free cell
        lo = min(a, b) - math.floor(min(a, b) / lp) * lp
        return lo >= band and lo + abs(b - a) <= lp - band

    def offsets(px: float, py: float) -> tuple[float, float]:
        return tuple(n[0] * (px - cx) + n[1] * (py - cy) + sh
                     for n, sh in zip(normals, shift, strict=True))

    share = edge_share(run, seg)
    for i, (x1, y1, x2, y2) in enumerate(seg.tolist()):
        if share[i] < TEXTURE_SHARE:
            out[i] = True
            continue
        ln = max(math.hypot(x2 - x1, y2 - y1), 1e-9)
        m = (-(y2 - y1) / ln, (x2 - x1) / ln)
        e = clip_line(m, m[0] * (x1 - cx) + m[1] * (y1 - cy), run.w, run.h)
        if e is None:
            continue
        ea, eb = offsets(e[0], e[1]), offsets(e[2], e[3])
        span = max(math.hypot(e[2] - e[0], e[3] - e[1]), 1e-9)
        if any(abs(eb[k] - ea[k]) <= PARALLEL * span and free_cell(ea[k], eb[k])
               for k in range(2)) and not grout_like(run, proj, e):
            out[i] = True
            continue
        d = ((x2 - x1) / ln, (y2 - y1) / ln)
        out[i] = all(
            ends(run, px, py, sx * d[0], sx * d[1], band, normals, shift)
            for px, py, sx in ((x2, y2, 1.0), (x1, y1, -1.0))
        )
    return out


PARALLEL = 0.03
"""An edge runs along a line family when its direction is within this angle (rad) of it: it
crosses the other family's lines nearly at right angles, adding about the same to every
sample of their profiles (:func:`clear_of_lattice`)."""


def edge_share(run: RobustRun, seg: np.ndarray) -> np.ndarray:
    """For each straight edge (rows of ``seg``: x1, y1, x2, y2, px), the share of the points
    along it (1 px apart) within 1 px of an edge pixel whose gradient is normal to it within
    :data:`NORMAL_TOLERANCE` (:func:`oriented_hits`): about 1 for the edge of one object (a
    cable, a box, a shadow), much less for a chance alignment of a texture's edges (grains,
    chips, a wavy grain), whose directions scatter. Compiled
    (:func:`~tileviz.vision.robust.foreign_kernel.edge_shares`) when numba is installed, else
    :func:`edge_shares_numpy`: the same values."""
    assert run.edges is not None and run.dxy is not None
    shares = foreign_kernel.edge_shares if kernel.AVAILABLE else edge_shares_numpy
    return shares(run.dxy[0], run.dxy[1], run.edges, np.ascontiguousarray(seg, np.float64),
                  _COS_TOL)


def edge_shares_numpy(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, seg: np.ndarray,
                      cos_tol: float) -> np.ndarray:
    """:func:`edge_share` on the gradients ``dx``, ``dy`` and edge pixels ``edges`` (HxW),
    with the tolerance's cosine ``cos_tol``: the share of each edge's points (1 px apart)
    that :func:`oriented_points` sees with its normal; 0 for an edge under 1 px."""
    out = np.zeros(len(seg))
    for i, (x1, y1, x2, y2) in enumerate(seg[:, :4].tolist()):
        ln = math.hypot(x2 - x1, y2 - y1)
        if ln < 1.0:
            continue
        t = np.arange(0.0, ln + 0.5, 1.0) / ln
        xs = np.rint(x1 + t * (x2 - x1)).astype(np.intp)
        ys = np.rint(y1 + t * (y2 - y1)).astype(np.intp)
        hit = oriented_points(dx, dy, edges, xs, ys, -(y2 - y1) / ln, (x2 - x1) / ln, cos_tol)
        out[i] = float(hit.mean())
    return out


def oriented_hits(run: RobustRun, xs: np.ndarray, ys: np.ndarray, nx: float, ny: float
                  ) -> np.ndarray:
    """Whether each pixel (xs, ys) lies within 1 px (its 3 x 3 neighbourhood) of an edge pixel
    of ``run.edges`` whose gradient is within :data:`NORMAL_TOLERANCE` of the unit normal
    (nx, ny), of either sign: the points where a straight edge with that normal is seen."""
    assert run.edges is not None and run.dxy is not None
    return oriented_points(run.dxy[0], run.dxy[1], run.edges, xs, ys, nx, ny, _COS_TOL)


def oriented_points(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, xs: np.ndarray,
                    ys: np.ndarray, nx: float, ny: float, cos_tol: float) -> np.ndarray:
    """:func:`oriented_hits` on the gradients ``dx``, ``dy`` and edge pixels ``edges`` (HxW),
    with the tolerance's cosine ``cos_tol``."""
    h, w = edges.shape
    # the 3 x 3 neighbours of every pixel at once (rows: the 9 offsets), as flat indices
    xx = np.clip(xs[None, :] + _NX[:, None], 0, w - 1)
    yy = np.clip(ys[None, :] + _NY[:, None], 0, h - 1)
    flat = yy * w + xx
    gx = dx.ravel()[flat].astype(np.float64)
    gy = dy.ravel()[flat].astype(np.float64)
    g = np.hypot(gx, gy)
    along = np.abs(gx * nx + gy * ny) >= cos_tol * g
    return ((edges.ravel()[flat] > 0) & along & (g > 0)).any(axis=0)


_NX = np.array([-1, -1, -1, 0, 0, 0, 1, 1, 1], np.intp)
_NY = np.array([-1, 0, 1, -1, 0, 1, -1, 0, 1], np.intp)


TEXTURE_SHARE = 0.75
"""A straight edge with a smaller :func:`edge_share` is a chance alignment of texture edges."""
NORMAL_TOLERANCE = math.radians(25.0)
"""An edge pixel belongs to a straight edge when its gradient is this close to the edge's
normal (rad)."""
_COS_TOL = math.cos(NORMAL_TOLERANCE)


def measurement_band(run: RobustRun) -> float:
    """How far from a grout line (px) its measurement reads the image: a dip's position uses
    its profile out to 4 plateau samples beyond its window c +- (1.5 w + 1.5)
    (:func:`~tileviz.vision.robust.profiles.dips`, w its half-depth width), and never beyond
    the measurement window ``run.window``; 2 px more for the heading's last correction."""
    wmax = max(ln.width for fam in run.lines for ln in fam)
    return min(float(run.window), 1.5 * wmax + 1.5 + 5.0) + 2.0


def grout_like(run: RobustRun, proj: object, e: tuple[float, float, float, float]) -> bool:
    """Whether the profile of the warp family that the line ``e`` (endpoints, px) runs along
    dips there at least a quarter as deep as the other family's grout lines."""
    from tileviz.vision.robust.projection import Projection

    assert isinstance(proj, Projection)
    cx, cy = (run.w - 1) / 2.0, (run.h - 1) / 2.0
    x0, y0 = run.centre
    s = [(pn[0] * (e[0] - cx) + pn[1] * (e[1] - cy), pn[0] * (e[2] - cx) + pn[1] * (e[3] - cy))
         for pn in family_normals(proj.y3)]
    k = 0 if abs(s[0][1] - s[0][0]) <= abs(s[1][1] - s[1][0]) else 1
    centre = y0 if k == 0 else x0
    i0 = int(math.floor(centre - max(s[k]) + proj.pad)) - 3
    i1 = int(math.ceil(centre - min(s[k]) + proj.pad)) + 3
    dark = proj.dark[k, max(i0, 0) : max(i1 + 1, 0)]
    dark = dark[np.isfinite(dark)]
    grout = float(np.median([g.depth for g in run.lines[1 - k]]))
    return dark.size > 0 and float(dark.max()) >= 0.25 * grout


def ends(run: RobustRun, px: float, py: float, dx: float, dy: float, band: float,
         normals: tuple[tuple[float, float], tuple[float, float]],
         shift: tuple[float, float]) -> bool:
    """Whether the object of a straight edge ending at (px, py) stops short of the grout lines
    in direction (dx, dy) (a unit vector), followed in 1 px steps to the border of the view
    (``band``: :func:`measurement_band`; ``normals``, ``shift``: each family's unit normal and
    offset, px, so that its lines lie where ``n . (p - centre) + shift`` is a multiple of the
    tile period). A step *sees the edge* when it lies within 1 px of an edge pixel whose
    gradient is normal to the edge (:func:`oriented_hits`; a texture's edges across it do not
    count).

    - The border of the view comes before any band: True.
    - At least 4 steps lead to the next band and at most half of them see the edge: it ends
      inside the tile (True).
    - Where the line meets the grout's centre line, the grout's gray level beside the line
      (:func:`straddle`) tells: an object crossing the grout covers it on one side (a cable,
      a box) or darkens it (a shadow), so the level varies there by more than
      :data:`STRADDLE_SIGMAS` x the image noise + :data:`STRADDLE_LEVELS` and more than the
      grout varies by itself elsewhere on its line (:func:`grout_variation`; where that
      cannot be read, about the levels' straight trend, :func:`trend_range`) (False); a
      texture's edge stops at the grout and leaves it alike (True when both sides of the
      crossing are read and the edge is not seen beyond the band). Where the line crosses
      the grout at under :data:`STRADDLE_ONE_SIDED`, or one side only is read, the far side
      in view (at least 6 steps) without the edge is enough (True), as where the grout
      cannot be read.
    - Beyond the band, up to the next band (at least 6 steps in view), at least half the
      steps see the edge (the object may go on across the grout, or the line runs along
      another tile's texture), or only one side of the crossing is in view and the far side
      is not: True only when the object, had it crossed, would have changed the grout's level
      there (:func:`conclusive`), else False.
    - The line does not reach the grout's core in the view: False when the edge is seen
      beyond the band; else True when the band runs to the border of the view or the far
      side is in view (6 steps or more); else (it leaves the band within 6 steps of the
      border or of another band) the grout's core beside its pass through the band
      (:func:`pass_unchanged`) must not vary by more than that limit and be conclusive, as
      where a crossing is read on one side only. The grout cannot be read where the line
      meets it (within 0.05 rad of the grout, or the crossing out of the view): True when the
      far side is in view without the edge, else the grout's core beside the line's pass
      through the band decides in the same way (:func:`pass_unchanged`).

    Assumed: an object whose gray level matches the grout's where it crosses it (within
    :data:`CONCLUSIVE` x the straddle's limit when the edge is seen beyond the band or the
    far side is out of view; within that limit otherwise), or whose step darkens the tiles
    by less than that limit, is not told from texture at that end."""
    assert run.edges is not None and run.dxy is not None
    steps = foreign_kernel.end_steps if kernel.AVAILABLE else end_steps_numpy
    done, xs, ys, i0, i1, i2, far, k, dmin = steps(
        run.dxy[0], run.dxy[1], run.edges, px, py, dx, dy, band, normals[0][0], normals[0][1],
        normals[1][0], normals[1][1], shift[0], shift[1], run.lp, _COS_TOL)
    if done:
        return True  # the border comes first, or the edge ends inside the tile
    n2 = i2 - i1
    # the steps (t, px from the end) where the edge is read again beyond the band
    seen_beyond = (float(i1 + 1), float(min(i2, i1 + 16))) if far else None
    if dmin >= 0.5 * run.details["width"]:
        # the line does not reach the grout of this band in the view
        if far:
            return False  # seen beyond the band
        if i1 == xs.size or n2 >= 6:
            return True
        # it leaves the band within 6 steps of the border or of the next band: the grout
        # beside its pass through the band decides, as at a crossing seen on one side only
        return pass_unchanged(run, xs, ys, i0, i1, px, py, dx, dy, normals[k], shift[k])
    read = straddle(run, px, py, dx, dy, normals[k], shift[k])
    if read is None:
        if n2 >= 6 and not far:
            return True
        # the crossing cannot be read (the line meets the grout within STRADDLE_PARALLEL of
        # it, or where it lies out of view): the grout's core beside the line's whole pass
        # through the band decides, as where the line does not reach the core
        return pass_unchanged(run, xs, ys, i0, i1, px, py, dx, dy, normals[k], shift[k],
                              seen_beyond)
    core, both, own = read
    steep = both and abs(normals[k][0] * dx + normals[k][1] * dy) >= STRADDLE_ONE_SIDED
    if not far and n2 >= 6 and not steep:
        return True  # as where the grout cannot be read: the far side is in view, unseen
    limit = straddle_limit(run)
    allowed = max(limit, own) if math.isfinite(own) else limit
    vary = float(core.max() - core.min())
    if vary > allowed and not math.isfinite(own):
        # the grout's own variation is not read (its line in view is too short for stretches
        # as long as this one: a shallow crossing reads the grout over up to 9 / 0.05 px either
        # side): about the straight trend, along which the light's gradient changes the
        # level slowly; an object covering or shading the grout from the crossing on is a
        # jump the trend leaves whole
        vary = min(vary, trend_range(core))
    if vary > allowed:
        return False  # the grout's level changes where the line crosses it
    if both and not far:
        return True
    # seen beyond the band, or the grout read on one side only (the crossing at the border
    # of the view, the far side out of it): texture only when anything seen beside the
    # grout would have changed the grout's level there
    return conclusive(run, px, py, dx, dy, float(np.median(core)), limit, seen_beyond)


def end_steps_numpy(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, px: float, py: float,
                    ux: float, uy: float, band: float, n00: float, n01: float, n10: float,
                    n11: float, sh0: float, sh1: float, lp: float, cos_tol: float
                    ) -> tuple[int, np.ndarray, np.ndarray, int, int, int, bool, int, float]:
    """The steps of :func:`ends` from a straight edge's end (px, py) along the unit vector
    (ux, uy), 1 px apart, to the border of the view (``edges``: the edge pixels, HxW; ``dx``,
    ``dy``: the gradients), and where they meet the grout bands (half-width ``band``, px; the
    families' unit normals (n00, n01), (n10, n11) and offsets sh0, sh1, px, so that a line
    lies where ``n . (p - centre) + sh`` is a multiple of the period ``lp``, px).

    Returns (done, xs, ys, i0, i1, i2, far, k, dmin): ``done`` (1) when the border of the view
    comes before any band, or at least 4 steps lead to the first band and at most half of them
    see the edge (:func:`oriented_hits` with tolerance cosine ``cos_tol``); else the steps
    (xs, ys, pixels), the first step in a band ``i0``, the first after it out of the bands
    ``i1``, the first in a band again ``i2`` (the number of steps when none), whether at
    least 6 steps lie between and at least half of them see the edge (``far``), the family
    ``k`` whose lines come nearest in ``i0..i1`` and that distance ``dmin`` (px)."""
    h, w = edges.shape
    empty = np.zeros(0, np.intp)
    # the steps to the border: t = 1 .. tmax, inside [-0.5, W - 0.5) x [-0.5, H - 0.5)
    lim = []
    for p, d, size in ((px, ux, w), (py, uy, h)):
        if d > 1e-12:
            lim.append((size - 0.5 - p) / d)
        elif d < -1e-12:
            lim.append((-0.5 - p) / d)
    tmax = int(math.floor(min(lim) - 1e-9)) if lim else 0
    if tmax < 1:
        return 1, empty, empty, 0, 0, 0, False, 0, 0.0
    t = np.arange(1.0, tmax + 1.0)
    xs = np.rint(px + t * ux).astype(np.intp)
    ys = np.rint(py + t * uy).astype(np.intp)
    keep = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
    xs, ys = xs[keep], ys[keep]
    m = int(xs.size)
    if m == 0:
        return 1, empty, empty, 0, 0, 0, False, 0, 0.0
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    # distance of each step to the nearest line of each family (px), from the offsets
    dk = []
    for n0, n1, sh in ((n00, n01, sh0), (n10, n11, sh1)):
        o = n0 * (xs - cx) + n1 * (ys - cy) + sh
        dk.append(np.abs(o - lp * np.rint(o / lp)))
    inb = np.minimum(dk[0], dk[1]) < band
    i0 = int(np.argmax(inb)) if inb.any() else m
    if i0 == m:
        return 1, xs, ys, i0, m, m, False, 0, 0.0  # the border comes first
    hit = _oriented(dx, dy, edges, -uy, ux, cos_tol)
    if i0 >= 4 and int(hit(xs[:i0], ys[:i0]).sum()) <= 0.5 * i0:
        return 1, xs, ys, i0, m, m, False, 0, 0.0  # it ends inside the tile
    out = np.flatnonzero(~inb[i0:])
    i1 = i0 + int(out[0]) if out.size else m
    back = np.flatnonzero(inb[i1:])
    i2 = i1 + int(back[0]) if back.size else m
    n2 = i2 - i1
    far = n2 >= 6 and int(hit(xs[i1:i2], ys[i1:i2]).sum()) >= 0.5 * n2
    k = 0 if float(dk[0][i0:i1].min()) <= float(dk[1][i0:i1].min()) else 1
    return 0, xs, ys, i0, i1, i2, far, k, float(dk[k][i0:i1].min())


def _oriented(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, nx: float, ny: float,
              cos_tol: float) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """:func:`oriented_hits` on the given gradients and edge pixels, for the unit normal
    (nx, ny) (tolerance cosine ``cos_tol``)."""

    def hit(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return oriented_points(dx, dy, edges, xs, ys, nx, ny, cos_tol)

    return hit


def pass_unchanged(run: RobustRun, xs: np.ndarray, ys: np.ndarray, i0: int, i1: int,
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


STRADDLE_SIGMAS = 3.0
STRADDLE_LEVELS = 4.0
"""An edge crosses the grout when the grout's gray level differs on its two sides
(:func:`straddle`) by more than this many times the image's noise plus this many levels."""


def straddle(run: RobustRun, px: float, py: float, dx: float, dy: float,
             n: tuple[float, float], sh: float) -> tuple[np.ndarray, bool, float] | None:
    """The grout's gray levels where the line through (px, py) along (dx, dy) crosses the
    grout's centre line (the next line ahead of the family with unit normal ``n`` and offset
    ``sh``, px): the centre line's gray levels (bilinear) at 0..9 px from the line on both
    sides (at most 180 px along the grout), whose range the caller compares with the noise.
    An object crossing the grout covers it (a cable, a box) or darkens it (a shadow) near the
    line; a texture's edge that stops at the grout leaves it alike.

    Returns the samples (median of 3 neighbours), whether both sides were read (3 samples
    or more each; one side is enough when the line crosses the grout at
    :data:`STRADDLE_ONE_SIDED` or more) and the grout's own variation over as long a stretch
    elsewhere on its line (:func:`grout_variation`, gray levels, NaN when not read). None
    when the line runs within :data:`STRADDLE_PARALLEL` of the grout or neither side can be
    read."""
    cx, cy = (run.w - 1) / 2.0, (run.h - 1) / 2.0
    nd = n[0] * dx + n[1] * dy
    if abs(nd) < STRADDLE_PARALLEL:
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
    if not both and (max(sides) < 3 or abs(nd) < STRADDLE_ONE_SIDED):
        return None
    return gray_levels(run, xs[ok], ys[ok]), both, grout_variation(run, qx, qy, g, 1.0 / abs(nd))


def grout_variation(run: RobustRun, qx: float, qy: float, g: tuple[float, float],
                    step: float) -> float:
    """How much the grout's gray level varies by itself over a stretch as long as a straddle's
    (19 samples ``step`` px apart along the unit direction ``g``) elsewhere on the same grout
    centre line through the crossing (qx, qy): the largest range of the stretches in view that
    keep :data:`VARIATION_CLEAR` samples clear of the crossing's own stretch (an object's
    other edge lies within them), NaN when fewer than :data:`VARIATION_STRETCHES`. A thin
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
    ranges = foreign_kernel.stretch_range if kernel.AVAILABLE else stretch_range_numpy
    return float(ranges(lv, idx, u, VARIATION_CLEAR, VARIATION_STRETCHES))


def stretch_range_numpy(lv: np.ndarray, idx: np.ndarray, u: np.ndarray, clear: int,
                        stretches: int) -> float:
    """The largest range of 19 consecutive gray levels ``lv`` (at the samples ``idx[1:-1]``,
    indices into the positions ``u`` along a line, px, one interval in view, at least 19
    levels) among the stretches that keep ``clear`` samples clear of the crossing's own
    samples -9..9 about u = 0; NaN when fewer than ``stretches`` stretches are clear."""
    win = np.lib.stride_tricks.sliding_window_view(lv, 19)
    first = idx[1 : 1 + win.shape[0]]
    zero = int(np.argmin(np.abs(u)))
    lim = 9 + clear
    far = (first + 18 < zero - lim) | (first > zero + lim)
    if int(far.sum()) < stretches:
        return math.nan
    return float((win.max(axis=1) - win.min(axis=1))[far].max())


VARIATION_CLEAR = 19
VARIATION_STRETCHES = 10
"""The grout's own variation (:func:`grout_variation`) is read on at least 10 stretches of its
line, each at least 19 samples clear of the crossing's."""


STRADDLE_PARALLEL = 0.05
STRADDLE_ONE_SIDED = 0.15
"""The grout is read where a line crosses it at an angle (rad, sine) of at least
``STRADDLE_PARALLEL`` when both sides of the crossing are in view, ``STRADDLE_ONE_SIDED`` when
only one is (:func:`straddle`)."""


def trend_range(v: np.ndarray) -> float:
    """The range of the values ``v`` (1-D, at least 2, in order along a line, equally
    spaced) about their least-squares straight line (gray levels): a slow change of the
    light along the line leaves it small; a jump (an object's edge) stays nearly whole."""
    x = np.arange(v.size, dtype=np.float64)
    rest = v - np.polyval(np.polyfit(x, v, 1), x)
    return float(rest.max() - rest.min())


def alongside(run: RobustRun, xs: np.ndarray, ys: np.ndarray, n: tuple[float, float],
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


def gray_levels(run: RobustRun, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
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


def straddle_limit(run: RobustRun) -> float:
    """How much the grout's gray level may vary where a texture's edge meets it (gray levels):
    :data:`STRADDLE_SIGMAS` x the image noise + :data:`STRADDLE_LEVELS`."""
    return STRADDLE_SIGMAS * run.details["noise_sigma"] + STRADDLE_LEVELS


def cross_profile(run: RobustRun, px: float, py: float, dx: float, dy: float, t0: float,
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


def conclusive(run: RobustRun, px: float, py: float, dx: float, dy: float, grout: float,
               limit: float, beyond: tuple[float, float] | None = None) -> bool:
    """Whether an object whose straight edge ends at (px, py) (a unit vector (dx, dy) pointing
    on along its line) would have changed the grout's gray level ``grout`` by more than
    :data:`CONCLUSIVE` x ``limit`` had it gone on across the grout, from the levels across
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
    need = CONCLUSIVE * limit
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


def on_grout(run: RobustRun, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
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


CONCLUSIVE = 2.0
"""An edge seen beyond the grout is taken for texture only when the grout's level there
(:func:`straddle`) shows no crossing, and any object seen beside the grout would have changed
it by this many times the straddle's limit (:func:`conclusive`)."""


def classify_edge(run: RobustRun, seg: np.ndarray) -> str:
    """``step edge`` when the longest foreign segment separates two different levels (a box,
    a shadow), ``foreign line`` when it is a dark or bright ridge with the same level on
    both sides (a cable): the gray profile across it, median along it, from -16 to 16 px."""
    lengths = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    x1, y1, x2, y2 = seg[int(np.argmax(lengths))]
    ln = max(math.hypot(x2 - x1, y2 - y1), 1e-9)
    nx, ny = -(y2 - y1) / ln, (x2 - x1) / ln
    ts = np.linspace(0.1, 0.9, 9)
    offs = np.arange(-16.0, 17.0, 2.0)
    px = x1 + ts[None, :] * (x2 - x1) + offs[:, None] * nx
    py = y1 + ts[None, :] * (y2 - y1) + offs[:, None] * ny
    xs = np.clip(np.round(px), 0, run.w - 1).astype(int)
    ys = np.clip(np.round(py), 0, run.h - 1).astype(int)
    prof = np.median(run.gray[ys, xs].astype(np.float64), axis=1)
    a, b = prof[0], prof[-1]
    ridge = max(min(a, b) - prof.min(), prof.max() - max(a, b))
    return "step edge" if abs(a - b) > ridge else "foreign line"



def draw_lattice_mask(
    img: np.ndarray, y: tuple[float, float, float], ppm: float, tile_size: float, thick: int
) -> None:
    """Blacken (in place) bands of ``thick`` px around every grout line ``y`` predicts."""
    h, w = img.shape
    n1, n2 = family_normals(y[2])
    lp = tile_size * ppm
    reach = 0.5 * math.hypot(w, h) + thick
    for n, yk in ((n1, y[0]), (n2, y[1])):
        j0 = math.floor((-reach + yk * ppm) / lp)
        j1 = math.ceil((reach + yk * ppm) / lp)
        for j in range(j0, j1 + 1):
            # clipped to the image grown by ``thick`` on every side: a line just outside the
            # view still masks the part of its band inside it
            e = clip_line(n, j * lp - yk * ppm, w + 2 * thick, h + 2 * thick)
            if e is None:
                continue
            a = (int(round(e[0])) - thick, int(round(e[1])) - thick)
            b = (int(round(e[2])) - thick, int(round(e[3])) - thick)
            cv2.line(img, a, b, 0, thick)
