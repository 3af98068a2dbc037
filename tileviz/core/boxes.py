"""Box sets on the localizer's hot path: lists of :class:`tileviz.types.Box` (metres and
radians, heading continuous), their validation, housekeeping (merging, the box cap) and
widening."""

from __future__ import annotations

import math

from tileviz.core.constants import LIMIT
from tileviz.core.intervals import (
    TWO_PI,
    TWO_PI_ERROR,
    lattice_hull,
    turn_shift,
)
from tileviz.types import Box

__all__ = [
    "LIMIT", "MIN_TILE", "ONE_TURN", "checked_box", "finite", "hull_of", "in_range",
    "inflate_box", "nonnegative", "one_turn", "tidy",
]

_INF = math.inf
_nextafter = math.nextafter

MIN_TILE = 1e-4
"""Smallest tile size L, metres (with LIMIT: at most 1e13 tiles across the representable floor)."""
ONE_TURN = _nextafter(TWO_PI + 2.0 * TWO_PI_ERROR, _INF)
"""A heading interval wider than this (radians) holds every heading: it is cut to one turn."""


def finite(name: str, v: object) -> float:
    """``v`` as a float; ValueError naming ``name`` unless it is a finite number within
    +-LIMIT (bools refused)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"{name} must be a finite number, got {v!r}")
    if not -LIMIT <= v <= LIMIT:
        raise ValueError(f"{name} must be within +-{LIMIT:g}, got {v!r}")
    return float(v)


def nonnegative(name: str, v: object) -> float:
    """:func:`finite`, and ValueError naming ``name`` when it is negative."""
    f = finite(name, v)
    if f < 0:
        raise ValueError(f"{name} must be >= 0, got {v!r}")
    return f


def checked_box(name: str, box: object) -> Box:
    """``box`` with float bounds and its heading cut to one turn; ValueError naming ``name``
    when it is not a :class:`Box`, has a bound that is not :func:`finite`, or is empty."""
    if not isinstance(box, Box):
        raise ValueError(f"{name} must be a Box, got {type(box).__name__}")
    t = tuple(finite(f"{name}.{k}", getattr(box, k)) for k in
              ("x_lo", "x_hi", "y_lo", "y_hi", "t_lo", "t_hi"))
    for axis, (lo, hi) in zip("xyt", (t[0:2], t[2:4], t[4:6]), strict=True):
        if lo > hi:
            raise ValueError(f"{name} is empty: {axis}_lo = {lo} > {axis}_hi = {hi}")
    return one_turn(Box(*t))


def one_turn(b: Box) -> Box:
    """``b`` with a heading interval wider than a turn cut to one turn from its low end (the
    same poses, heading modulo 2 pi)."""
    if b[5] - b[4] <= ONE_TURN:
        return b
    return Box(b[0], b[1], b[2], b[3], b[4],
               _nextafter(_nextafter(b[4] + TWO_PI, _INF) + TWO_PI_ERROR, _INF))


def in_range(boxes: list[Box]) -> list[Box]:
    """The boxes, headings cut to one turn; ValueError when a bound leaves +-LIMIT."""
    out = boxes
    for i, b in enumerate(boxes):
        if not (-LIMIT <= b[0] and b[1] <= LIMIT and -LIMIT <= b[2] and b[3] <= LIMIT
                and -LIMIT <= b[4] and b[5] <= LIMIT):
            raise ValueError(f"the set left +-{LIMIT:g} (m, rad): {b}; the odometry or the "
                             f"bounds are too large")
        if b[5] - b[4] > ONE_TURN:
            if out is boxes:
                out = list(boxes)
            out[i] = one_turn(b)
    return out


def _shift_heading(b: Box, ref: float) -> Box:
    """``b`` with its heading moved by the multiple of 2 pi that brings its centre nearest
    ``ref`` (outward rounded: :func:`tileviz.core.intervals.turn_shift`)."""
    k = round((ref - 0.5 * (b[4] + b[5])) / TWO_PI)
    if k == 0:
        return b
    t_lo, t_hi = turn_shift(b[4], b[5], k)
    return Box(b[0], b[1], b[2], b[3], t_lo, t_hi)


def hull_of(boxes: list[Box]) -> Box:
    """The bounding box; headings shifted next to the first box's first."""
    ref = 0.5 * (boxes[0][4] + boxes[0][5])
    x_lo, x_hi, y_lo, y_hi, t_lo, t_hi = boxes[0]
    for raw in boxes[1:]:
        b = _shift_heading(raw, ref)
        x_lo = min(x_lo, b[0])
        x_hi = max(x_hi, b[1])
        y_lo = min(y_lo, b[2])
        y_hi = max(y_hi, b[3])
        t_lo = min(t_lo, b[4])
        t_hi = max(t_hi, b[5])
    return Box(x_lo, x_hi, y_lo, y_hi, t_lo, t_hi)


def _meet(a: Box, b: Box) -> bool:
    """Whether two boxes share a point (heading modulo 2 pi)."""
    return (
        a[0] <= b[1] and b[0] <= a[1] and a[2] <= b[3] and b[2] <= a[3]
        and lattice_hull(a[4], a[5], b[4], b[5], TWO_PI, TWO_PI_ERROR) is not None
    )


def tidy(boxes: list[Box], cap: int) -> tuple[list[Box], bool]:
    """Make the boxes disjoint (boxes that meet are replaced by their hull, repeatedly) and apply
    the cap (more than ``cap`` boxes: the hull of all). Returns (boxes, whether the cap fired).
    Boxes are swept in order of x_lo, so only pairs whose x ranges overlap are compared."""
    if len(boxes) > cap:
        return [hull_of(boxes)], True
    if len(boxes) < 2:
        return boxes, False
    out = sorted(boxes)
    i = 0
    while i < len(out):
        a = out[i]
        j = i + 1
        while j < len(out) and out[j][0] <= a[1]:
            if _meet(a, out[j]):
                out[i] = hull_of([a, out[j]])
                del out[j]
                out.sort()
                i = -1  # a hull can meet boxes already passed: sweep again
                break
            j += 1
        i += 1
    return out, False


def inflate_box(b: Box, d: float, dt: float) -> Box:
    """Box ``b`` widened by ``d`` metres on each side in x and y and ``dt`` rad in heading
    (outward rounded): every pose within (d, d, dt) of a pose of ``b``."""
    n = _nextafter
    return Box(n(b[0] - d, -_INF), n(b[1] + d, _INF), n(b[2] - d, -_INF), n(b[3] + d, _INF),
               n(b[4] - dt, -_INF), n(b[5] + dt, _INF))
