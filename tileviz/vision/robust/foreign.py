"""Foreign objects: long straight edges the predicted grout lines do not explain (a cable, a box
or shadow edge), and what kind of edge the longest one is."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.geometry import family_normals
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
      its line, extended from each end, runs mostly over pixels with no edge at the search's
      own thresholds (edges weaker than those are not searched at all) before the next band,
      or beyond it. A straight edge inside a tile (the mortar of a brick photograph, a
      plank's end) touches the grout's plateaus as any texture does; an object crossing a
      grout line (a cable, a box or shadow edge) shows on both sides of it.

    Assumed: an object whose straight edge ends inside a grout band without crossing it is
    not told from texture there."""
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

    near = cv2.dilate(run.edges, np.ones((3, 3), np.uint8))
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
            ends(run, near, px, py, sx * d[0], sx * d[1], band, offsets)
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
    :data:`NORMAL_TOLERANCE`: about 1 for the edge of one object (a cable, a box, a shadow),
    much less for a chance alignment of a texture's edges (grains, chips, a wavy grain), whose
    directions scatter."""
    assert run.edges is not None and run.dxy is not None
    dx, dy = run.dxy
    out = np.zeros(len(seg))
    cos_tol = math.cos(NORMAL_TOLERANCE)
    for i, (x1, y1, x2, y2) in enumerate(seg.tolist()):
        ln = math.hypot(x2 - x1, y2 - y1)
        if ln < 1.0:
            continue
        nx, ny = -(y2 - y1) / ln, (x2 - x1) / ln
        t = np.arange(0.0, ln + 0.5, 1.0) / ln
        xs = np.rint(x1 + t * (x2 - x1)).astype(np.intp)
        ys = np.rint(y1 + t * (y2 - y1)).astype(np.intp)
        good = np.zeros(t.size, bool)
        for ox in (-1, 0, 1):
            for oy in (-1, 0, 1):
                xx = np.clip(xs + ox, 0, run.w - 1)
                yy = np.clip(ys + oy, 0, run.h - 1)
                gx = dx[yy, xx].astype(np.float64)
                gy = dy[yy, xx].astype(np.float64)
                g = np.hypot(gx, gy)
                along = np.abs(gx * nx + gy * ny) >= cos_tol * g
                good |= (run.edges[yy, xx] > 0) & along & (g > 0)
        out[i] = float(good.mean())
    return out


TEXTURE_SHARE = 0.75
"""A straight edge with a smaller :func:`edge_share` is a chance alignment of texture edges."""
NORMAL_TOLERANCE = math.radians(25.0)
"""An edge pixel belongs to a straight edge when its gradient is this close to the edge's
normal (rad)."""


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
    from tileviz.vision.robust.profiles import Projection

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


def ends(run: RobustRun, near: np.ndarray, px: float, py: float, dx: float, dy: float,
         band: float, offsets: object) -> bool:
    """Whether the object of an edge ending at (px, py) stops short of the grout lines in
    direction (dx, dy), followed in 1 px steps: it stops before the next band (most of the
    steps to it land on no edge: ``near`` holds the edges dilated by 1 px), or it runs into a
    band but does not go on beyond it (most of the first 20 steps past the band land on no
    edge). An object crossing a grout line shows on both sides of it. True when the border of
    the view comes first; False when it comes fewer than 6 steps past a band."""

    def in_band(qx: float, qy: float) -> bool:
        return any(abs(math.remainder(o, run.lp)) < band
                   for o in offsets(qx, qy))  # type: ignore[operator]

    def inside(qx: float, qy: float) -> bool:
        return 0 <= round(qx) < run.w and 0 <= round(qy) < run.h

    def hit(qx: float, qy: float) -> int:
        return int(near[int(round(qy)), int(round(qx))] > 0)

    t, steps, hits = 1.0, 0, 0
    while inside(px + t * dx, py + t * dy) and not in_band(px + t * dx, py + t * dy):
        steps += 1
        hits += hit(px + t * dx, py + t * dy)
        t += 1.0
    if not inside(px + t * dx, py + t * dy):
        return True
    if steps >= 4 and hits <= 0.5 * steps:
        return True  # it ends inside the tile
    while inside(px + t * dx, py + t * dy) and in_band(px + t * dx, py + t * dy):
        t += 1.0
    steps, hits = 0, 0
    while (steps < 20 and inside(px + t * dx, py + t * dy)
           and not in_band(px + t * dx, py + t * dy)):
        steps += 1
        hits += hit(px + t * dx, py + t * dy)
        t += 1.0
    return steps >= 6 and hits < 0.5 * steps


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
