"""The adversarial soundness suite (issue 13): runs that respect every declared bound at its
nastiest, the truth in exact arithmetic, every frame's ``predicted``, ``updated`` and written hull
checked (``tileviz/testing/adversary.py`` says how). One hypothesis strategy per class of
nastiness; the long run (>= 1e5 frames) is ``bench/soundness_audit.py``.

The suite is deterministic (the shared hypothesis profile is derandomized) and takes a few tens of
seconds; it can fail: the last tests show it catching a localizer told bounds tighter than the
truth's, and the hull hole of the audit on the pre-fix rounding.
"""

from __future__ import annotations

from dataclasses import replace

import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

import tileviz.types
from tileviz.testing.adversary import KINDS, HypothesisChooser, RandomChooser, run, scenario
from tileviz.types import SensorBounds

EXAMPLES = 15
FRAMES = 8
# No shrinking: one run costs milliseconds of 256-bit arithmetic and the shrinker would try
# thousands; the failing example is printed as drawn (and its message names frame and class).


def _check(data: st.DataObject, kind: str) -> None:
    scn = scenario(HypothesisChooser(data), kind, FRAMES)
    rep = run(scn)
    assert not rep.violations, f"{rep.violations[0]}\n{scn!r}"
    assert rep.frames == FRAMES


@pytest.mark.parametrize("kind", KINDS)
@settings(max_examples=EXAMPLES, phases=[Phase.explicit, Phase.reuse, Phase.generate])
@given(data=st.data())
def test_the_truth_is_in_every_set_of_every_frame(kind, data) -> None:
    """Headings at +-pi and many turns out (``wrap``), at the pi/4 branch edges with either
    branch's reading (``branch_edge``), the camera on a grout line (``grout``), zero, subnormal
    and several-tile lever arms (``lever``), tiles 1 cm - 10 m, coordinates to 1e8 m, dt 1e-6 -
    5 s (``scales``), zero, negative and zero-straddling speeds (``speeds``), zero-width boxes
    and bounds, subnormal parameters (``degenerate``), all at once (``mixed``); controls
    bang-bang within the bounds over up to 40 sub-steps a frame, every reading at its bound."""
    _check(data, kind)


def test_seeded_runs_of_every_class() -> None:
    """A fixed batch beside the shrinking strategies: 8 classes x 12 seeds x 10 frames; also
    checks the batch does exercise the view (most frames contract)."""
    statuses: dict[str, int] = {}
    for kind in KINDS:
        for seed in range(12):
            rep = run(scenario(RandomChooser(1000 * KINDS.index(kind) + seed), kind, 10))
            assert not rep.violations, rep.violations[0]
            for k, v in rep.statuses.items():
                statuses[k] = statuses.get(k, 0) + v
    assert statuses.get("contracted", 0) > statuses.get("predicted", 0)


def test_the_adversary_catches_bounds_the_truth_exceeds() -> None:
    """Tell the localizer half the speed and yaw-rate bounds the truth uses: the adversary must
    report the truth outside the set (so a passing run means something)."""
    found = 0
    for seed in range(40):
        scn = scenario(RandomChooser(seed), "speeds", 10)
        b = scn.bounds
        if b.speed_error < 0.01 and b.yaw_rate_error < 0.01:
            continue
        scn = replace(scn, bounds=SensorBounds(b.speed_error / 2, b.yaw_rate_error / 2,
                                               b.compass_error))
        # (the readings were drawn for the true bounds: the compass and the view stay honest)
        found += bool(run(scn).violations)
    assert found >= 3


def test_the_adversary_catches_the_audits_hull_hole(monkeypatch) -> None:
    """Seed 495 of class ``mixed``: with BoxSet.hull shifting headings in round-to-nearest (the
    code before the fix) the written hull missed the truth by 4.1e-16 rad at frame 1."""
    scn = scenario(RandomChooser(495), "mixed", 4)
    assert not run(scn).violations
    two_pi = tileviz.types.TWO_PI

    def nearest_shift(lo: float, hi: float, k: int) -> tuple[float, float]:
        return (lo + k * two_pi, hi + k * two_pi)

    monkeypatch.setattr(tileviz.types, "turn_shift", nearest_shift)
    rep = run(scn)
    assert rep.violations and "not in hull" in rep.violations[0]
