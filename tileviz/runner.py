"""The frame loop: source -> vision -> localizer -> immutable FrameRecord.

One :class:`Runner` serves the live server, the replay CLI and the tests. A *source* yields
:class:`FrameInput` objects: the simulator (:class:`tileviz.sim.source.SimSource`) or a dataset
reader (:class:`tileviz.dataset.DatasetSource`). Frame k uses the odometry of row k-1 (the motion
from frame k-1 to frame k) to predict, then the compass and image of frame k to contract.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from tileviz.config import Config
from tileviz.localizer import Localizer, LocalizerStep
from tileviz.tiles import equivalence_residuals
from tileviz.types import Box, BoxSet, FrameInput, Odometry, Pose, SensorBounds
from tileviz.vision import VisionResult, extract

__all__ = ["FrameInput", "FrameRecord", "Runner", "Source", "initial_box"]


class Source(Protocol):
    """Anything that yields frames in time order."""

    def __iter__(self) -> Iterator[FrameInput]: ...


@dataclass(frozen=True)
class FrameRecord:
    """Everything about one processed frame; never mutated after creation.

    ``predicted`` is the set after the prediction step (before the view), ``updated`` the set after
    this frame's update (what the replay output writes). ``timings`` are milliseconds.
    ``residuals``: the six equivalence residuals of report table 6.1 (corrected signs) between the
    true pose and the observation, or None.
    """

    index: int
    t: float
    truth: Pose | None
    odometry: Odometry | None
    compass: float | None
    image: np.ndarray
    setpoint: tuple[float, float] | None
    vision: VisionResult
    predicted: BoxSet
    updated: BoxSet
    status: str
    residuals: tuple[float, ...] | None
    timings: dict[str, float] = field(default_factory=dict)
    step: LocalizerStep | None = None
    """The localizer's own account of the frame (rejection streak, compass rejected, recovery
    re-inflation, passes), or None."""

    @property
    def observation(self) -> object:
        return self.vision.observation

    @property
    def hull(self) -> Box | None:
        return self.updated.hull()

    def truth_inside(self) -> bool | None:
        """True/False when the truth is known and the status vouches for the set, else None."""
        if self.truth is None or self.status == "lost":
            return None
        return self.updated.contains(*self.truth.as_tuple())


def _finite(v: object) -> bool:
    """Whether ``v`` is a finite real number."""
    try:
        return math.isfinite(v)  # type: ignore[arg-type]
    except TypeError:
        return False


def initial_box(cfg: Config, pose: tuple[float, float, float] | None = None,
                error: tuple[float, float, float] | None = None) -> Box:
    """The box around the known initial pose, +- the declared initial pose error."""
    x, y, th = pose if pose is not None else cfg.sim.initial_pose
    ex, ey, et = error if error is not None else cfg.sim.initial_pose_error
    return Box(x - ex, x + ex, y - ey, y + ey, th - et, th + et)


class Runner:
    """Steps a source through vision and the localizer, one FrameRecord per frame.

    ``keep_stages``: keep every pipeline stage image in the record (for display).
    """

    def __init__(
        self,
        cfg: Config,
        *,
        initial: Box | None = None,
        bounds: SensorBounds | None = None,
        keep_stages: bool = False,
    ) -> None:
        self.cfg = cfg
        self.keep_stages = keep_stages
        self.bounds = bounds or SensorBounds(
            cfg.noise.speed_error, cfg.noise.yaw_rate_error, cfg.noise.compass_error
        )
        self.localizer = self._make_localizer(
            initial if initial is not None else initial_box(cfg)
        )
        self._pending_odometry: Odometry | None = None

    def _make_localizer(self, initial: Box) -> Localizer:
        return Localizer(
            tile_size=self.cfg.floor.tile_size,
            camera_offset=self.cfg.camera.offset,
            bounds=self.bounds,
            config=self.cfg.localizer,
            initial=initial,
        )

    def reset(self, initial: Box) -> None:
        """Start again from ``initial`` (e.g. after a kidnap the user reports), with the current
        configuration (see :meth:`reconfigure`)."""
        self.localizer = self._make_localizer(initial)
        self._pending_odometry = None

    def reconfigure(self, cfg: Config, *, bounds: SensorBounds | None = None) -> None:
        """Use ``cfg`` from the next frame on (the live server's GUI): vision options, localizer
        options and the declared sensor bounds (``bounds``, default from ``cfg.noise``). The floor
        and the camera must not change (start a new Runner for that).

        When the localizer options or the bounds change, the localizer restarts from the hull of
        its current set (a superset of it, so the guarantee holds) and keeps the pending odometry.
        A localizer that is ``lost`` stays lost (its set vouches for nothing) until :meth:`reset`,
        which builds it with the new settings; switching to mode ``truth`` needs no prior and
        takes effect at once.
        """
        if (cfg.floor, cfg.camera) != (self.cfg.floor, self.cfg.camera):
            raise ValueError("reconfigure cannot change the floor or the camera; start a new run")
        new_bounds = bounds or SensorBounds(
            cfg.noise.speed_error, cfg.noise.yaw_rate_error, cfg.noise.compass_error
        )
        changed = new_bounds != self.bounds or cfg.localizer != self.cfg.localizer
        self.cfg = cfg
        self.bounds = new_bounds
        if changed and (not self.localizer.lost or cfg.localizer.mode == "truth"):
            hull = self.localizer.current.hull()
            self.localizer = self._make_localizer(hull if hull is not None else initial_box(cfg))

    def process(self, frame: FrameInput, vision: VisionResult | None = None) -> FrameRecord:
        """Run one frame: predict with the previous frame's odometry, contract with this image.
        ``vision``: this frame's vision result when it was computed elsewhere (a replay that
        runs vision in worker processes, :mod:`tileviz.parallel`); None runs it here.
        Bad numbers raise ValueError naming the frame (this frame's odometry is checked now,
        though the localizer only uses it on the next frame)."""
        odo = frame.odometry
        if odo is not None and not (_finite(odo.speed) and _finite(odo.yaw_rate)
                                    and _finite(odo.dt) and odo.dt >= 0):
            raise ValueError(f"frame {frame.index}: odometry must hold finite numbers "
                             f"(dt >= 0), got {odo}")
        t0 = time.perf_counter()
        if vision is None:
            vision = extract(
                frame.image,
                camera=self.cfg.camera,
                tile_size=self.cfg.floor.tile_size,
                vision=self.cfg.vision,
                keep_stages=self.keep_stages,
            )
            t1 = time.perf_counter()
            vision_ms = (t1 - t0) * 1e3
        else:
            t1 = t0
            vision_ms = sum(vision.timings.values())  # the worker's stage times
        try:
            step: LocalizerStep = self.localizer.step(
                odometry=self._pending_odometry,
                compass=frame.compass,
                observation=vision.observation,
                truth=frame.truth,
            )
        except ValueError as e:
            raise ValueError(f"frame {frame.index}: {e}") from None
        t2 = time.perf_counter()
        self._pending_odometry = frame.odometry
        residuals = None
        if frame.truth is not None and vision.observation is not None:
            residuals = equivalence_residuals(
                frame.truth, vision.observation, self.cfg.floor.tile_size, self.cfg.camera.offset
            )
        return FrameRecord(
            index=frame.index,
            t=frame.t,
            truth=frame.truth,
            odometry=frame.odometry,
            compass=frame.compass,
            image=frame.image,
            setpoint=frame.setpoint,
            vision=vision,
            predicted=step.predicted,
            updated=step.updated,
            status=step.status,
            residuals=residuals,
            timings={"vision_ms": vision_ms, "localizer_ms": (t2 - t1) * 1e3},
            step=step,
        )

    def run(self, source: Source) -> Iterator[FrameRecord]:
        """Process every frame of ``source`` in order."""
        for frame in source:
            yield self.process(frame)
