"""Bounded sensors: the readings keep their declared bounds, and the true poses are consistent with
the odometry the way the localizer's prediction assumes (docs/method.md, "Prediction")."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.config import Config, NoiseConfig, SimConfig
from tileviz.sim.controller import wrap_pi
from tileviz.sim.sensors import Sensors, prediction_encloses, within
from tileviz.sim.source import BlankRenderer, SimSource
from tileviz.sim.world import World
from tileviz.types import Odometry, Pose


def _source(cfg: Config) -> SimSource:
    return SimSource(cfg, renderer=BlankRenderer(cfg.camera.width, cfg.camera.height))


def _cfg(seed: int = 3, noise: NoiseConfig | None = None, **sim: object) -> Config:
    cfg = Config()
    return replace(cfg, noise=noise or cfg.noise, sim=replace(cfg.sim, seed=seed, **sim))


def _run(src: SimSource, frames: int, waypoints: list[tuple[float, float]] | None = None):
    """Frames with the true motion of each (frame, StepTruth)."""
    if waypoints:
        src.set_waypoints(waypoints)
    out = []
    for frame in itertools.islice(src, frames):
        out.append((frame, src.last_step))
    return out


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31), fraction=st.floats(0.0, 1.0),
       ev=st.floats(0.0, 0.2), ew=st.floats(0.0, 0.2), ec=st.floats(0.0, 0.3),
       pts=st.lists(st.tuples(st.floats(-4, 4), st.floats(-4, 4)), min_size=1, max_size=4))
def test_sensor_errors_stay_within_the_declared_bounds(seed, fraction, ev, ew, ec, pts) -> None:
    noise = NoiseConfig(speed_error=ev, yaw_rate_error=ew, compass_error=ec, fraction=fraction)
    src = _source(_cfg(seed, noise))
    for frame, step in _run(src, 300, pts):
        odo = frame.odometry
        assert abs(odo.speed - step.speed) <= ev
        assert abs(odo.yaw_rate - step.yaw_rate) <= ew
        assert odo.dt == step.dt == pytest.approx(src.cfg.sim.dt, rel=1e-12)
        assert -math.pi < frame.compass <= math.pi
        assert abs(wrap_pi(frame.compass - frame.truth.theta)) <= ec + 1e-15


def test_errors_use_the_whole_bound_and_are_centred() -> None:
    noise = NoiseConfig(speed_error=0.02, yaw_rate_error=0.01, compass_error=0.02, fraction=1.0)
    runs = _run(_source(_cfg(5, noise)), 2000)
    ev = np.array([f.odometry.speed - s.speed for f, s in runs]) / 0.02
    ew = np.array([f.odometry.yaw_rate - s.yaw_rate for f, s in runs]) / 0.01
    ec = np.array([wrap_pi(f.compass - f.truth.theta) for f, _ in runs]) / 0.02
    for e in (ev, ew, ec):
        assert e.max() > 0.95 and e.min() < -0.95  # uniform over the whole bound
        assert abs(e.mean()) < 0.1
    half = _run(_source(_cfg(5, replace(noise, fraction=0.5))), 500)
    assert max(abs(f.odometry.speed - s.speed) for f, s in half) <= 0.01


def test_zero_bounds_give_exact_readings() -> None:
    noise = NoiseConfig(speed_error=0.0, yaw_rate_error=0.0, compass_error=0.0)
    for frame, step in _run(_source(_cfg(1, noise)), 200):
        assert frame.odometry.speed == step.speed
        assert frame.odometry.yaw_rate == step.yaw_rate
        assert frame.compass == wrap_pi(frame.truth.theta)


def _consistent(frames, bounds: NoiseConfig, tol: float = 1e-9) -> list[bool]:
    """Per frame k: is truth k+1 inside the prediction from truth k with odometry k?"""
    out = []
    for a, b in itertools.pairwise(frames):
        out.append(prediction_encloses(a.truth.as_tuple(), b.truth.as_tuple(), a.odometry,
                                       bounds.speed_error, bounds.yaw_rate_error, tol))
    return out


@pytest.mark.parametrize("setpoint", ["lissajous", "waypoints", "manual"])
def test_true_poses_are_consistent_with_the_measured_odometry(setpoint: str) -> None:
    """The soundness point: with readings anywhere within their bounds (fraction 1), the next true
    pose lies in the prediction from the current true pose, every frame — including the start
    from rest, sharp waypoint turns, turning in place and stopping."""
    noise = NoiseConfig(fraction=1.0)
    cfg = _cfg(11, noise, setpoint=setpoint, manual_target=(-2.0, 1.0),
               waypoints=((1.0, 0.0), (1.0, 1.0), (-1.0, -1.0), (0.5, -2.0)))
    runs = _run(_source(cfg), 1500)
    assert all(s.model_ok for _, s in runs)
    frames = [f for f, _ in runs]
    assert all(_consistent(frames, noise))
    # the check has teeth: the same truth with the readings pushed just past the bounds fails
    pushed = [replace(f, odometry=Odometry(s.speed + 1.5 * noise.speed_error,
                                           s.yaw_rate + 1.5 * noise.yaw_rate_error, s.dt))
              for f, s in runs]
    assert sum(_consistent(pushed, noise)) < 0.2 * len(pushed)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.integers(1, 30)),
                min_size=1, max_size=8),
       st.integers(0, 2**31))
def test_any_wheel_commands_keep_the_odometry_sound(commands, seed) -> None:
    noise = NoiseConfig(speed_error=0.005, yaw_rate_error=0.002, compass_error=0.01)
    world = World(SimConfig(), pose=Pose(0.3, -0.2, 2.0))
    sensors = Sensors(noise, np.random.default_rng(seed))
    for left, right, hold in commands:
        world.set_wheel_speeds(left, right)
        for _ in range(hold):
            step = world.step()
            odo = sensors.odometry(step)
            assert prediction_encloses(step.start.as_tuple(), step.end.as_tuple(), odo,
                                       noise.speed_error, noise.yaw_rate_error)


def test_hitting_a_wall_is_flagged_as_outside_the_model() -> None:
    cfg = _cfg(2, walls=True, room_half_size=2.0, setpoint="manual", manual_target=(5.0, 0.0),
               initial_pose=(0.0, 0.0, 0.0))
    runs = _run(_source(cfg), 300)
    touching = [s for _, s in runs if s.contact]
    assert touching
    assert all(s.model_ok for _, s in runs if not s.contact)


def test_prediction_encloses_is_the_design_formula() -> None:
    # straight ahead at 1 m/s for 0.1 s, exact
    odo = Odometry(1.0, 0.0, 0.1)
    assert prediction_encloses((0, 0, 0), (0.1, 0.0, 0.0), odo, 0.0, 0.0)
    assert not prediction_encloses((0, 0, 0), (0.1, 0.001, 0.0), odo, 0.0, 0.0)
    assert prediction_encloses((0, 0, 0), (0.1, 0.0009, 0.0), odo, 0.0, 0.1)  # heading may turn
    assert not prediction_encloses((0, 0, 0), (0.1, -0.001, 0.02), odo, 0.0, 0.1)
    # around theta = pi the cosine's minimum -1 is inside the heading hull
    odo = Odometry(1.0, 1.0, 0.1)
    assert prediction_encloses((0, 0, math.pi - 0.05), (-0.1, 0.0, math.pi + 0.05), odo, 0.0,
                               0.0)


def test_within_only_nudges_by_rounding() -> None:
    assert within(0.30000000000000004, 0.1, 0.2) <= 0.3
    assert abs(within(0.30000000000000004, 0.1, 0.2) - 0.1) <= 0.2
    with pytest.raises(ValueError, match="not within"):
        within(0.5, 0.1, 0.2)
