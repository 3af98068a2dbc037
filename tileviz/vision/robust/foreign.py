"""Foreign objects: long straight edges the predicted grout lines do not explain (a cable, a box
or shadow edge), and what kind of edge the longest one is. The readings of the grout's gray
levels where such an edge meets a grout line (:func:`straddle`, :func:`conclusive`,
:func:`pass_unchanged`, :func:`grout_variation`, :func:`trend_range`) are in
:mod:`~tileviz.vision.robust.grout_levels`."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.geometry import family_normals
from tileviz.vision.robust import checks, foreign_kernel
from tileviz.vision.robust.grout_levels import (
    conclusive,
    pass_unchanged,
    straddle,
    straddle_limit,
    trend_range,
)
from tileviz.vision.robust.lattice import clip_line
from tileviz.vision.robust.state import ReadingState

__all__ = ["classify_edge", "clear_of_lattice", "draw_lattice_mask", "foreign_edges"]


def foreign_edges(run: ReadingState) -> None:
    """Refuse when a long straight edge is not explained by the predicted grout lines (check
    ``foreign_edge``: ``step edge`` or ``foreign line`` by :func:`classify_edge`)."""
    assert run.y is not None and run.dxy is not None
    # Edges at least ``foreign.contrast`` of the grout's own contrast (in gray levels: a
    # texture's fine edges are not objects) and above the noise.
    st = run.st.foreign
    dx, dy = run.dxy
    high = max(st.min_edge, st.edge_noise * SCHARR_NOISE * run.noise,
               SCHARR_STEP * st.contrast * run.details["depth"])
    run.edges = cv2.Canny(dx, dy, st.canny_low * high, high, L2gradient=True)
    free = run.edges.copy()
    wmax = max(ln.width for fam in run.lines for ln in fam)
    # each line may lie the declared tolerance off the ideal lattice the mask is drawn on
    thick = int(math.ceil(wmax + 2.0 * max(2.0, 0.5 * wmax) + 2.0 + 2.0 * run.tol_px))
    draw_lattice_mask(free, run.y, run.ppm, run.tile_size, thick)
    run.free_edges = free
    minlen = max(st.min_length, st.length * run.side)
    votes = int(st.vote_share * minlen)
    seg = straight_edges(free, votes, minlen, st.max_gap)
    if seg is None:
        seg = _NO_EDGES
    else:
        clear = clear_of_lattice(run, seg)
        run.details["foreign_clear"] = float(clear.sum())
        seg = seg[~clear]
    if seg.size:
        run.foreign = seg
        run.details["foreign_segments"] = float(len(seg))
    run.record.require(checks.FOREIGN_EDGE, run, len(seg),
                       reason=classify_edge(run, seg) if seg.size else None)


def straight_edges(free: np.ndarray, votes: int, minlen: float, gap: float
                   ) -> np.ndarray | None:
    """The straight edges (rows: x1, y1, x2, y2, px) of the edge pixels ``free`` (HxW uint8)
    that a probabilistic Hough transform finds with ``votes`` votes, at least ``minlen`` px
    long, bridging gaps up to ``gap`` px; None when it is not run (too few edge pixels for the
    votes) or finds none."""
    # a segment needs that many votes, at most one per edge pixel: with fewer free edge
    # pixels (a clean view: every edge lies on the grout) the search finds none
    if cv2.countNonZero(free) < votes:
        return None
    seg = cv2.HoughLinesP(free, 1.0, math.pi / 180.0, votes, minLineLength=minlen,
                          maxLineGap=gap)
    return None if seg is None else np.asarray(seg, np.float64).reshape(-1, 4)


_NO_EDGES = np.zeros((0, 4))


def clear_of_lattice(run: ReadingState, seg: np.ndarray) -> np.ndarray:
    """Which straight edges (rows of ``seg``: x1, y1, x2, y2, px) are no foreign object that
    could have moved a measured grout line. Exempt:

    - a chance alignment of a texture's edges (grains, chips, a wavy grain): fewer than
      ``foreign.texture_share`` of its points lie on an edge pixel whose gradient is normal to it
      (:func:`edge_share`); the edge of one object has nearly all of them;
    - an edge along one line family (within ``foreign.parallel``) whose whole line, extended across
      the view, stays between two measurement bands of that family (a dip's position reads its
      profile only within its band, :func:`measurement_band`), where that family's profile shows no
      dip ``foreign.grout_like`` as deep as the other family's grout (a missed grout line would,
      whatever the lines were taken for): the mortar of a brick photograph, a plank's edge, a cable
      or a shadow along the grout in the middle of a tile;
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
        (a0, a1), (b0, b1) = normals
        return (a0 * (px - cx) + a1 * (py - cy) + shift[0],
                b0 * (px - cx) + b1 * (py - cy) + shift[1])

    st = run.st.foreign
    share = edge_share(run, seg)
    for i, (x1, y1, x2, y2) in enumerate(seg.tolist()):
        if share[i] < st.texture_share:
            out[i] = True
            continue
        ln = max(math.hypot(x2 - x1, y2 - y1), 1e-9)
        m = (-(y2 - y1) / ln, (x2 - x1) / ln)
        e = clip_line(m, m[0] * (x1 - cx) + m[1] * (y1 - cy), run.w, run.h)
        if e is None:
            continue
        ea, eb = offsets(e[0], e[1]), offsets(e[2], e[3])
        span = max(math.hypot(e[2] - e[0], e[3] - e[1]), 1e-9)
        if any(abs(eb[k] - ea[k]) <= st.parallel * span and free_cell(ea[k], eb[k])
               for k in range(2)) and not grout_like(run, proj, e):
            out[i] = True
            continue
        d = ((x2 - x1) / ln, (y2 - y1) / ln)
        out[i] = all(
            ends(run, px, py, sx * d[0], sx * d[1], band, normals, shift)
            for px, py, sx in ((x2, y2, 1.0), (x1, y1, -1.0))
        )
    return out


def edge_share(run: ReadingState, seg: np.ndarray) -> np.ndarray:
    """For each straight edge (rows of ``seg``: x1, y1, x2, y2, px), the share of the points
    along it (1 px apart) within 1 px of an edge pixel whose gradient is normal to it within
    ``foreign.normal_tolerance``, of either sign: about 1 for the edge of one object (a cable, a
    box, a shadow), much less for a chance alignment of a texture's edges (grains, chips, a
    wavy grain), whose directions scatter (compiled:
    :func:`~tileviz.vision.robust.foreign_kernel.edge_shares`)."""
    assert run.edges is not None and run.dxy is not None
    return foreign_kernel.edge_shares(run.dxy[0], run.dxy[1], run.edges,
                                      np.ascontiguousarray(seg, np.float64),
                                      math.cos(run.st.foreign.normal_tolerance))


SCHARR_STEP = 16.0
"""Scharr's answer to a unit step of gray levels (its gain)."""
SCHARR_NOISE = 15.4
"""Scharr's noise per gray level of pixel noise std, per component."""


def measurement_band(run: ReadingState) -> float:
    """How far from a grout line (px) its measurement reads the image: a dip's position uses
    its profile out to 4 plateau samples beyond its window c +- (1.5 w + 1.5)
    (:func:`~tileviz.vision.robust.profiles.dips`, w its half-depth width), and never beyond
    the widest measurement window (``run.window_of``); 2 px more for the heading's last
    correction."""
    wmax = max(ln.width for fam in run.lines for ln in fam)
    return min(float(max(run.window_of(0), run.window_of(1))), 1.5 * wmax + 1.5 + 5.0) + 2.0


def grout_like(run: ReadingState, proj: object, e: tuple[float, float, float, float]) -> bool:
    """Whether the profile of the warp family that the line ``e`` (endpoints, px) runs along
    dips there at least ``foreign.grout_like`` as deep as the other family's grout lines."""
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
    return dark.size > 0 and float(dark.max()) >= run.st.foreign.grout_like * grout


def ends(run: ReadingState, px: float, py: float, dx: float, dy: float, band: float,
         normals: tuple[tuple[float, float], tuple[float, float]],
         shift: tuple[float, float]) -> bool:
    """Whether the object of a straight edge ending at (px, py) stops short of the grout lines
    in direction (dx, dy) (a unit vector), followed in 1 px steps to the border of the view
    (``band``: :func:`measurement_band`; ``normals``, ``shift``: each family's unit normal and
    offset, px, so that its lines lie where ``n . (p - centre) + shift`` is a multiple of the
    tile period). A step *sees the edge* when it lies within 1 px of an edge pixel whose
    gradient is normal to the edge within ``foreign.normal_tolerance`` (a texture's edges across
    it do not count; compiled: :func:`~tileviz.vision.robust.foreign_kernel.end_steps`).

    - The border of the view comes before any band: True.
    - At least ``foreign.inside_steps`` steps lead to the next band and at most
      ``foreign.seen_share`` of them see the edge: it ends inside the tile (True).
    - Where the line meets the grout's centre line, the grout's gray level beside the line
      (:func:`straddle`) tells: an object crossing the grout covers it on one side (a cable,
      a box) or darkens it (a shadow), so the level varies there by more than
      ``foreign.straddle_sigmas`` x the image noise + ``straddle_levels`` and more than the
      grout varies by itself elsewhere on its line (:func:`grout_variation`; where that
      cannot be read, about the levels' straight trend, :func:`trend_range`) (False); a
      texture's edge stops at the grout and leaves it alike (True when both sides of the
      crossing are read and the edge is not seen beyond the band). Where the line crosses
      the grout at under ``foreign.straddle_one_sided``, or one side only is read, the far side
      in view (at least ``foreign.far_steps`` steps) without the edge is enough (True), as
      where the grout cannot be read.
    - Beyond the band, up to the next band (at least ``far_steps`` steps in view), at least
      ``seen_share`` of the steps see the edge (the object may go on across the grout, or the line
      runs along another tile's texture), or only one side of the crossing is in view and the far
      side is not: True only when the object, had it crossed, would have changed the grout's level
      there (:func:`conclusive`), else False.
    - The line does not reach the grout's core in the view: False when the edge is seen beyond the
      band; else True when the band runs to the border of the view or the far side is in view
      (``far_steps`` steps or more); else (it leaves the band within ``far_steps`` steps of the
      border or of another band) the grout's core beside its pass through the band
      (:func:`pass_unchanged`) must not vary by more than that limit and be conclusive, as where a
      crossing is read on one side only. The grout cannot be read where the line meets it (within
      ``foreign.straddle_parallel`` of the grout, or the crossing out of the view): True when the
      far side is in view without the edge, else the grout's core beside the line's pass through the
      band decides in the same way (:func:`pass_unchanged`).

    Assumed: an object whose gray level matches the grout's where it crosses it (within
    ``foreign.conclusive`` x the straddle's limit when the edge is seen beyond the band or the
    far side is out of view; within that limit otherwise), or whose step darkens the tiles
    by less than that limit, is not told from texture at that end."""
    assert run.edges is not None and run.dxy is not None
    st = run.st.foreign
    done, xs, ys, i0, i1, i2, far, k, dmin = foreign_kernel.end_steps(
        run.dxy[0], run.dxy[1], run.edges, px, py, dx, dy, band, normals[0][0], normals[0][1],
        normals[1][0], normals[1][1], shift[0], shift[1], run.lp,
        math.cos(st.normal_tolerance), st.inside_steps, st.far_steps, st.seen_share)
    if done:
        return True  # the border comes first, or the edge ends inside the tile
    n2 = i2 - i1
    # the steps (t, px from the end) where the edge is read again beyond the band
    seen_beyond = (float(i1 + 1), float(min(i2, i1 + 16))) if far else None
    if dmin >= 0.5 * run.details["width"]:
        # the line does not reach the grout of this band in the view
        if far:
            return False  # seen beyond the band
        if i1 == xs.size or n2 >= st.far_steps:
            return True
        # it leaves the band within far_steps steps of the border or of the next band: the grout
        # beside its pass through the band decides, as at a crossing seen on one side only
        return pass_unchanged(run, xs, ys, i0, i1, px, py, dx, dy, normals[k], shift[k])
    read = straddle(run, px, py, dx, dy, normals[k], shift[k])
    if read is None:
        if n2 >= st.far_steps and not far:
            return True
        # the crossing cannot be read (the line meets the grout within straddle_parallel of
        # it, or where it lies out of view): the grout's core beside the line's whole pass
        # through the band decides, as where the line does not reach the core
        return pass_unchanged(run, xs, ys, i0, i1, px, py, dx, dy, normals[k], shift[k],
                              seen_beyond)
    core, both, own = read
    steep = both and abs(normals[k][0] * dx + normals[k][1] * dy) >= st.straddle_one_sided
    if not far and n2 >= st.far_steps and not steep:
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


def classify_edge(run: ReadingState, seg: np.ndarray) -> str:
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
