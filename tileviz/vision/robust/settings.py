"""Every threshold of the robust extractor (:class:`RobustSettings`), grouped by stage, with its
default: gray levels 0..255, pixels (px), radians (rad).

One group per stage of :mod:`tileviz.vision.robust`: :class:`StatisticsSettings` (step 1),
:class:`HeadingSettings` (step 2 and the headings read again), :class:`ProfileSettings` (steps
3-4: the profiles, their dips and the parts they are measured in), :class:`SelectionSettings`
(which dips are lines), :class:`LineSettings` (the checks on the lines), :class:`FitSettings`
(the common fit of the parts), :class:`ScaleSettings` (the scale of the consistency checks),
:class:`LatticeSettings` (spacing and evidence), :class:`BoundSettings` (the view's own error
bound), :class:`ForeignSettings` (edges off the lattice) and :class:`CheckerSettings` (a
checkerboard recognised from the view). Every check's limit is computed
from these in one place, :mod:`.checks` (its docstring lists the check ids and the settings
each reads).

What is here: every value a decision is compared with (keep or drop, accept or refuse, read
again or not) and every tunable scale of the search. What is not: the definitions of the
measurements themselves (the half-depth crossings at 50 %, the 25 / 75 % midpoints, the 20-80 %
rise, plateaus of 4 samples, a dip's window of 1.5 x its half-depth width + 1.5, the median
absolute deviation's 1.4826), which are the method (docs/vision.md), and the constants of the
operators (Scharr's gain).

``RobustSettings()`` holds the defaults; a variant replaces one group, e.g.
``replace(DEFAULT_SETTINGS, lines=replace(DEFAULT_SETTINGS.lines, max_rise=5.0))``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["DEFAULT_SETTINGS", "BoundSettings", "CheckerSettings", "FitSettings",
           "ForeignSettings",
           "HeadingSettings", "LatticeSettings", "LineSettings", "ProfileSettings",
           "RobustSettings", "ScaleSettings", "SelectionSettings", "StatisticsSettings"]


@dataclass(frozen=True)
class StatisticsSettings:
    """Step 1, the gray statistics: ``constant image`` and ``glare``."""

    range_quantiles: tuple[float, float] = (0.02, 0.98)
    """Quantiles whose gray levels span the view's range (``constant.range``)."""
    min_range: float = 6.0
    """Gray range (``range_quantiles``) below which the image is ``constant image``, unless
    its thin structure shows (``min_thin_range``)."""
    thin_quantiles: tuple[float, float] = (0.002, 0.998)
    """Quantiles whose gray levels span the range of thin structure (``constant.thin_range``)."""
    min_thin_range: float = 24.0
    """Gray range (``thin_quantiles``) at or above which an image of narrower 2-98 range still
    has structure: thin grout lines on a large tile cover under 2 % of the pixels (1 px lines
    across a 320x240 view about 1.5 %); camera noise alone on a blank frame narrow enough for
    the 2-98 test (sigma under 1.5 levels) spans under 9 levels there."""
    saturated_level: int = 250
    """A pixel at or above this gray level is saturated."""
    glare_fraction: float = 0.04
    """Fraction of saturated pixels (``glare.saturated``), and of pixels inside a saturated
    patch ``glare_patch`` px across (``glare.patches``), above which the frame is refused as
    ``glare`` (scattered saturated specks of a light texture are not glare)."""
    glare_patch: int = 7
    """Side of the square a saturated patch must hold to count as glare, px."""


@dataclass(frozen=True)
class HeadingSettings:
    """Step 2, the heading from the gradient directions, and the headings read again when the
    first one's lines fail (:mod:`.readings`)."""

    share: float = 0.2
    """Share of the pixels (the strongest gradients) that vote for the heading."""
    min_voters: int = 20
    """Fewest pixels that vote (of the every-other-row-and-column grid)."""
    bins: int = 90
    """Bins of the 4 phi histogram (4 degrees of 4 phi, 1 of phi)."""
    near: float = 0.35
    """Votes within this angle (rad, of 4 phi) of the histogram's peak are averaged."""
    smoothing: tuple[float, ...] = (1.0, 2.0)
    """Gaussian stds (px) of the smoothed views whose votes are read again (strong noise can
    outvote thin grout pixel by pixel)."""
    lattice_scale: float = 0.5
    """The periodicity search's coarse pass reads the view at this scale."""
    lattice_coarse_step: float = 0.01
    """Step of the coarse periodicity search over [-pi/4, pi/4), rad."""
    lattice_fine_span: float = 0.012
    """The fine periodicity search spans this much either side of the coarse best, rad."""
    lattice_fine_step: float = 0.002
    """Step of the fine periodicity search, rad."""
    lattice_harmonics: int = 4
    """Harmonics of the tile period the periodicity is measured on."""
    sharpen_span: float = 0.06
    """The sharpened headings are searched this far (rad) either side of each heading read."""
    sharpen_coarse_step: float = 0.01
    """Step of that search, rad (on a grid common to every heading searched around)."""
    sharpen_fine_step: float = 0.002
    """Step of the fine search, one coarse step either side of the coarse best, rad."""
    sharpen_wavelength: float = 4.0
    """The sharpness is measured on the harmonics of the tile period down to this wavelength
    (px): a thin line's profile is sharp only at the right heading, a few harmonics are not."""
    sharpen_readings: int = 2
    """Sharpened headings read at most (the sharpest first)."""
    same_heading: float = 0.004
    """A heading within this (rad, modulo pi/2) of one already read is not read again."""
    refine_tilt: float = 0.012
    """Heading correction (rad) above which the warp is redone."""
    max_warps: int = 3
    """Warps of one reading at most (the first and its redos)."""


@dataclass(frozen=True)
class ProfileSettings:
    """Steps 3-4, the family profiles of the warped view, their dips and the parts each dip is
    measured in."""

    min_row: float = 8.0
    """A warp row (column) shorter than this in view, px, is not part of its profile."""
    min_row_share: float = 0.15
    """... nor one shorter than this share of its family's longest."""
    min_rows: int = 8
    """A family with fewer rows (profile samples) than this has no profile noise and no say
    in the grout's polarity."""
    dip_noise: float = 5.0
    """A dip is a run of profile samples darker than this many profile noise stds below the
    profile's grey closing (and at least half of the ``contrast.depth`` limit)."""
    closing_share: float = 0.17
    """The grey closing spans 2 x this share of the tile period + 1 samples, ..."""
    closing_min: float = 8.0
    """... the half-width at least this many px ..."""
    closing_max: float = 30.0
    """... and at most this many (a grout band up to ~20 px wide on any floor whose tiles span
    80 px or more)."""
    window: int = 20
    """Half-size of the window each dip is measured in at first, samples (grout up to ~9 px
    wide), at most the closing's width + ``window_slack``."""
    window_slack: int = 8
    """The widest window: the closing's width + this, samples."""
    window_per_width: float = 1.5
    """A band wider than the window is measured again with a half-window of this many times
    its half-depth width + ``window_margin`` (up to the widest)."""
    window_margin: float = 12.0
    """See ``window_per_width``, samples."""
    wide_family: int = 2
    """A family with this many strong dips or more (``selection.rel_depth`` of the deepest,
    and as deep as ``contrast.depth`` asks of a line) that the window cannot measure (band
    and plateaus reach past it) is measured again in a
    window of its own fitting their median half-depth width (``window_per_width``): its grout
    is wider than the other family's (the two families of joints of a mosaic), not one stain
    or shadow."""
    min_part: float = 20.0
    """Shortest stretch of a line measured on its own (a part), px."""


@dataclass(frozen=True)
class SelectionSettings:
    """Which dips are grout lines: depth, width, and the tile period (:mod:`.periodic`)."""

    rel_depth: float = 0.3
    """A dip counts as a line when at least this fraction of the deepest dip."""
    strong_share: float = 0.5
    """The strong dips (at least this share of the deepest's depth) give the reference width."""
    wide_ratio: float = 2.0
    """A dip wider than this many times the strong dips' median width (+ ``wide_slack`` px) is
    not a line (a shadow, a stain)."""
    wide_slack: float = 2.0
    """See ``wide_ratio``, px."""
    phase_tolerance: float = 0.04
    """A dip is on a phase when within this fraction of the tile period of it (modulo the
    period); a dip kept a little off (more than the spacing check allows) is refused there."""
    weak_share: float = 0.5
    """A dip off the phase is dropped when its evidence (depth x measured length) is under this
    share of the strongest line on the phase, unless it runs along its whole line (measured in
    ``like_parts`` parts or more) and looks like the other family's grout."""
    like_parts: int = 3
    """See ``weak_share``."""
    like_depth: float = 0.8
    """A dip as deep as this share of the other family's deepest is as deep as the grout."""
    like_width: float = 1.3
    """A dip whose half-depth width is within this factor (+ ``like_slack`` px) of the other
    family's deepest dip's is as wide as the grout."""
    like_slack: float = 1.0
    """See ``like_width``, px."""


@dataclass(frozen=True)
class LineSettings:
    """Step 6, the checks on the measured lines (``no lines`` .. ``foreign line``)."""

    min_depth: float = 15.0
    """Weakest grout dip trusted in a noisy view, gray levels (``contrast.depth``: ``low
    contrast`` when the deepest is weaker) ..."""
    depth_noise: float = 5.0
    """... in a quieter view the deepest dip must reach this many times the noise std of a
    part's profile (the camera's noise measured on the view, at least the 8-bit rounding's,
    over the square root of ``profiles.min_part``: a part averages at least that many pixels
    along its line): no fixed number of levels, so faint grout through a plain camera is read
    where it stands above the view's own noise."""
    rounding_noise: float = 0.2887
    """The least noise std a view has, gray levels: the 8-bit rounding's, 1 / sqrt(12) (a view
    with no camera noise measured)."""
    max_rise: float = 6.0
    """Median 20-80 % edge rise of the lines above which the view is ``blurred``, px (a blur
    costs bound, not soundness: a softer edge widens each part's own bound and the floor term
    ``bound.floor_rise``; a wide band under 1.2-1.8 px of blur, JPEG and strong vignetting
    rises 4-6 px)."""
    max_step: float = 0.85
    """|level left - level right| / brighter level above which a line is a ``step edge``."""
    straight_fraction: float = 1.0
    """A line's parts may sit at most this fraction of the position check scale off the common
    fit (``angle.straight``)."""
    straight_part_share: float = 0.25
    """Only parts at least this share of their line's longest part count in the straightness."""
    stray_share: float = 0.5
    """Read again without its stray part, a line's other parts must lie within this share of
    the straightness limit of their own mean offset from the fit ..."""
    stray_min_rest: int = 2
    """... and be at least this many."""
    width_ratio: float = 1.5
    """Lines may differ in half-depth width at most by this factor (+ ``width_slack`` px)."""
    width_slack: float = 1.0
    """See ``width_ratio``, px."""
    contrast_ratio: float = 1.7
    """Lines may differ in contrast (depth / level) at most by this factor."""
    crossing_ratio: float = 1.3
    """Lines of lighter grout that differ in contrast beyond ``contrast_ratio`` (tiles of
    strongly different shades under uneven light) are one grout when, beside every crossing
    of two of them that the view holds, their depths differ at most by this factor
    (:func:`~tileviz.vision.robust.crossings.crossings_agree`)."""
    crossing_reach: int = 20
    """Longest stretch (px) of each line read on each side of a crossing, beyond the other
    line's band."""
    crossing_min_reach: int = 6
    """Shortest such stretch (px): a crossing nearer the border of the view is not read."""
    beside_share: float = 0.3
    """A line is foreign when the profile holds, within its measurement window and as far as
    the lattice spacing would not show that dip read instead (:func:`~tileviz.vision.robust.
    fit.unseen_reach`), another dip at least this share of the line's depth, apart from it (the
    darkness between them falls below ``beside_apart`` of that dip's): a cable laid a few px
    beside a grout line (:func:`~tileviz.vision.robust.profiles.beside_dip`). The share at
    which the selection counts a dip as a line (``SelectionSettings.rel_depth``): a thin joint
    beside a wide cable, or a joint whose dip the panels' offsets smear, is well under half the
    cable's."""
    beside_same_px: float = 2.0
    """A band beside a line among others of its family is the floor's own (a bevel, a double
    joint), not bounded, when another line of the family has one within this many px of the
    same offset (:func:`~tileviz.vision.robust.fit.beside_reach`)."""
    unlike_others: int = 2
    """A reading that leaves out the line most unlike the others (``Reading.unlike``: a panel's
    seam, a cable along a joint) does so in a family where at least this many other lines
    remain to agree (``foreign_line.left_out``)."""
    beside_apart: float = 0.75
    """See ``beside_share``: two dips are apart when the darkness between them falls below
    this share of the shallower one's, a valley between two bands (a cable 4 px beside light
    grout under blur keeps about half of the grout's darkness between them; the bottom of one
    band, noisy, keeps more)."""
    shoulder_px: float = 0.75
    """A line has a shoulder when, in every part of it measured (two or more), its 25 % and 75 %
    midpoints lie more than this many px off its 50 % midpoint (a dark cable touching a grout
    line, the grout shallower than half the cable's depth, is read as the cable; clean grout
    keeps them within a few tenths of a px): it is refused as foreign, or, on a shoulder
    reading, bounded by its band at a quarter of its depth."""


@dataclass(frozen=True)
class FitSettings:
    """Step 5, the common fit of every line's parts, and the errors it gives."""

    sigmas: float = 4.0
    """The fit's own standard errors times this must stay within the declared bounds (the
    position bound's scatter term), and the two families' tilts must agree within this many
    standard errors (``angle.perpendicular``)."""
    part_sigmas: float = 4.0
    """A part's own bound: this many of its predicted standard errors (its profile's
    roughness over its edges' slopes) plus the spread of its 25/50/75 % midpoints."""
    prior_sigma: float = 1.5
    """Prior scatter of a part's position at unit part length, px sqrt(px) (0.15 px for a
    100 px part), weighing ``prior_dof`` degrees of freedom."""
    prior_dof: float = 2.0
    """Degrees of freedom the prior scatter ``prior_sigma`` weighs in the fit's scatter."""


@dataclass(frozen=True)
class ScaleSettings:
    """The scale of the consistency checks (straightness, spacing)."""

    position_px: float = 2.0
    """Scale of the position consistency checks, px: they use the smaller of this and the
    declared ``VisionConfig.position_error_px``."""
    heading: float = 0.02
    """Scale of the heading consistency, rad (the smaller of this and ``heading_error``)."""


@dataclass(frozen=True)
class LatticeSettings:
    """The lattice: line spacing, missing lines, evidence (``inconsistent spacing``, ``too few
    segments``)."""

    spacing_fraction: float = 0.5
    """A line may sit at most this fraction of the position check scale off the lattice."""
    found_share: float = 0.25
    """A predicted line is found when a measured line lies within this share of the period."""
    min_chord: float = 0.35
    """A lattice line is expected (``inconsistent spacing`` when missing) where its chord is at
    least this fraction of the longest chord in the view."""
    min_evidence: float = 0.5
    """Total line length per family, as a fraction of the smaller image side."""


@dataclass(frozen=True)
class BoundSettings:
    """The view's own error bound (:mod:`.bound`) and the largest a view may declare."""

    heading_sigmas: float = 6.0
    """The heading bound is this many standard errors of the fitted tilt (plus ``floor_rad``):
    the tilt's error has heavier tails than the positions' (bench/vision_study.py)."""
    floor_px: float = 0.1
    """Smallest position bound of a view, px (with ``floor_width`` x the grout's half-depth
    width and ``floor_rise`` x its edge rise added: :func:`.bound.part_floor`); where the
    parts' own bounds allow no lattice, each part is allowed it too."""
    floor_width: float = 0.02
    """Part of the grout's half-depth width (px per px) added to the position bound."""
    floor_rise: float = 0.05
    """Part of the grout's 20-80 % edge rise (px per px) added to the position bound."""
    floor_rad: float = 0.0005
    """Smallest heading bound of a view, rad."""
    max_px: float = 5.0
    """Largest position bound a view may declare, px, unless the configured
    ``VisionConfig.position_error_px`` is larger: a view whose own bound exceeds both is refused
    (``imprecise``). A wider bound is honest, only loose: the localizer's box contracts less
    on it than on a tight one, never more than its evidence allows."""
    max_rad: float = 0.05
    """Largest heading bound a view may declare, rad, unless ``VisionConfig.heading_error`` is
    larger (as ``max_px``)."""


@dataclass(frozen=True)
class ForeignSettings:
    """The last checks: long straight edges the predicted grout lines do not explain
    (:mod:`.foreign`, :mod:`.grout_levels`)."""

    length: float = 0.3
    """Straight edges off the lattice longer than this fraction of the smaller side refuse ..."""
    min_length: float = 25.0
    """... and at least this many px."""
    vote_share: float = 0.5
    """A straight edge needs this share of its shortest length in Hough votes."""
    max_gap: float = 3.0
    """Largest gap (px) the Hough transform bridges along a straight edge."""
    contrast: float = 0.35
    """Edges weaker than this fraction of the grout's depth (a step of that many gray levels)
    are not searched for foreign objects."""
    min_edge: float = 240.0
    """... nor edges weaker than this (Scharr gradient magnitude, 16 x a step's gray levels) ..."""
    edge_noise: float = 6.0
    """... nor edges within this many noise stds of the gradient's noise."""
    canny_low: float = 0.5
    """Canny's low hysteresis threshold, as a share of its high one."""
    parallel: float = 0.03
    """An edge runs along a line family when its direction is within this angle (rad) of it: it
    crosses the other family's lines nearly at right angles, adding about the same to every
    sample of their profiles (:func:`~tileviz.vision.robust.foreign.clear_of_lattice`)."""
    grout_like: float = 0.25
    """A family's profile dipping at least this share of the other family's grout depth along
    an edge shows grout there."""
    texture_share: float = 0.75
    """A straight edge with a smaller share of its points seen as an edge normal to it is a
    chance alignment of texture edges."""
    normal_tolerance: float = math.radians(25.0)
    """An edge pixel belongs to a straight edge when its gradient is this close to the edge's
    normal (rad)."""
    inside_steps: int = 4
    """An edge followed from its end ends inside its tile when at least this many steps lead to
    the next grout band and at most ``seen_share`` of them see it."""
    far_steps: int = 6
    """Beyond a grout band, at least this many steps up to the next band are needed to read
    whether the edge goes on (seen on at least ``seen_share`` of them)."""
    seen_share: float = 0.5
    """See ``inside_steps`` and ``far_steps``."""
    straddle_sigmas: float = 3.0
    """An edge crosses the grout when the grout's gray level differs on its two sides by more
    than this many times the image's noise plus ``straddle_levels``."""
    straddle_levels: float = 4.0
    """See ``straddle_sigmas``, gray levels."""
    straddle_parallel: float = 0.05
    """The grout is read where a line crosses it at an angle (rad, sine) of at least this when
    both sides of the crossing are in view, ..."""
    straddle_one_sided: float = 0.15
    """... at least this when only one is."""
    variation_clear: int = 19
    """The grout's own variation is read on stretches of its line at least this many samples
    clear of the crossing's, ..."""
    variation_stretches: int = 10
    """... on at least this many stretches."""
    conclusive: float = 2.0
    """An edge seen beyond the grout is taken for texture only when the grout's level there
    shows no crossing, and any object seen beside the grout would have changed it by this many
    times the straddle's limit."""


@dataclass(frozen=True)
class CheckerSettings:
    """Checkerboards (:mod:`.checker`): recognising one the user did not declare (every piece
    of every line its edge image read must be one step between two tiles' levels), and on every
    checkerboard the tiles beside each line swapping shades at its crossings."""

    min_piece: float = 0.25
    """A piece of a line between two crossings (or a crossing and the border) is measured
    when its middle is at least this share of the tile period long ..."""
    piece_margin: float = 0.15
    """... its ends this share of it left out (the crossings' corners)."""
    reach: float = 0.12
    """The profile across a line spans this share of the tile period each side ..."""
    min_reach: float = 6.0
    """... at least this many px."""
    plateau: float = 2.0
    """A side's level: the mean of the profile's outer this many px on that side."""
    step_sigmas: float = 6.0
    """The two sides' levels differ by at least this many times the profile's noise (and, on
    every checkerboard, each pair of neighbouring tiles around a crossing differs by as much,
    the way a checkerboard's alternate: :func:`~tileviz.vision.robust.checker.sides_alternate`)
    ..."""
    min_step: float = 6.0
    """... and at least this many gray levels."""
    single_edge: float = 0.5
    """The profile's slope the step's way reaches this share of its steepest over one stretch
    only: a band of a third level between two edges is two."""
    band_edge: float = 0.15
    """A slope against the step steeper than this share of the steepest (and than 3 times its
    noise) is an edge the other way: a band's far side (a thin grout) ..."""
    max_band: float = 0.03
    """... and a piece's reach (the farther of its steepest point and such an edge from the
    line read) is at most this share of the tile period; a second reading with the floor's
    tolerance widened by the largest reach widens the first's bounds."""
    min_pieces: int = 2
    """A view is recognised as a checkerboard from this many pieces, every one a step."""


@dataclass(frozen=True)
class RobustSettings:
    """Every threshold of the robust extractor, one group per stage (module docstring)."""

    statistics: StatisticsSettings = field(default_factory=StatisticsSettings)
    heading: HeadingSettings = field(default_factory=HeadingSettings)
    profiles: ProfileSettings = field(default_factory=ProfileSettings)
    selection: SelectionSettings = field(default_factory=SelectionSettings)
    lines: LineSettings = field(default_factory=LineSettings)
    fit: FitSettings = field(default_factory=FitSettings)
    scale: ScaleSettings = field(default_factory=ScaleSettings)
    lattice: LatticeSettings = field(default_factory=LatticeSettings)
    bound: BoundSettings = field(default_factory=BoundSettings)
    foreign: ForeignSettings = field(default_factory=ForeignSettings)
    checker: CheckerSettings = field(default_factory=CheckerSettings)


DEFAULT_SETTINGS = RobustSettings()
