"""A setpoint-following controller for the differential-drive robot (it uses the true pose: it is
part of the simulated robot, not of the localizer).

Control law, once a frame (world frame, SI units):

- Aim point ``a = p_target + lookahead * v_target`` (a moving target is led, a fixed one is not).
- Heading error ``e = wrap(atan2(a - p) - theta)`` in (-pi, pi] rad, where p is the point between
  the wheels.
- Yaw rate ``w = sat(kp * e + kd * de/dt, +- max_yaw_rate)`` rad/s — a PD on the heading error
  with saturation (``de/dt`` by a backward difference over the frame, 0 on the first frame and
  when the goal jumps).
- Speed from distance: ``v = sat(v_target . u + kv * (p_target - p) . u, [0, max_speed])`` m/s
  with ``u = (cos theta, sin theta)``: feed-forward of the target's velocity along the heading
  plus a proportional term on the along-track distance. A target behind the robot gives v = 0,
  so the robot turns in place first. Within ``arrive_radius`` of a ``stop`` target: v = w = 0.
- Wheels: ``left = v - w b/2``, ``right = v + w b/2``; when a wheel would exceed the saturation,
  the speed is reduced first so the turn is kept (turning priority), then both wheels are clipped.

Default gains (:class:`Gains`): kp = 2.0 (rad/s)/rad, kd = 0.1 s, max_yaw_rate = 1.5 rad/s,
kv = 0.8 (m/s)/m, lookahead = 1.0 s, arrive_radius = 0.03 m. With dt = 0.05 s, kp * dt = 0.1:
the discrete heading loop is well damped despite the one-frame actuation delay.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tileviz.sim.setpoints import Target
from tileviz.types import Pose


def wrap_pi(a: float) -> float:
    """Angle wrapped to (-pi, pi], rad."""
    r = math.remainder(a, 2 * math.pi)  # in [-pi, pi]
    return math.pi if r <= -math.pi else r


@dataclass(frozen=True)
class Gains:
    """Controller gains (see the module docstring for the law)."""

    kp: float = 2.0
    """Heading P gain, (rad/s) per rad of heading error."""
    kd: float = 0.1
    """Heading D gain, (rad/s) per (rad/s) of heading-error rate, i.e. seconds."""
    max_yaw_rate: float = 1.5
    """Yaw rate saturation, rad/s."""
    kv: float = 0.8
    """Speed gain, (m/s) per metre of along-track distance to the target."""
    lookahead: float = 1.0
    """Lead on a moving target, seconds."""
    arrive_radius: float = 0.03
    """Stop within this distance of a ``stop`` target, metres."""

    def __post_init__(self) -> None:
        for name in ("kp", "kd", "max_yaw_rate", "kv", "lookahead", "arrive_radius"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0:
                raise ValueError(f"controller gain {name} must be a finite number >= 0, got {v!r}")


class Controller:
    """Turns (pose, target) into wheel speed commands; ``wheel_base`` m, ``max_wheel_speed`` m/s."""

    def __init__(self, wheel_base: float, max_wheel_speed: float, gains: Gains | None = None
                 ) -> None:
        if not math.isfinite(wheel_base) or wheel_base <= 0:
            raise ValueError(f"wheel_base must be a finite number > 0, got {wheel_base!r}")
        if not math.isfinite(max_wheel_speed) or max_wheel_speed <= 0:
            raise ValueError(
                f"max_wheel_speed must be a finite number > 0, got {max_wheel_speed!r}")
        self.wheel_base = float(wheel_base)
        self.max_wheel_speed = float(max_wheel_speed)
        self.gains = gains or Gains()
        self._prev_error: float | None = None
        self._prev_goal: tuple[float, float] | None = None

    def reset(self) -> None:
        """Forget the derivative state."""
        self._prev_error = None
        self._prev_goal = None

    def command(self, pose: Pose, target: Target, dt: float) -> tuple[float, float]:
        """Wheel speed commands (left, right), m/s, for the next ``dt`` seconds."""
        g = self.gains
        dx, dy = target.x - pose.x, target.y - pose.y
        if target.stop and math.hypot(dx, dy) <= g.arrive_radius:
            self.reset()
            return (0.0, 0.0)
        ax, ay = dx + g.lookahead * target.vx, dy + g.lookahead * target.vy
        error = wrap_pi(math.atan2(ay, ax) - pose.theta)
        goal = (target.x, target.y)
        # a jump of the goal (new waypoint, new manual target) restarts the derivative
        jumped = self._prev_goal is not None and math.hypot(
            goal[0] - self._prev_goal[0], goal[1] - self._prev_goal[1]
        ) > self.max_wheel_speed * dt + math.hypot(target.vx, target.vy) * dt + 1e-9
        derr = 0.0
        if self._prev_error is not None and not jumped and dt > 0:
            derr = wrap_pi(error - self._prev_error) / dt
        self._prev_error = error
        self._prev_goal = goal
        w = g.kp * error + g.kd * derr
        w = min(max(w, -g.max_yaw_rate), g.max_yaw_rate)
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        v = target.vx * c + target.vy * s + g.kv * (dx * c + dy * s)
        v = min(max(v, 0.0), self.max_wheel_speed)
        half = 0.5 * w * self.wheel_base
        # turning priority: give up speed before turn rate
        v = min(v, max(0.0, self.max_wheel_speed - abs(half)))
        vmax = self.max_wheel_speed
        left = min(max(v - half, -vmax), vmax)
        right = min(max(v + half, -vmax), vmax)
        return (left, right)
