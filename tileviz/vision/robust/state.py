"""The state of one frame through the robust extractor, shared by its steps.

:class:`RobustRun` holds the frame, its settings and every intermediate result (the stage images
read them); :class:`Line` is one measured grout line candidate;
:class:`~tileviz.vision.robust.checks.Refusal` carries the reason of the first failed check. Each
step (:mod:`.statistics`, :mod:`.heading`, :mod:`.profiles`, :mod:`.fit`, :mod:`.lattice`,
:mod:`.bound`, :mod:`.foreign`) is a function of a RobustRun. """

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tileviz.config import CameraConfig, VisionConfig
from tileviz.vision.robust.checks import Record
from tileviz.vision.robust.settings import RobustSettings

__all__ = ["PARTS", "Line", "RobustRun"]

PARTS = 4
"""Each line is measured in this many parts along its length."""


@dataclass
class Line:
    """A grout line candidate of one family, measured on the warped image.

    Positions are profile coordinates (row for family 1, column for family 2) in the warp
    frame; tangent coordinates t are along the line, relative to the warp centre."""

    depth: float
    width: float  # half-depth width, median over the parts, px
    rise: float  # 20-80 % edge rise, median over the parts, px
    step: float  # |level left - level right| / brighter level
    contrast: float  # depth / brighter plateau level (vignetting and shading cancel)
    chord: float  # line length in the view, px
    parts: np.ndarray  # (PARTS,) position in each part, 50 % midpoint (NaN when not measured)
    tpart: np.ndarray  # (PARTS,) mean tangent coordinate of each part
    wpart: np.ndarray  # (PARTS,) length of each part (0 when not measured)
    sigma: np.ndarray  # (PARTS,) predicted standard error of each part's position, px
    spread: np.ndarray  # (PARTS,) largest distance of its 25 / 75 % midpoints from the 50 %, px
    infl: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # d pos / d(position of every part of the fit), px per px (set by the fit)
    # lighter grout (an inverted view) only: depth / the grout's own level in the gray image
    # (light falling off across the view cancels), median over the parts; NaN otherwise
    contrast_grout: float = math.nan
    pos: float = math.nan  # at tangent coordinate 0, after the common tilt fit
    var: float = math.inf  # variance of pos from the fit's scatter, px^2


class RobustRun:
    """One frame through the robust extractor (keeps intermediate arrays for the stages)."""

    def __init__(
        self,
        gray: np.ndarray,
        camera: CameraConfig,
        tile_size: float,
        vision: VisionConfig,
        settings: RobustSettings,
        timings: dict[str, float],
    ) -> None:
        self.gray = gray
        self.vision = vision
        self.st = settings
        self.tm = timings
        self.h, self.w = gray.shape
        self.side = float(min(self.h, self.w))
        self.ppm = float(camera.ppm)
        self.tile_size = float(tile_size)
        self.lp = self.tile_size * self.ppm  # tile period, px
        # the consistency checks work at the smaller of the declared bounds and the check
        # scales (the declared bounds keep a margin over the errors the checks let through)
        self.bound_px = min(float(vision.position_error_px), settings.scale.position_px)
        self.bound_rad = min(float(vision.heading_error), settings.scale.heading)
        self.mean = 0.0
        self.edges: np.ndarray | None = None
        self.free_edges: np.ndarray | None = None
        self.warped: np.ndarray | None = None
        self.centre = (0.0, 0.0)  # warp centre (X0, Y0)
        self.lines: list[list[Line]] = [[], []]
        self.y3: float | None = None
        self.y: tuple[float, float, float] | None = None
        self.foreign: np.ndarray = np.zeros((0, 4))
        self.dxy: tuple[np.ndarray, np.ndarray] | None = None  # Scharr gradients (CV_16S)
        self.details: dict[str, float] = {}
        self.record = Record()  # every check run, in order
        # each measured part's own error bound (px), in the fit's order of parts (set by it)
        self.part_bound: np.ndarray = np.zeros(0)
        # grey-closing window of the profile baseline (wider than any grout dip), samples (px)
        # (up to a third of the tile period: ProfileSettings.closing_*)
        pst = settings.profiles
        self.closing = 2 * int(round(min(max(pst.closing_min, pst.closing_share * self.lp),
                                         pst.closing_max))) + 1
        # half-size of the window each dip is measured in; a wider band measures again with a
        # window up to the widest (ProfileSettings.window*)
        self.widest = self.closing + pst.window_slack
        self.window = min(pst.window, self.widest)
        # half-depth width (px) of the deepest dip when the window could not measure it in
        # parts (NaN otherwise; set by profiles.dips): a wider window is tried
        self.unmeasured_width = math.nan
        self.inverted = False  # grout lighter than the tiles: the gray levels are inverted
        # the grout's polarity imposed (True: lighter) instead of decided from the profiles
        self.force_inverted: bool | None = None
        self.projection: Any = None  # the last profiles.Projection (reused by a wider window)
        # leave out the one part that alone keeps the lines from straight (fit.drop_stray_part)
        # only when reading the view again after a refusal; whether a reading found the lines
        # not straight (so that reading again may differ)
        self.drop_stray = False
        self.not_straight = False

    def lap(self, name: str, t0: float) -> float:
        """Add the time since ``t0`` (perf_counter, s) to stage ``name`` (ms); the time now."""
        t = time.perf_counter()
        self.tm[name] = self.tm.get(name, 0.0) + (t - t0) * 1e3
        return t
