"""Box sets on the localizer's hot path: plain 6-tuples (x_lo, x_hi, y_lo, y_hi, t_lo, t_hi),
metres and radians (heading continuous), their validation, housekeeping (merging, the box cap)
and conversion to the public :class:`tileviz.types.Box` / :class:`tileviz.types.BoxSet`."""

from __future__ import annotations

import math

from tileviz.core.constants import LIMIT
from tileviz.core.intervals import (
    TWO_PI,
    TWO_PI_ERROR,
    lattice_hull,
    turn_shift,
)
from tileviz.types import Box, BoxSet

__all__ = ["LIMIT", "MIN_TILE", "Tuple6", "inflate_box"]

Tuple6 = tuple[float, float, float, float, float, float]
"""A box as (x_lo, x_hi, y_lo, y_hi, t_lo, t_hi): metres, metres, radians (continuous)."""

_INF = math.inf
_nextafter = math.nextafter

MIN_TILE = 1e-4
"""Smallest tile size L, metres (with LIMIT: at most 1e13 tiles across the representable floor)."""
_TURN = _nextafter(TWO_PI + 2.0 * TWO_PI_ERROR, _INF)
"""A heading interval wider than this holds every heading: it is cut to one turn."""


def _finite(name: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"{name} must be a finite number, got {v!r}")
    if not -LIMIT <= v <= LIMIT:
        raise ValueError(f"{name} must be within +-{LIMIT:g}, got {v!r}")
    return float(v)


def _nonneg(name: str, v: object) -> float:
    f = _finite(name, v)
    if f < 0:
        raise ValueError(f"{name} must be >= 0, got {v!r}")
    return f


def _check_box(name: str, box: Box) -> Tuple6:
    if not isinstance(box, Box):
        raise ValueError(f"{name} must be a Box, got {type(box).__name__}")
    t = tuple(_finite(f"{name}.{k}", getattr(box, k)) for k in
              ("x_lo", "x_hi", "y_lo", "y_hi", "t_lo", "t_hi"))
    for axis, (lo, hi) in zip("xyt", (t[0:2], t[2:4], t[4:6]), strict=True):
        if lo > hi:
            raise ValueError(f"{name} is empty: {axis}_lo = {lo} > {axis}_hi = {hi}")
    return _one_turn(t)  # type: ignore[arg-type]


def _one_turn(b: Tuple6) -> Tuple6:
    """``b`` with a heading interval wider than a turn cut to one turn from its low end (the
    same poses, heading modulo 2 pi)."""
    if b[5] - b[4] <= _TURN:
        return b
    return (b[0], b[1], b[2], b[3], b[4],
            _nextafter(_nextafter(b[4] + TWO_PI, _INF) + TWO_PI_ERROR, _INF))


def _in_range(boxes: list[Tuple6]) -> list[Tuple6]:
    """The boxes, headings cut to one turn; ValueError when a bound leaves +-LIMIT."""
    out = boxes
    for i, b in enumerate(boxes):
        if not (-LIMIT <= b[0] and b[1] <= LIMIT and -LIMIT <= b[2] and b[3] <= LIMIT
                and -LIMIT <= b[4] and b[5] <= LIMIT):
            raise ValueError(f"the set left +-{LIMIT:g} (m, rad): {b}; the odometry or the "
                             f"bounds are too large")
        if b[5] - b[4] > _TURN:
            if out is boxes:
                out = list(boxes)
            out[i] = _one_turn(b)
    return out


def _shift_heading(b: Tuple6, ref: float) -> Tuple6:
    """``b`` with its heading moved by the multiple of 2 pi that brings its centre nearest
    ``ref`` (outward rounded: :func:`tileviz.core.intervals.turn_shift`)."""
    k = round((ref - 0.5 * (b[4] + b[5])) / TWO_PI)
    if k == 0:
        return b
    t_lo, t_hi = turn_shift(b[4], b[5], k)
    return (b[0], b[1], b[2], b[3], t_lo, t_hi)


def _hull_all(boxes: list[Tuple6]) -> Tuple6:
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
    return (x_lo, x_hi, y_lo, y_hi, t_lo, t_hi)


def _meet(a: Tuple6, b: Tuple6) -> bool:
    """Whether two boxes share a point (heading modulo 2 pi)."""
    return (
        a[0] <= b[1] and b[0] <= a[1] and a[2] <= b[3] and b[2] <= a[3]
        and lattice_hull(a[4], a[5], b[4], b[5], TWO_PI, TWO_PI_ERROR) is not None
    )


def _tidy(boxes: list[Tuple6], cap: int) -> tuple[list[Tuple6], bool]:
    """Make the boxes disjoint (boxes that meet are replaced by their hull, repeatedly) and apply
    the cap (more than ``cap`` boxes: the hull of all). Returns (boxes, whether the cap fired).
    Boxes are swept in order of x_lo, so only pairs whose x ranges overlap are compared."""
    if len(boxes) > cap:
        return [_hull_all(boxes)], True
    if len(boxes) < 2:
        return boxes, False
    out = sorted(boxes)
    i = 0
    while i < len(out):
        a = out[i]
        j = i + 1
        while j < len(out) and out[j][0] <= a[1]:
            if _meet(a, out[j]):
                out[i] = _hull_all([a, out[j]])
                del out[j]
                out.sort()
                i = -1  # a hull can meet boxes already passed: sweep again
                break
            j += 1
        i += 1
    return out, False


# Building the frozen result objects through their dataclass __init__ (one object.__setattr__
# per field) cost as much as the whole prediction; the hot path fills the same slots directly.
# The objects are the same as Box(*b) / BoxSet(boxes) (tests/test_localizer_golden.py checks).
_new = object.__new__
_BOX_SLOTS = tuple(Box.__dict__[k].__set__
                   for k in ("x_lo", "x_hi", "y_lo", "y_hi", "t_lo", "t_hi"))
_BOXSET_SLOT = BoxSet.__dict__["boxes"].__set__


def _box(b: Tuple6) -> Box:
    """``Box(*b)``, built without the frozen dataclass __init__."""
    s0, s1, s2, s3, s4, s5 = _BOX_SLOTS
    x_lo, x_hi, y_lo, y_hi, t_lo, t_hi = b
    o = _new(Box)
    s0(o, x_lo)
    s1(o, x_hi)
    s2(o, y_lo)
    s3(o, y_hi)
    s4(o, t_lo)
    s5(o, t_hi)
    return o


def _to_boxset(boxes: list[Tuple6]) -> BoxSet:
    """``BoxSet(tuple(Box(*b) for b in boxes))``, built without the dataclass __init__s."""
    o = _new(BoxSet)
    _BOXSET_SLOT(o, (_box(boxes[0]),) if len(boxes) == 1 else tuple(map(_box, boxes)))
    return o


def inflate_box(b: Tuple6, d: float, dt: float) -> Tuple6:
    """Box ``b`` widened by ``d`` metres on each side in x and y and ``dt`` rad in heading
    (outward rounded): every pose within (d, d, dt) of a pose of ``b``."""
    n = _nextafter
    return (n(b[0] - d, -_INF), n(b[1] + d, _INF), n(b[2] - d, -_INF), n(b[3] + d, _INF),
            n(b[4] - dt, -_INF), n(b[5] + dt, _INF))
