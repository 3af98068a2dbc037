"""The one frame loop: every estimator gets the same inputs with the same frame alignment, a
failing optional estimator leaves the loop without stopping it, and the record carries every
estimate."""

from __future__ import annotations

import itertools
from dataclasses import replace

import pytest

from tileviz.baselines import MclConfig, MclEstimate, MclEstimator
from tileviz.config import preset
from tileviz.core.estimators import Estimator, IntervalEstimator, StepInputs
from tileviz.core.localizer import LocalizerStep
from tileviz.pipeline import PRIMARY, FrameLoop, initial_box
from tileviz.sim.source import SimSource
from tileviz.types import Box

CFG = preset("default")


class Recorder:
    """An estimator that keeps the inputs it was stepped with (and can be told to fail)."""

    def __init__(self, fail_at: int | None = None) -> None:
        self.inputs: list[StepInputs] = []
        self.resets: list[Box] = []
        self.fail_at = fail_at

    def reset(self, initial: Box) -> None:
        self.resets.append(initial)

    def step(self, inputs: StepInputs) -> int:
        if self.fail_at is not None and len(self.inputs) == self.fail_at:
            raise ValueError("out of particles")
        self.inputs.append(inputs)
        return len(self.inputs)


@pytest.fixture(scope="module")
def frames() -> list:
    return list(itertools.islice(SimSource(CFG), 5))


def test_every_estimator_predicts_with_the_previous_frames_odometry(frames: list) -> None:
    rec = Recorder()
    loop = FrameLoop(CFG, estimators={PRIMARY: IntervalEstimator.from_config(
        CFG, initial=initial_box(CFG)), "rec": rec})
    records = [loop.process(f) for f in frames]
    assert rec.inputs[0].odometry is None  # frame 0: no motion yet
    for k in range(1, len(frames)):
        assert rec.inputs[k].odometry == frames[k - 1].odometry == records[k].motion
        assert rec.inputs[k].compass == frames[k].compass
        assert rec.inputs[k].observation == records[k].vision.observation
        assert rec.inputs[k].truth == frames[k].truth
    assert [r.estimates["rec"] for r in records] == [1, 2, 3, 4, 5]
    assert all(isinstance(r.estimates[PRIMARY], LocalizerStep) for r in records)
    assert records[-1].step is records[-1].estimates[PRIMARY]


def test_the_default_loop_is_the_interval_localizer_of_the_config(frames: list) -> None:
    a = FrameLoop(CFG)
    b = FrameLoop(CFG, estimators={PRIMARY: IntervalEstimator.from_config(
        CFG, initial=initial_box(CFG))})
    for f in frames:
        ra, rb = a.process(f), b.process(f)
        assert ra.updated == rb.updated and ra.status == rb.status
        assert list(ra.estimates) == [PRIMARY]


def test_an_optional_estimator_that_fails_is_dropped_and_the_frame_goes_on(frames: list) -> None:
    bad = Recorder(fail_at=2)
    loop = FrameLoop(CFG)
    clean = FrameLoop(CFG)
    loop.add("bad", bad, optional=True)
    records = [loop.process(f) for f in frames]
    assert [r.dropped for r in records] == [{}, {}, {"bad": "out of particles"}, {}, {}]
    assert "bad" not in loop.estimators and "bad" not in records[2].estimates
    # the interval localizer went on as if the other one had never been there
    assert [r.updated for r in records] == [clean.process(f).updated for f in frames]


def test_a_required_estimator_that_fails_fails_the_frame_naming_it(frames: list) -> None:
    loop = FrameLoop(CFG)
    loop.add("bad", Recorder(fail_at=0))
    with pytest.raises(ValueError, match="frame 0: out of particles"):
        loop.process(frames[0])


def test_mcl_behind_the_interface_matches_the_filter_stepped_by_hand(frames: list) -> None:
    box = initial_box(CFG)
    config = MclConfig(particles=200, seed=3)
    loop = FrameLoop(CFG, estimators={"mcl": MclEstimator.from_config(CFG, initial=box,
                                                                     config=config)})
    by_hand = MclEstimator.from_config(CFG, initial=box, config=config).mcl
    pending = None
    for f in frames:
        rec = loop.process(f)
        est = by_hand.step(pending, f.compass, rec.vision.observation)
        got: MclEstimate = rec.estimates["mcl"]
        assert (got.particles == est.particles).all() and (got.mean == est.mean).all()
        assert rec.step is None and rec.status == "lost"  # no interval localizer: vouches none
        pending = f.odometry


def test_reset_restarts_every_estimator_without_pending_motion(frames: list) -> None:
    rec = Recorder()
    loop = FrameLoop(CFG)
    loop.add("rec", rec)
    loop.process(frames[0])
    box = initial_box(CFG, pose=frames[1].truth.as_tuple())
    loop.reset(box)
    r = loop.process(frames[1])
    assert rec.resets == [box] and rec.inputs[-1].odometry is None
    assert r.truth_inside()


def test_rotation_changes_the_order_not_the_estimates() -> None:
    def loop(rotate: bool) -> FrameLoop:
        ests: dict[str, Estimator] = {
            m: IntervalEstimator.from_config(CFG, initial=initial_box(CFG), mode=m)
            for m in ("autonomous", "odometry", "truth")}
        return FrameLoop(CFG, estimators=ests, rotate=rotate)

    a, b = loop(False), loop(True)
    followed: set[tuple[str, str]] = set()
    for f in itertools.islice(SimSource(CFG), 20):
        ra, rb = a.process(f), b.process(f)
        assert list(ra.estimates) == list(rb.estimates)
        assert all(ra.estimates[m].updated == rb.estimates[m].updated for m in ra.estimates)
        order = [k[:-3] for k in rb.timings if k != "vision_ms"]  # in stepping order
        followed |= set(zip(order, order[1:], strict=False))
    # no estimator always inherits the caches of the same predecessor
    assert len(followed) == 6, followed


def test_reconfigure_keeps_the_other_estimators(frames: list) -> None:
    rec = Recorder()
    loop = FrameLoop(CFG)
    loop.add("rec", rec)
    loop.process(frames[0])
    loop.reconfigure(replace(CFG, localizer=replace(CFG.localizer, max_boxes=8)))
    loop.process(frames[1])
    assert loop.estimators["rec"] is rec and len(rec.inputs) == 2
