"""Outward-rounded interval arithmetic on plain float pairs.

An interval is a pair ``(lo, hi)`` of floats with ``lo <= hi``; the empty set is ``None``. Every
bound that comes out of a float operation is pushed one ulp outward with :func:`math.nextafter`
(design.md, "Rounding"): with IEEE round-to-nearest the computed value is within half an ulp of
the exact one, so the pushed bound encloses the exact real result. Enclosures of cos, sin, acos
and asin are widened by :data:`TRIG_ULPS` ulps (libm is good to about one ulp), clamped to
[-1, 1], and include the extrema +-1 whenever the argument interval may contain one.

The functions take and return bare floats so the localizer's hot path costs no object
allocation beyond tuples. Units are whatever the caller's are (metres, radians).
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = [
    "HALF_PI",
    "HALF_PI_ERROR",
    "HALF_PI_HI",
    "HALF_PI_LO",
    "PI_HI",
    "PI_LO",
    "TRIG_ULPS",
    "TWO_PI",
    "TWO_PI_ERROR",
    "Interval",
    "acos_preimage",
    "add",
    "asin_preimage",
    "cos_range",
    "cos_sin_range",
    "down",
    "hull",
    "intersect",
    "lattice_cut",
    "lattice_hull",
    "lattice_intersect",
    "lattice_pieces_indexed",
    "mul",
    "scale",
    "sin_range",
    "sub",
    "turn_shift",
    "up",
]

Interval = tuple[float, float]
"""(lo, hi) with lo <= hi."""

_INF = math.inf
_nextafter = math.nextafter
_ulp = math.ulp
_cos = math.cos
_sin = math.sin
_ceil = math.ceil
_floor = math.floor

TWO_PI = 2.0 * math.pi
"""The float nearest 2 pi (used as the heading period)."""
TWO_PI_ERROR = 5e-16
"""A bound on |2 pi - TWO_PI| (the true gap is 2.45e-16)."""
PI_LO = _nextafter(math.pi, -_INF)
PI_HI = _nextafter(math.pi, _INF)
"""PI_LO < pi < PI_HI."""
HALF_PI = 0.5 * math.pi
"""The float nearest pi/2 (the period of the heading branches)."""
HALF_PI_ERROR = 1.25e-16
"""A bound on |pi/2 - HALF_PI| (the true gap is 6.1e-17)."""
HALF_PI_LO = _nextafter(0.5 * math.pi, -_INF)
HALF_PI_HI = _nextafter(0.5 * math.pi, _INF)
"""HALF_PI_LO < pi/2 < HALF_PI_HI."""

TRIG_ULPS = 4.0
"""Widening, in ulps of the result, applied to every libm trig value."""

_INV_PI = 1.0 / math.pi
_Q_REL = 1e-15
"""Relative slack on t/pi when deciding whether [t] may contain a multiple of pi (the computed
quotient is good to about 2e-16 relative); including an extremum too eagerly costs nothing
measurable since cos is within 1e-29 of +-1 there."""


def down(v: float) -> float:
    """The float just below ``v``."""
    return _nextafter(v, -_INF)


def up(v: float) -> float:
    """The float just above ``v``."""
    return _nextafter(v, _INF)


def add(a_lo: float, a_hi: float, b_lo: float, b_hi: float) -> Interval:
    """[a] + [b], outward rounded."""
    return (_nextafter(a_lo + b_lo, -_INF), _nextafter(a_hi + b_hi, _INF))


def sub(a_lo: float, a_hi: float, b_lo: float, b_hi: float) -> Interval:
    """[a] - [b], outward rounded."""
    return (_nextafter(a_lo - b_hi, -_INF), _nextafter(a_hi - b_lo, _INF))


def scale(s: float, lo: float, hi: float) -> Interval:
    """s * [lo, hi] for an exact float s, outward rounded."""
    if s >= 0.0:
        return (_nextafter(s * lo, -_INF), _nextafter(s * hi, _INF))
    return (_nextafter(s * hi, -_INF), _nextafter(s * lo, _INF))


def mul(a_lo: float, a_hi: float, b_lo: float, b_hi: float) -> Interval:
    """[a] * [b], outward rounded."""
    p1 = a_lo * b_lo
    p2 = a_lo * b_hi
    p3 = a_hi * b_lo
    p4 = a_hi * b_hi
    lo = p1  # min(p1, p2, p3, p4) and max(...) written out (same ties: the first one wins)
    hi = p1
    if p2 < lo:
        lo = p2
    elif p2 > hi:
        hi = p2
    if p3 < lo:
        lo = p3
    elif p3 > hi:
        hi = p3
    if p4 < lo:
        lo = p4
    elif p4 > hi:
        hi = p4
    return (_nextafter(lo, -_INF), _nextafter(hi, _INF))


def intersect(a_lo: float, a_hi: float, b_lo: float, b_hi: float) -> Interval | None:
    """[a] ∩ [b] (exact: no rounding), or None when empty."""
    lo = a_lo if a_lo > b_lo else b_lo
    hi = a_hi if a_hi < b_hi else b_hi
    if lo > hi:
        return None
    return (lo, hi)


def hull(a_lo: float, a_hi: float, b_lo: float, b_hi: float) -> Interval:
    """The smallest interval containing [a] and [b] (exact)."""
    return (a_lo if a_lo < b_lo else b_lo, a_hi if a_hi > b_hi else b_hi)


def _trig_range(
    fn: Callable[[float], float], lo: float, hi: float, phase: float
) -> Interval:
    """Enclosure of fn over [lo, hi] for fn = cos (phase 0) or sin (phase 1/2), whose extrema are
    at (k + phase) pi: +1 for even k, -1 for odd k. Between extrema fn is monotone, so the range
    is spanned by the end values (widened by TRIG_ULPS ulps) and the extrema [lo, hi] may hold."""
    q = lo * _INV_PI - phase  # [lo, hi] may hold (k + phase) pi for k1 <= k <= k2 (a superset)
    k1 = _ceil(q - (abs(q) + 1.0) * _Q_REL)
    q = hi * _INV_PI - phase
    k2 = _floor(q + (abs(q) + 1.0) * _Q_REL)
    if k2 > k1:
        return (-1.0, 1.0)
    a = fn(lo)
    b = fn(hi)
    if a > b:
        a, b = b, a
    r_lo = a - TRIG_ULPS * _ulp(a)
    r_hi = b + TRIG_ULPS * _ulp(b)
    if k1 == k2:
        if k1 & 1:
            r_lo = -1.0
        else:
            r_hi = 1.0
    return (r_lo if r_lo > -1.0 else -1.0, r_hi if r_hi < 1.0 else 1.0)


def cos_range(lo: float, hi: float) -> Interval:
    """An enclosure of {cos t : t in [lo, hi]}, clamped to [-1, 1]: the end values widened by
    TRIG_ULPS ulps, plus 1 when [lo, hi] may contain an even multiple of pi, -1 an odd one."""
    return _trig_range(_cos, lo, hi, 0.0)


def sin_range(lo: float, hi: float) -> Interval:
    """An enclosure of {sin t : t in [lo, hi]}: as :func:`cos_range` with the extrema at
    pi/2 + k pi (1 for even k)."""
    return _trig_range(_sin, lo, hi, 0.5)


def cos_sin_range(lo: float, hi: float) -> tuple[float, float, float, float]:
    """``cos_range(lo, hi) + sin_range(lo, hi)`` as (c_lo, c_hi, s_lo, s_hi), bit for bit, in
    one call (the localizer's hot path needs both over the same interval: the quotients t/pi
    are shared). Same method as :func:`_trig_range`: end values widened by TRIG_ULPS ulps, the
    extremum +-1 added when [lo, hi] may contain it, clamped to [-1, 1]."""
    p = lo * _INV_PI  # = lo / pi - 0 (phase 0: cos), exactly as _trig_range computes it
    q = hi * _INV_PI
    k1 = _ceil(p - (abs(p) + 1.0) * _Q_REL)
    k2 = _floor(q + (abs(q) + 1.0) * _Q_REL)
    if k2 > k1:
        c_lo = -1.0
        c_hi = 1.0
    else:
        a = _cos(lo)
        b = _cos(hi)
        if a > b:
            a, b = b, a
        c_lo = a - TRIG_ULPS * _ulp(a)
        c_hi = b + TRIG_ULPS * _ulp(b)
        if k1 == k2:
            if k1 & 1:
                c_lo = -1.0
            else:
                c_hi = 1.0
        c_lo = c_lo if c_lo > -1.0 else -1.0
        c_hi = c_hi if c_hi < 1.0 else 1.0
    p = p - 0.5  # phase 1/2: sin
    q = q - 0.5
    k1 = _ceil(p - (abs(p) + 1.0) * _Q_REL)
    k2 = _floor(q + (abs(q) + 1.0) * _Q_REL)
    if k2 > k1:
        return (c_lo, c_hi, -1.0, 1.0)
    a = _sin(lo)
    b = _sin(hi)
    if a > b:
        a, b = b, a
    s_lo = a - TRIG_ULPS * _ulp(a)
    s_hi = b + TRIG_ULPS * _ulp(b)
    if k1 == k2:
        if k1 & 1:
            s_lo = -1.0
        else:
            s_hi = 1.0
    return (c_lo, c_hi, s_lo if s_lo > -1.0 else -1.0, s_hi if s_hi < 1.0 else 1.0)


def turn_shift(lo: float, hi: float, k: int) -> Interval:
    """[lo, hi] + 2 pi k, outward rounded: encloses [lo, hi] + k * (the true 2 pi). The float
    TWO_PI is 2.45e-16 below 2 pi, so a shift in round-to-nearest alone can miss the true bound
    by |k| times that; the enclosure adds |k| * TWO_PI_ERROR on each side. k = 0 is exact."""
    if k == 0:
        return (lo, hi)
    s = k * TWO_PI
    s_lo = s_hi = s
    if not -_EXACT_TURNS <= k <= _EXACT_TURNS:  # k * TWO_PI was rounded: bound it outward
        s_lo = _nextafter(s, -_INF)
        s_hi = _nextafter(s, _INF)
    err = abs(k) * TWO_PI_ERROR
    return (
        _nextafter(_nextafter(lo + s_lo, -_INF) - err, -_INF),
        _nextafter(_nextafter(hi + s_hi, _INF) + err, _INF),
    )


_EXACT_TURNS = 7
"""k * TWO_PI is exact for |k| <= 7: TWO_PI's significand has 50 significant bits (its last three
are zero), so k of at most 3 bits fits float64's 53 (tests/test_intervals.py checks it)."""


# --- lattices ---------------------------------------------------------------------------------


def _piece_lo(k: int, c_lo: float, period: float, period_error: float) -> float:
    """A lower bound of c_lo + k * P for every true period P within period_error of ``period``."""
    if k == 0:
        return c_lo
    v = _nextafter(_nextafter(k * period, -_INF) + c_lo, -_INF)
    if period_error:
        v = _nextafter(v - abs(k) * period_error, -_INF)
    return v


def _piece_hi(k: int, c_hi: float, period: float, period_error: float) -> float:
    """An upper bound of c_hi + k * P (see :func:`_piece_lo`)."""
    if k == 0:
        return c_hi
    v = _nextafter(_nextafter(k * period, _INF) + c_hi, _INF)
    if period_error:
        v = _nextafter(v + abs(k) * period_error, _INF)
    return v


def _index_range(
    lo: float, hi: float, c_lo: float, c_hi: float, period: float, period_error: float
) -> tuple[int, int, float, float]:
    """(k1, k2, b1, a2): the first and last k whose outward piece [c_lo, c_hi] + k P meets
    [lo, hi] (k1 > k2 when none does), with the bounds the walks computed on the way: b1 the upper
    bound of piece k1 and a2 the lower bound of piece k2 (outward, as :func:`_piece_hi` and
    :func:`_piece_lo`), so that a caller left with a single piece rounds nothing again."""
    # The quotients are good to a few ulps: the estimate is right but for a rounding tie, which
    # the walks settle with the outward piece bounds themselves. This runs several times per
    # localizer frame, so the two checks of the estimate write _piece_hi / _piece_lo out.
    n = _nextafter
    k1 = _ceil((lo - c_hi) / period)
    k = k1 - 1
    b = n(n(k * period, _INF) + c_hi, _INF) if k else c_hi  # _piece_hi(k1 - 1)
    if period_error and k:
        b = n(b + abs(k) * period_error, _INF)
    if b >= lo:  # piece k1 - 1 reaches lo too: walk down
        k1 = k
        b1 = b
        b = _piece_hi(k1 - 1, c_hi, period, period_error)
        while b >= lo:
            k1 -= 1
            b1 = b
            b = _piece_hi(k1 - 1, c_hi, period, period_error)
    else:
        b1 = n(n(k1 * period, _INF) + c_hi, _INF) if k1 else c_hi  # _piece_hi(k1)
        if period_error and k1:
            b1 = n(b1 + abs(k1) * period_error, _INF)
        while b1 < lo:  # piece k1 ends below lo: walk up
            k1 += 1
            b1 = _piece_hi(k1, c_hi, period, period_error)
    k2 = _floor((hi - c_lo) / period)
    k = k2 + 1
    a = n(n(k * period, -_INF) + c_lo, -_INF) if k else c_lo  # _piece_lo(k2 + 1)
    if period_error and k:
        a = n(a - abs(k) * period_error, -_INF)
    if a <= hi:  # piece k2 + 1 starts below hi too: walk up
        k2 = k
        a2 = a
        a = _piece_lo(k2 + 1, c_lo, period, period_error)
        while a <= hi:
            k2 += 1
            a2 = a
            a = _piece_lo(k2 + 1, c_lo, period, period_error)
    else:
        a2 = n(n(k2 * period, -_INF) + c_lo, -_INF) if k2 else c_lo  # _piece_lo(k2)
        if period_error and k2:
            a2 = n(a2 - abs(k2) * period_error, -_INF)
        while a2 > hi:  # piece k2 starts above hi: walk down
            k2 -= 1
            a2 = _piece_lo(k2, c_lo, period, period_error)
    return k1, k2, b1, a2


def lattice_intersect(
    lo: float,
    hi: float,
    c_lo: float,
    c_hi: float,
    period: float,
    *,
    period_error: float = 0.0,
) -> list[Interval]:
    """[lo, hi] ∩ ([c_lo, c_hi] + period * Z) as a sorted list of disjoint intervals.

    Exact up to outward rounding: piece k is [c_lo + k P, c_hi + k P] with both bounds pushed
    outward, widened by |k| * period_error when the true period P is only known to within
    ``period_error`` of ``period`` (2 pi). Pieces that overlap or touch are merged, so when
    c_hi - c_lo >= period the answer is [[lo, hi]]. Empty list when nothing is left. (To cap the
    number of pieces, :func:`lattice_cut` says when it replaced them by their hull.)
    """
    return lattice_cut(lo, hi, c_lo, c_hi, period, period_error=period_error)[0]


def lattice_cut(
    lo: float,
    hi: float,
    c_lo: float,
    c_hi: float,
    period: float,
    *,
    period_error: float = 0.0,
    max_pieces: int | None = None,
) -> tuple[list[Interval], bool]:
    """(:func:`lattice_intersect`, hulled): with ``max_pieces``, more disjoint pieces than that are
    replaced by their hull (one interval, a superset) and ``hulled`` is True; it is False whenever
    the list is the exact (outward-rounded) intersection."""
    if not lo <= hi or not c_lo <= c_hi or not period > 0.0:
        raise ValueError(
            f"lattice_intersect needs lo <= hi, c_lo <= c_hi and period > 0, got "
            f"[{lo}, {hi}], [{c_lo}, {c_hi}], {period}"
        )
    k1, k2, b1, a2 = _index_range(lo, hi, c_lo, c_hi, period, period_error)
    if k1 >= k2:
        if k1 > k2:
            return [], False
        return [(a2 if a2 > lo else lo, b1 if b1 < hi else hi)], False  # the one piece, k1 = k2
    capped = max_pieces is not None and k2 - k1 + 1 > max_pieces
    if c_hi - c_lo >= period or capped:
        a = _piece_lo(k1, c_lo, period, period_error)
        b = _piece_hi(k2, c_hi, period, period_error)
        # (pieces this wide touch or overlap: their union is this interval, nothing was added)
        return [(a if a > lo else lo, b if b < hi else hi)], capped and c_hi - c_lo < period
    out: list[Interval] = []
    for _, a, b in _clipped_pieces(k1, k2, lo, hi, c_lo, c_hi, period, period_error):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out, False


def _clipped_pieces(
    k1: int,
    k2: int,
    lo: float,
    hi: float,
    c_lo: float,
    c_hi: float,
    period: float,
    period_error: float,
) -> list[tuple[int, float, float]]:
    """(k, piece k clipped to [lo, hi]) for k = k1..k2, outward rounded."""
    out = []
    for k in range(k1, k2 + 1):
        a = _piece_lo(k, c_lo, period, period_error)
        b = _piece_hi(k, c_hi, period, period_error)
        out.append((k, a if a > lo else lo, b if b < hi else hi))
    return out


def lattice_pieces_indexed(
    lo: float, hi: float, c_lo: float, c_hi: float, period: float, period_error: float = 0.0
) -> list[tuple[int, float, float]]:
    """[lo, hi] ∩ ([c_lo, c_hi] + k period) for every k, as (k, piece_lo, piece_hi), unmerged
    (outward rounded as in :func:`lattice_intersect`). Pieces may touch or overlap when
    c_hi - c_lo is close to the period; the caller decides."""
    k1, k2, b1, a2 = _index_range(lo, hi, c_lo, c_hi, period, period_error)
    if k1 == k2:
        return [(k1, a2 if a2 > lo else lo, b1 if b1 < hi else hi)]
    return _clipped_pieces(k1, k2, lo, hi, c_lo, c_hi, period, period_error)


def lattice_hull(
    lo: float, hi: float, c_lo: float, c_hi: float, period: float, period_error: float = 0.0
) -> Interval | None:
    """The hull of [lo, hi] ∩ ([c_lo, c_hi] + period * Z), or None (see lattice_intersect).

    This is what a forward-backward contractor on sin(pi (t - c) / period) = 0 computes."""
    k1, k2, b, a = _index_range(lo, hi, c_lo, c_hi, period, period_error)
    if k1 > k2:
        return None
    if k1 < k2:
        a = _piece_lo(k1, c_lo, period, period_error)
        b = _piece_hi(k2, c_hi, period, period_error)
    return (a if a > lo else lo, b if b < hi else hi)


# --- inverse trig (hull of a preimage) ----------------------------------------------------------


def _hull_of_two(
    lo: float,
    hi: float,
    p: tuple[float, float],
    q: tuple[float, float],
) -> Interval | None:
    """Hull of [lo, hi] ∩ ((p ∪ q) + 2 pi Z)."""
    a = lattice_hull(lo, hi, p[0], p[1], TWO_PI, TWO_PI_ERROR)
    b = lattice_hull(lo, hi, q[0], q[1], TWO_PI, TWO_PI_ERROR)
    if a is None:
        return b
    if b is None:
        return a
    return (a[0] if a[0] < b[0] else b[0], a[1] if a[1] > b[1] else b[1])


def acos_preimage(lo: float, hi: float, c_lo: float, c_hi: float) -> Interval | None:
    """Hull of {t in [lo, hi] : cos t in [c_lo, c_hi]} (outward), or None when empty.

    cos t in [c_lo, c_hi] iff t in [A, B] + 2 pi Z or [-B, -A] + 2 pi Z with A = acos(c_hi),
    B = acos(c_lo); A and B are widened by TRIG_ULPS ulps."""
    if c_lo > 1.0 or c_hi < -1.0:
        return None
    if c_lo <= -1.0 and c_hi >= 1.0:
        return (lo, hi)
    a = math.acos(c_hi) if c_hi < 1.0 else 0.0
    b = math.acos(c_lo) if c_lo > -1.0 else math.pi
    a = a - TRIG_ULPS * _ulp(a)
    b = b + TRIG_ULPS * _ulp(b)
    return _hull_of_two(lo, hi, (a, b), (-b, -a))


def asin_preimage(lo: float, hi: float, s_lo: float, s_hi: float) -> Interval | None:
    """Hull of {t in [lo, hi] : sin t in [s_lo, s_hi]} (outward), or None when empty.

    sin t in [s_lo, s_hi] iff t in [A, B] + 2 pi Z or [pi - B, pi - A] + 2 pi Z with
    A = asin(s_lo), B = asin(s_hi)."""
    if s_lo > 1.0 or s_hi < -1.0:
        return None
    if s_lo <= -1.0 and s_hi >= 1.0:
        return (lo, hi)
    a = math.asin(s_lo) if s_lo > -1.0 else -0.5 * math.pi
    b = math.asin(s_hi) if s_hi < 1.0 else 0.5 * math.pi
    a = a - TRIG_ULPS * _ulp(a)
    b = b + TRIG_ULPS * _ulp(b)
    return _hull_of_two(
        lo, hi, (a, b), (_nextafter(PI_LO - b, -_INF), _nextafter(PI_HI - a, _INF))
    )
