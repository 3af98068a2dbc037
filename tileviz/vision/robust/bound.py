"""The error bound of one view from its own evidence (docs/vision.md, "The bound of a view")."""

from __future__ import annotations

from tileviz.vision.robust.state import RobustRun

__all__ = ["frame_bound"]


def frame_bound(run: RobustRun, se: float) -> tuple[float, float]:
    """This view's error bound (px, rad) from its own evidence (docs/vision.md, "The
    bound of a view"): ``sigmas`` standard errors of the fit (the scatter of every line's
    parts about one straight lattice), plus the largest deviations the fit could not
    explain (a line off the lattice spacing, half the worst part off its line), plus a
    floor for what the scatter cannot show (interpolation, a band's width under uneven
    light, blur)."""
    st = run.st
    d = run.details
    # a step between the two sides of a line (a shadow or a box edge near it, a shade step)
    # inside the centroid's window pulls the centroid off the half-depth midpoint; without
    # a step the difference is only the crossings' noise
    d["asymmetry_px"] = max(ln.asym * min(1.0, ln.step / st.asym_step)
                            for fam in run.lines for ln in fam)
    pos = (st.sigmas * se + d["spacing_residual_px"] + 0.5 * d["straightness_px"]
           + st.asym_factor * d["asymmetry_px"]
           + st.floor_px + st.floor_width * d["width"] + st.floor_rise * d["rise"])
    head = st.heading_sigmas * d["heading_se"] + st.floor_rad
    return pos, head
