"""The pymunk world: a differential-drive robot seen from above, walls and round obstacles.

Frames and units: world metres, x east, y north, heading ``theta`` counter-clockwise from +x in
radians, continuous (pymunk's ``Body.angle`` is never wrapped). The robot's body origin and centre
of gravity is the point between the wheels, so ``Body.position`` / ``Body.angle`` *are* the pose of
``docs/dataset-format.md``.

Top-down friction, the way pymunk's ``examples/tank.py`` does it: there is no gravity; a kinematic
*control body* carries the velocity the wheels ask for, and two joints tie the robot to it. A
``PivotJoint`` with ``max_bias = 0`` (no position correction) makes the robot's linear velocity
match the control body's, with at most the traction force ``mu m g`` (wheel grip, forwards *and*
sideways: a wheel does not slide sideways unless pushed harder than its grip). A ``GearJoint``
with ``max_bias = 0`` does the same for the yaw rate with at most the friction torque. Pressed
against a wall, the robot pushes with its traction force and stops; the contacts win.

Exact odometry model. One frame advances ``dt`` in ``substeps`` equal steps of ``h = dt/substeps``.
Chipmunk integrates positions *before* solving velocities; here the robot's ``position_func`` is a
no-op and the position update is called right after each solve, so during substep j the robot
moves by ``h * v_j`` with the velocity ``v_j`` solved for that substep, aligned with the heading at
the substep's start, and turns by ``h * w_j``. The wheels' speeds are held over a frame
(zero-order hold) and slew-limited (:attr:`World.max_wheel_accel`) so the joints never saturate
in free driving: the motion of a frame is then an exact constant-(speed, yaw rate) Euler polyline
whose segment directions all lie in the heading range of the frame, which is what the localizer's
prediction (docs/method.md, "Prediction") encloses. :class:`StepTruth` records the substeps and says
whether that held (``model_ok``); it does not when the robot hits something.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pymunk

from tileviz.config import SimConfig
from tileviz.types import Pose

GRAVITY = 9.81
"""m/s^2, only to turn the friction coefficient into a traction force."""
ROBOT_MASS = 10.0
"""kg."""
ROBOT_LENGTH = 0.5
"""Chassis length along the heading, metres, centred on the wheel axle."""
WHEEL_GRIP = 0.8
"""Friction coefficient mu between wheels and floor (traction force mu m g)."""
TURN_GRIP_ARM = 0.5
"""Friction torque = mu m g * TURN_GRIP_ARM * wheel_base (skid-steer scrub), N m."""
SLEW_SAFETY = 0.7
"""Wheel acceleration limit as a share of what the joints can deliver in one substep."""
WALL_THICKNESS = 0.05
"""Radius of the wall segments, metres."""
LATERAL_TOL = 1e-9
"""m/s: a substep whose sideways speed exceeds this breaks the odometry model (``model_ok``)."""


def _wrap_check_finite(name: str, *values: float) -> None:
    for v in values:
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"{name} must be finite numbers, got {values!r}")


@dataclass(frozen=True)
class StepTruth:
    """The true motion over one frame step, from ``start`` (pose k) to ``end`` (pose k+1).

    ``speed`` is the mean signed forward speed over the substeps (m/s) and ``yaw_rate`` the mean
    turn rate ``(end.theta - start.theta) / dt`` (rad/s): the "true" values the odometry sensor
    measures, the ones that make the prediction model valid. ``speed_min/max`` and
    ``yaw_rate_min/max`` span the substeps; ``lateral_max`` is the largest sideways speed (m/s,
    0 for a rolling wheel). ``model_ok``: every substep moved along a heading inside the frame's
    heading range, sideways speed ~0, speeds of one sign and a monotone heading — then the pose k+1
    lies in the prediction from pose k with (speed, yaw_rate) held over dt. ``contact``: the robot
    touched a wall or obstacle during the step.
    """

    start: Pose
    end: Pose
    dt: float
    speed: float
    yaw_rate: float
    speed_min: float
    speed_max: float
    yaw_rate_min: float
    yaw_rate_max: float
    lateral_max: float
    contact: bool
    model_ok: bool


class World:
    """A differential-drive robot in a pymunk space, stepped one frame (``sim.dt``) at a time.

    ``set_wheel_speeds(left, right)`` sets the wheel speed *commands* (m/s, saturated to
    ``+- sim.max_wheel_speed``); :meth:`step` moves the actual wheel speeds toward them by at most
    ``max_wheel_accel * dt`` and holds them over the frame. Reproducible: the same calls give the
    same poses (pymunk is deterministic and nothing here is random).
    """

    def __init__(self, sim: SimConfig, *, pose: Pose | None = None, substeps: int = 5) -> None:
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.sim = sim
        self.dt = float(sim.dt)
        self.substeps = int(substeps)
        self.h = self.dt / self.substeps
        half_w = sim.wheel_base / 2 + 0.05
        self.robot_size = (ROBOT_LENGTH, 2 * half_w)
        """Chassis (length, width), metres."""

        space = pymunk.Space()
        space.iterations = 10
        space.gravity = (0.0, 0.0)
        self.space = space

        moment = pymunk.moment_for_box(ROBOT_MASS, self.robot_size)
        body = pymunk.Body(ROBOT_MASS, moment)
        body.center_of_gravity = (0.0, 0.0)
        # Positions are integrated after the solve (see module docstring), not before.
        body.position_func = _no_position_update
        shape = pymunk.Poly.create_box(body, self.robot_size)
        shape.friction = 0.5
        shape.elasticity = 0.0
        space.add(body, shape)
        self.body = body
        self.shape = shape

        control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        space.add(control)
        self.control = control
        traction = WHEEL_GRIP * ROBOT_MASS * GRAVITY
        torque = traction * TURN_GRIP_ARM * sim.wheel_base
        pivot = pymunk.PivotJoint(control, body, (0.0, 0.0), (0.0, 0.0))
        pivot.max_bias = 0.0
        pivot.max_force = traction
        gear = pymunk.GearJoint(control, body, 0.0, 1.0)
        gear.max_bias = 0.0
        gear.max_force = torque
        space.add(pivot, gear)
        self.traction = traction
        """Largest force the wheels transmit (N)."""
        self.turn_torque = torque
        """Largest yaw torque the wheels transmit (N m)."""

        # The joints reach a new velocity within one substep when m |dv| <= F h and
        # I |dw| <= T h; a wheel slew a*dt per frame changes v by <= a*dt and w by <= 2 a dt / b.
        a_lin = traction / (ROBOT_MASS * self.substeps)
        a_ang = torque * sim.wheel_base / (2 * moment * self.substeps)
        self.max_wheel_accel = SLEW_SAFETY * min(a_lin, a_ang)
        """Wheel acceleration limit, m/s^2 (independent of dt)."""

        self._contact = False
        self.obstacles: list[tuple[float, float, float]] = []
        if sim.walls:
            r = sim.room_half_size + WALL_THICKNESS
            corners = [(-r, -r), (r, -r), (r, r), (-r, r)]
            for i in range(4):
                seg = pymunk.Segment(space.static_body, corners[i], corners[(i + 1) % 4],
                                     WALL_THICKNESS)
                seg.friction = 0.5
                seg.elasticity = 0.0
                space.add(seg)
        for ox, oy, rad in sim.obstacles:
            self.add_obstacle(ox, oy, rad)
        space.on_collision(begin=None, pre_solve=self._on_contact)

        self.command = (0.0, 0.0)
        """Commanded wheel speeds (left, right), m/s, after saturation."""
        self.wheels = (0.0, 0.0)
        """Actual wheel speeds (left, right), m/s, held over the current frame."""
        self.time = 0.0
        """Simulated seconds since the start."""
        start = pose if pose is not None else Pose(*sim.initial_pose)
        self.teleport(start)

    # ------------------------------------------------------------------ state
    @property
    def pose(self) -> Pose:
        """The true pose (point between the wheels, continuous heading)."""
        p = self.body.position
        return Pose(float(p.x), float(p.y), float(self.body.angle))

    def teleport(self, pose: Pose) -> None:
        """Put the robot at ``pose`` at rest (wheels stopped). Nothing else is told."""
        _wrap_check_finite("pose", pose.x, pose.y, pose.theta)
        self.body.position = (pose.x, pose.y)
        self.body.angle = pose.theta
        self.body.velocity = (0.0, 0.0)
        self.body.angular_velocity = 0.0
        self.control.velocity = (0.0, 0.0)
        self.control.angular_velocity = 0.0
        self.command = (0.0, 0.0)
        self.wheels = (0.0, 0.0)
        self.space.reindex_shapes_for_body(self.body)

    def add_obstacle(self, x: float, y: float, radius: float) -> None:
        """A static round obstacle centred at (x, y), metres."""
        _wrap_check_finite("obstacle", x, y, radius)
        if radius <= 0:
            raise ValueError(f"obstacle radius must be > 0, got {radius!r}")
        c = pymunk.Circle(self.space.static_body, radius, (x, y))
        c.friction = 0.5
        c.elasticity = 0.0
        self.space.add(c)
        self.obstacles.append((float(x), float(y), float(radius)))

    def set_wheel_speeds(self, left: float, right: float) -> tuple[float, float]:
        """Command the wheel speeds (m/s, forward positive); returns them after saturation."""
        _wrap_check_finite("wheel speeds", left, right)
        vmax = self.sim.max_wheel_speed
        self.command = (min(max(left, -vmax), vmax), min(max(right, -vmax), vmax))
        return self.command

    # ------------------------------------------------------------------ stepping
    def _on_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        self._contact = True

    def _slew(self) -> None:
        """Move the actual wheel speeds toward the command by at most max_wheel_accel * dt."""
        step = self.max_wheel_accel * self.dt
        out = []
        for cur, cmd in zip(self.wheels, self.command, strict=True):
            out.append(cur + min(max(cmd - cur, -step), step))
        self.wheels = (out[0], out[1])

    def step(self, dt: float | None = None) -> StepTruth:
        """Advance one frame of ``dt`` seconds (default ``sim.dt``) and return the true motion
        over it."""
        dt = self.dt if dt is None else float(dt)
        self._slew()
        left, right = self.wheels
        v_cmd = 0.5 * (left + right)
        w_cmd = (right - left) / self.sim.wheel_base
        body, control, h = self.body, self.control, dt / self.substeps
        # the body's state is read once after each substep (every pymunk read is a C call that
        # gives up the GIL, and waits for it again when another thread holds it)
        p0, th = body.position, body.angle
        start = Pose(float(p0.x), float(p0.y), float(th))
        speeds: list[float] = []
        rates: list[float] = []
        lateral = 0.0
        self._contact = False
        monotone = True
        for _ in range(self.substeps):
            c, s = math.cos(th), math.sin(th)
            control.velocity = (v_cmd * c, v_cmd * s)
            control.angular_velocity = w_cmd
            self.space.step(h)
            pymunk.Body.update_position(body, h)
            p1, th1 = body.position, body.angle
            d = p1 - p0
            speeds.append((d.x * c + d.y * s) / h)
            lateral = max(lateral, abs(-d.x * s + d.y * c) / h)
            rates.append((th1 - th) / h)
            p0, th = p1, th1
        self.time += dt
        end = Pose(float(p0.x), float(p0.y), float(th))
        yaw_rate = (end.theta - start.theta) / dt
        speed = math.fsum(speeds) / len(speeds)
        if any(r > 0 for r in rates) and any(r < 0 for r in rates):
            monotone = False
        same_sign = not (any(v > 0 for v in speeds) and any(v < 0 for v in speeds))
        return StepTruth(
            start=start,
            end=end,
            dt=dt,
            speed=speed,
            yaw_rate=yaw_rate,
            speed_min=min(speeds),
            speed_max=max(speeds),
            yaw_rate_min=min(rates),
            yaw_rate_max=max(rates),
            lateral_max=lateral,
            contact=self._contact,
            model_ok=lateral <= LATERAL_TOL and monotone and same_sign,
        )


def _no_position_update(body: pymunk.Body, dt: float) -> None:
    """Body position function that does nothing: :meth:`World.step` integrates after the solve."""
