"""Where the live run's frames come from: the pymunk simulator, a recorded dataset or a ROS run.

:class:`tileviz.app.session.Session` steps one *run source*; every kind answers the same few
questions (:class:`RunSource`), so the session has no per-kind branches beyond the gate on the
commands that only a simulator understands (``simulator``), the restart on new localizer
settings (``restart_on_settings``) and a source that runs on its own clock (``realtime``).

- :class:`LiveSimulator`: the simulator (:class:`tileviz.sim.source.SimSource`), endless; it obeys
  setpoint, kidnap, noise and fault commands.
- :class:`DatasetReplay`: a tileviz-dataset/1 folder read by
  :class:`tileviz.datasets.DatasetSource`, the reader ``python -m tileviz replay`` uses. Its end,
  and a bad row, raise :class:`SourceEnded` (every frame before it was delivered).
- :class:`tileviz.ros.viewer.RosSource`: a ROS 1 run followed live (``serve --ros``), its
  messages combined as ``python -m tileviz ros`` combines them; no frame yet raises
  :class:`SourceWaiting`.

Units: metres, radians, seconds; world frame as in ``docs/dataset-format.md``.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from tileviz.config import Config
from tileviz.datasets import MAX_MAGNITUDE, DatasetSource, replay_config
from tileviz.datasets.camera_model import Rectifier
from tileviz.sim.source import SimSource
from tileviz.types import FrameInput, Pose

if TYPE_CHECKING:
    from tileviz.pipeline import FrameLoop

__all__ = [
    "DatasetReplay", "LiveSimulator", "RunSource", "SourceEnded", "SourceNote", "SourceWaiting",
    "make_source", "replay_config",
]

PATH_POINTS = 4000
"""Most points of a dataset's drawn true path (longer paths are thinned evenly)."""
FLOOR_MARGIN = 1.5
"""Floor drawn beyond the farthest true position of a dataset, metres."""
MAX_FLOOR_HALF = 500.0
"""Largest half side of the drawn floor for a dataset, metres."""


class SourceEnded(Exception):
    """The source has no more frames: ``level`` ``info`` at the end of a dataset, ``error`` when a
    bad row stopped it (the message names the file and the row)."""

    def __init__(self, message: str, level: str = "info") -> None:
        super().__init__(message)
        self.level = level


class SourceWaiting(Exception):
    """No frame is ready yet (a source on its own clock, ``realtime``): nothing failed, try
    again; the message, when not empty, says why no frame came for a while."""


@dataclass(frozen=True)
class SourceNote:
    """A line the source has for the page (``level`` info or error); ``degrades``: the set no
    longer vouches for the truth from now on (the session's ``degraded``)."""

    text: str
    level: str = "info"
    degrades: bool = False


class RunSource(Protocol):
    """What the session needs of a source of frames."""

    simulator: bool
    """True: setpoint, kidnap, noise, fault, floor/camera and recording commands apply."""
    restart_on_settings: bool
    """True: a new localizer mode, extractor or inflation replays from frame 0 (so every box
    shown is one the command-line replay writes with those settings)."""
    path_closed: bool
    """Whether :meth:`path` is a loop (its last point joins its first)."""
    index: int
    """Index of the next frame ``next()`` returns."""
    rectifier: Rectifier | None
    """Turns the source's raw images into the orthographic view (None: they are already)."""
    realtime: bool
    """True: frames come on the source's own clock (a ROS run): the session takes each as it
    comes (no pacing; ``next()`` raises :class:`SourceWaiting` while none is ready) and cannot
    start the run again (Reset is refused)."""

    def __next__(self) -> FrameInput: ...

    def prime(self, runner: FrameLoop) -> list[SourceNote]:
        """Called between ``next()`` and processing its frame: what the source tells the frame
        loop for that frame (a ROS source: the motion since the previous frame and the bounds
        declared now), and its lines for the page since the last call."""
        ...

    @property
    def pose(self) -> Pose | None:
        """The true pose of the next frame, or None when unknown."""
        ...

    def path(self) -> list[tuple[float, float]]:
        """The path to draw on the floor (x, y), metres."""
        ...

    def describe(self) -> str:
        """A few words for the readout."""
        ...


class LiveSimulator(SimSource):
    """The simulator as a run source (see :class:`tileviz.sim.source.SimSource`)."""

    simulator = True
    restart_on_settings = False
    path_closed = True
    rectifier: Rectifier | None = None
    """Set when the simulator's camera has a lens (its images are raw)."""
    realtime = False

    def prime(self, runner: FrameLoop) -> list[SourceNote]:
        """Nothing: each frame carries its own odometry."""
        return []

    def path(self) -> list[tuple[float, float]]:
        """One lap of the configured Lissajous curve, metres."""
        return self.lissajous_path()

    def describe(self) -> str:
        return "simulator"


class DatasetReplay:
    """A recorded dataset as a run source: frame after frame from ``folder`` (validated row by
    row as ``replay`` does), then :class:`SourceEnded`.

    Opening checks meta.json and the header of frames.csv (DatasetError, a ValueError naming the
    file). ``frames``: frames delivered so far.
    """

    simulator = False
    restart_on_settings = True
    path_closed = False
    realtime = False

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        # raw images: the session rectifies them, to show the raw and the rectified view
        self.dataset = DatasetSource(self.folder, rectify=False)
        self.meta = self.dataset.meta
        self.rectifier = self.meta.rectifier()
        """The rectification of the stored images (None without a ``camera_model``)."""
        self._frames = iter(self.dataset)
        self.index = 0
        self.frames = 0
        self._ahead: FrameInput | None = None
        self._end: SourceEnded | None = None
        self._path: list[tuple[float, float]] | None = None

    def _fetch(self) -> FrameInput:
        if self._end is not None:
            raise self._end
        try:
            return next(self._frames)
        except StopIteration:
            early = self.dataset.ended_early
            self._end = SourceEnded(f"end of dataset, {self.frames} frames"
                                    + (f" ({early})" if early else ""))
        except Exception as e:  # noqa: BLE001 - DatasetError names file and row; anything else
            self._end = SourceEnded(f"dataset stopped after {self.frames} frames: {e}", "error")
        raise self._end

    def __iter__(self) -> DatasetReplay:
        return self

    def __next__(self) -> FrameInput:
        if self._ahead is not None:
            frame, self._ahead = self._ahead, None
        else:
            frame = self._fetch()
        self.frames += 1
        self.index = frame.index + 1
        return frame

    @property
    def pose(self) -> Pose | None:
        """The true pose of the next frame (read ahead; its errors wait for ``next()``)."""
        if self._ahead is None:
            try:
                self._ahead = self._fetch()
            except SourceEnded:
                return None
        return self._ahead.truth

    def path(self) -> list[tuple[float, float]]:
        """The true (x, y) of the rows before the first one without a readable truth (read from
        frames.csv alone, no image), thinned to at most :data:`PATH_POINTS` points."""
        if self._path is None:
            self._path = truth_path(self.dataset.frames_path, self.dataset.columns)
        return self._path

    def describe(self) -> str:
        return f"dataset {self.folder}"

    def prime(self, runner: FrameLoop) -> list[SourceNote]:
        """Nothing: each row carries its own odometry."""
        return []

    def floor_half_size(self, at_least: float) -> float:
        """Half side of a floor centred on the origin that holds the true path (plus a margin),
        and at least ``at_least``; metres."""
        far = max((max(abs(x), abs(y)) for x, y in self.path()), default=0.0)
        return min(max(at_least, math.ceil(far + FLOOR_MARGIN)), MAX_FLOOR_HALF)


def truth_path(frames_csv: Path, columns: list[str]) -> list[tuple[float, float]]:
    """The (x, y) columns of ``frames_csv`` (header ``columns``) up to the first row without
    finite numbers there; thinned evenly to :data:`PATH_POINTS` points. For drawing only: the
    reader proper (:class:`tileviz.datasets.DatasetSource`) validates each row when it gets there.
    """
    if "x" not in columns or "y" not in columns:
        return []
    ix, iy = columns.index("x"), columns.index("y")
    points: list[tuple[float, float]] = []
    try:
        with open(frames_csv, newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            next(reader, None)
            for cells in reader:
                if not cells or all(not c.strip() for c in cells):
                    continue
                try:
                    x, y = float(cells[ix]), float(cells[iy])
                except (ValueError, IndexError):
                    break
                if not (math.isfinite(x) and math.isfinite(y)) or max(abs(x), abs(y)) > (
                        MAX_MAGNITUDE):
                    break
                points.append((x, y))
    except (OSError, UnicodeDecodeError, csv.Error):
        pass
    if len(points) > PATH_POINTS:
        step = len(points) / PATH_POINTS
        points = [points[int(i * step)] for i in range(PATH_POINTS)] + [points[-1]]
    return points


def make_source(cfg: Config, *, dataset: Path | None = None, renderer: Any = None,
                lens: str | None = None, ros: Any = None) -> RunSource:
    """The run source: the ROS run of ``ros`` (a :class:`tileviz.ros.viewer.RosFeed`) when
    given, a replay of ``dataset`` when given, else the simulator for ``cfg``
    (``renderer``: the simulator's camera, None = the real floor renderer; ``lens``: a
    :data:`tileviz.sim.lens.LENSES` preset, the simulator's camera is then that real camera and
    the source's ``rectifier`` turns its raw images into ``cfg.camera``'s view)."""
    if ros is not None:
        from tileviz.ros.viewer import RosSource

        return RosSource(ros)
    if dataset is not None:
        return DatasetReplay(dataset)
    if lens is None:
        return LiveSimulator(cfg, renderer=renderer)
    from tileviz.sim.lens import LENSES, LensRenderer, webcam_model

    if lens not in LENSES:
        raise ValueError(f"lens must be one of {', '.join(LENSES)}, got {lens!r}")
    model = webcam_model(cfg.camera)
    sim = LiveSimulator(cfg, renderer=LensRenderer(cfg.floor, cfg.camera, model))
    sim.rectifier = Rectifier(model, ppm=cfg.camera.ppm, width=cfg.camera.width,
                              height=cfg.camera.height, camera_offset=cfg.camera.offset)
    return sim
