"""Small immutable value types shared by every module.

Frames and units (``docs/dataset-format.md``): world metres, x east, y north; heading ``theta``
counter-clockwise from +x, radians, continuous (not wrapped) unless a docstring says otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, NamedTuple, get_args

import numpy as np

from tileviz.core.constants import TWO_PI
from tileviz.core.intervals import turn_shift

Status = Literal["contracted", "predicted", "rejected", "lost"]
STATUSES: tuple[Status, ...] = get_args(Status)
"""Per-frame localizer status (meanings in ``docs/dataset-format.md``)."""


@dataclass(frozen=True, slots=True)
class Pose:
    """Robot pose: the point between the wheels (x, y, metres) and the heading theta (rad)."""

    x: float
    y: float
    theta: float

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.theta)


@dataclass(frozen=True, slots=True)
class Odometry:
    """Measured motion from frame k to frame k+1, held over ``dt`` seconds.

    ``speed`` is the forward speed u1 (m/s), ``yaw_rate`` the turn rate u2 (rad/s). The compass is
    not part of it: it is a reading taken at a frame (see ``FrameInput``).
    """

    speed: float
    yaw_rate: float
    dt: float


@dataclass(frozen=True, slots=True)
class SensorBounds:
    """Bounds on the sensor errors: |measured - true| <= bound (m/s, rad/s, rad)."""

    speed_error: float
    yaw_rate_error: float
    compass_error: float


@dataclass(frozen=True, slots=True)
class Observation:
    """The tile parameters seen in one image (docs/method.md).

    ``y1, y2`` in [0, L) metres and ``y3`` in [-pi/4, pi/4) radians, such that for some
    m in {0, 1, 2, 3}: camera centre c == R(m pi/2) (y1, y2) (mod L) and
    theta == y3 + m pi/2 (mod 2 pi). The true parameters lie within +- ``position_error`` (m) of
    y1, y2 (modulo L) and within +- ``heading_error`` (rad) of y3 (modulo pi/2).
    """

    y1: float
    y2: float
    y3: float
    position_error: float
    heading_error: float


class Box(NamedTuple):
    """An axis-aligned box of robot poses: [x_lo, x_hi] x [y_lo, y_hi] x [t_lo, t_hi].

    Metres and radians. The heading interval is continuous; a pose (x, y, theta) is in the box when
    theta + 2 pi k is in [t_lo, t_hi] for some integer k. A named tuple: the localizer's hot path
    computes on it directly (``b[0]`` is ``b.x_lo``, and so on in field order).
    """

    x_lo: float
    x_hi: float
    y_lo: float
    y_hi: float
    t_lo: float
    t_hi: float

    @property
    def widths(self) -> tuple[float, float, float]:
        return (self.x_hi - self.x_lo, self.y_hi - self.y_lo, self.t_hi - self.t_lo)

    @property
    def centre(self) -> tuple[float, float, float]:
        return (
            0.5 * (self.x_lo + self.x_hi),
            0.5 * (self.y_lo + self.y_hi),
            0.5 * (self.t_lo + self.t_hi),
        )

    def as_tuple(self) -> tuple[float, float, float, float, float, float]:
        """The six bounds as a plain tuple."""
        return (self.x_lo, self.x_hi, self.y_lo, self.y_hi, self.t_lo, self.t_hi)

    def contains(self, x: float, y: float, theta: float) -> bool:
        """True when (x, y, theta + 2 pi k) is in the box for some integer k."""
        if not (self.x_lo <= x <= self.x_hi and self.y_lo <= y <= self.y_hi):
            return False
        k = math.ceil((self.t_lo - theta) / TWO_PI)
        return theta + k * TWO_PI <= self.t_hi


@dataclass(frozen=True, slots=True)
class BoxSet:
    """A set of robot poses kept as a tuple of disjoint boxes (possibly empty)."""

    boxes: tuple[Box, ...] = ()

    def __len__(self) -> int:
        return len(self.boxes)

    @property
    def is_empty(self) -> bool:
        return not self.boxes

    def hull(self) -> Box | None:
        """The bounding box, or None when the set is empty. Heading intervals are first shifted by
        multiples of 2 pi next to the first box's, so the hull is the tightest continuous one; the
        shifts are outward rounded (:func:`tileviz.core.intervals.turn_shift`), so the hull holds
        every pose of the set for the real 2 pi, not only for the float TWO_PI."""
        if not self.boxes:
            return None
        ref = self.boxes[0].centre[2]
        x_lo = min(b.x_lo for b in self.boxes)
        x_hi = max(b.x_hi for b in self.boxes)
        y_lo = min(b.y_lo for b in self.boxes)
        y_hi = max(b.y_hi for b in self.boxes)
        t_lo = math.inf
        t_hi = -math.inf
        for b in self.boxes:
            lo, hi = turn_shift(b.t_lo, b.t_hi, round((ref - b.centre[2]) / TWO_PI))
            t_lo = min(t_lo, lo)
            t_hi = max(t_hi, hi)
        return Box(x_lo, x_hi, y_lo, y_hi, t_lo, t_hi)

    def contains(self, x: float, y: float, theta: float) -> bool:
        """True when some box contains the pose (heading modulo 2 pi)."""
        return any(b.contains(x, y, theta) for b in self.boxes)


@dataclass(frozen=True)
class FrameInput:
    """What a source delivers for frame k.

    ``image``: HxWx3 uint8 RGB (or HxW gray) taken at pose k. ``odometry``: the measured motion
    from frame k to k+1 (None on the last frame or when unknown). ``compass``: heading measured at
    frame k, rad, wrapped to (-pi, pi], or None. ``truth``: the true pose k when known.
    ``setpoint``: the controller's target (x, y) in metres, for display, or None.
    ``faults``: labels of the faults injected at this frame (simulation only, e.g. ``slip``,
    ``cable``, ``kidnap``), for evaluation; recorded in a dataset's optional ``faults.csv``.
    """

    index: int
    t: float
    image: np.ndarray
    odometry: Odometry | None
    compass: float | None
    truth: Pose | None = None
    setpoint: tuple[float, float] | None = None
    image_name: str = ""
    faults: tuple[str, ...] = ()
