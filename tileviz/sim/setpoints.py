"""Where the robot should go: a Lissajous curve, a manual target point, a waypoint loop.

World frame, metres, seconds (``docs/dataset-format.md``). Every setpoint answers
``target(t, pose) -> Target``: the point to reach now, its velocity (for feed-forward, m/s) and
whether the robot should stop there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from tileviz.types import Pose


@dataclass(frozen=True)
class Target:
    """The controller's goal at one instant: point (x, y) m, velocity (vx, vy) m/s, and ``stop``
    (True: come to rest on the point; False: a moving or pass-through point)."""

    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    stop: bool = True


class Setpoint(Protocol):
    """A setpoint generator; ``kind`` is one of ``config.SETPOINTS``."""

    kind: str

    def target(self, t: float, pose: Pose) -> Target: ...


def _finite_point(name: str, x: float, y: float) -> tuple[float, float]:
    try:
        fx, fy = float(x), float(y)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be two numbers, got {(x, y)!r}") from None
    if not (math.isfinite(fx) and math.isfinite(fy)):
        raise ValueError(f"{name} must be finite, got {(x, y)!r}")
    return fx, fy


class Lissajous:
    """The original's curve: x = A cos(w t + pi/2), y = A sin(2 (w t + pi/2)) (docs/seed-code.md).

    ``amplitude`` A in metres, ``omega`` w in rad/s, t in seconds. It passes through the origin at
    t = 0 heading atan2(-2, -1); one lap takes 2 pi / w seconds; the path speed is at most
    A w sqrt(5) (at t = 0).
    """

    kind = "lissajous"

    def __init__(self, amplitude: float, omega: float) -> None:
        if not math.isfinite(amplitude) or amplitude <= 0:
            raise ValueError(f"lissajous_amplitude must be a finite number > 0, got {amplitude!r}")
        if not math.isfinite(omega) or omega < 0:
            raise ValueError(f"lissajous_omega must be a finite number >= 0, got {omega!r}")
        self.amplitude = float(amplitude)
        self.omega = float(omega)

    def position(self, t: float) -> tuple[float, float]:
        """The curve's point at time t, metres."""
        a, ph = self.amplitude, self.omega * t + math.pi / 2
        return (a * math.cos(ph), a * math.sin(2 * ph))

    def velocity(self, t: float) -> tuple[float, float]:
        """d/dt of :meth:`position`, m/s."""
        a, w, ph = self.amplitude, self.omega, self.omega * t + math.pi / 2
        return (-a * w * math.sin(ph), 2 * a * w * math.cos(2 * ph))

    def path(self, n: int = 400) -> list[tuple[float, float]]:
        """n points along one lap (for drawing)."""
        if self.omega == 0:
            return [self.position(0.0)]
        period = 2 * math.pi / self.omega
        return [self.position(period * i / n) for i in range(n + 1)]

    def target(self, t: float, pose: Pose) -> Target:
        x, y = self.position(t)
        vx, vy = self.velocity(t)
        return Target(x, y, vx, vy, stop=False)


class ManualTarget:
    """A fixed point the robot drives to and stops on (x, y in metres)."""

    kind = "manual"

    def __init__(self, x: float, y: float) -> None:
        self.x, self.y = _finite_point("manual target", x, y)

    def target(self, t: float, pose: Pose) -> Target:
        return Target(self.x, self.y, stop=True)


class Waypoints:
    """A loop of points visited in order; the next one becomes the goal when the robot's point
    between the wheels is within ``radius`` metres of the current one. After the last, the first.
    """

    kind = "waypoints"

    def __init__(self, points: Sequence[tuple[float, float]], radius: float = 0.3) -> None:
        pts = [_finite_point(f"waypoint {i}", *p) for i, p in enumerate(points)]
        if not pts:
            raise ValueError("waypoints must hold at least one point")
        if not math.isfinite(radius) or radius <= 0:
            raise ValueError(f"waypoint radius must be a finite number > 0, got {radius!r}")
        self.points = pts
        self.radius = float(radius)
        self.index = 0
        """Index of the current goal in ``points``."""
        self.laps = 0
        """How many times the loop was completed."""

    def target(self, t: float, pose: Pose) -> Target:
        x, y = self.points[self.index]
        if math.hypot(x - pose.x, y - pose.y) <= self.radius and len(self.points) > 1:
            self.index += 1
            if self.index == len(self.points):
                self.index = 0
                self.laps += 1
            x, y = self.points[self.index]
        # a single point is a place to stop at; a loop is driven through
        return Target(x, y, stop=len(self.points) == 1)
