"""The magnified top-down inset: the localizer's set around the truth, drawn with OpenCV.

In the 3-D scene the boxes of a localized robot are about a centimetre wide and vanish at any
view that shows the robot. The inset draws one frame's sets at a scale that fits them: the
prediction (green), the contracted box or boxes (blue; several disjoint candidates when the set
has them), the heading interval as a wedge from the set's centre, the true pose (pink dot and
heading arrow), the grout lines' centre lines when any is in view (grey), and a scale bar in
centimetres. World frame: x east (right), y north (up), metres.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING

import cv2
import numpy as np

from tileviz.app.scene import COLOURS
from tileviz.types import Box

if TYPE_CHECKING:
    from viser import GuiApi

    from tileviz.runner import FrameRecord

__all__ = ["INSET_SIZE", "InsetView", "nice_length", "render_inset"]

INSET_SIZE = 360
"""Side of the inset image, pixels."""
MIN_HALF_SPAN = 0.005
"""The inset shows at least +-5 mm around its centre, metres."""
MARGIN = 0.18
"""Share of the half side left free around the farthest box."""
BACKGROUND = (246, 246, 242)
GROUT = (175, 175, 170)
TEXT = (40, 40, 40)


def nice_length(most: float) -> float:
    """The largest 1, 2 or 5 x 10^k not above ``most`` (> 0), in the same unit."""
    k = math.floor(math.log10(most))
    for m in (5.0, 2.0, 1.0):
        if m * 10.0**k <= most:
            return m * 10.0**k
    return 10.0 ** (k - 1) * 5.0


def _format_length(metres: float) -> str:
    cm = 100.0 * metres
    if cm >= 100.0:
        return f"{metres:g} m"
    if cm >= 1.0:
        return f"{cm:g} cm"
    return f"{10.0 * cm:g} mm"


class _Frame:
    """World (m) -> inset pixels: ``centre`` at the middle, ``scale`` px/m, y up."""

    def __init__(self, centre: tuple[float, float], scale: float, size: int) -> None:
        self.cx, self.cy = centre
        self.scale = scale
        self.half = size / 2.0

    def px(self, x: float, y: float) -> tuple[int, int]:
        u = self.half + (x - self.cx) * self.scale
        v = self.half - (y - self.cy) * self.scale
        return (int(round(min(max(u, -1e5), 1e5))), int(round(min(max(v, -1e5), 1e5))))


def _boxes(boxes: Iterable[Box]) -> list[Box]:
    return [b for b in boxes if all(math.isfinite(v) for v in (b.x_lo, b.x_hi, b.y_lo, b.y_hi))]


def _draw_boxes(img: np.ndarray, frame: _Frame, boxes: list[Box], colour: tuple[int, int, int],
                alpha: float) -> None:
    """Translucent fills, then outlines; a box drawn at least 3 px wide so a tiny one shows."""
    fill = img.copy()
    corners = []
    for b in boxes:
        (u0, v0), (u1, v1) = frame.px(b.x_lo, b.y_hi), frame.px(b.x_hi, b.y_lo)
        if u1 - u0 < 3:
            u0, u1 = (u0 + u1) // 2 - 1, (u0 + u1) // 2 + 1
        if v1 - v0 < 3:
            v0, v1 = (v0 + v1) // 2 - 1, (v0 + v1) // 2 + 1
        corners.append(((u0, v0), (u1, v1)))
        cv2.rectangle(fill, (u0, v0), (u1, v1), colour, thickness=-1)
    cv2.addWeighted(fill, alpha, img, 1.0 - alpha, 0.0, dst=img)
    for p0, p1 in corners:
        cv2.rectangle(img, p0, p1, colour, thickness=2, lineType=cv2.LINE_AA)


def render_inset(rec: FrameRecord, tile_size: float, size: int = INSET_SIZE) -> np.ndarray:
    """The inset of frame record ``rec`` (``tile_size``: L, m, for the grout lines) as a
    ``size`` x ``size`` x 3 uint8 RGB image, centred on the truth (or, without one, on the set),
    scaled so every box of the prediction and of the contracted set fits."""
    img = np.empty((size, size, 3), np.uint8)
    img[:] = BACKGROUND
    predicted, updated = _boxes(rec.predicted.boxes), _boxes(rec.updated.boxes)
    truth = rec.truth
    hull = rec.updated.hull() or rec.predicted.hull()
    if truth is not None:
        centre = (truth.x, truth.y)
    elif hull is not None and math.isfinite(hull.x_lo + hull.x_hi + hull.y_lo + hull.y_hi):
        centre = ((hull.x_lo + hull.x_hi) / 2.0, (hull.y_lo + hull.y_hi) / 2.0)
    else:
        cv2.putText(img, "no set to show", (12, size // 2), cv2.FONT_HERSHEY_SIMPLEX, 0.6, TEXT,
                    1, cv2.LINE_AA)
        return img
    half = MIN_HALF_SPAN
    for b in predicted + updated:
        half = max(half, abs(b.x_lo - centre[0]), abs(b.x_hi - centre[0]),
                   abs(b.y_lo - centre[1]), abs(b.y_hi - centre[1]))
    half = min(half, 1e4)
    frame = _Frame(centre, (size / 2.0) * (1.0 - MARGIN) / half, size)
    span = size / frame.scale  # metres across the image
    # grout line centres x = kL, y = kL (when a few are in view)
    lo_x, lo_y = centre[0] - span / 2, centre[1] - span / 2
    if span / tile_size < 40:
        for k in range(math.floor(lo_x / tile_size), math.ceil((lo_x + span) / tile_size) + 1):
            u = frame.px(k * tile_size, 0.0)[0]
            cv2.line(img, (u, 0), (u, size), GROUT, 1, cv2.LINE_AA)
        for k in range(math.floor(lo_y / tile_size), math.ceil((lo_y + span) / tile_size) + 1):
            v = frame.px(0.0, k * tile_size)[1]
            cv2.line(img, (0, v), (size, v), GROUT, 1, cv2.LINE_AA)
    _draw_boxes(img, frame, predicted, COLOURS["prediction"], 0.22)
    _draw_boxes(img, frame, updated, COLOURS["boxes"], 0.40)
    r = 0.42 * size
    if hull is not None and rec.status != "lost" and math.isfinite(hull.t_lo + hull.t_hi):
        # the heading interval: a wedge from the set's centre
        ox, oy = (hull.x_lo + hull.x_hi) / 2.0, (hull.y_lo + hull.y_hi) / 2.0
        o = frame.px(ox, oy)
        t_lo, t_hi = hull.t_lo, hull.t_hi
        if t_hi - t_lo >= 2.0 * math.pi:
            t_lo, t_hi = 0.0, 2.0 * math.pi
        arc = np.linspace(t_lo, t_hi, 24)
        pts = np.array([o] + [(o[0] + r * math.cos(a), o[1] - r * math.sin(a)) for a in arc],
                       np.int32)
        wedge = img.copy()
        cv2.fillPoly(wedge, [pts], COLOURS["boxes"], cv2.LINE_AA)
        cv2.addWeighted(wedge, 0.18, img, 0.82, 0.0, dst=img)
        for a in (t_lo, t_hi):
            end = (int(o[0] + r * math.cos(a)), int(o[1] - r * math.sin(a)))
            cv2.line(img, o, end, COLOURS["boxes"], 1, cv2.LINE_AA)
    if truth is not None:
        p = frame.px(truth.x, truth.y)
        tip = (int(p[0] + 0.9 * r * math.cos(truth.theta)),
               int(p[1] - 0.9 * r * math.sin(truth.theta)))
        cv2.arrowedLine(img, p, tip, COLOURS["truth"], 2, cv2.LINE_AA, tipLength=0.08)
        cv2.circle(img, p, 5, COLOURS["truth"], -1, cv2.LINE_AA)
        cv2.circle(img, p, 5, (255, 255, 255), 1, cv2.LINE_AA)
    # scale bar, bottom left
    bar = nice_length(0.3 * span)
    n = int(round(bar * frame.scale))
    x0, y0 = 14, size - 16
    cv2.line(img, (x0, y0), (x0 + n, y0), TEXT, 2)
    for u in (x0, x0 + n):
        cv2.line(img, (u, y0 - 5), (u, y0 + 5), TEXT, 2)
    cv2.putText(img, _format_length(bar), (x0 + n + 8, y0 + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                TEXT, 1, cv2.LINE_AA)
    label = f"{len(updated)} box{'es' if len(updated) != 1 else ''}, {rec.status}"
    cv2.putText(img, label, (10, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, TEXT, 1, cv2.LINE_AA)
    return img


class InsetView:
    """The inset as a GUI image (made in the caller's current GUI container; ``gui``: a viser
    ``GuiApi``)."""

    def __init__(self, gui: GuiApi, size: int = INSET_SIZE) -> None:
        blank = np.full((size, size, 3), BACKGROUND, np.uint8)
        self.size = size
        self.handle = gui.add_image(blank, label="the set around the truth, magnified "
                                    "(green prediction, blue set, pink truth)", format="png")
        self._key: object = None

    def show(self, rec: FrameRecord, tile_size: float) -> None:
        """Draw ``rec`` (nothing is sent when that frame is already shown)."""
        key = (rec.index, rec.t, id(rec))
        if key == self._key:
            return
        self.handle.image = render_inset(rec, tile_size, self.size)
        self._key = key
