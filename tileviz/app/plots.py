"""Plots (viser's uPlot): the equivalence residuals over time (report Fig 6.3), the widths of the
localizer's box and the error of its centre, over the frames up to the one shown. Titles and
series labels are in plain words; the page's help ("How to read this page") gives the report's
figure and table numbers.

The x axis is the simulated time in seconds (``scales={"x": {"time": False}}``: uPlot would
otherwise print dates). Frames without a value (no observation, no truth) are left out of the
series that need it rather than sent as NaN.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from tileviz.app.history import METRIC_NAMES

if TYPE_CHECKING:
    from viser import GuiApi

__all__ = ["Plots"]

_COL = {name: i for i, name in enumerate(METRIC_NAMES)}
_RESIDUAL_COLOURS = ("#e6194b", "#3cb44b", "#4363d8", "#f58231", "#911eb4", "#42d4f4")
RESIDUAL_LABELS = ("x, upright", "y, upright", "heading, upright", "x, quarter turn",
                   "y, quarter turn", "heading, quarter turn")
"""Legend of r1..r6 (``tileviz.tiles.equivalence_residuals``): the first three compare the view
with the true pose for the upright and half-turned readings, the last three for the quarter
turns."""
TITLES = {
    "residuals": "Does the view agree with the true pose? (0 = yes)",
    "widths": "Size of the set",
    "error": "Distance from the set's centre to the truth",
    "mcl": "Monte Carlo Localization baseline",
}
PADDING = (18, 14, 0, 0)
"""Room (top, right, bottom, left px) around each plot so its top tick label is not cut."""


def _series(label: str, stroke: str, width: float = 1.5) -> dict[str, Any]:
    return {"label": label, "stroke": stroke, "width": width}


def _xscale() -> dict[str, Any]:
    return {"x": {"time": False}}


def _axes(ylabel: str) -> tuple[dict[str, Any], dict[str, Any]]:
    return ({"label": "t (s)"}, {"label": ylabel})


class Plots:
    """uPlot charts made in the caller's current GUI container (``gui``: a ``GuiApi``): the
    residuals, the box widths, the centre error, and the MCL baseline's error (shown while it
    runs)."""

    def __init__(self, gui: GuiApi, *, height: int = 190) -> None:
        x = np.zeros(2)
        zeros = np.zeros(2)
        self.residuals = gui.add_uplot(
            (x, *([zeros] * 6)),
            (_series("t", "black"),
             *(_series(label, c) for label, c in zip(RESIDUAL_LABELS, _RESIDUAL_COLOURS,
                                                     strict=True))),
            title=TITLES["residuals"], scales=_xscale(), axes=_axes("residual"),
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
        res = rows[:, _COL["r1"]: _COL["r6"] + 1]
        ok = np.isfinite(res).all(axis=1)
        if ok.sum() < 2:
            ok[:] = False
        self.residuals.data = (t[ok], *(res[ok, i] for i in range(6)))
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
