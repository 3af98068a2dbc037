"""The truth in exact arithmetic, for the soundness tests (independent of ``tileviz``'s own maths).

Poses are carried as mpmath numbers at :data:`PREC` bits (256: some 77 decimal digits): the
motion is integrated to that precision, which stands for the truth. Every comparison of the truth
with a float bound is then exact (differences of binary rationals taken with ``exact=True``, 2 pi
to 4096 bits), so a value of 1e-92 beside one of 0.01 is not rounded away. Nothing here calls
``tileviz.core.intervals`` or ``tileviz.core.localizer``.

Units and frames as everywhere: metres, radians, world x east, y north, heading counter-clockwise
from +x, continuous (a pose is in a box when theta + 2 pi k is, for some integer k).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from tileviz.testing import missing

try:
    import mpmath
except ImportError as exc:
    raise ImportError(missing("mpmath", "tileviz.testing.exact_truth")) from exc

Exact = Any
"""An mpmath number (or a float: read exactly)."""

PREC = 256
MP = mpmath.MPContext()
MP.prec = PREC
mpf = MP.mpf
PI = MP.pi
TWO_PI = 2 * MP.pi
HALF_PI = MP.pi / 2
PI_PREC = 4096
with MP.workprec(PI_PREC):
    TWO_PI_FINE = 2 * MP.pi
"""2 pi to PI_PREC bits, for the membership tests (a heading of 1e-300 rad next to a turn)."""


def sub(a: Exact, b: Exact) -> Exact:
    """a - b exactly (floats or mpmath numbers: binary rationals), whatever their magnitudes."""
    return MP.fsub(mpf(a), mpf(b), exact=True)


def heading_margin(t_lo: float, t_hi: float, theta: Exact) -> Exact:
    """The largest d such that theta + 2 pi k lies in [t_lo + d, t_hi - d] for some integer k
    (>= 0: theta is in the heading interval, modulo 2 pi; < 0: it misses it by -d). Exact but
    for pi itself, known to PI_PREC bits."""
    th = mpf(theta)
    lo = mpf(t_lo)
    hi = mpf(t_hi)
    width = sub(hi, lo)
    if width >= TWO_PI_FINE:
        return (width - TWO_PI_FINE) / 2 + PI  # every heading: at least half the excess
    k = int(MP.ceil(sub(lo, th) / TWO_PI))  # about the smallest k with theta + 2 pi k >= lo
    best = None
    for kk in (k - 1, k, k + 1):
        v = MP.fadd(th, MP.fmul(kk, TWO_PI_FINE, exact=True), exact=True)
        d = min(sub(v, lo), sub(hi, v))
        if best is None or d > best:
            best = d
    return best


def margin(box: Any, x: Exact, y: Exact, theta: Exact) -> Exact:
    """How deep the pose is inside ``box`` (a ``tileviz.types.Box`` or anything with x_lo, ...,
    t_hi), in its worst dimension, exactly: >= 0 inside (0: on the boundary), < 0 outside."""
    mx = min(sub(x, box.x_lo), sub(box.x_hi, x))
    my = min(sub(y, box.y_lo), sub(box.y_hi, y))
    return min(mx, my, heading_margin(box.t_lo, box.t_hi, theta))


def in_box(box: Any, x: Exact, y: Exact, theta: Exact) -> bool:
    """Whether the exact pose is in the box (heading modulo 2 pi)."""
    return margin(box, x, y, theta) >= 0


def in_set(boxes: Iterable[Any], x: Exact, y: Exact, theta: Exact) -> bool:
    """Whether the exact pose is in some box of ``boxes`` (a BoxSet's ``boxes``)."""
    return any(in_box(b, x, y, theta) for b in boxes)
