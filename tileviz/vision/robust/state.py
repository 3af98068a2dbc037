"""What the robust extractor's steps read and write: :class:`View`, one frame's immutable data
shared by every reading of it (the image, its geometry, the settings, the check scale, the gray
statistics, the gradients and the first heading), and :class:`ReadingState`, the working state
of one reading (:func:`~tileviz.vision.robust.readings.read`), made for that reading and
dropped with it; :class:`Line` is one measured grout line candidate. Each step
(:mod:`.profiles`, :mod:`.fit`, :mod:`.lattice`, :mod:`.bound`, :mod:`.foreign`) is a function
of a ReadingState; the view's steps (:mod:`.statistics`, :mod:`.heading`) of a View."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, NamedTuple

import numpy as np

from tileviz.config import CameraConfig, VisionConfig
from tileviz.vision.decision import CheckResult, Reading
from tileviz.vision.robust.checks import Record
from tileviz.vision.robust.settings import RobustSettings

__all__ = ["PARTS", "Line", "ReadingState", "Scale", "View", "check_scale"]

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
    reach: np.ndarray  # (PARTS,) farther 25 % crossing from the 50 % midpoint (>= spread), px
    infl: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # d pos / d(position of every part of the fit), px per px (set by the fit)
    # lighter grout (an inverted view) only: depth / the grout's own level in the gray image
    # (light falling off across the view cancels), median over the parts; NaN otherwise
    contrast_grout: float = math.nan
    # (PARTS,) the contrast of each part (depth / brighter plateau level; NaN not measured)
    part_contrast: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pos: float = math.nan  # at tangent coordinate 0, after the common tilt fit
    var: float = math.inf  # variance of pos from the fit's scatter, px^2
    # the part left out as stray (fit.drop_stray_part): its position and tangent coordinate
    # and its own bound (px); None when no part was left out
    dropped: tuple[float, float, float] | None = None


@dataclass(frozen=True, eq=False)
class View:
    """One frame's data, the same for every reading of it (read only: no step writes into its
    arrays). Geometry: ``gray`` (HxW uint8), ``h``, ``w``, ``side`` (the smaller, px), ``ppm``,
    ``tile_size`` (m) and ``lp`` (the tile period, px); ``vision`` and ``st`` (the settings);
    ``tol_px``, the declared floor's lattice tolerance in this view (px:
    ``FloorModel.lattice_tolerance`` x ppm; 0 for a perfect lattice); the check scale ``bound_px``
    / ``bound_rad`` (the smaller of the declared bounds and ``st.scale``); the profiles' grey
    ``closing`` (samples), the first measurement ``window`` and the ``widest`` (half-sizes,
    samples). Measured on the whole view (:func:`~tileviz.vision.robust.extractor.prepare`): the
    gray ``mean``, the ``noise`` std (gray levels; the contrast limit assumes at least
    ``noise_floor``, the luma's for a colour projection), the Scharr gradients ``dxy`` (CV_16S), the
    first ``heading`` (rad, modulo pi/2), their ``details`` and the ``checks`` run on the view."""

    gray: np.ndarray
    h: int
    w: int
    side: float
    ppm: float
    tile_size: float
    lp: float
    vision: VisionConfig
    st: RobustSettings
    tol_px: float
    bound_px: float
    bound_rad: float
    closing: int
    window: int
    widest: int
    mean: float = 0.0
    noise: float = math.nan
    noise_floor: float = 0.0
    dxy: tuple[np.ndarray, np.ndarray] | None = None
    heading: float = math.nan
    details: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    checks: tuple[CheckResult, ...] = ()

    @classmethod
    def of(cls, gray: np.ndarray, camera: CameraConfig, tile_size: float, vision: VisionConfig,
           settings: RobustSettings, tol_px: float = 0.0, **measured: Any) -> View:
        """The view's geometry, settings, lattice tolerance (px) and check scale
        (:func:`check_scale`), with the ``measured`` fields (``mean``, ``noise``, ...)."""
        h, w = gray.shape
        ppm = float(camera.ppm)
        lp = float(tile_size) * ppm
        pst = settings.profiles
        # grey-closing window of the profile baseline (wider than any grout dip), samples
        # (up to a third of the tile period: ProfileSettings.closing_*)
        closing = 2 * int(round(min(max(pst.closing_min, pst.closing_share * lp),
                                    pst.closing_max))) + 1
        widest = closing + pst.window_slack
        bound_px, bound_rad = check_scale(vision, settings)
        return cls(
            gray=gray, h=h, w=w, side=float(min(h, w)), ppm=ppm, tile_size=float(tile_size),
            lp=lp, vision=vision, st=settings, tol_px=float(tol_px), bound_px=bound_px,
            bound_rad=bound_rad, closing=closing, window=min(pst.window, widest), widest=widest,
            **measured)


def check_scale(vision: VisionConfig, settings: RobustSettings) -> tuple[float, float]:
    """The scale of the consistency checks (px, rad): the smaller of the declared bounds and
    ``settings.scale`` (the declared bounds keep a margin over the errors the checks let
    through)."""
    return (min(float(vision.position_error_px), settings.scale.position_px),
            min(float(vision.heading_error), settings.scale.heading))


class Scale(NamedTuple):
    """The view-level checks' context (:class:`~tileviz.vision.robust.checks.Context`) before
    the :class:`View` is made: settings, check scale (px), smaller side (px), declared bounds,
    noise std (gray levels; NaN until measured), lattice tolerance (px)."""

    st: RobustSettings
    bound_px: float
    side: float
    vision: VisionConfig
    noise: float
    tol_px: float
    noise_floor: float = 0.0


class ReadingState:
    """The working state of one reading of ``view`` (:class:`~tileviz.vision.decision.
    Reading`): made by :func:`~tileviz.vision.robust.readings.read` for that reading alone and
    dropped after it (its arrays are kept for the stage images). The view's data it reads are
    referenced here under the view's names (``gray``, ``w``, ``st``, ...)."""

    def __init__(self, view: View, reading: Reading) -> None:
        self.view = view
        self.reading = reading
        self.gray = view.gray
        self.h, self.w, self.side = view.h, view.w, view.side
        self.ppm, self.tile_size, self.lp = view.ppm, view.tile_size, view.lp
        self.vision, self.st = view.vision, view.st
        self.bound_px, self.bound_rad = view.bound_px, view.bound_rad
        self.tol_px = view.tol_px
        self.closing, self.widest = view.closing, view.widest
        self.dxy = view.dxy
        self.noise = view.noise
        self.noise_floor = view.noise_floor
        # this reading's
        self.tm: dict[str, float] = {}
        self.details: dict[str, float] = {}
        self.record = Record()  # every check run, in order
        self.mean = view.mean  # the levels measured: the gray ones, or 255 - gray (inverted)
        self.window = view.window  # half-size of the window each dip is measured in
        self.inverted = False  # grout lighter than the tiles: the gray levels are inverted
        # the grout's polarity imposed (True: lighter) instead of decided from the profiles
        self.force_inverted: bool | None = (
            None if reading.polarity == "auto" else reading.polarity == "light")
        # leave out the one part that alone keeps the lines from straight (fit.drop_stray_part)
        self.drop_stray = reading.stray
        # bound a line with a shoulder in every part by its band at a quarter of its depth
        # (its parts' reach) instead of refusing it (fit.fit_tilt, fit.check_lines)
        self.bound_shoulders = reading.shoulder
        # the other lines of the family whose most unlike line was left out (Reading.unlike;
        # fit.leave_out_unlike), NaN before
        self.unlike_others = math.nan
        self.not_straight = False  # whether the lines were found not straight
        self.edges: np.ndarray | None = None
        self.free_edges: np.ndarray | None = None
        self.warped: np.ndarray | None = None
        self.centre = (0.0, 0.0)  # warp centre (X0, Y0)
        self.lines: list[list[Line]] = [[], []]
        self.y3: float | None = None
        self.y: tuple[float, float, float] | None = None
        # each family's lattice offset at the image centre (px, the signed s of
        # lattice.lattice_offsets; None before the lattice is read)
        self.offsets: tuple[float, float] | None = None
        self.foreign: np.ndarray = np.zeros((0, 4))
        # each measured part's own error bound (px), in the fit's order of parts (set by it)
        self.part_bound: np.ndarray = np.zeros(0)
        # what the band-shape terms add to each part's bound (px, the same order; fit.fit_tilt)
        self.part_band: np.ndarray = np.zeros(0)
        self.tilt = 0.0  # the fit's residual tilt (rad; fit.fit_tilt)
        # each measured part's tangent coordinate and position (px) and its line's index in
        # lines[0] + lines[1], the same order (fit.fit_tilt; lattice.feasible_terms)
        self.part_t: np.ndarray = np.zeros(0)
        self.part_p: np.ndarray = np.zeros(0)
        self.part_line: np.ndarray = np.zeros(0, np.intp)
        # half-depth width (px) of the deepest dip when the window could not measure it in
        # parts (NaN otherwise; set by profiles.dips): a wider window is tried
        self.unmeasured_width = math.nan
        # per family, the median half-depth width (px) of its strong dips that the window
        # could not measure in parts (NaN when fewer than profiles.wide_family; set by
        # profiles.dips), and the wider window such a family is measured in (0: ``window``)
        self.unmeasured_family: tuple[float, float] = (math.nan, math.nan)
        self.family_window: tuple[int, int] = (0, 0)
        self.projection: Any = None  # the last profiles.Projection (reused by a wider window)

    def window_of(self, k: int) -> int:
        """The half-size of the window family ``k``'s dips are measured in (samples)."""
        return max(self.window, self.family_window[k])

    def lap(self, name: str, t0: float) -> float:
        """Add the time since ``t0`` (perf_counter, s) to stage ``name`` (ms); the time now."""
        t = time.perf_counter()
        self.tm[name] = self.tm.get(name, 0.0) + (t - t0) * 1e3
        return t
