"""Image-to-tile-parameter geometry shared by the extractors (docs/method.md convention).

Pixel frame: x = column, y = row, image centre ``(cx, cy) = ((W - 1) / 2, (H - 1) / 2)``. A
floor point at camera-frame coordinates ``a = (a_forward, a_left)`` metres from the camera centre
is at ``col = cx - a_left * ppm``, ``row = cy - a_forward * ppm`` (docs/dataset-format.md).

With ``b = R(y3) a``, the grout lines seen are ``{a : y1 + b1 in LZ}`` (family 1) and
``{a : y2 + b2 in LZ}`` (family 2) (report eq. 3.7, corrected signs). So a line of family k lies
where its signed offset ``s_k = n_k . a`` equals ``jL - y_k``, with the camera-frame normals
``n_1 = (cos y3, -sin y3)`` and ``n_2 = (sin y3, cos y3)``. In pixels (see
:func:`family_normals`) a family-1 line runs along the image angle ``y3`` and a family-2 line
along ``y3 + pi/2`` (angles ``atan2(d_row, d_col)``): the segment angle gives y3 modulo pi/2, and
``y_k = -s_k mod L``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from tileviz.core.constants import HALF_PI, TWO_PI
from tileviz.types import Observation, Pose

__all__ = [
    "circular_median",
    "family_normals",
    "median",
    "observation_error",
    "wrap_quarter",
]

QUARTER = HALF_PI


def wrap_quarter(angle: float) -> float:
    """``angle`` modulo pi/2, in [-pi/4, pi/4) (radians)."""
    r = math.remainder(angle, QUARTER)  # in [-pi/4, pi/4]
    if r >= 0.25 * math.pi:
        r -= QUARTER
    return r


def family_normals(y3: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """Unit normals (in pixel coordinates: d_col, d_row) of the two line families.

    For a pixel p, ``n_k . (p - centre) / ppm`` is the family-k signed offset ``s_k`` in metres
    (the camera-frame ``n_k . a``): ``n_1 = (sin y3, -cos y3)``, ``n_2 = (-cos y3, -sin y3)``.
    """
    c, s = math.cos(y3), math.sin(y3)
    return (s, -c), (-c, -s)


def median(values: Sequence[float]) -> float:
    """The median of a non-empty sequence (plain Python: faster than numpy for a few dozen
    values)."""
    v = sorted(values)
    k = len(v) // 2
    return v[k] if len(v) % 2 else 0.5 * (v[k - 1] + v[k])


def circular_median(values: Sequence[float], period: float) -> float:
    """A median of ``values`` taken modulo ``period``, in [0, period).

    The values are first unwrapped next to their circular mean, so a cluster that straddles 0
    (e.g. 0.01 L and 0.99 L) gives a value near 0, not near L/2. Raises ValueError when empty.
    """
    if len(values) == 0:
        raise ValueError("circular_median needs at least one value")
    k = TWO_PI / period
    ref = math.atan2(sum(math.sin(k * v) for v in values), sum(math.cos(k * v) for v in values))
    ref /= k
    dev = [(v - ref + 0.5 * period) % period - 0.5 * period for v in values]
    out = (ref + median(dev)) % period
    return 0.0 if out >= period else out


def observation_error(
    y: tuple[float, float, float] | Observation,
    pose: Pose,
    tile_size: float,
    offset: tuple[float, float],
) -> tuple[float, float, float]:
    """How far an observation is from the truth, modulo the floor's symmetries.

    Returns ``(e1, e2, e3)``: for the quarter-turn m whose heading branch is closest to the true
    heading, ``e3 = theta - (y3 + m pi/2)`` wrapped to (-pi, pi] (rad) and ``(e1, e2) = c -
    R(m pi/2) (y1, y2)`` wrapped to [-L/2, L/2) (metres), where c is the true camera centre.
    An observation is right within (ep, eh) when ``|e1|, |e2| <= ep`` and ``|e3| <= eh``.
    """
    if isinstance(y, Observation):
        y1, y2, y3 = y.y1, y.y2, y.y3
    else:
        y1, y2, y3 = y
    f, left = offset
    ct, st = math.cos(pose.theta), math.sin(pose.theta)
    cx = pose.x + f * ct - left * st
    cy = pose.y + f * st + left * ct
    m = round((pose.theta - y3) / QUARTER)
    e3 = math.remainder(pose.theta - (y3 + m * QUARTER), 2.0 * math.pi)
    k = m & 3
    r1, r2 = ((y1, y2), (-y2, y1), (-y1, -y2), (y2, -y1))[k]
    e1 = math.remainder(cx - r1, tile_size)
    e2 = math.remainder(cy - r2, tile_size)
    return (e1, e2, e3)
