"""Prediction of a box with bounded odometry (docs/method.md, "Prediction") and its intersection
with a compass reading; every bound outward rounded."""

from __future__ import annotations

import math

from tileviz.core.intervals import (
    TWO_PI,
    TWO_PI_ERROR,
    cos_sin_range,
    lattice_intersect,
    mul,
)
from tileviz.types import Box

__all__ = ["compass_pieces", "predict_box"]

_INF = math.inf
_nextafter = math.nextafter


def predict_box(
    b: Box, v_lo: float, v_hi: float, w_lo: float, w_hi: float, dt: float
) -> Box:
    """Enclosure of every pose reachable from box ``b`` in ``dt`` s (docs/method.md, "Prediction").

    The true speed v(s) in [v_lo, v_hi] (m/s) and yaw rate w(s) in [w_lo, w_hi] (rad/s) may vary
    over the step. The heading theta(s) = theta0 + int_0^s w stays in
    H = hull([t], [t] + dt [w]); the displacement int_0^dt v(s) (cos, sin)(theta(s)) ds lies in
    dt * hull{v cos h : v in [v], h in H} (resp. sin) because the integrand never leaves that
    interval; the final heading is in [t] + dt [w]. Every bound is outward rounded.
    """
    x_lo, x_hi, y_lo, y_hi, t_lo, t_hi = b
    n = _nextafter
    tn_lo = n(t_lo + n(dt * w_lo, -_INF), -_INF)
    tn_hi = n(t_hi + n(dt * w_hi, _INF), _INF)
    h_lo = t_lo if t_lo < tn_lo else tn_lo
    h_hi = t_hi if t_hi > tn_hi else tn_hi
    c_lo, c_hi, s_lo, s_hi = cos_sin_range(h_lo, h_hi)
    d_lo = n(dt * v_lo, -_INF)
    d_hi = n(dt * v_hi, _INF)
    if d_lo >= 0.0:
        # moving forward: which of the four products is the least / greatest follows from the
        # signs (rounding is monotone, so these are mul's min and max, up to the sign of a zero,
        # which the outward step removes)
        dx_lo = n((d_lo if c_lo >= 0.0 else d_hi) * c_lo, -_INF)
        dx_hi = n((d_hi if c_hi >= 0.0 else d_lo) * c_hi, _INF)
        dy_lo = n((d_lo if s_lo >= 0.0 else d_hi) * s_lo, -_INF)
        dy_hi = n((d_hi if s_hi >= 0.0 else d_lo) * s_hi, _INF)
    else:
        dx_lo, dx_hi = mul(d_lo, d_hi, c_lo, c_hi)
        dy_lo, dy_hi = mul(d_lo, d_hi, s_lo, s_hi)
    return Box(
        n(x_lo + dx_lo, -_INF),
        n(x_hi + dx_hi, _INF),
        n(y_lo + dy_lo, -_INF),
        n(y_hi + dy_hi, _INF),
        tn_lo,
        tn_hi,
    )


def compass_pieces(b: Box, h_lo: float, h_hi: float) -> list[Box]:
    """Box ``b`` with its heading intersected with [h_lo, h_hi] + 2 pi Z (the compass reading
    +- its bound, any 2 pi shift): zero, one or (for a wide heading) several boxes."""
    pieces = lattice_intersect(b[4], b[5], h_lo, h_hi, TWO_PI, period_error=TWO_PI_ERROR)
    if len(pieces) == 1:  # the usual case, without a comprehension's frame
        lo, hi = pieces[0]
        return [Box(b[0], b[1], b[2], b[3], lo, hi)]
    return [Box(b[0], b[1], b[2], b[3], lo, hi) for lo, hi in pieces]
