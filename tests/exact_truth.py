"""The truth in exact arithmetic, for the soundness tests (independent of ``tileviz``'s own maths).

Poses are carried as mpmath numbers at :data:`PREC` bits (256: some 77 decimal digits), so every
comparison with a float bound is decided by the real numbers, not by float rounding: a float is an
exact binary rational, mpmath's pi is correct to the working precision, and no float bound is
within 1e-60 of a transcendental truth unless it is the truth's own float (that case is reported
by :func:`margin`). Nothing here calls ``tileviz.intervals`` or ``tileviz.localizer``.

Units and frames as everywhere: metres, radians, world x east, y north, heading counter-clockwise
from +x, continuous (a pose is in a box when theta + 2 pi k is, for some integer k).
"""

from __future__ import annotations

from collections.abc import Iterable

import mpmath

PREC = 256
MP = mpmath.MPContext()
MP.prec = PREC
mpf = MP.mpf
PI = MP.pi
TWO_PI = 2 * MP.pi
HALF_PI = MP.pi / 2


def heading_margin(t_lo: float, t_hi: float, theta: object) -> object:
    """The largest d such that theta + 2 pi k lies in [t_lo + d, t_hi - d] for some integer k
    (>= 0: theta is in the heading interval, modulo 2 pi; < 0: it misses it by -d), exact."""
    th = mpf(theta)
    lo = mpf(t_lo)
    hi = mpf(t_hi)
    if hi - lo >= TWO_PI:
        return (hi - lo - TWO_PI) / 2 + PI  # every heading: at least half the excess
    k = int(MP.ceil((lo - th) / TWO_PI))  # smallest k with theta + 2 pi k >= lo
    best = None
    for kk in (k - 1, k, k + 1):
        v = th + kk * TWO_PI
        d = min(v - lo, hi - v)
        if best is None or d > best:
            best = d
    return best


def margin(box: object, x: object, y: object, theta: object) -> object:
    """How deep the pose is inside ``box`` (a ``tileviz.types.Box`` or anything with x_lo, ...,
    t_hi), in its worst dimension, exactly: >= 0 inside (0: on the boundary), < 0 outside."""
    mx = min(mpf(x) - mpf(box.x_lo), mpf(box.x_hi) - mpf(x))
    my = min(mpf(y) - mpf(box.y_lo), mpf(box.y_hi) - mpf(y))
    return min(mx, my, heading_margin(box.t_lo, box.t_hi, theta))


def in_box(box: object, x: object, y: object, theta: object) -> bool:
    """Whether the exact pose is in the box (heading modulo 2 pi)."""
    return margin(box, x, y, theta) >= 0


def in_set(boxes: Iterable[object], x: object, y: object, theta: object) -> bool:
    """Whether the exact pose is in some box of ``boxes`` (a BoxSet's ``boxes``)."""
    return any(in_box(b, x, y, theta) for b in boxes)
