"""Regressions for the soundness holes of issue 13, each from the audit's own snippet, plus the
property of the shared mechanism each fix lives in. The truth is checked in exact arithmetic
(``tileviz/testing/exact_truth.py``), never with ``Box.contains`` (which compares in floats)."""

from __future__ import annotations

import importlib.util
import math
import random
import sys
from fractions import Fraction

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from tileviz.config import LocalizerConfig
from tileviz.core.contraction import contract_branch, lever_enclosure, observation_windows
from tileviz.core.intervals import TWO_PI, lattice_cut, lattice_intersect, turn_shift
from tileviz.core.localizer import Localizer
from tileviz.testing import codac_oracle_worker  # (codac runs in its subprocess only)
from tileviz.testing.exact_truth import MP, heading_margin, in_box, in_set, mpf
from tileviz.types import Box, BoxSet, Observation, Odometry, SensorBounds

FAST = settings(max_examples=200)

# --- 1. a subnormal lever arm ------------------------------------------------------------------


def test_a_subnormal_lever_arm_keeps_the_truth() -> None:
    """Audit snippet: a 5e-324 m sideways arm put rho_lo at or below 0, the heading preimage came
    out empty and the cell holding the truth (0, 0.5, 0) vanished under ``contracted``."""
    loc = Localizer(tile_size=1.0, camera_offset=(0.0, 5e-324), bounds=SensorBounds(0, 0, 0),
                    config=LocalizerConfig(), initial=Box(-1.3, 0.0, 0.4, 0.6, -0.1, 0.6))
    st_ = loc.step(None, None, Observation(0.1, 0.5, 0.29, 0.1, 0.3))
    assert st_.status == "contracted"
    assert in_set(st_.updated.boxes, 0, mpf(0.5), 0)
    assert in_set(st_.predicted.boxes, 0, mpf(0.5), 0)


def test_a_negative_subnormal_lever_arm_does_not_divide_by_zero() -> None:
    """Audit snippet: (-1e-323, 0) made rho_lo negative, then 0: ZeroDivisionError. The true pose
    (0, 0.5, pi) (camera at (1e-323, 0.5)) is consistent with the view and must stay."""
    loc = Localizer(tile_size=1.0, camera_offset=(-1e-323, 0.0), bounds=SensorBounds(0, 0, 0),
                    config=LocalizerConfig(),
                    initial=Box(0.0, 0.0, 0.4, 0.6, math.pi - 3.0, math.pi + 3.0))
    st_ = loc.step(None, None, Observation(0.25, 0.5, math.pi, 0.25, 2.0))
    assert st_.status == "contracted"
    assert in_set(st_.updated.boxes, 0, mpf(0.5), MP.pi)


_tiny = st.one_of(
    st.floats(-1e-300, 1e-300, allow_subnormal=True),
    st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 1e-323, -1e-323, 2.2250738585072014e-308]),
)
_arm = st.one_of(_tiny, st.floats(-20.0, 20.0))


@FAST
@given(_arm, _arm)
@example(0.0, 5e-324)
@example(-1e-323, 0.0)
@example(5e-324, 5e-324)
@example(1.0, 1e-300)
def test_lever_enclosure_holds_the_exact_arm_for_every_float(f, left) -> None:
    """rho_lo <= hypot(f, l) <= rho_hi exactly (squared, in rationals), rho_lo > 0 for any arm
    that is not zero, and [phi] holds atan2(l, f) (checked at 256 bits)."""
    lever = lever_enclosure((f, left))
    if f == 0.0 and left == 0.0:
        assert lever is None
        return
    rho_lo, rho_hi, phi_lo, phi_hi = lever
    sq = Fraction(f) ** 2 + Fraction(left) ** 2
    assert 0 < rho_lo and Fraction(rho_lo) ** 2 <= sq <= Fraction(rho_hi) ** 2
    phi = MP.atan2(mpf(left), mpf(f))  # (mpmath has no -0: atan2(-0, -1) is pi, not -pi)
    assert heading_margin(phi_lo, phi_hi, phi) >= 0


# --- 2. the hull's heading shifts ----------------------------------------------------------------


def test_the_hull_replay_writes_keeps_the_truth() -> None:
    """Audit snippet: BoxSet.hull() shifted a heading by -TWO_PI in round-to-nearest; the float
    TWO_PI is below 2 pi, so the hull's t_lo = -6.283185307179586 missed the truth's heading
    0 = -2 pi (mod 2 pi) by 2.4e-16 rad although the set held it."""
    loc = Localizer(tile_size=1.0, camera_offset=(0.4, 0.3),
                    bounds=SensorBounds(0.05, 0.2, 0.05), config=LocalizerConfig(),
                    initial=Box(-0.3, 0.9, 0.1, 1.3, -3.5, 3.5))
    st_ = loc.step(None, None, Observation(0.71, 0.009999999999999945, 0.05, 0.01, 0.05))
    truth = (mpf(0.3), mpf(0.7), 0)
    assert in_set(st_.updated.boxes, *truth)
    assert in_box(st_.updated.hull(), *truth)


def test_k_two_pi_is_exact_up_to_seven_turns() -> None:
    """turn_shift skips the outward step of k * TWO_PI for |k| <= 7 because the product is exact
    there; it is not for some larger k."""
    for k in range(-7, 8):
        assert Fraction(k * TWO_PI) == k * Fraction(TWO_PI)
    assert any(Fraction(k * TWO_PI) != k * Fraction(TWO_PI) for k in range(8, 40))


@FAST
@given(st.floats(-1e6, 1e6), st.floats(0.0, 7.0), st.integers(-10**6, 10**6), st.floats(0, 1))
@example(-3.141592653589795, 2.0, -1, 0.0)
@example(-5e-324, 0.1, -1, 0.0)
@example(1e-3, 0.0, 3, 0.0)
def test_turn_shift_encloses_the_true_shift(lo, width, k, where) -> None:
    """Every heading of [lo, lo + width], moved by k true turns, is in turn_shift(.., k)."""
    hi = lo + width
    s_lo, s_hi = turn_shift(lo, hi, k)
    for t in (mpf(lo), mpf(hi), mpf(lo) + mpf(where) * (mpf(hi) - mpf(lo))):
        assert mpf(s_lo) <= t + k * 2 * MP.pi <= mpf(s_hi)


@FAST
@given(st.lists(st.tuples(st.floats(-20, 20), st.floats(0, 3.5)), min_size=1, max_size=5),
       st.data())
def test_boxset_hull_holds_every_pose_of_the_set(headings, data) -> None:
    """Whatever the boxes' headings (shifted by many turns from each other), every exact pose
    of one of the boxes is in the hull."""
    boxes = tuple(Box(0.0, 1.0, 0.0, 1.0, lo, lo + w) for lo, w in headings)
    hull = BoxSet(boxes).hull()
    b = boxes[data.draw(st.integers(0, len(boxes) - 1))]
    where = data.draw(st.sampled_from([0.0, 1.0, 0.5]))
    theta = mpf(b.t_lo) + where * (mpf(b.t_hi) - mpf(b.t_lo))
    assert in_box(hull, mpf(0.5), mpf(0.5), theta)


# --- 3. a lattice split too fine to keep --------------------------------------------------------


def test_lattice_cut_says_when_it_hulled() -> None:
    pieces, hulled = lattice_cut(0.0, 100.0, 0.4, 0.5, 1.0, max_pieces=16)
    assert hulled and len(pieces) == 1
    pieces, hulled = lattice_cut(0.0, 10.0, 0.4, 0.5, 1.0, max_pieces=16)
    assert not hulled and len(pieces) == 10
    # pieces as wide as the period merge into one exact interval: nothing was added
    pieces, hulled = lattice_cut(0.0, 100.0, 0.0, 1.0, 1.0, max_pieces=16)
    assert not hulled and pieces == [(0.0, 100.0)]
    assert lattice_intersect(0.0, 100.0, 0.4, 0.5, 1.0) == lattice_cut(0.0, 100.0, 0.4, 0.5,
                                                                       1.0)[0]


def test_a_camera_range_over_many_tiles_is_flagged_hulled() -> None:
    """A box 3 m wide in x on 0.1 m tiles: 30 x pieces, more than the 16 cells kept. The result
    must say ``hulled`` (it was silently a hull before), through contract_branch and step()."""
    obs = Observation(0.0, 0.0, 0.0, 0.01, 0.05)  # the view of (0, 0, 0): camera at (0.3, 0.1)
    box = (-1.5, 1.5, -0.01, 0.01, -0.1, 0.1)
    boxes, _, hulled = contract_branch(box, observation_windows(obs)[0], 0.1,
                                       lever_enclosure((0.3, 0.1)), 3, 16)
    assert boxes and hulled
    loc = Localizer(tile_size=0.1, camera_offset=(0.3, 0.1), bounds=SensorBounds(0, 0, 0),
                    config=LocalizerConfig(), initial=Box(*box))
    step = loc.step(None, None, obs)
    assert step.hulled and in_set(step.updated.boxes, 0, 0, 0)


def test_a_hulled_cell_is_recut_every_pass() -> None:
    """Once the lever arm narrows the heading, the camera range of a hulled cell shrinks and the
    lattice pieces it still meets must be cut again (as codac's forward-backward contractor
    does), or x keeps the end of a piece the robot can no longer reach. Case from the codac
    comparison (0.166 m tiles, a box 18 tiles wide, branch m = 3): codac's x_hi is 4.38735;
    before the fix ours stayed at the box's 4.49021."""
    L = 0.166
    rho, phi = 0.27447799010168517, -2.5365233539657095
    box = (1.4318395929946077, 4.490207255158319, 2.7172074194633447, 2.7551780807725996,
           -3.806768795343159, -1.18827877889539)
    win0 = (0.08936990047009087, 0.12303624614189228, 0.1405733737180762, 0.17423971938987765,
            0.06877617847129734, 1.2193615544697411)
    # branch 3: R(3 pi/2) (y1, y2) = (y2, -y1), heading + 3 pi/2 (widened: the case is not at
    # a branch edge)
    win3 = (win0[2], win0[3], -win0[1], -win0[0],
            win0[4] + 3 * math.pi / 2 - 1e-12, win0[5] + 3 * math.pi / 2 + 1e-12)
    lever = lever_enclosure((rho * math.cos(phi), rho * math.sin(phi)))
    boxes, _, hulled = contract_branch(box, win3, L, lever, 3, 16)
    assert hulled and boxes
    assert max(b[1] for b in boxes) < 4.3874


# --- 4. the codac oracle reads its input exactly ------------------------------------------------


def test_the_codac_worker_reads_every_float_exactly() -> None:
    """After ``import codac`` the process rounds upward and CPython misparses ~1 decimal literal
    in 8; the worker parses its input first and answers in float.hex."""
    if importlib.util.find_spec("codac") is None:  # (never import it here: upward rounding)
        pytest.skip("codac is not installed")
    rng = random.Random(13)
    values = [rng.uniform(-10, 10) for _ in range(500)] + [0.1, 0.166, 0.009999999999999945]
    out = codac_oracle_worker.run({"task": "echo", "values": values}, timeout=300)
    back = [float.fromhex(v) for v in out["values"]]
    assert back == values
    assert "codac" not in sys.modules and 1.0 + 2.0**-53 == 1.0  # this process: nearest


# --- degenerate parameters: handled exactly (the adversary covers those) or refused ---------------

_BASE = dict(tile_size=1.0, camera_offset=(0.3, 0.0), bounds=SensorBounds(0.01, 0.01, 0.01),
             config=LocalizerConfig(), initial=Box(0, 0.1, 0, 0.1, 0, 0.1))


@pytest.mark.parametrize(("over", "name"), [
    ({"tile_size": math.nan}, "tile_size"), ({"tile_size": math.inf}, "tile_size"),
    ({"tile_size": 5e-324}, "tile_size"), ({"tile_size": 0.0}, "tile_size"),
    ({"camera_offset": (math.nan, 0.0)}, "camera_offset[0]"),
    ({"camera_offset": (0.0, -math.inf)}, "camera_offset[1]"),
    ({"bounds": SensorBounds(math.nan, 0, 0)}, "speed_error"),
    ({"bounds": SensorBounds(0, math.inf, 0)}, "yaw_rate_error"),
    ({"bounds": SensorBounds(0, 0, -5e-324)}, "compass_error"),
    ({"initial": Box(0, math.inf, 0, 1, 0, 1)}, "initial box.x_hi"),
    ({"initial": Box(0, 1, math.nan, 1, 0, 1)}, "initial box.y_lo"),
])
def test_degenerate_settings_are_refused_in_one_line(over, name) -> None:
    with pytest.raises(ValueError) as err:
        Localizer(**{**_BASE, **over})
    assert str(err.value).startswith(name) and "\n" not in str(err.value)


@pytest.mark.parametrize("kw", [{"max_slip": (math.inf, 0.0)}, {"max_slip": (0.1, math.nan)},
                                {"truth_inflation": (math.nan, 0.0, 0.0)}])
def test_degenerate_config_is_refused_in_one_line(kw) -> None:
    with pytest.raises(ValueError, match=f"^{next(iter(kw))}") as err:
        LocalizerConfig(**kw)
    assert "\n" not in str(err.value)


def test_zero_and_subnormal_bounds_are_legal_and_exact() -> None:
    """Zero-width (and -0.0, subnormal) error bounds and a zero-width initial box: the set is the
    exact pose, rounded outward, and stays around the truth through a step at the bounds."""
    loc = Localizer(tile_size=0.5, camera_offset=(5e-324, -0.0),
                    bounds=SensorBounds(-0.0, 5e-324, 0.0), config=LocalizerConfig(),
                    initial=Box(0.25, 0.25, 0.1, 0.1, 0.5, 0.5))
    step = loc.step(None, 0.5, None)
    assert step.status == "predicted" and in_set(step.updated.boxes, mpf(0.25), mpf(0.1),
                                                 mpf(0.5))
    step = loc.step(Odometry(0.0, 0.0, 1.0), 0.5, None)  # standing still, exactly
    assert in_set(step.updated.boxes, mpf(0.25), mpf(0.1), mpf(0.5))
    assert max(step.updated.hull().widths) < 1e-15
