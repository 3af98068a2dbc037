"""The robust extractor's checks: each a named predicate on one measured value, with its limit
computed here, in one place, from the settings (:mod:`.settings`) and the view's context
(:class:`Context`: the check scale, the view's size, the declared bounds).

A check passes or fails; a failed check refuses the view with its ``reason`` (one of
:data:`tileviz.vision.REASONS`), except where the next check can still accept it (``constant.range``
fails, then ``constant.thin_range`` decides; ``glare.saturated``, then ``glare.patches``;
``foreign_line.contrast`` of lighter grout, then the crossings). Every check run is recorded
(:class:`~tileviz.vision.decision.CheckResult`: id, value, limit, passed) so that a decision can be
followed: the refusal carries its check's result (:class:`Refusal`).

The checks, in the order they run (value; passes when; limit from settings):

- ``constant.range``: gray range between ``statistics.range_quantiles``; >=
  ``statistics.min_range``; when it fails, ``constant.thin_range`` decides (``constant image``).
- ``constant.thin_range``: gray range between ``statistics.thin_quantiles``; >=
  ``statistics.min_thin_range`` (``constant image``).
- ``glare.saturated``: share of pixels >= ``statistics.saturated_level``; <=
  ``statistics.glare_fraction``; when it fails, ``glare.patches`` decides (``glare``).
- ``glare.patches``: share of pixels in saturated patches ``statistics.glare_patch`` px
  across; <= ``statistics.glare_fraction`` (``glare``).
- ``heading.gradients``: squared Scharr magnitude of the weakest voting gradient (the top
  ``heading.share``); > 0 (``no lines``).

Per reading (:mod:`.readings`), on its lines:

- ``lines.found``: lines found (both families); >= 1 (``no lines``).
- ``contrast.depth``: the deepest dip, gray levels; >= ``lines.depth_noise`` x the noise std of
  a part's profile (the view's noise over the square root of ``profiles.min_part``, the fewest
  pixels a part averages along its line), at most ``lines.min_depth`` (``low contrast``).
- ``lines.families``: lines of the family with fewer; >= 1 (``one family``).
- ``foreign_line.left_out`` (a reading that leaves out the line most unlike the others,
  ``Reading.unlike``): the other lines of its family; >= ``lines.unlike_others``
  (``foreign line``).
- ``blur.rise``: median 20-80 % edge rise, px; <= ``lines.max_rise`` (``blurred``; not
  measured fails).
- ``step_edge.levels``: largest step between a line's two sides over the brighter;
  <= ``lines.max_step`` (``step edge``).
- ``angle.straight``: the worst part off the common fit, px; <= ``lines.straight_fraction`` x
  the position check scale + twice the lattice tolerance (``inconsistent angle``).
- ``angle.perpendicular``: the two families' own tilts apart beyond what the lattice tolerance
  allows, standard errors; <= ``fit.sigmas`` (``inconsistent angle``).
- ``foreign_line.width``: widest line's half-depth width, px; <= ``lines.width_ratio`` x the
  narrowest's + ``lines.width_slack`` + twice the lattice tolerance (``foreign line``; no width
  fails).
- ``foreign_line.contrast``: largest / smallest line contrast (lighter grout: or of the depth
  over the grout's own level); <= ``lines.contrast_ratio`` x how much the lines' contrast
  varies along themselves (the median over the lines of max / min over a line's parts, at
  least 1: a floor whose grout varies along each line varies between lines as much) (``foreign
  line``); lighter grout
  that fails is one grout when the three crossing checks pass:
- ``foreign_line.crossings_read``: lines read beside a crossing of the two families; >= 1.
- ``foreign_line.crossings``: largest ratio of two crossing lines' depths beside their crossing;
  <= ``lines.crossing_ratio``.
- ``foreign_line.unread``: lines not read at a crossing that agree in contrast (within
  ``lines.contrast_ratio``) with none read there; <= 0.
- ``foreign_line.beside``: a second dip beside a line, as far as the lattice spacing would not
  show it read instead (:func:`~tileviz.vision.robust.fit.unseen_reach`), over its depth;
  < ``lines.beside_share`` (``foreign line``).
- ``foreign_line.shoulder``: the smallest spread of a line's 25 / 75 % midpoints over its
  parts, px; <= ``lines.shoulder_px`` (``foreign line``); not run on a reading that bounds
  such a line by its band at a quarter of its depth instead (``Reading.shoulder``).

On the reading whose lines passed, the lattice and the bound:

- ``spacing.missing`` (per family): a well-visible line the lattice predicts and the view does
  not show (1) or not (0); <= 0 (``inconsistent spacing``; ``lattice.min_chord``,
  ``lattice.found_share``).
- ``spacing``: the worst line off the lattice, px; <= ``lattice.spacing_fraction`` x the
  position check scale + twice the lattice tolerance (``inconsistent spacing``).
- ``evidence`` (per family): line length in view, px; >= ``lattice.min_evidence`` x the smaller
  side (``too few segments``).
- ``bound.position``: the larger of the position bound the view declares (the set's reach as
  its parts' term) and the one with the fit's sums (``details["position_fit"]``), px; <= the
  larger of
  ``VisionConfig.position_error_px`` and ``bound.max_px``, plus what the lattice tolerance adds
  to the bound (its part of the parts' term, and ``fit.sigmas`` + 1 times it for the scatter and
  a width's excess: ``imprecise``; a declared tolerance alone is never a reason to refuse).
- ``bound.heading``: the larger of the declared heading bound and the one with the fit's sum,
  rad; each <= the larger of ``VisionConfig.heading_error`` and ``bound.max_rad``, plus what the
  tolerance adds to it (to the fit's sum: its part of the parts' term; to the declared set's
  reach: that reach less the reach of the same set with every part's bound less the
  tolerance, or as to the fit's sum where that set is empty). Shown: the larger bound against
  the limit plus that bound less the larger of the two bounds' excesses over their allowances.
- ``foreign_edge``: long straight edges (``foreign.length`` x the smaller side, at least
  ``foreign.min_length`` px) off the lattice (its bands widened by the lattice tolerance each
  side) that no texture explains; <= 0 (``step edge`` when
  the longest separates two levels, else ``foreign line``).
- ``foreign_line.polarity`` (a reading with the grout's polarity imposed, accepted after a
  first reading at the polarity the profiles decided saw its lines in part, ``low contrast``
  or ``one family``; run only when that reading's deepest dip is deeper than this reading's):
  the farthest of the first reading's lines from this reading's lattice, at the view's
  centre, modulo the period (px; infinite for a line parallel to neither family within this
  reading's heading bound, or when the first reading kept no line); <= this reading's position
  bound less the lattice tolerance (``foreign line``, final). Deeper lines of the other
  polarity on the lattice are the same joints (filled with light dirt along part of them);
  off it they are the grout, and this reading's lines something beside them (a bevel's
  shadow along a light ridge).

The position check scale is the smaller of ``VisionConfig.position_error_px`` and
``scale.position_px``. The lattice tolerance is the declared floor's (``FloorModel``,
``docs/dataset-format.md``) in the view's pixels: a line may lie that far off the ideal lattice at
any point, so two lines, two parts of a line, or a line and the lattice fitted to the others may
differ by twice it.

Adding a check: a :class:`Check` below (id, reason, relation, limit from the context, the
settings it reads), added to :data:`CHECKS` and to this list, and one ``record.require(CHECK,
context, value)`` where its value is measured.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from tileviz.config import VisionConfig
from tileviz.vision.decision import CheckResult
from tileviz.vision.robust.settings import RobustSettings

__all__ = ["CHECKS", "Check", "Context", "Record", "Refusal", "Relation"]


class Context(Protocol):
    """What a limit is computed from: the settings (``st``) and the view's context: the
    position check scale (``bound_px``, px), the smaller side of the view (``side``, px), the
    declared bounds (``vision``), the view's noise std (``noise``, gray levels), the least noise
    std its contrast limit assumes (``noise_floor``: the camera's, measured on the luma, for a
    colour projection; else 0) and the floor's lattice tolerance in the view (``tol_px``, px: 0
    for a perfect lattice).
    :class:`~tileviz.vision.robust.state.View` and
    :class:`~tileviz.vision.robust.state.ReadingState` are contexts."""

    @property
    def st(self) -> RobustSettings: ...
    @property
    def bound_px(self) -> float: ...
    @property
    def side(self) -> float: ...
    @property
    def vision(self) -> VisionConfig: ...
    @property
    def noise(self) -> float: ...
    @property
    def noise_floor(self) -> float: ...
    @property
    def tol_px(self) -> float: ...


@dataclass(frozen=True)
class Relation:
    """How a value must compare with its limit to pass: ``symbol`` (shown); the value passes
    when ``test(value, limit)`` (an ``operator`` comparison) differs from ``negate``."""

    symbol: str
    test: Callable[[float, float], bool]
    negate: bool

    def passes(self, value: float, limit: float) -> bool:
        """Whether ``value`` passes against ``limit``."""
        return self.test(value, limit) != self.negate


AT_LEAST = Relation(">=", operator.lt, True)
"""Passes unless below the limit (NaN passes)."""
AT_MOST = Relation("<=", operator.gt, True)
"""Passes unless above the limit (NaN passes)."""
WITHIN = Relation("<=", operator.le, False)
"""Passes when at most the limit (NaN fails: not measured)."""
BELOW = Relation("<", operator.ge, True)
"""Passes unless at or above the limit (NaN passes)."""
ABOVE = Relation(">", operator.le, True)
"""Passes unless at or below the limit (NaN passes)."""


@dataclass(frozen=True)
class Check:
    """One named check: ``id`` (dotted), the ``reason`` it refuses with, how the value must
    compare with the limit, ``limit(context, *extra)`` (the limit from the settings and the
    view's context; ``extra``: what the limit scales with in this view), the ``setting`` names
    it reads, and ``what`` the value is."""

    id: str
    reason: str
    relation: Relation
    limit: Callable[..., float]
    setting: str
    what: str


class Refusal(Exception):
    """A refusal: ``reason`` (one of ``tileviz.vision.REASONS``) and the ``result`` of the
    check that refused."""

    def __init__(self, result: CheckResult, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason
        self.result = result


CONSTANT_RANGE = Check("constant.range", "constant image", AT_LEAST,
                       lambda c: c.st.statistics.min_range, "statistics.min_range",
                       "gray range (2-98 %)")
CONSTANT_THIN = Check("constant.thin_range", "constant image", AT_LEAST,
                      lambda c: c.st.statistics.min_thin_range, "statistics.min_thin_range",
                      "gray range of thin structure (0.2-99.8 %)")
GLARE_SATURATED = Check("glare.saturated", "glare", AT_MOST,
                        lambda c: c.st.statistics.glare_fraction, "statistics.glare_fraction",
                        "share of saturated pixels")
GLARE_PATCHES = Check("glare.patches", "glare", AT_MOST,
                      lambda c: c.st.statistics.glare_fraction,
                      "statistics.glare_fraction, glare_patch",
                      "share of pixels in saturated patches")
HEADING_GRADIENTS = Check("heading.gradients", "no lines", ABOVE, lambda c: 0.0,
                          "heading.share", "weakest voting gradient (squared magnitude)")
LINES_FOUND = Check("lines.found", "no lines", AT_LEAST, lambda c: 1.0, "",
                    "lines found")
CONTRAST_DEPTH = Check("contrast.depth", "low contrast", AT_LEAST,
                       lambda c: c.st.lines.min_depth if not c.noise <= c.st.lines.min_depth
                       else min(c.st.lines.min_depth, c.st.lines.depth_noise * max(
                           c.noise, c.noise_floor, c.st.lines.rounding_noise)
                           / math.sqrt(c.st.profiles.min_part)),
                       "lines.min_depth, depth_noise, rounding_noise, profiles.min_part",
                       "deepest dip (gray levels)")
LINES_FAMILIES = Check("lines.families", "one family", AT_LEAST, lambda c: 1.0, "",
                       "lines of the sparser family")
FOREIGN_LEFT_OUT = Check("foreign_line.left_out", "foreign line", AT_LEAST,
                         lambda c: float(c.st.lines.unlike_others), "lines.unlike_others",
                         "other lines of the left-out line's family")
BLUR_RISE = Check("blur.rise", "blurred", WITHIN, lambda c: c.st.lines.max_rise,
                  "lines.max_rise", "median edge rise (px)")
STEP_LEVELS = Check("step_edge.levels", "step edge", AT_MOST, lambda c: c.st.lines.max_step,
                    "lines.max_step", "largest step between a line's sides")
ANGLE_STRAIGHT = Check("angle.straight", "inconsistent angle", AT_MOST,
                       lambda c: c.st.lines.straight_fraction * c.bound_px + 2.0 * c.tol_px,
                       "lines.straight_fraction, scale.position_px",
                       "worst part off the common fit (px)")
ANGLE_PERPENDICULAR = Check("angle.perpendicular", "inconsistent angle", AT_MOST,
                            lambda c: c.st.fit.sigmas, "fit.sigmas",
                            "families' tilts apart (standard errors)")
FOREIGN_WIDTH = Check("foreign_line.width", "foreign line", WITHIN,
                      lambda c, narrowest: c.st.lines.width_ratio * narrowest
                      + c.st.lines.width_slack + 2.0 * c.tol_px, "lines.width_ratio, width_slack",

                      "widest line's width (px)")
FOREIGN_CONTRAST = Check("foreign_line.contrast", "foreign line", AT_MOST,
                         lambda c, along: c.st.lines.contrast_ratio * max(1.0, along),
                         "lines.contrast_ratio",
                         "largest / smallest contrast")
CROSSINGS_READ = Check("foreign_line.crossings_read", "foreign line", AT_LEAST,
                       lambda c: 1.0, "lines.crossing_reach, crossing_min_reach",
                       "lines read beside a crossing")
CROSSINGS = Check("foreign_line.crossings", "foreign line", AT_MOST,
                  lambda c: c.st.lines.crossing_ratio, "lines.crossing_ratio",
                  "largest depth ratio at a crossing")
CROSSINGS_UNREAD = Check("foreign_line.unread", "foreign line", AT_MOST, lambda c: 0.0,
                         "lines.contrast_ratio", "unread lines unlike the read ones")
FOREIGN_BESIDE = Check("foreign_line.beside", "foreign line", BELOW,
                       lambda c: c.st.lines.beside_share, "lines.beside_share",
                       "second dip beside a line / its depth")
FOREIGN_SHOULDER = Check("foreign_line.shoulder", "foreign line", AT_MOST,
                         lambda c: c.st.lines.shoulder_px, "lines.shoulder_px",
                         "a line's 25/75 % midpoints off its 50 % (px)")
SPACING_MISSING = Check("spacing.missing", "inconsistent spacing", AT_MOST, lambda c: 0.0,
                        "lattice.min_chord, found_share", "a predicted line missing")
SPACING = Check("spacing", "inconsistent spacing", AT_MOST,
                lambda c: c.st.lattice.spacing_fraction * c.bound_px + 2.0 * c.tol_px,
                "lattice.spacing_fraction, scale.position_px", "worst line off the lattice (px)")
EVIDENCE = Check("evidence", "too few segments", AT_LEAST,
                 lambda c: c.st.lattice.min_evidence * c.side, "lattice.min_evidence",
                 "line length in view (px)")
BOUND_POSITION = Check("bound.position", "imprecise", AT_MOST,
                       lambda c, tolerance: max(c.vision.position_error_px, c.st.bound.max_px)
                       + tolerance,
                       "bound.max_px, VisionConfig.position_error_px",
                       "the view's position bound, declared or from the fit's sums (px)")
BOUND_HEADING = Check("bound.heading", "imprecise", AT_MOST,
                      lambda c, tolerance: max(c.vision.heading_error, c.st.bound.max_rad)
                      + tolerance,
                      "bound.max_rad, VisionConfig.heading_error",
                      "the view's heading bound, declared or from the fit's sum (rad)")
FOREIGN_POLARITY = Check("foreign_line.polarity", "foreign line", AT_MOST,
                         lambda c, bound: max(bound - c.tol_px, 0.0), "",
                         "the decided polarity's deeper lines' farthest from this lattice, px")
FOREIGN_EDGE = Check("foreign_edge", "foreign line", AT_MOST, lambda c: 0.0,
                     "foreign.length, min_length, contrast",
                     "long straight edges off the lattice")

CHECKS: dict[str, Check] = {c.id: c for c in (
    CONSTANT_RANGE, CONSTANT_THIN, GLARE_SATURATED, GLARE_PATCHES, HEADING_GRADIENTS,
    LINES_FOUND, CONTRAST_DEPTH, LINES_FAMILIES, FOREIGN_LEFT_OUT, BLUR_RISE, STEP_LEVELS,
    ANGLE_STRAIGHT, ANGLE_PERPENDICULAR, FOREIGN_WIDTH, FOREIGN_CONTRAST, CROSSINGS_READ, CROSSINGS,
    CROSSINGS_UNREAD, FOREIGN_BESIDE, FOREIGN_SHOULDER, SPACING_MISSING, SPACING, EVIDENCE,
    BOUND_POSITION, BOUND_HEADING, FOREIGN_EDGE, FOREIGN_POLARITY)}
"""Every check by id, in the order they run."""


_new_result = tuple.__new__
"""Makes a CheckResult from its fields' tuple without a Python-level call (a view runs a few
dozen checks)."""


class Record:
    """The checks run so far on one view or one reading, in order (``results``)."""

    __slots__ = ("results",)

    def __init__(self) -> None:
        self.results: list[CheckResult] = []

    def check(self, check: Check, context: Context, value: float, *extra: float,
              subject: str = "") -> bool:
        """Run ``check`` on ``value`` (its limit from ``context`` and ``extra``), record the
        result and return whether it passed."""
        v, lim = float(value), float(check.limit(context, *extra))
        rel = check.relation
        ok = rel.test(v, lim) != rel.negate
        self.results.append(_new_result(CheckResult, (check.id, v, lim, rel.symbol, ok,
                                                      subject)))
        return ok

    def require(self, check: Check, context: Context, value: float, *extra: float,
                subject: str = "", reason: str | None = None) -> None:
        """:meth:`check`, raising :class:`Refusal` (``reason``, default the check's) when it
        fails."""
        v, lim = float(value), float(check.limit(context, *extra))
        rel = check.relation
        ok = rel.test(v, lim) != rel.negate
        result = _new_result(CheckResult, (check.id, v, lim, rel.symbol, ok, subject))
        self.results.append(result)
        if not ok:
            raise Refusal(result, reason or check.reason)
