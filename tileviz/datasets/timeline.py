"""How asynchronous odometry and IMU messages combine around image stamps: the one rule that
``import-bag`` (a recorded bag) and the live ROS node (``python -m tileviz ros``) both apply, so
that the declared bounds hold in both (``docs/dataset-format.md``, "Importing a ROS bag").

Stamps are integer nanoseconds (ROS time). An odometry message (speed m/s, yaw rate rad/s)
holds from its stamp until the next one; the motion between two image stamps is the middle of
the values held during [t0, t1), its bound grows by half their range. The heading at an image's
stamp lies on the shorter arc between the IMU yaws (rad) just before and just after it; the
compass is that arc's middle, its bound grows by half the arc.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Motion", "SensorTimeline", "combine_compass", "combine_odometry", "seconds_since"]


def combine_odometry(times: np.ndarray, values: np.ndarray, t0: float,
                     t1: float) -> tuple[float, float] | None:
    """The middle and half-range of the values an odometry series (held from each stamp to the
    next) takes during [t0, t1); None when no message precedes t1."""
    i0 = int(np.searchsorted(times, t0, side="right")) - 1  # the one held at t0
    i1 = int(np.searchsorted(times, t1, side="left"))  # messages before t1
    i0 = max(i0, 0)
    if i1 <= i0:
        return None
    seg = values[i0:i1]
    lo, hi = float(seg.min()), float(seg.max())
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


def combine_compass(times: np.ndarray, yaws: np.ndarray, t: float) -> tuple[float, float] | None:
    """The middle (wrapped to (-pi, pi]) and half-length of the shorter arc between the IMU
    yaws just before and just after ``t`` (one yaw stamped at ``t`` exactly: it, 0); None when
    ``t`` is not between two messages."""
    i = int(np.searchsorted(times, t, side="left"))
    if i < len(times) and times[i] == t:
        return float(yaws[i]), 0.0
    if i == 0 or i >= len(times):
        return None
    a, b = float(yaws[i - 1]), float(yaws[i])
    d = math.remainder(b - a, 2 * math.pi)
    mid = math.remainder(a + 0.5 * d, 2 * math.pi)
    return (math.pi if mid <= -math.pi else mid), 0.5 * abs(d)


def seconds_since(t_ns: int, first_ns: int) -> float:
    """A frame's ``t`` (seconds) from its stamp and the first image's (both ns), as a dataset
    row stores it; a frame's odometry lasts the difference of two such values."""
    return (t_ns - first_ns) * 1e-9


@dataclass(frozen=True)
class Motion:
    """The combined odometry over [t0, t1): ``speed`` +- ``speed_half`` (m/s), ``yaw_rate`` +-
    ``yaw_rate_half`` (rad/s)."""

    speed: float
    speed_half: float
    yaw_rate: float
    yaw_rate_half: float


class SensorTimeline:
    """Odometry and IMU samples by stamp (kept sorted whatever the order they are added in).

    :meth:`motion` and :meth:`compass` apply :func:`combine_odometry` and
    :func:`combine_compass`. :meth:`forget_before` drops samples no later query needs.
    """

    def __init__(self) -> None:
        self.odom_t: list[int] = []
        self.odom_v: list[tuple[float, float]] = []
        self.imu_t: list[int] = []
        self.imu_v: list[float] = []

    @staticmethod
    def _insert(ts: list[int], vs: list, t: int, v: object) -> bool:
        """Insert in stamp order; True when ``t`` is not before the last stamp (in order)."""
        if not ts or t >= ts[-1]:
            ts.append(t)
            vs.append(v)
            return True
        i = bisect.bisect_right(ts, t)
        ts.insert(i, t)
        vs.insert(i, v)
        return False

    def add_odometry(self, t: int, speed: float, yaw_rate: float) -> bool:
        """One odometry sample (ns, m/s, rad/s); False when it came out of order."""
        return self._insert(self.odom_t, self.odom_v, int(t), (float(speed), float(yaw_rate)))

    def add_imu(self, t: int, yaw: float) -> bool:
        """One IMU yaw (ns, rad); False when it came out of order."""
        return self._insert(self.imu_t, self.imu_v, int(t), float(yaw))

    def motion(self, t0: int, t1: int) -> Motion | None:
        """The odometry combined over [t0, t1) (ns), or None when no sample precedes t1."""
        if not self.odom_t:
            return None
        ot = np.array(self.odom_t)
        ov = np.array(self.odom_v).reshape(-1, 2)
        sp = combine_odometry(ot, ov[:, 0], t0, t1)
        if sp is None:
            return None
        yr = combine_odometry(ot, ov[:, 1], t0, t1)
        assert yr is not None
        return Motion(sp[0], sp[1], yr[0], yr[1])

    def compass(self, t: int) -> tuple[float, float] | None:
        """The compass at ``t`` (ns) and its half-arc (rad), or None."""
        if not self.imu_t:
            return None
        return combine_compass(np.array(self.imu_t), np.array(self.imu_v), t)

    def odometry_through(self, t: int) -> bool:
        """A sample stamped at or after ``t`` was added (so, in order, every one before it)."""
        return bool(self.odom_t) and self.odom_t[-1] >= t

    def imu_through(self, t: int) -> bool:
        """An IMU sample stamped at or after ``t`` was added."""
        return bool(self.imu_t) and self.imu_t[-1] >= t

    def forget_before(self, t: int) -> None:
        """Drop the samples before ``t`` (ns) but the last one before it (the one held at t,
        the IMU yaw just before t)."""
        for ts, vs in ((self.odom_t, self.odom_v), (self.imu_t, self.imu_v)):
            i = bisect.bisect_left(ts, t) - 1
            if i > 0:
                del ts[:i]
                del vs[:i]
