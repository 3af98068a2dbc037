"""The top-down figure of a replayed run, and its movie (``python -m tileviz figure``).

The figure is the report's kind (docs/method.md's sets over the floor): the tiles' grout lines,
the true path (pink), the predicted set (green) and the contracted set (blue) of every Nth frame
as rectangles in (x, y), the last frame's sets drawn bolder and, magnified in a corner, that
final set around the true pose. World frame: metres, x east (right), y north (up). From a
replay CSV instead of a replay (``--boxes``), the figure draws what the CSV holds: each
contracted set's bounding box and status.

The movie is the same view over time, one movie frame per shown run frame, beside the camera
view vision read: the path so far, the current sets, and the magnified set following the truth.
It needs the ``share`` extra (imageio and imageio-ffmpeg, which ships the ffmpeg encoder).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tileviz.share.files import atomic_output, check_output
from tileviz.share.run import Run, bounds_of, fit_width
from tileviz.types import Box, BoxSet

if TYPE_CHECKING:
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from tileviz.pipeline import FrameRecord

__all__ = ["FIGURE_SUFFIXES", "MOVIE_SUFFIXES", "SHARE_INSTALL", "drawn_sets", "movie",
           "render_figure", "save_figure", "share_missing"]

FIGURE_SUFFIXES = (".png", ".pdf", ".svg")
MOVIE_SUFFIXES = (".mp4", ".gif")
SHARE_INSTALL = "pip install -e '.[share]'"
"""The install line of the ``share`` extra."""

PINK, GREEN, BLUE = "#ff40a0", "#28be46", "#1e64f0"
"""The live scene's colours (:data:`tileviz.app.scene.COLOURS`): truth, prediction, set."""
GROUT = "#b4b4ae"
MARGIN = 0.5
"""Floor shown around the path and the sets, metres."""


def share_missing() -> str | None:
    """None when a movie can be written here, else one line saying what to install."""
    from importlib.util import find_spec

    for module in ("imageio", "imageio_ffmpeg"):
        if find_spec(module) is None:
            return f"a movie needs the imageio and imageio-ffmpeg packages: {SHARE_INSTALL}"
    return None


def drawn_sets(run: Run, every: int) -> list[tuple[int, BoxSet, BoxSet]]:
    """(frame index, predicted set, contracted set) of every frame the figure draws: every
    ``every``-th kept frame from the first, and the last kept frame (the final set)."""
    picks = run.picks(every)
    if picks[-1] is not run.records[-1]:
        picks = [*picks, run.records[-1]]
    return [(r.index, r.predicted, r.updated) for r in picks]


def _rects(boxes: Sequence[Box]) -> list[np.ndarray]:
    """The (x, y) rectangles of ``boxes`` as closed polygons (5, 2), metres (boxes with an
    infinite side left out)."""
    out = []
    for b in boxes:
        if all(math.isfinite(v) for v in (b.x_lo, b.x_hi, b.y_lo, b.y_hi)):
            out.append(np.array([[b.x_lo, b.y_lo], [b.x_hi, b.y_lo], [b.x_hi, b.y_hi],
                                 [b.x_lo, b.y_hi], [b.x_lo, b.y_lo]]))
    return out


def _grid(ax: Axes, tile: float, bounds: tuple[float, float, float, float]) -> None:
    """The grout lines x = kL, y = kL over ``bounds`` (x0, y0, x1, y1)."""
    x0, y0, x1, y1 = bounds
    if (x1 - x0) / tile > 400 or (y1 - y0) / tile > 400:
        return
    for k in range(math.ceil(x0 / tile), math.floor(x1 / tile) + 1):
        ax.axvline(k * tile, color=GROUT, lw=0.8, zorder=0)
    for k in range(math.ceil(y0 / tile), math.floor(y1 / tile) + 1):
        ax.axhline(k * tile, color=GROUT, lw=0.8, zorder=0)


def _bounds(run: Run) -> tuple[float, float, float, float]:
    pts = [p for p in run.truth_path() if np.isfinite(p).all()]
    for r in run.records:
        h = r.updated.hull()
        if h is not None and r.status != "lost" and math.isfinite(h.x_lo + h.x_hi + h.y_lo
                                                                      + h.y_hi):
            pts.append(np.array(h.centre[:2]))
    x0, y0, x1, y1 = bounds_of(pts, at_least=2 * run.cfg.floor.tile_size)
    return (x0 - MARGIN, y0 - MARGIN, x1 + MARGIN, y1 + MARGIN)


def _magnified(ax: Axes, rec: FrameRecord, tile: float, boxes_in_set: int | None = None
               ) -> None:
    """``rec``'s sets around its true pose (or the set's centre), scaled so they fit."""
    boxes = list(rec.predicted.boxes) + list(rec.updated.boxes)
    centre: tuple[float, float] | None = None
    if rec.truth is not None:
        centre = (rec.truth.x, rec.truth.y)
    elif (h := rec.updated.hull()) is not None:
        centre = (h.centre[0], h.centre[1])
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_aspect("equal")
    if centre is None:
        ax.text(0.5, 0.5, "no set", ha="center", va="center", transform=ax.transAxes)
        return
    half = 0.005
    for b in boxes:
        for v, c in ((b.x_lo, centre[0]), (b.x_hi, centre[0]), (b.y_lo, centre[1]),
                     (b.y_hi, centre[1])):
            if math.isfinite(v):
                half = max(half, abs(v - c))
    half = min(half * 1.25, 1e3)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    _grid(ax, tile, (centre[0] - half, centre[1] - half, centre[0] + half, centre[1] + half))
    for poly in _rects(rec.predicted.boxes):
        ax.fill(poly[:, 0], poly[:, 1], color=GREEN, alpha=0.25, lw=1.2, ec=GREEN)
    for poly in _rects(rec.updated.boxes):
        ax.fill(poly[:, 0], poly[:, 1], color=BLUE, alpha=0.35, lw=1.2, ec=BLUE)
    if rec.truth is not None:
        t = rec.truth
        ax.plot([t.x], [t.y], "o", color=PINK, ms=5)
        ax.annotate("", xy=(t.x + 0.8 * half * math.cos(t.theta),
                            t.y + 0.8 * half * math.sin(t.theta)), xytext=(t.x, t.y),
                    arrowprops={"arrowstyle": "->", "color": PINK, "lw": 1.5})
    cm = 100.0 * 2 * half
    n = len(rec.updated) if boxes_in_set is None else boxes_in_set
    ax.set_title(f"frame {rec.index}: {n} box{'es' if n != 1 else ''}"
                 f"{' (their bounding box)' if n > len(rec.updated) else ''}, {rec.status} "
                 f"({cm:.2g} cm across)", fontsize=8)


def render_figure(run: Run, every: int = 20) -> Figure:
    """The run's top-down figure (see the module docstring): a matplotlib Figure (Agg, not
    shown); boxes of :func:`drawn_sets`. A run read from a replay CSV (:attr:`Run.table`) has
    no predicted sets to draw, and a set the CSV says had several boxes is drawn as its
    bounding box, outlined dashed."""
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig = Figure(figsize=(8.0, 7.0), dpi=150, layout="constrained")
    ax = fig.add_subplot()
    bounds = _bounds(run)
    tile = run.cfg.floor.tile_size
    ax.set_xlim(bounds[0], bounds[2])
    ax.set_ylim(bounds[1], bounds[3])
    ax.set_aspect("equal")
    _grid(ax, tile, bounds)
    path = run.truth_path()
    ax.plot(path[:, 0], path[:, 1], color=PINK, lw=1.2, zorder=2)
    sets = drawn_sets(run, every)
    pred = [p for _, s, _ in sets for p in _rects(s.boxes)]
    upd = [p for _, _, s in sets for p in _rects(s.boxes)]
    ax.add_collection(PolyCollection(pred, facecolors=GREEN, edgecolors=GREEN, alpha=0.35,
                                     linewidths=0.6, zorder=3))
    ax.add_collection(PolyCollection(upd, facecolors=BLUE, edgecolors=BLUE, alpha=0.6,
                                     linewidths=0.6, zorder=4))
    last = run.records[-1]
    ax.add_collection(PolyCollection(_rects(last.updated.boxes), facecolors="none",
                                     edgecolors=BLUE, linewidths=1.6, zorder=5))
    handles: list[Artist] = [Line2D([], [], color=PINK, lw=1.5, label="true path")]
    source = ""
    if run.table is None:
        handles.append(Patch(color=GREEN, alpha=0.5, label="predicted set"))
        handles.append(Patch(color=BLUE, alpha=0.7, label="contracted set"))
    else:  # a replay CSV holds each contracted set's bounding box, not the predicted sets
        source = f" (from {run.table.name})"
        handles.append(Patch(color=BLUE, alpha=0.7, label="contracted set"))
        several = [p for i, _, s in sets if run.box_counts.get(i, 1) > 1
                   for p in _rects(s.boxes)]
        if several:
            ax.add_collection(PolyCollection(several, facecolors="none", edgecolors="black",
                                             linestyles="dashed", linewidths=0.8, zorder=6))
            handles.append(Patch(facecolor="none", edgecolor="black", linestyle="dashed",
                                 label="bounding box of a set of several boxes"))
    ax.set_xlabel("x (m, east)")
    ax.set_ylabel("y (m, north)")
    ax.set_title(f"{run.name}: frames {run.start} to {run.end - 1}, sets every {every} "
                 f"frame{'s' if every != 1 else ''}{source}\n{_wrap(run.summary(), 110)}",
                 fontsize=8)
    ax.legend(handles=handles, loc="lower left", fontsize=7, framealpha=0.9)
    inset = ax.inset_axes((0.68, 0.68, 0.3, 0.3))
    _magnified(inset, last, tile, run.box_counts.get(last.index))
    inset.set_title("final set, magnified\n" + inset.get_title(), fontsize=7)
    return fig


def _wrap(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width))


def save_figure(run: Run, out: str | os.PathLike[str], every: int = 20) -> Path:
    """Write :func:`render_figure` to ``out`` (.png, .pdf or .svg; written whole or not at
    all); its path."""
    path = check_output(out, "OUT", FIGURE_SUFFIXES + MOVIE_SUFFIXES)
    if path.suffix.lower() not in FIGURE_SUFFIXES:
        raise OSError(f"OUT {path}: a figure is {' or '.join(FIGURE_SUFFIXES)}")
    fig = render_figure(run, every)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lower()[1:])
    return path


class _MovieFrame:
    """The movie's frames: the top-down view drawn by matplotlib (its static part once, the
    moving artists over it each frame), the camera view and the magnified set pasted beside it
    as they are (no resampling by matplotlib)."""

    def __init__(self, run: Run, width_px: int) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import PolyCollection
        from matplotlib.figure import Figure

        self.run = run
        self.width = width_px
        self.height = width_px // 2
        dpi = 100
        side = self.height / dpi
        self.fig = Figure(figsize=(side, side), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        self.ax = ax = self.fig.add_axes((0.12, 0.08, 0.85, 0.84))
        bounds = _bounds(run)
        self.tile = run.cfg.floor.tile_size
        ax.set_xlim(bounds[0], bounds[2])
        ax.set_ylim(bounds[1], bounds[3])
        ax.set_aspect("equal")
        ax.tick_params(labelsize=6)
        _grid(ax, self.tile, bounds)
        self.path = run.truth_path()
        (self.line,) = ax.plot([], [], color=PINK, lw=1.2, zorder=2, animated=True)
        (self.dot,) = ax.plot([], [], "o", color=PINK, ms=3, zorder=6, animated=True)
        self.pred = PolyCollection([], facecolors=GREEN, edgecolors=GREEN, alpha=0.4,
                                   linewidths=1.0, zorder=3, animated=True)
        self.upd = PolyCollection([], facecolors=BLUE, edgecolors=BLUE, alpha=0.7,
                                  linewidths=1.0, zorder=4, animated=True)
        ax.add_collection(self.pred)
        ax.add_collection(self.upd)
        self.title = ax.set_title("", fontsize=7, animated=True)
        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(self.fig.bbox)

    def draw(self, k: int, rec: FrameRecord, camera: np.ndarray) -> np.ndarray:
        """The movie frame of ``rec`` (the ``k``-th kept record) as HxWx3 uint8 RGB."""
        import cv2

        from tileviz.app.inset import render_inset

        p = self.path[: k + 1]
        self.line.set_data(p[:, 0], p[:, 1])
        if rec.truth is not None:
            self.dot.set_data([rec.truth.x], [rec.truth.y])
        self.pred.set_verts(_rects(rec.predicted.boxes))
        self.upd.set_verts(_rects(rec.updated.boxes))
        self.title.set_text(f"{self.run.name}: frame {rec.index}, t = {rec.t:.2f} s, "
                            f"{rec.status}")
        self.canvas.restore_region(self.background)
        for artist in (self.line, self.pred, self.upd, self.dot, self.title):
            self.ax.draw_artist(artist)
        left = np.asarray(self.canvas.buffer_rgba())[..., :3]
        frame = np.full((self.height, self.width, 3), 255, np.uint8)
        frame[:, : left.shape[1]] = left[: self.height]
        x0 = left.shape[1]
        room = self.width - x0
        cam = fit_width(camera, min(room - 8, int(1.3 * self.height * camera.shape[1]
                                                  / max(1, camera.shape[0]) * 0.55)))
        h_cam = min(cam.shape[0], self.height // 2 + self.height // 8)
        u = x0 + (room - cam.shape[1]) // 2
        frame[18: 18 + h_cam, u: u + cam.shape[1]] = cam[:h_cam]
        cv2.putText(frame, "camera view", (u, 13), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (40, 40, 40),
                    1, cv2.LINE_AA)
        size = max(16, self.height - 18 - h_cam - 8)
        inset = render_inset(rec, self.tile, size=size)
        v = 18 + h_cam + 4
        u = x0 + (room - size) // 2
        frame[v: v + size, u: u + size] = inset[: self.height - v]
        return frame


def movie(run: Run, out: str | os.PathLike[str], every: int = 2, width_px: int = 960,
          on_frame: Callable[[FrameRecord], None] | None = None) -> Path:
    """Write the run's movie to ``out`` (.mp4 with ffmpeg's H.264, or .gif): one frame per
    ``every``-th kept record at the run's pace (``1 / (dt * every)`` frames a second), the
    top-down view beside the camera view (see the module docstring), ``width_px`` wide;
    written whole or not at all. ``on_frame`` gets each record drawn (a progress bar)."""
    path = check_output(out, "OUT", FIGURE_SUFFIXES + MOVIE_SUFFIXES)
    if path.suffix.lower() not in MOVIE_SUFFIXES:
        raise OSError(f"OUT {path}: a movie is {' or '.join(MOVIE_SUFFIXES)}")
    missing = share_missing()
    if missing is not None:
        raise OSError(missing)
    import imageio.v2 as iio

    width_px = max(320, int(width_px) // 16 * 16)
    view = _MovieFrame(run, width_px)
    fps = 1.0 / (run.dt * every)
    cam_px = width_px // 2
    with atomic_output(path) as tmp:
        if path.suffix.lower() == ".mp4":
            writer = iio.get_writer(tmp, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                    quality=6, macro_block_size=16,
                                    ffmpeg_log_level="error")
        else:
            writer = iio.get_writer(tmp, format="GIF", mode="I", duration=1000.0 / fps,
                                    loop=0)
        try:
            for k, rec in enumerate(run.records):
                if k % every:
                    continue
                camera = run.kept_view(rec, "camera")
                if camera is None:
                    camera = fit_width(run.image(rec), cam_px)
                writer.append_data(view.draw(k, rec, camera))
                if on_frame is not None:
                    on_frame(rec)
        finally:
            writer.close()
    return path
