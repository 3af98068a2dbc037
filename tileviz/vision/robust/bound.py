"""The error bound of one view from its own evidence (docs/vision.md, "The bound of a view")."""

from __future__ import annotations

from tileviz.vision.robust.state import ReadingState

__all__ = ["frame_bound", "part_floor"]


def frame_bound(run: ReadingState, se: float, position_parts: float,
                heading_parts: float) -> tuple[float, float]:
    """This view's error bound (px, rad) from its own evidence (docs/vision.md, "The
    bound of a view"): ``sigmas`` standard errors of the fit (the scatter of every line's
    parts about one straight lattice), plus the parts' terms (``position_parts`` px,
    ``heading_parts`` rad: what the parts' own bounds allow), plus the largest deviations the
    fit could not explain (a line off the lattice spacing, half the worst part off its line,
    half a line's width beyond the narrowest line's, chord-weighted as the lines' offsets
    are), plus a floor for what the scatter cannot show (interpolation, a band's width under
    uneven light, blur)."""
    st = run.st.bound
    d = run.details
    # a floor's lattice tolerance is in every part's own bound (position_parts): of the
    # spacing and straightness residuals, only what it does not explain is added again
    tol2 = 2.0 * run.tol_px
    pos = part_floor(run, run.st.fit.sigmas * se + max(d["spacing_residual_px"] - tol2, 0.0)
                     + 0.5 * max(d["straightness_px"] - tol2, 0.0)
                     + position_parts + d["width_excess_px"])
    head = st.heading_sigmas * d["heading_se"] + heading_parts + st.floor_rad
    return pos, head


def part_floor(run: ReadingState, base: float = 0.0) -> float:
    """``base`` (px) plus what the scatter and the parts' own bounds cannot show (px): the
    warp's interpolation and the pixel grid, a band's width under uneven light, blur:
    ``bound.floor_px`` plus ``floor_width`` x the grout's half-depth width plus ``floor_rise``
    x its edge rise."""
    st = run.st.bound
    d = run.details
    return base + st.floor_px + st.floor_width * d["width"] + st.floor_rise * d["rise"]
