"""Foreign objects: long straight edges the predicted grout lines do not explain (a cable, a box
or shadow edge), and what kind of edge the longest one is."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.geometry import family_normals
from tileviz.vision.robust.lattice import clip_line
from tileviz.vision.robust.state import Fail, RobustRun

__all__ = ["classify_edge", "draw_lattice_mask", "foreign_edges"]


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
    seg = cv2.HoughLinesP(
        free, 1.0, math.pi / 180.0, int(0.5 * minlen), minLineLength=minlen, maxLineGap=3.0
    )
    if seg is None:
        return
    seg = np.asarray(seg, np.float64).reshape(-1, 4)
    run.foreign = seg
    run.details["foreign_segments"] = float(len(seg))
    raise Fail(classify_edge(run, seg))


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
