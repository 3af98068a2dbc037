"""Outward-rounded interval arithmetic: every result encloses the exact real answer (checked with
exact rationals or 60-digit decimals) and is no wider than a few ulps / 1e-12 beyond it."""

from __future__ import annotations

import math
from decimal import Decimal, localcontext
from fractions import Fraction

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from tileviz.intervals import (
    HALF_PI_HI,
    HALF_PI_LO,
    PI_HI,
    PI_LO,
    TWO_PI,
    TWO_PI_ERROR,
    acos_preimage,
    add,
    asin_preimage,
    cos_range,
    lattice_cut,
    lattice_hull,
    lattice_intersect,
    mul,
    scale,
    sin_range,
    sub,
)

FAST = settings(max_examples=150, deadline=None)
num = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
angle = st.floats(min_value=-40.0, max_value=40.0, allow_nan=False, allow_infinity=False)

# --- exact references ---------------------------------------------------------------------------

_PI_DIGITS = (
    "3.14159265358979323846264338327950288419716939937510582097494459230781640628620899"
)


def _series(x: float, first_power: int) -> Decimal:
    """cos (first_power 0) or sin (first_power 1) of the exact float x, to about 60 digits:
    Taylor series after reduction into (-pi, pi]."""
    with localcontext() as ctx:
        ctx.prec = 80
        two_pi = 2 * Decimal(_PI_DIGITS)
        t = Decimal(x) % two_pi
        if t > two_pi / 2:
            t -= two_pi
        term = t if first_power else Decimal(1)
        total = Decimal(0)
        k = first_power
        while term != 0 and (k == first_power or abs(term) > abs(total) * Decimal(10) ** -75):
            total += term
            term = -term * t * t / ((k + 1) * (k + 2))
            k += 2
        return +total


def _dcos(x: float) -> Decimal:
    return _series(x, 0)


def _dsin(x: float) -> Decimal:
    return _series(x, 1)


def _encloses(lo: float, hi: float, exact: Fraction | Decimal) -> bool:
    return Fraction(lo) <= Fraction(exact) <= Fraction(hi)


def _tight(lo: float, hi: float, exact_lo: Fraction, exact_hi: Fraction) -> bool:
    """Encloses [exact_lo, exact_hi] and is at most 2 ulps wider on each side."""
    return (
        exact_lo - 2 * Fraction(math.ulp(lo)) <= Fraction(lo) <= exact_lo
        and exact_hi <= Fraction(hi) <= exact_hi + 2 * Fraction(math.ulp(hi))
    )


# --- arithmetic ---------------------------------------------------------------------------------


def test_pi_constants_enclose_pi() -> None:
    pi = Fraction(Decimal(_PI_DIGITS))
    assert Fraction(PI_LO) < pi < Fraction(PI_HI)
    assert Fraction(HALF_PI_LO) < pi / 2 < Fraction(HALF_PI_HI)
    assert abs(Fraction(TWO_PI) - 2 * pi) < Fraction(TWO_PI_ERROR)


@FAST
@given(num, num, num, num)
def test_add_sub_mul_enclose_the_exact_result(a, b, c, d) -> None:
    a_lo, a_hi = min(a, b), max(a, b)
    b_lo, b_hi = min(c, d), max(c, d)
    fa = (Fraction(a_lo), Fraction(a_hi))
    fb = (Fraction(b_lo), Fraction(b_hi))
    assert _tight(*add(a_lo, a_hi, b_lo, b_hi), fa[0] + fb[0], fa[1] + fb[1])
    assert _tight(*sub(a_lo, a_hi, b_lo, b_hi), fa[0] - fb[1], fa[1] - fb[0])
    products = [x * y for x in fa for y in fb]
    assert _tight(*mul(a_lo, a_hi, b_lo, b_hi), min(products), max(products))
    scaled = sorted([Fraction(a) * fb[0], Fraction(a) * fb[1]])
    assert _tight(*scale(a, b_lo, b_hi), scaled[0], scaled[1])


def test_bounds_are_pushed_outward_even_when_exact() -> None:
    # 0.5 + 0.25 is exact in floats: the bounds still move one ulp out (design.md rounding rule)
    lo, hi = add(0.5, 0.5, 0.25, 0.25)
    assert lo < 0.75 < hi
    assert (lo, hi) == (math.nextafter(0.75, -1), math.nextafter(0.75, 1))


# --- trig ---------------------------------------------------------------------------------------


def _true_cos_range(lo: float, hi: float) -> tuple[Decimal, Decimal]:
    """Exact-enough range of cos over [lo, hi]: end values and interior extrema k pi."""
    vals = [_dcos(lo), _dcos(hi)]
    pi = Decimal(_PI_DIGITS)
    k = math.ceil(Decimal(lo) / pi)
    while k * pi <= Decimal(hi):
        vals.append(Decimal(1) if k % 2 == 0 else Decimal(-1))
        k += 1
    return min(vals), max(vals)


def _true_sin_range(lo: float, hi: float) -> tuple[Decimal, Decimal]:
    vals = [_dsin(lo), _dsin(hi)]
    pi = Decimal(_PI_DIGITS)
    k = math.ceil(Decimal(lo) / pi - Decimal("0.5"))
    while (k + Decimal("0.5")) * pi <= Decimal(hi):
        vals.append(Decimal(1) if k % 2 == 0 else Decimal(-1))
        k += 1
    return min(vals), max(vals)


@FAST
@given(angle, st.floats(min_value=0.0, max_value=7.0))
def test_cos_sin_ranges_enclose_and_are_tight(lo, width) -> None:
    hi = lo + width
    for f, ref in ((cos_range, _true_cos_range), (sin_range, _true_sin_range)):
        r_lo, r_hi = f(lo, hi)
        t_lo, t_hi = ref(lo, hi)
        assert Fraction(r_lo) <= Fraction(t_lo) and Fraction(t_hi) <= Fraction(r_hi)
        assert -1.0 <= r_lo <= r_hi <= 1.0
        assert float(Decimal(r_hi) - t_hi) < 1e-14 and float(t_lo - Decimal(r_lo)) < 1e-14


@pytest.mark.parametrize("k", [-7, -2, -1, 0, 1, 2, 5, 12])
def test_cos_range_includes_extremum_at_float_multiples_of_pi(k) -> None:
    # [t, t] with t the float nearest k*pi: cos(t) is within 1e-30 of +-1, the enclosure must
    # reach it; intervals crossing k*pi by one ulp reach +-1 exactly
    t = k * math.pi
    lo, hi = cos_range(math.nextafter(t, -math.inf), math.nextafter(t, math.inf))
    assert (hi == 1.0) if k % 2 == 0 else (lo == -1.0)
    s = (k + 0.5) * math.pi
    lo, hi = sin_range(math.nextafter(s, -math.inf), math.nextafter(s, math.inf))
    assert (hi == 1.0) if k % 2 == 0 else (lo == -1.0)


def test_cos_of_a_point_interval_is_a_few_ulps_wide() -> None:
    lo, hi = cos_range(0.7, 0.7)
    assert lo < math.cos(0.7) < hi and hi - lo < 1e-15
    assert cos_range(-1.0, 8.0) == (-1.0, 1.0)


@FAST
@given(angle, st.floats(min_value=0.0, max_value=7.0), st.floats(-1.2, 1.2), st.floats(0, 1.5))
def test_acos_asin_preimages_are_sound_and_tight(lo, width, c0, cw) -> None:
    hi = lo + width
    c_lo, c_hi = c0, c0 + cw
    for inv, fn in ((acos_preimage, math.cos), (asin_preimage, math.sin)):
        r = inv(lo, hi, c_lo, c_hi)
        # sound: every sample t in [lo, hi] with fn(t) safely inside [c] is kept
        samples = [min(hi, lo + width * i / 400) for i in range(401)]
        inside = [t for t in samples if c_lo + 1e-12 < fn(t) < c_hi - 1e-12]
        if inside:
            assert r is not None
            assert r[0] <= min(inside) and max(inside) <= r[1]
        if r is None:
            continue
        assert lo <= r[0] <= r[1] <= hi
        # tight: each returned end is the interval's end or a point where fn is in [c]
        for t in r:
            assert t in (lo, hi) or c_lo - 1e-9 <= fn(t) <= c_hi + 1e-9


# --- lattices -----------------------------------------------------------------------------------


def _exact_lattice(lo: float, hi: float, c_lo: float, c_hi: float, period: float) -> list:
    """[lo, hi] ∩ ([c_lo, c_hi] + period Z) in exact rationals, by brute force over k."""
    flo, fhi, fcl, fch, fp = map(Fraction, (lo, hi, c_lo, c_hi, period))
    k0 = math.floor((flo - fch) / fp) - 3
    k1 = math.ceil((fhi - fcl) / fp) + 3
    pieces = []
    for k in range(k0, k1 + 1):
        a, b = max(flo, fcl + k * fp), min(fhi, fch + k * fp)
        if a <= b:
            if pieces and a <= pieces[-1][1]:
                pieces[-1] = (pieces[-1][0], max(b, pieces[-1][1]))
            else:
                pieces.append((a, b))
    return pieces


@FAST
@given(
    st.floats(-50, 50),
    st.floats(0, 8),
    st.floats(-3, 3),
    st.floats(0, 1.2),
    st.sampled_from([0.166, 0.5, 1.0, 0.3, 2.0]),
)
def test_lattice_intersect_matches_exact_brute_force(lo, width, c_lo, cw, period) -> None:
    hi = lo + width
    c_hi = c_lo + cw
    got = lattice_intersect(lo, hi, c_lo, c_hi, period)
    exact = _exact_lattice(lo, hi, c_lo, c_hi, period)
    dilated = _exact_lattice(lo, hi, c_lo - 1e-12, c_hi + 1e-12, period)
    # sorted, disjoint, inside [lo, hi]
    for (a, b), (c, _d) in zip(got, got[1:], strict=False):
        assert a <= b < c
    assert all(lo <= a <= b <= hi for a, b in got)
    # sandwich: exact ⊆ got (sound) ⊆ exact with the window dilated by 1e-12 (outward rounding
    # only; it may keep a sliver of a piece that ends a rounding error outside [lo, hi])
    for a, b in exact:
        assert any(Fraction(g0) <= a and b <= Fraction(g1) for g0, g1 in got)
    for a, b in got:
        assert any(d0 <= Fraction(a) and Fraction(b) <= d1 for d0, d1 in dilated)
    h = lattice_hull(lo, hi, c_lo, c_hi, period)
    assert (h is None) == (not got)
    if got:
        assert h == (got[0][0], got[-1][1])


def test_lattice_intersect_known_answers() -> None:
    # [0.2, 2.7] ∩ ([0.4, 0.5] + Z) = [0.4, 0.5] ∪ [1.4, 1.5] ∪ [2.4, 2.5] (up to rounding)
    got = lattice_intersect(0.2, 2.7, 0.4, 0.5, 1.0)
    assert [(round(a, 12), round(b, 12)) for a, b in got] == [(0.4, 0.5), (1.4, 1.5), (2.4, 2.5)]
    # a window as wide as the period covers everything: one piece, the whole interval
    assert lattice_intersect(0.2, 2.7, 0.0, 1.0, 1.0) == [(0.2, 2.7)]
    # pieces that wrap past the interval end are clipped
    assert lattice_intersect(0.45, 0.47, 0.4, 0.5, 1.0) == [(0.45, 0.47)]
    # nothing
    assert lattice_intersect(0.6, 0.9, 0.4, 0.5, 1.0) == []
    # max_pieces: too many pieces become their hull
    (only,), hulled = lattice_cut(0.0, 100.0, 0.4, 0.5, 1.0, max_pieces=16)
    assert hulled
    assert only[0] == pytest.approx(0.4) and only[1] == pytest.approx(99.5)


def test_two_pi_lattice_accounts_for_the_period_error() -> None:
    # a heading window a thousand turns away: the piece is widened by |k| * TWO_PI_ERROR so the
    # true 2 pi k shift is still covered
    k = 1000
    exact_centre = Fraction(0.3) + 2 * k * Fraction(Decimal(_PI_DIGITS))
    lo = float(exact_centre) - 0.1
    hi = float(exact_centre) + 0.1
    (piece,) = lattice_intersect(lo, hi, 0.3, 0.3, TWO_PI, period_error=TWO_PI_ERROR)
    assert Fraction(piece[0]) <= exact_centre <= Fraction(piece[1])
    assert piece[1] - piece[0] < 1e-9


def test_lattice_intersect_rejects_inverted_input() -> None:
    with pytest.raises(ValueError, match="lo <= hi"):
        lattice_intersect(1.0, 0.0, 0.0, 0.1, 1.0)
    with pytest.raises(ValueError, match="period > 0"):
        lattice_intersect(0.0, 1.0, 0.0, 0.1, 0.0)


@FAST
@given(st.floats(-1e3, 1e3), st.floats(1e-3, 10))
def test_cos_range_wide_interval_is_full(lo, extra) -> None:
    assume(extra > 0)
    assert cos_range(lo, lo + 2 * math.pi + extra) == (-1.0, 1.0)
    assert sin_range(lo, lo + 2 * math.pi + extra) == (-1.0, 1.0)
