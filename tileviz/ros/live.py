"""The live localizer behind ``python -m tileviz ros``, without ROS: messages in (images,
odometry, IMU yaws, each with its stamp), frames out (:class:`LiveFrame`).

The messages are combined by :class:`tileviz.datasets.timeline.SensorTimeline`, the rule
``import-bag`` applies to a recorded bag, and the frames go through the frame loop with the
configuration ``replay`` builds from the same meta.json (:func:`tileviz.datasets.replay_config`):
a live run and the replay of its recording give the same sets.

Timing (stamps in integer nanoseconds, ``now`` in nanoseconds of the same clock as the stamps):
an image at ``t`` is processed once an odometry message stamped at or after ``t`` and (with an
IMU) an IMU message stamped at or after ``t`` arrived (then, messages arriving in order, every
message before ``t`` is in), or ``max_delay`` after it arrived, with what is there. Images are
processed in stamp order; an image older than the last processed one is late and dropped; when
more than ``max_pending`` images wait, the oldest are dropped. Dropping an image is sound: the
next frame's motion covers both intervals.

Bounds: the localizer's declared bounds are the meta's plus ``widening`` (m/s, rad/s, rad). A
frame whose combination widens a bound beyond that raises the declared bound from that frame on
(the localizer restarts from its set's hull: ``FrameLoop.reconfigure``), counted in
``bounds_raised``. A message arriving after the frames it would have changed were processed
(``late``) is checked against what those frames used: when it leaves the declared bound of one
of them, the set no longer vouches for the truth and the status is ``lost`` from then on
(:attr:`LiveLocalizer.lost_reason`).
"""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass, field, replace

import numpy as np

from tileviz.datasets import DatasetMeta, replay_config
from tileviz.datasets.timeline import Motion, SensorTimeline, seconds_since
from tileviz.pipeline.frame_loop import FrameLoop, FrameRecord
from tileviz.types import FrameInput, Odometry, Status
from tileviz.vision import VisionResult

__all__ = ["COUNTERS", "LiveFrame", "LiveLocalizer"]

COUNTERS = ("images", "odometry", "imu", "frames", "bad_images", "out_of_order", "late",
            "dropped_behind", "dropped_upstream", "no_odometry", "timeouts", "bounds_raised")
"""What :attr:`LiveLocalizer.counts` counts: messages received per kind; frames processed;
images that could not be read (processed without a view); messages older than their topic's
last one; messages (and images) that arrived after the frames they concern were processed;
images dropped because the node fell behind; messages missing upstream (gaps in the header's
``seq``); images skipped for want of any odometry before them; frames processed at
``max_delay`` without their topics' messages after them; raises of the declared bounds."""


@dataclass(frozen=True)
class LiveFrame:
    """One processed frame: the frame loop's record, the status the node publishes
    (``lost`` once a late message broke a bound, else the localizer's), the refusal reason
    (the vision reason, or why the image could not be read), the stamp (ns) and the arrival
    time (ns) of its image."""

    record: FrameRecord
    status: Status
    reason: str
    stamp: int
    arrived: int


@dataclass
class _Pending:
    stamp: int
    arrived: int
    image: np.ndarray | None
    error: str | None


@dataclass
class _Used:
    """What a processed frame used: its interval (ns), the motion and compass combined, the
    declared widening then."""

    t0: int | None
    t1: int
    motion: Motion | None
    compass: tuple[float, float] | None
    widening: tuple[float, float, float]


@dataclass
class _Seq:
    last: dict[str, int] = field(default_factory=dict)

    def gap(self, topic: str, seq: int | None) -> int:
        if seq is None or seq <= 0:
            return 0
        prev = self.last.get(topic)
        self.last[topic] = max(seq, prev or 0)
        return max(0, seq - prev - 1) if prev is not None and seq > prev else 0


class LiveLocalizer:
    """Thread-safe: the ``add_*`` methods may be called from subscriber threads while one
    thread calls :meth:`step`. ``meta``: the floor, camera, bounds and start, as a dataset's
    meta.json gives them; ``has_imu``: wait for IMU messages (else no compass);
    ``max_delay``, ``now`` and stamps: nanoseconds."""

    def __init__(self, meta: DatasetMeta, *, has_imu: bool = True,
                 widening: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 max_delay: int = 500_000_000, max_pending: int = 4) -> None:
        if any(not math.isfinite(w) or w < 0 for w in widening):
            raise ValueError(f"widening must be three finite numbers >= 0, got {widening}")
        self.meta = meta
        self.cfg = replay_config(meta)
        self.loop = FrameLoop(self.cfg, residuals=False)
        self.rectifier = meta.rectifier()
        self.has_imu = has_imu
        self.widening: tuple[float, float, float] = (float(widening[0]), float(widening[1]),
                                                     float(widening[2]))
        self.max_delay = int(max_delay)
        self.max_pending = int(max_pending)
        self.timeline = SensorTimeline()
        self.counts = dict.fromkeys(COUNTERS, 0)
        self.lost_reason: str | None = None
        self.last_problem: str | None = None
        """The last bad input, one line (for the node's log)."""
        self._lock = threading.Lock()
        self._pending: list[_Pending] = []
        self._used: deque[_Used] = deque(maxlen=200)
        self._first: int | None = None
        self._last: int | None = None  # stamp of the last processed frame
        self._index = 0
        self._seq = _Seq()
        if self.widening != (0.0, 0.0, 0.0):
            self._declare(self.widening)

    # ------------------------------------------------------------------ messages in
    def _problem(self, text: str) -> None:
        self.last_problem = text

    def add_image(self, stamp: int, image: np.ndarray | None, now: int, *,
                  error: str | None = None, seq: int | None = None) -> None:
        """An image (HxWx3 RGB uint8, the raw camera's size) or, when it could not be read,
        ``error`` (the frame is then processed without a view)."""
        with self._lock:
            self.counts["images"] += 1
            self.counts["dropped_upstream"] += self._seq.gap("image", seq)
            if image is not None and error is None:
                cm = self.meta.camera_model
                want = ((cm.raw_width, cm.raw_height) if cm is not None
                        else (self.meta.image_width, self.meta.image_height))
                if image.ndim != 3 or (image.shape[1], image.shape[0]) != want:
                    error = (f"image stamped {stamp} is {image.shape[1]}x{image.shape[0]}, "
                             f"expected {want[0]}x{want[1]}")
                    image = None
            if error is not None:
                self.counts["bad_images"] += 1
                self._problem(error)
            if self._last is not None and stamp <= self._last:
                self.counts["late"] += 1
                self._problem(f"image stamped {stamp} arrived after a later frame was "
                              "processed: dropped")
                return
            if self._pending and stamp < self._pending[-1].stamp:
                self.counts["out_of_order"] += 1
            self._pending.append(_Pending(stamp, now, image, error))
            self._pending.sort(key=lambda p: p.stamp)
            while len(self._pending) > self.max_pending:
                self._pending.pop(0)
                self.counts["dropped_behind"] += 1

    def add_odometry(self, stamp: int, speed: float, yaw_rate: float, *,
                     seq: int | None = None) -> None:
        """An odometry message: forward speed (m/s) and yaw rate (rad/s)."""
        if not (math.isfinite(speed) and math.isfinite(yaw_rate)):
            with self._lock:
                self._problem(f"odometry stamped {stamp} holds a non-finite value: ignored")
            return
        with self._lock:
            self.counts["odometry"] += 1
            self.counts["dropped_upstream"] += self._seq.gap("odometry", seq)
            if not self.timeline.add_odometry(stamp, speed, yaw_rate):
                self.counts["out_of_order"] += 1
            if self._last is not None and stamp < self._last:
                self._late(stamp, "odometry")

    def add_imu(self, stamp: int, yaw: float, *, seq: int | None = None) -> None:
        """An IMU orientation's yaw (rad, counter-clockwise about z)."""
        if not math.isfinite(yaw):
            with self._lock:
                self._problem(f"IMU stamped {stamp} holds a non-finite yaw: ignored")
            return
        with self._lock:
            self.counts["imu"] += 1
            self.counts["dropped_upstream"] += self._seq.gap("imu", seq)
            if not self.timeline.add_imu(stamp, yaw):
                self.counts["out_of_order"] += 1
            if self._last is not None and stamp <= self._last:
                self._late(stamp, "IMU")

    def _late(self, stamp: int, kind: str) -> None:
        """A message before the last processed frame: does it leave a used bound?"""
        self.counts["late"] += 1
        for used in self._used:
            if used.t1 < stamp and kind == "odometry":
                continue
            if kind == "odometry" and used.t0 is not None and used.motion is not None:
                m = self.timeline.motion(used.t0, used.t1)
                ws, wy, _ = used.widening
                if m is not None and (
                        abs(m.speed - used.motion.speed) + m.speed_half > ws
                        or abs(m.yaw_rate - used.motion.yaw_rate) + m.yaw_rate_half > wy):
                    self._lose(f"a late odometry message (stamp {stamp}) leaves the bound "
                               f"frame stamped {used.t1} used")
                    return
            if kind == "IMU" and used.compass is not None:
                c = self.timeline.compass(used.t1)
                if c is not None and (abs(math.remainder(c[0] - used.compass[0], 2 * math.pi))
                                      + c[1] > used.widening[2]):
                    self._lose(f"a late IMU message (stamp {stamp}) leaves the compass bound "
                               f"frame stamped {used.t1} used")
                    return
        self._problem(f"late {kind} message (stamp {stamp}): within the bounds used")

    def _lose(self, why: str) -> None:
        if self.lost_reason is None:
            self.lost_reason = why
        self._problem(why)

    # ------------------------------------------------------------------ frames out
    def _ready(self, now: int) -> tuple[_Pending, bool] | None:
        if not self._pending:
            return None
        p = self._pending[0]
        complete = (self.timeline.odometry_through(p.stamp) or self._last is None) and (
            not self.has_imu or self.timeline.imu_through(p.stamp))
        if complete:
            return p, False
        if now - p.arrived >= self.max_delay:
            return p, True
        return None

    def _declare(self, widening: tuple[float, float, float]) -> None:
        m = self.meta
        bounds = replace(self.cfg.noise, speed_error=m.speed_error + widening[0],
                         yaw_rate_error=m.yaw_rate_error + widening[1],
                         compass_error=m.compass_error + widening[2])
        self.cfg = replace(self.cfg, noise=bounds)
        self.loop.reconfigure(self.cfg)

    def step(self, now: int) -> LiveFrame | None:
        """Process the next frame that is ready at ``now`` (ns), or None."""
        with self._lock:
            got = self._ready(now)
            if got is None:
                return None
            p, timed_out = got
            self._pending.pop(0)
            motion = None
            if self._last is not None:
                motion = self.timeline.motion(self._last, p.stamp)
                if motion is None:
                    self.counts["no_odometry"] += 1
                    self._problem(f"image stamped {p.stamp}: no odometry before it; skipped")
                    return None
            compass = self.timeline.compass(p.stamp) if self.has_imu else None
            if timed_out:
                self.counts["timeouts"] += 1
            need = (motion.speed_half if motion else 0.0, motion.yaw_rate_half if motion else 0.0,
                    compass[1] if compass else 0.0)
            if any(n > w for n, w in zip(need, self.widening, strict=True)):
                ws, wy, wc = (max(n, w) for n, w in zip(need, self.widening, strict=True))
                self.widening = (ws, wy, wc)
                self.counts["bounds_raised"] += 1
                self._problem("the messages' asynchrony widens the bounds to "
                              f"+{self.widening[0]:.4g} m/s, +{self.widening[1]:.4g} rad/s, "
                              f"+{self.widening[2]:.4g} rad")
                self._declare(self.widening)
            first = self._first if self._first is not None else p.stamp
            if motion is not None and self._last is not None:
                dt = seconds_since(p.stamp, first) - seconds_since(self._last, first)
                self.loop.set_motion(Odometry(motion.speed, motion.yaw_rate, dt))
            self._used.append(_Used(self._last, p.stamp, motion, compass,
                                    self.widening))
            self._first = first
            self._last = p.stamp
            index = self._index
            self._index += 1
            self.counts["frames"] += 1
            self.timeline.forget_before(self._used[0].t0 or self._used[0].t1)
        frame = FrameInput(index=index, t=seconds_since(p.stamp, first),
                           image=self._prepare(p), odometry=None,
                           compass=None if compass is None else compass[0], truth=None)
        vision = None
        if p.error is not None:
            vision = VisionResult(observation=None, accepted=False, reason="constant image")
        rec = self.loop.process(frame, vision)
        status: Status = "lost" if self.lost_reason is not None else rec.status
        reason = p.error if p.error is not None else rec.vision.reason
        return LiveFrame(rec, status, reason, p.stamp, p.arrived)

    def _prepare(self, p: _Pending) -> np.ndarray:
        """The image as vision reads it: rectified to gray with a camera model (as a dataset's
        reader gives it), else as it came."""
        if p.image is None:
            return np.zeros((self.meta.image_height, self.meta.image_width, 3), np.uint8)
        if self.rectifier is not None:
            return np.ascontiguousarray(self.rectifier.gray(p.image))
        return np.ascontiguousarray(p.image)

    def pending(self) -> int:
        """Images waiting."""
        with self._lock:
            return len(self._pending)
