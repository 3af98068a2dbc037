"""Bit-exact regression of :class:`tileviz.core.localizer.Localizer` against stored output.

``tests/data/localizer_golden.npz`` holds, for a few fixed input sequences, the inputs of every
frame (odometry, compass, observation; the truth in mode truth) and what the localizer returned:
both box sets (every bound as a float64 bit pattern), the status, passes, rejection streak and
flags. The test
replays the stored inputs and requires every output bit to be the same, so an optimisation of the
hot path (``tileviz/core/``: localizer, prediction, contraction, boxes, intervals) that changes
a single rounding shows up here with the sequence and the first frame that differs.

The inputs come from the simulator (``SimSource``, fixed seeds) through the *robust* extractor
(deterministic), and are stored, so the test depends neither on vision nor on the machine. The
sequences are made to reach every path of ``Localizer.step``: the ``default`` and ``seed``
presets; modes autonomous, truth and odometry; no lever arm; a wide start (many boxes, the box
cap); outlier views (random observations), missing compass readings and views, wide heading
bounds (each branch cut on its own); a wheel slip and kidnaps (rejections, recovery,
``lost``).

Regenerate (only when an output change is intended, and say why in the commit):

    python tests/test_localizer_golden.py

which rebuilds the inputs (a minute of simulation and vision) and records the current
localizer's output.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tileviz.config import LocalizerConfig
from tileviz.core.localizer import Localizer
from tileviz.testing.golden import (
    SEQUENCES,
    Golden,
    first_difference,
    load,
    regenerate,
    run_localizer,
)
from tileviz.types import STATUSES, Box, BoxSet, Observation, Odometry, SensorBounds

GOLDEN = Path(__file__).with_name("data") / "localizer_golden.npz"


@pytest.fixture(scope="module")
def golden() -> Golden:
    return load(GOLDEN)


@pytest.mark.parametrize("name", [s.name for s in SEQUENCES])
def test_output_is_bit_identical(golden, name: str) -> None:
    setup, inputs, want = golden[name]
    got = run_localizer(setup, inputs)
    assert first_difference(want, got) is None, f"{name}: {first_difference(want, got)}"


def test_sequences_reach_every_path(golden) -> None:
    """The stored sequences exercise what they are meant to (a golden file of easy frames would
    prove little): every status, the box cap, compass rejections, recovery, several boxes, no
    lever arm, several passes, wide heading bounds."""
    scal = np.concatenate([g[2]["scalars"] for g in golden.values()])
    assert set(scal[:, 0]) == set(range(len(STATUSES)))
    assert scal[:, 1].max() >= 2  # a second contraction pass
    assert scal[:, 3].any() and scal[:, 4].any() and scal[:, 5].any()
    assert max(int(g[2]["updated_count"].max()) for g in golden.values()) >= 4
    assert any(g[0]["camera_offset"] == [0.0, 0.0] for g in golden.values())
    obs = np.concatenate([g[1]["observation"] for g in golden.values()])
    assert (obs[:, 4] >= math.pi / 8).any() and np.isnan(obs[:, 0]).any()


def test_a_changed_bit_is_noticed(golden) -> None:
    """The comparison itself: one ulp moved in one bound is reported with its frame."""
    setup, inputs, want = golden["default-autonomous"]
    got = {k: v.copy() for k, v in want.items()}
    got["updated"][5, 2] = math.nextafter(got["updated"][5, 2], math.inf)
    msg = first_difference(want, got)
    assert msg is not None and "updated box" in msg


if __name__ == "__main__":
    regenerate(GOLDEN)


def test_results_are_the_public_types_the_hot_path_computes_on() -> None:
    """The localizer's results are public objects: every box of both sets is a
    :class:`Box` (the type the hot path computes on), the sets are :class:`BoxSet` with the
    boxes as a tuple, the step is an immutable :class:`LocalizerStep`, equal to one built from
    its fields."""
    from tileviz.core.localizer import LocalizerStep

    t1 = (0.1, 0.2, -0.3, 0.4, 0.0, 0.1)
    loc = Localizer(tile_size=1.0, camera_offset=(0.3, 0.0), bounds=SensorBounds(0.02, 0.01, 0.02),
                    config=LocalizerConfig(max_slip=(0.1, 0.1)), initial=Box(*t1))
    steps = [loc.step(Odometry(0.5, 0.1, 0.05), 0.05, None),
             loc.step(Odometry(0.5, 0.1, 0.05), 0.1, Observation(0.4, 0.7, 0.12, 0.01, 0.01))]
    for step in steps:
        assert type(step) is LocalizerStep
        for s in (step.predicted, step.updated):
            assert type(s) is BoxSet and type(s.boxes) is tuple and s.boxes
            assert all(type(b) is Box for b in s.boxes)
        again = LocalizerStep(step.predicted, step.updated, step.status, step.passes,
                              step.hulled, step.compass_rejected, step.rejections,
                              step.reinflated)
        assert step == again and repr(step) == repr(again) and hash(step) == hash(again)
        with pytest.raises(AttributeError):
            step.status = "lost"  # type: ignore[misc]
    assert type(loc.current) is BoxSet and all(type(b) is Box for b in loc.current.boxes)
