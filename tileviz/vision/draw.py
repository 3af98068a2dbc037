"""Stage images for display (report Fig 4.2 and 4.3): every one HxWx3 uint8 RGB."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.geometry import family_normals

__all__ = [
    "BAG_COLOURS",
    "disambiguation_plot",
    "draw_lattice",
    "draw_offsets",
    "draw_segments",
    "to_rgb",
]

BAG_COLOURS: dict[int, tuple[int, int, int]] = {
    0: (230, 40, 40),  # rejected: red
    1: (40, 200, 60),  # horizontal bag (y1): green
    2: (40, 110, 240),  # vertical bag (y2): blue
}
"""RGB colour of each bag in the overlays."""


def to_rgb(image: np.ndarray) -> np.ndarray:
    """A gray (HxW) or colour (HxWx3) uint8 image as a new HxWx3 uint8 RGB image."""
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2RGB)
    return np.ascontiguousarray(image[..., :3]).copy()


def draw_segments(
    base: np.ndarray, segments: np.ndarray, bags: np.ndarray | None = None, thickness: int = 2
) -> np.ndarray:
    """``base`` (HxWx3 uint8, drawn on in place and returned) with each segment in its bag's
    colour (all yellow when ``bags`` is None); endpoints are pixel (col, row)."""
    for i, (x1, y1, x2, y2) in enumerate(np.asarray(segments, dtype=np.float64)):
        colour = (250, 210, 30) if bags is None else BAG_COLOURS.get(int(bags[i]), (255, 0, 255))
        cv2.line(
            base,
            (int(round(x1)), int(round(y1))),
            (int(round(x2)), int(round(y2))),
            colour,
            thickness,
            cv2.LINE_AA,
        )
    return base


def draw_offsets(
    base: np.ndarray,
    bags: np.ndarray,
    offsets: np.ndarray,
    y3: float | None,
    *,
    ppm: float,
) -> np.ndarray:
    """Report Fig 4.1, corrected: from the image centre, each bagged line's signed offset along
    its family's normal (the arrow ends on the line), in the bag's colour; in place, returned.
    Offsets in metres (``VisionResult.offsets``)."""
    h, w = base.shape[:2]
    c = ((w - 1) / 2.0, (h - 1) / 2.0)
    if y3 is not None:
        normals = family_normals(y3)
        for bag, off in zip(np.asarray(bags), np.asarray(offsets, dtype=np.float64), strict=True):
            if int(bag) not in (1, 2) or not math.isfinite(off):
                continue
            n = normals[int(bag) - 1]
            end = (c[0] + off * ppm * n[0], c[1] + off * ppm * n[1])
            cv2.arrowedLine(base, (int(round(c[0])), int(round(c[1]))),
                            (int(round(end[0])), int(round(end[1]))), BAG_COLOURS[int(bag)], 1,
                            cv2.LINE_AA, tipLength=0.08)
    cv2.drawMarker(base, (int(round(c[0])), int(round(c[1]))), (255, 255, 255),
                   cv2.MARKER_CROSS, 12, 1)
    return base


def draw_lattice(
    base: np.ndarray,
    y: tuple[float, float, float],
    *,
    ppm: float,
    tile_size: float,
    thickness: int = 1,
) -> np.ndarray:
    """``base`` with the grout line centres an observation y predicts (green: family 1, blue:
    family 2) and a cross at the image centre; in place, returned."""
    h, w = base.shape[:2]
    cxp, cyp = (w - 1) / 2.0, (h - 1) / 2.0
    n1, n2 = family_normals(y[2])
    lp = tile_size * ppm
    reach = math.hypot(w, h)
    for n, yk, bag in ((n1, y[0], 1), (n2, y[1], 2)):
        # lines where n . (p - centre) = (j L - y_k) ppm
        t = (-n[1], n[0])
        j0 = math.floor((-reach + yk * ppm) / lp)
        j1 = math.ceil((reach + yk * ppm) / lp)
        for j in range(j0, j1 + 1):
            s = j * lp - yk * ppm
            px, py = cxp + s * n[0], cyp + s * n[1]
            a = (int(round(px - reach * t[0])), int(round(py - reach * t[1])))
            b = (int(round(px + reach * t[0])), int(round(py + reach * t[1])))
            cv2.line(base, a, b, BAG_COLOURS[bag], thickness, cv2.LINE_AA)
    c = (int(round(cxp)), int(round(cyp)))
    cv2.drawMarker(base, c, (255, 255, 255), cv2.MARKER_CROSS, 12, 1)
    return base


def disambiguation_plot(
    points: np.ndarray,
    bags: np.ndarray,
    median: tuple[float, float] | None,
    *,
    size: int = 240,
    radius: float | None = None,
) -> np.ndarray:
    """Report Fig 4.3 (b-d): the (cos 4a, sin 4a) points on the unit circle coloured by bag, the
    median as a white cross and the L1 acceptance diamond of ``radius`` around it. Square
    ``size`` x ``size`` HxWx3 uint8."""
    img = np.full((size, size, 3), 24, np.uint8)
    c = (size - 1) / 2.0
    r = 0.42 * size

    def px(u: float, v: float) -> tuple[int, int]:
        return (int(round(c + r * u)), int(round(c - r * v)))  # sin 4a up

    cv2.circle(img, px(0.0, 0.0), int(round(r)), (90, 90, 90), 1, cv2.LINE_AA)
    cv2.line(img, px(-1.1, 0.0), px(1.1, 0.0), (60, 60, 60), 1)
    cv2.line(img, px(0.0, -1.1), px(0.0, 1.1), (60, 60, 60), 1)
    if median is not None and radius is not None:
        mu, mv = median
        diamond = [px(mu + radius, mv), px(mu, mv + radius), px(mu - radius, mv),
                   px(mu, mv - radius)]
        cv2.polylines(img, [np.array(diamond, np.int32)], True, (200, 200, 80), 1, cv2.LINE_AA)
    for (u, v), bag in zip(np.asarray(points, dtype=np.float64), bags, strict=False):
        cv2.circle(img, px(u, v), 3, BAG_COLOURS.get(int(bag), (255, 0, 255)), -1, cv2.LINE_AA)
    if median is not None:
        cv2.drawMarker(img, px(*median), (255, 255, 255), cv2.MARKER_CROSS, 14, 2)
    return img
