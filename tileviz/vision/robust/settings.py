"""Thresholds of the robust extractor (:class:`RobustSettings`) and their defaults."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DEFAULT_SETTINGS", "RobustSettings"]


@dataclass(frozen=True)
class RobustSettings:
    """Thresholds of the robust extractor (gray levels 0..255, pixels, radians)."""

    min_range: float = 6.0
    """Gray range (2nd to 98th percentile) below which the image is ``constant image``,
    unless its thin structure shows (``min_thin_range``)."""
    min_thin_range: float = 24.0
    """Gray range (0.2th to 99.8th percentile) at or above which an image of narrower 2-98
    range still has structure: thin grout lines on a large tile cover under 2 % of the
    pixels (1 px lines across a 320x240 view about 1.5 %); camera noise alone on a blank
    frame narrow enough for the 2-98 test (sigma under 1.5 levels) spans under 9 levels
    there."""
    glare_fraction: float = 0.04
    """Fraction of pixels >= 250, and of pixels inside a saturated patch ``glare_patch`` px
    across, above which the frame is refused as ``glare`` (scattered saturated specks of a
    light texture are not glare)."""
    glare_patch: int = 7
    """Side of the square a saturated patch must hold to count as glare, px."""
    min_depth: float = 15.0
    """Weakest grout dip trusted, gray levels (``low contrast`` when the deepest is weaker)."""
    rel_depth: float = 0.3
    """A dip counts as a line when at least this fraction of the deepest dip."""
    max_rise: float = 6.0
    """Median 20-80 % edge rise of the lines above which the view is ``blurred``, px (a blur
    costs bound, not soundness: a softer edge widens each part's own bound and the floor term
    ``floor_rise``; a wide band under 1.2-1.8 px of blur, JPEG and strong vignetting rises 4-6
    px)."""
    max_step: float = 0.85
    """|level left - level right| / brighter level above which a line is a ``step edge``."""
    spacing_fraction: float = 0.5
    """A line may sit at most this fraction of the declared position bound off the lattice."""
    straight_fraction: float = 1.0
    """A line's parts may sit at most this fraction of the position bound off the common fit."""
    min_chord: float = 0.35
    """A lattice line is expected (``inconsistent spacing`` when missing) where its chord is at
    least this fraction of the longest chord in the view."""
    min_evidence: float = 0.5
    """Total line length per family, as a fraction of the smaller image side."""
    width_ratio: float = 1.5
    """Lines may differ in half-depth width at most by this factor (+ ``width_slack`` px)."""
    width_slack: float = 1.0
    beside_share: float = 0.5
    """The one line of its family in view is foreign when the profile holds, within its measurement
    window, another dip at least this share of the line's depth, apart from it (the darkness
    between them falls below half of that dip's): a cable laid a few px beside a grout line
    (:func:`~tileviz.vision.robust.profiles.beside_dip`)."""
    shoulder_px: float = 0.75
    """A line is foreign when, in every part of it measured (two or more), its 25 % and
    75 % midpoints lie more than this many px off its 50 % midpoint: a band with a shoulder
    (a dark cable touching a grout line, the grout shallower than half the cable's depth,
    is read as the cable; clean grout keeps them within a few tenths of a px)."""
    contrast_ratio: float = 1.7
    """Lines may differ in contrast (depth / level) at most by this factor."""
    crossing_ratio: float = 1.3
    """Lines of lighter grout that differ in contrast beyond ``contrast_ratio`` (tiles of
    strongly different shades under uneven light) are one grout when, beside every crossing
    of two of them that the view holds, their depths differ at most by this factor
    (:func:`~tileviz.vision.robust.crossings.crossings_agree`)."""
    foreign_length: float = 0.3
    """Straight edges off the lattice longer than this fraction of the smaller side refuse."""
    foreign_contrast: float = 0.35
    """Edges weaker than this fraction of the grout's depth (a step of that many gray levels)
    are not searched for foreign objects."""
    heading_share: float = 0.2
    """Share of the pixels (the strongest gradients) that vote for the heading."""
    refine_tilt: float = 0.012
    """Heading correction (rad) above which the warp is redone."""
    check_position_px: float = 2.0
    """Scale of the position consistency checks, px: they use the smaller of this and the
    declared ``VisionConfig.position_error_px``."""
    check_heading: float = 0.02
    """Scale of the heading check, rad (the smaller of this and ``heading_error``)."""
    min_part: float = 20.0
    """Shortest stretch of a line measured on its own (a part), px."""
    sigmas: float = 4.0
    """The fit's own standard errors times this must stay within the declared bounds."""
    prior_sigma: float = 1.5
    """Prior scatter of a part's position at unit part length, px sqrt(px) (0.15 px for a
    100 px part), weighing ``prior_dof`` degrees of freedom."""
    prior_dof: float = 2.0
    """Degrees of freedom the prior scatter ``prior_sigma`` weighs in the fit's scatter."""
    floor_px: float = 0.1
    """Smallest position bound of a view, px (with ``floor_width`` x the grout's half-depth
    width and ``floor_rise`` x its edge rise added)."""
    floor_width: float = 0.02
    """Part of the grout's half-depth width (px per px) added to the position bound."""
    part_sigmas: float = 4.0
    """A part's own bound: this many of its predicted standard errors (its profile's
    roughness over its edges' slopes) plus the spread of its 25/50/75 % midpoints."""
    floor_rise: float = 0.05
    """Part of the grout's 20-80 % edge rise (px per px) added to the position bound."""
    floor_rad: float = 0.0005
    """Smallest heading bound of a view, rad."""
    max_bound_px: float = 5.0
    """Largest position bound a view may declare, px, unless the configured
    ``VisionConfig.position_error_px`` is larger: a view whose own bound exceeds both is refused
    (``imprecise``). A wider bound is honest, only loose: the localizer's box contracts less
    on it than on a tight one, never more than its evidence allows."""
    max_bound_rad: float = 0.05
    """Largest heading bound a view may declare, rad, unless ``VisionConfig.heading_error`` is
    larger (as ``max_bound_px``)."""
    heading_sigmas: float = 6.0
    """The heading bound is this many standard errors of the fitted tilt (plus ``floor_rad``):
    the tilt's error has heavier tails than the positions' (bench/vision_study.py)."""


DEFAULT_SETTINGS = RobustSettings()
