"""The pymunk world, the setpoints and the controller: motion a user would see."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.config import SimConfig, preset
from tileviz.sim.controller import Controller, Gains, wrap_pi
from tileviz.sim.setpoints import Lissajous, ManualTarget, Waypoints
from tileviz.sim.world import World
from tileviz.types import Pose

SIM = SimConfig()


def drive(world: World, setpoint, frames: int, controller: Controller | None = None,
          t0: float = 0.0) -> list[tuple[Pose, object]]:
    """Run the controller on the world for ``frames`` frames; returns (pose k, target k) pairs."""
    ctl = controller or Controller(world.sim.wheel_base, world.sim.max_wheel_speed)
    out = []
    for k in range(frames):
        pose = world.pose
        target = setpoint.target(t0 + k * world.dt, pose)
        world.set_wheel_speeds(*ctl.command(pose, target, world.dt))
        world.step()
        out.append((pose, target))
    return out


def test_same_commands_give_the_same_poses() -> None:
    runs = []
    for _ in range(2):
        w = World(replace(SIM, walls=True, obstacles=((1.0, -1.0, 0.3),)))
        drive(w, Waypoints([(1.0, -1.0), (-1.0, 1.0)]), 400)
        runs.append(w.pose)
    assert runs[0] == runs[1]


def test_pose_is_the_point_between_the_wheels_with_a_continuous_heading() -> None:
    w = World(SIM, pose=Pose(1.0, 2.0, 0.5))
    assert w.pose == Pose(1.0, 2.0, 0.5)
    w.set_wheel_speeds(-0.3, 0.3)  # spin on the spot, counter-clockwise
    for _ in range(400):
        w.step()
    p = w.pose
    assert math.hypot(p.x - 1.0, p.y - 2.0) < 1e-9  # turning in place does not move it
    assert p.theta > 0.5 + 2 * math.pi  # more than a full turn, not wrapped


def test_constant_wheels_drive_a_circle_of_radius_v_over_w() -> None:
    w = World(SIM, pose=Pose(0.0, 0.0, 0.0))
    left, right = 0.2, 0.4
    v, om = 0.5 * (left + right), (right - left) / SIM.wheel_base
    w.set_wheel_speeds(left, right)
    for _ in range(40):  # reach the commanded speeds
        w.step()
    assert w.wheels == (left, right)
    p0 = w.pose
    centre = (p0.x - v / om * math.sin(p0.theta), p0.y + v / om * math.cos(p0.theta))
    for _ in range(int(2 * math.pi / om / SIM.dt)):
        s = w.step()
        assert abs(s.speed - v) < 1e-9 and abs(s.yaw_rate - om) < 1e-9
        p = w.pose
        assert abs(math.hypot(p.x - centre[0], p.y - centre[1]) - v / om) < 2e-3


def test_wheel_speeds_saturate_and_slew() -> None:
    w = World(SIM, pose=Pose(0.0, 0.0, 0.0))
    assert w.set_wheel_speeds(5.0, -7.0) == (SIM.max_wheel_speed, -SIM.max_wheel_speed)
    w.set_wheel_speeds(5.0, 5.0)
    prev = w.wheels
    fastest = 0.0
    for _ in range(200):
        s = w.step()
        for a, b in zip(prev, w.wheels, strict=True):
            assert abs(b - a) <= w.max_wheel_accel * SIM.dt + 1e-12
        prev = w.wheels
        fastest = max(fastest, s.speed_max)
    assert w.wheels == (SIM.max_wheel_speed, SIM.max_wheel_speed)
    assert SIM.max_wheel_speed - 1e-9 < fastest <= SIM.max_wheel_speed + 1e-9


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-1.5, 1.5), st.floats(-1.5, 1.5)), min_size=1, max_size=12),
       st.integers(1, 15))
def test_free_driving_always_obeys_the_odometry_model(commands, hold) -> None:
    """Any wheel commands (reversals, spins, saturation): without contacts every frame moves as a
    constant-(speed, yaw rate) polyline (StepTruth.model_ok)."""
    w = World(SIM, pose=Pose(0.0, 0.0, 1.0))
    for left, right in commands:
        w.set_wheel_speeds(left, right)
        for _ in range(hold):
            s = w.step()
            assert s.model_ok and not s.contact
            assert s.lateral_max <= 1e-9
            assert s.speed_max - s.speed_min <= 1e-9
            assert abs(s.speed) <= SIM.max_wheel_speed + 1e-9


def test_walls_stop_the_robot() -> None:
    sim = replace(SIM, walls=True, room_half_size=2.0)
    w = World(sim, pose=Pose(0.0, 0.0, 0.0))
    w.set_wheel_speeds(0.8, 0.8)
    contacts = 0
    for _ in range(300):  # 15 s at full speed: 12 m of wheel travel toward a wall 2 m away
        s = w.step()
        contacts += s.contact
        assert w.pose.x < 2.0 - 0.25 + 0.01  # nose at most 1 cm into the wall
    assert contacts > 100
    assert abs(s.speed) < 0.01  # pushing, not moving
    assert s.contact and w.pose.x > 2.0 - 0.25 - 0.02  # it did reach the wall
    # without walls the same run goes far
    free = World(SIM, pose=Pose(0.0, 0.0, 0.0))
    free.set_wheel_speeds(0.8, 0.8)
    for _ in range(300):
        free.step()
    assert free.pose.x > 10.0


def _chassis_gap(pose: Pose, size: tuple[float, float], cx: float, cy: float) -> float:
    """Distance from a point to the robot's rectangle (0 inside)."""
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    dx, dy = cx - pose.x, cy - pose.y
    f, lft = dx * c + dy * s, -dx * s + dy * c
    ex = max(abs(f) - size[0] / 2, 0.0)
    ey = max(abs(lft) - size[1] / 2, 0.0)
    return math.hypot(ex, ey)


def test_the_robot_bumps_into_round_obstacles() -> None:
    obstacle = (2.0, 0.05, 0.3)
    w = World(replace(SIM, obstacles=(obstacle,)), pose=Pose(0.0, 0.0, 0.0))
    hit = False
    for pose, _ in drive(w, ManualTarget(4.0, 0.0), 300):
        assert _chassis_gap(pose, w.robot_size, obstacle[0], obstacle[1]) >= obstacle[2] - 0.01
        hit |= _chassis_gap(pose, w.robot_size, obstacle[0], obstacle[1]) < obstacle[2] + 0.01
    assert hit


def test_lissajous_is_the_originals_curve() -> None:
    c = Lissajous(10.0, 0.01)
    for t in (0.0, 17.0, 123.4, 600.0):
        ph = 0.01 * t + math.pi / 2
        assert c.position(t) == pytest.approx((10 * math.cos(ph), 10 * math.sin(2 * ph)))
        h = 1e-4
        num = [(a - b) / (2 * h) for a, b in zip(c.position(t + h), c.position(t - h),
                                                 strict=True)]
        assert c.velocity(t) == pytest.approx(num, rel=1e-6, abs=1e-9)
    assert c.position(0.0) == pytest.approx((0.0, 0.0), abs=1e-12)


@pytest.mark.parametrize("name", ["default", "seed"])
def test_preset_lissajous_fits_the_room_and_the_wheels(name: str) -> None:
    sim = preset(name).sim
    c = Lissajous(sim.lissajous_amplitude, sim.lissajous_omega)
    pts = c.path(2000)
    margin = 0.5  # room for the chassis and the tracking error
    assert max(max(abs(x), abs(y)) for x, y in pts) <= sim.room_half_size - margin
    period = 2 * math.pi / sim.lissajous_omega
    fastest = max(math.hypot(*c.velocity(period * i / 2000)) for i in range(2000))
    assert fastest <= 0.6 * sim.max_wheel_speed
    # the robot starts on the curve, heading along it
    x, y = c.position(0.0)
    vx, vy = c.velocity(0.0)
    assert sim.initial_pose[:2] == pytest.approx((x, y), abs=1e-9)
    assert abs(wrap_pi(sim.initial_pose[2] - math.atan2(vy, vx))) < 1e-9


@pytest.mark.parametrize("name", ["default", "seed"])
def test_the_robot_follows_the_lissajous_curve(name: str) -> None:
    sim = preset(name).sim
    w = World(sim)
    c = Lissajous(sim.lissajous_amplitude, sim.lissajous_omega)
    lap = int(2 * math.pi / sim.lissajous_omega / sim.dt)
    settle = int(20 / sim.dt)
    run = drive(w, c, lap + settle)
    errors = [math.hypot(t.x - p.x, t.y - p.y) for p, t in run]
    assert max(errors[settle:]) < 0.05
    # it went around the whole curve: x and y both spanned +-A
    a = sim.lissajous_amplitude
    for coord in (0, 1):
        values = [p.as_tuple()[coord] for p, _ in run]
        assert max(values) > 0.95 * a and min(values) < -0.95 * a


def test_manual_target_is_reached_and_held() -> None:
    w = World(SIM, pose=Pose(0.0, 0.0, 0.0))
    target = ManualTarget(-1.5, 2.0)  # behind and to the left: turn in place first
    drive(w, target, 600)
    g = Gains()
    assert math.hypot(w.pose.x + 1.5, w.pose.y - 2.0) <= g.arrive_radius + 0.01
    before = w.pose
    drive(w, target, 100)
    assert w.pose == before or math.hypot(w.pose.x - before.x, w.pose.y - before.y) < 0.02


def test_waypoints_are_visited_in_order_and_loop() -> None:
    w = World(SIM, pose=Pose(0.0, 0.0, 0.0))
    pts = [(2.0, 0.0), (2.0, 2.0), (-1.0, 2.0)]
    wp = Waypoints(pts, radius=0.3)
    visited: list[int] = []
    ctl = Controller(SIM.wheel_base, SIM.max_wheel_speed)
    for k in range(2000):
        before = wp.index
        pose = w.pose
        target = wp.target(k * SIM.dt, pose)
        if wp.index != before:
            visited.append(before)
            assert math.hypot(pose.x - pts[before][0], pose.y - pts[before][1]) <= 0.3
        w.set_wheel_speeds(*ctl.command(pose, target, SIM.dt))
        w.step()
    assert wp.laps >= 1
    assert visited[:4] == [0, 1, 2, 0]


def test_controller_never_asks_more_than_the_wheels_can_and_keeps_the_turn() -> None:
    ctl = Controller(0.4, 0.5, Gains(kp=50.0, kv=50.0))
    goal = ManualTarget(5, 5).target(0.0, Pose(0, 0, 0))
    for theta in (0.0, 1.0, 2.5, -3.0):
        left, right = ctl.command(Pose(0.0, 0.0, theta), goal, 0.05)
        assert abs(left) <= 0.5 and abs(right) <= 0.5
        err = wrap_pi(math.atan2(5, 5) - theta)
        if abs(err) > 0.1:
            # turning the right way, at the saturated yaw rate
            assert (right - left) * err > 0
            assert (right - left) / 0.4 == pytest.approx(math.copysign(1.5, err))


def test_bad_inputs_raise_naming_the_quantity() -> None:
    w = World(SIM)
    with pytest.raises(ValueError, match="wheel speeds"):
        w.set_wheel_speeds(math.nan, 0.0)
    with pytest.raises(ValueError, match="obstacle radius"):
        w.add_obstacle(0.0, 0.0, -1.0)
    with pytest.raises(ValueError, match="pose"):
        w.teleport(Pose(math.inf, 0.0, 0.0))
    with pytest.raises(ValueError, match="substeps"):
        World(SIM, substeps=0)
    with pytest.raises(ValueError, match="waypoints"):
        Waypoints([])
    with pytest.raises(ValueError, match="manual target"):
        ManualTarget(math.nan, 1.0)
    with pytest.raises(ValueError, match="kp"):
        Gains(kp=-1.0)
