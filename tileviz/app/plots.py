"""Plots (viser's uPlot): how far each view is from the true pose over its declared bound (the
readable form of report Fig 6.3's residuals: the branch that fits, per coordinate), the widths of
the localizer's box and the error of its centre, over the frames up to the one shown. Titles and
series labels are in plain words; the page's help ("How to read this page") gives the report's
figure and table numbers.

The x axis is the simulated time in seconds (``scales={"x": {"time": False}}``: uPlot would
otherwise print dates). Frames without a value (no observation, no truth) are left out of the
series that need it rather than sent as NaN.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from viser.uplot import Axis, Scale, Series

from tileviz.app.history import METRIC_NAMES

if TYPE_CHECKING:
    from viser import GuiApi

__all__ = ["Plots"]

_COL = {name: i for i, name in enumerate(METRIC_NAMES)}
VIEW_LABELS = ("x error / bound", "y error / bound", "heading error / bound", "the bound")
"""Legend of the view plot: each view's error from the true pose (``FrameRecord.view_error``,
the tile and heading branch that fits best) over the bound the view declared, per coordinate,
and the bound itself (1)."""
_VIEW_COLOURS = ("#e6194b", "#3cb44b", "#4363d8", "#888888")
TITLES = {
    "residuals": "Is the view within its bound of the true pose? (at or below 1 = yes)",
    "widths": "Size of the set",
    "error": "Distance from the set's centre to the truth",
    "mcl": "Monte Carlo Localization baseline",
}
PADDING = (18, 14, 0, 0)
"""Room (top, right, bottom, left px) around each plot so its top tick label is not cut."""


def _series(label: str, stroke: str, width: float = 1.5) -> Series:
    return Series(label=label, stroke=stroke, width=width)


def _xscale() -> dict[str, Scale]:
    return {"x": Scale(time=False)}


def _axes(ylabel: str) -> tuple[Axis, Axis]:
    return (Axis(label="t (s)"), Axis(label=ylabel))


class Plots:
    """uPlot charts made in the caller's current GUI container (``gui``: a ``GuiApi``): the
    residuals, the box widths, the centre error, and the MCL baseline's error (shown while it
    runs)."""

    def __init__(self, gui: GuiApi, *, height: int = 190) -> None:
        x = np.zeros(2)
        zeros = np.zeros(2)
        self.residuals = gui.add_uplot(
            (x, *([zeros] * 4)),
            (_series("t", "black"),
             *(_series(label, c, 1.0 if label == VIEW_LABELS[-1] else 1.5)
               for label, c in zip(VIEW_LABELS, _VIEW_COLOURS, strict=True))),
            title=TITLES["residuals"], scales=_xscale(), axes=_axes("error / bound"),
            height=height, padding=PADDING)
        self.widths = gui.add_uplot(
            (x, zeros, zeros, zeros),
            (_series("t", "black"), _series("x width (cm)", "#e6194b"),
             _series("y width (cm)", "#3cb44b"), _series("heading width (deg)", "#4363d8")),
            title=TITLES["widths"], scales=_xscale(), axes=_axes("cm / deg"), height=height,
            padding=PADDING)
        self.error = gui.add_uplot(
            (x, zeros, zeros),
            (_series("t", "black"), _series("position error (cm)", "#e6194b"),
             _series("heading error (deg)", "#4363d8")),
            title=TITLES["error"], scales=_xscale(), axes=_axes("cm / deg"),
            height=height, padding=PADDING)

        self.mcl = gui.add_uplot(
            (x, zeros, zeros),
            (_series("t", "black"), _series("MCL mean error (cm)", "#f58231"),
             _series("interval centre error (cm)", "#e6194b")),
            title=TITLES["mcl"], scales=_xscale(), axes=_axes("cm"), height=height,
            padding=PADDING, visible=False)

    def update(self, rows: np.ndarray) -> None:
        """Redraw from metric rows (:data:`tileviz.app.history.METRIC_NAMES`), oldest first; a
        series with fewer than two points is emptied (a new run shows nothing of the old one)."""
        rows = rows.reshape(-1, len(METRIC_NAMES))
        t = rows[:, _COL["t"]]
        res = rows[:, [_COL["view_x"], _COL["view_y"], _COL["view_heading"]]]
        ok = np.isfinite(res).all(axis=1)
        if ok.sum() < 2:
            ok[:] = False
        self.residuals.data = (t[ok], *(res[ok, i] for i in range(3)), np.ones(int(ok.sum())))
        w = rows[:, [_COL["width_x"], _COL["width_y"], _COL["width_theta"]]]
        ok = np.isfinite(w).all(axis=1)
        if ok.sum() < 2:
            ok[:] = False
        self.widths.data = (t[ok], 100.0 * w[ok, 0], 100.0 * w[ok, 1], np.degrees(w[ok, 2]))
        e = rows[:, [_COL["error_xy"], _COL["error_theta"]]]
        ok = np.isfinite(e).all(axis=1)
        if ok.sum() < 2:
            ok[:] = False
        self.error.data = (t[ok], 100.0 * e[ok, 0], np.degrees(np.abs(e[ok, 1])))
        m = rows[:, [_COL["mcl_error_xy"], _COL["error_xy"]]]
        ok = np.isfinite(m).all(axis=1)
        self.mcl.visible = bool(ok.sum() >= 2)
        if ok.sum() >= 2:
            self.mcl.data = (t[ok], 100.0 * m[ok, 0], 100.0 * m[ok, 1])


def summary(rows: np.ndarray) -> dict[str, float]:
    """Containment over the rows where it is known: share of frames (0..1) whose truth is in the
    reported set, and how many frames that is over. NaN share when none."""
    inside = rows[:, _COL["inside"]] if rows.size else np.zeros(0)
    known = inside[np.isfinite(inside)]
    share = float(known.mean()) if known.size else math.nan
    return {"contained": share, "frames": float(known.size)}
