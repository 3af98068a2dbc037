"""The one frame loop: source -> vision -> every estimator -> immutable FrameRecord.

:class:`FrameLoop` serves the live server, the replay CLI, the evaluation and the tests. A
*source* yields :class:`~tileviz.types.FrameInput` objects: the simulator
(:class:`tileviz.sim.source.SimSource`) or a dataset reader
(:class:`tileviz.datasets.DatasetSource`). Frame alignment, the same for every estimator: frame k
hands the odometry of frame k-1 (the motion from frame k-1 to frame k) to each estimator's
prediction, then the compass and the observation of image k (:class:`StepInputs`).

The loop drives any set of named estimators (:class:`tileviz.core.estimators.Estimator`). The
*primary* one, named :data:`PRIMARY`, is the interval localizer: its step is the record's
``step`` (``predicted``, ``updated``, ``status``); a bad input that it refuses fails the frame.
An *optional* estimator (e.g. the live demo's MCL) that raises is dropped from the loop instead,
and the record says so (``FrameRecord.dropped``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Collection, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from tileviz.config import Config
from tileviz.core.estimators import Estimator, IntervalEstimator, StepInputs, sensor_bounds
from tileviz.core.localizer import LocalizerStep
from tileviz.core.tiles import equivalence_residuals
from tileviz.types import Box, BoxSet, FrameInput, Odometry, Pose, SensorBounds, Status
from tileviz.vision import VisionResult, extract, observation_error

__all__ = ["PRIMARY", "FrameLoop", "FrameRecord", "Source", "initial_box"]

PRIMARY = "interval"
"""Name of the interval localizer in every frame loop."""


class Source(Protocol):
    """Anything that yields frames in time order."""

    def __iter__(self) -> Iterator[FrameInput]: ...


_NO_SET = BoxSet()


@dataclass(frozen=True)
class FrameRecord:
    """Everything about one processed frame; never mutated after creation.

    ``odometry``: this frame's odometry (the motion to the next frame); ``motion``: the odometry
    the estimators used at this frame (the previous frame's). ``estimates``: each estimator's
    estimate by name, in the loop's order. ``step``: the primary interval localizer's
    (:data:`PRIMARY`), or None when the loop has none; ``predicted`` is its set after the
    prediction step (before the view), ``updated`` the set after this frame's update (what the
    replay output writes). ``dropped``: optional estimators that raised at this frame and left
    the loop (name -> the error). ``timings``: milliseconds (``vision_ms``, ``localizer_ms`` the
    primary's step, ``<name>_ms`` every estimator's step). ``residuals``: the six equivalence
    residuals (``docs/method.md``, "Equivalence") between the true pose and the observation, or
    None (computed with ``view_error`` when the loop's ``residuals`` is on).
    """

    index: int
    t: float
    truth: Pose | None
    odometry: Odometry | None
    compass: float | None
    image: np.ndarray
    setpoint: tuple[float, float] | None
    vision: VisionResult
    residuals: tuple[float, ...] | None
    view_error: tuple[float, float, float] | None = None
    """How far the observation is from the true pose, modulo the floor's symmetries (e1, e2 m,
    e3 rad: :func:`tileviz.vision.observation_error`), or None (no observation, no truth, or
    residuals off)."""
    timings: dict[str, float] = field(default_factory=dict)
    step: LocalizerStep | None = None
    motion: Odometry | None = None
    estimates: Mapping[str, Any] = field(default_factory=dict)
    dropped: Mapping[str, str] = field(default_factory=dict)
    image_name: str = ""
    """The frame's stored image file, relative to its dataset folder ("" when not from one)."""

    @property
    def predicted(self) -> BoxSet:
        """The primary localizer's set after prediction and compass (empty without one)."""
        return self.step.predicted if self.step is not None else _NO_SET

    @property
    def updated(self) -> BoxSet:
        """The primary localizer's set after this frame (empty without one)."""
        return self.step.updated if self.step is not None else _NO_SET

    @property
    def status(self) -> Status:
        """The primary localizer's status (``lost``, vouching for nothing, without one)."""
        return self.step.status if self.step is not None else "lost"

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


class FrameLoop:
    """Steps a source through vision and every estimator, one :class:`FrameRecord` per frame.

    ``estimators``: name -> estimator, stepped in this order; default: the interval localizer of
    ``cfg`` alone, as :data:`PRIMARY`, from ``initial`` (default :func:`initial_box`) with
    ``bounds`` (default from ``cfg.noise``). ``optional``: names of estimators dropped (not
    failing the frame) when they raise. ``keep_stages``: keep every vision stage image in the
    record (for display). ``residuals``: compute the equivalence residuals. ``clock``: the clock
    of the timings (seconds). ``rotate``: each frame steps the estimators in an order drawn
    afresh (a permutation seeded by the frame's count, so runs repeat): the first one stepped
    after vision finds the caches cold, and each one inherits the caches its predecessor
    leaves; a fresh order shares both costs when the timings are compared. The estimates do
    not depend on the order.
    """

    def __init__(
        self,
        cfg: Config,
        *,
        initial: Box | None = None,
        bounds: SensorBounds | None = None,
        estimators: Mapping[str, Estimator[Any]] | None = None,
        optional: Collection[str] = (),
        keep_stages: bool = False,
        residuals: bool = True,
        clock: Callable[[], float] = time.perf_counter,
        rotate: bool = False,
    ) -> None:
        self.cfg = cfg
        self.keep_stages = keep_stages
        self.bounds = bounds or sensor_bounds(cfg)
        if estimators is None:
            estimators = {PRIMARY: self._interval(
                initial if initial is not None else initial_box(cfg))}
        self.estimators: dict[str, Estimator[Any]] = dict(estimators)
        self.optional = set(optional)
        self.residuals = residuals
        self.clock = clock
        self.rotate = rotate
        self._pending_odometry: Odometry | None = None
        self._frames = 0

    def _interval(self, initial: Box) -> IntervalEstimator:
        return IntervalEstimator.from_config(self.cfg, initial=initial, bounds=self.bounds)

    @property
    def primary(self) -> IntervalEstimator | None:
        """The interval localizer named :data:`PRIMARY`, or None."""
        est = self.estimators.get(PRIMARY)
        return est if isinstance(est, IntervalEstimator) else None

    def add(self, name: str, estimator: Estimator[Any], *, optional: bool = False) -> None:
        """Step ``estimator`` from the next frame on (after the others), with the same motion as
        them; it should start from the set the others hold now."""
        self.estimators[name] = estimator
        if optional:
            self.optional.add(name)

    def remove(self, name: str) -> None:
        """Stop stepping ``name`` (nothing when absent)."""
        self.estimators.pop(name, None)
        self.optional.discard(name)

    def reset(self, initial: Box) -> None:
        """Start again from ``initial`` (e.g. after a kidnap the user reports): the primary
        localizer is rebuilt with the current configuration (see :meth:`reconfigure`), every other
        estimator reset; no motion is pending."""
        for name, est in self.estimators.items():
            if name == PRIMARY and isinstance(est, IntervalEstimator):
                self.estimators[name] = self._interval(initial)
            else:
                est.reset(initial)
        self._pending_odometry = None

    def reconfigure(self, cfg: Config, *, bounds: SensorBounds | None = None) -> None:
        """Use ``cfg`` from the next frame on (the live server's GUI): vision options, localizer
        options and the declared sensor bounds (``bounds``, default from ``cfg.noise``). The floor
        and the camera must not change (start a new loop for that).

        When the localizer options or the bounds change, the primary localizer restarts from the
        hull of its current set (a superset of it, so the guarantee holds) and keeps the pending
        odometry. A localizer that is ``lost`` stays lost (its set vouches for nothing) until
        :meth:`reset`, which builds it with the new settings; switching to mode ``truth`` needs no
        prior and takes effect at once. Other estimators are left as they are.
        """
        if (cfg.floor, cfg.camera) != (self.cfg.floor, self.cfg.camera):
            raise ValueError("reconfigure cannot change the floor or the camera; start a new run")
        new_bounds = bounds or sensor_bounds(cfg)
        changed = new_bounds != self.bounds or cfg.localizer != self.cfg.localizer
        self.cfg = cfg
        self.bounds = new_bounds
        primary = self.primary
        if changed and primary is not None and (not primary.lost
                                                or cfg.localizer.mode == "truth"):
            hull = primary.current.hull()
            self.estimators[PRIMARY] = self._interval(hull if hull is not None
                                                      else initial_box(cfg))

    def set_motion(self, odometry: Odometry | None) -> None:
        """The odometry the estimators use at the next frame (the motion since the previous
        one), for a live source that learns a frame's motion only when the next frame arrives
        (:mod:`tileviz.ros.live`); it then hands frames with ``odometry=None``. Checked as
        :meth:`process` checks a frame's odometry."""
        if odometry is not None and not (_finite(odometry.speed) and _finite(odometry.yaw_rate)
                                         and _finite(odometry.dt) and odometry.dt >= 0):
            raise ValueError(f"odometry must hold finite numbers (dt >= 0), got {odometry}")
        self._pending_odometry = odometry

    def process(self, frame: FrameInput, vision: VisionResult | None = None) -> FrameRecord:
        """Run one frame: every estimator predicts with the previous frame's odometry and updates
        with this frame's compass and view. ``vision``: this frame's vision result when it was
        computed elsewhere (a replay that runs vision in worker processes); None runs it here.
        Bad numbers raise ValueError naming the frame (this frame's odometry is checked now,
        though the estimators only use it on the next frame); the pending odometry is then kept."""
        odo = frame.odometry
        if odo is not None and not (_finite(odo.speed) and _finite(odo.yaw_rate)
                                    and _finite(odo.dt) and odo.dt >= 0):
            raise ValueError(f"frame {frame.index}: odometry must hold finite numbers "
                             f"(dt >= 0), got {odo}")
        clock = self.clock
        t0 = clock()
        if vision is None:
            vision = extract(
                frame.image,
                camera=self.cfg.camera,
                tile_size=self.cfg.floor.tile_size,
                vision=self.cfg.vision,
                keep_stages=self.keep_stages,
                floor=self.cfg.floor.model,
            )
            vision_ms = (clock() - t0) * 1e3
        else:
            vision_ms = sum(vision.timings.values())  # the worker's stage times
        inputs = StepInputs(self._pending_odometry, frame.compass, vision.observation,
                            frame.truth)
        names = list(self.estimators)
        if self.rotate and names:
            names = [names[i] for i in np.random.default_rng(self._frames).permutation(len(names))]
        estimates: dict[str, Any] = {}
        timings = {"vision_ms": vision_ms}
        dropped: dict[str, str] = {}
        for name in names:
            est = self.estimators[name]
            c0 = clock()
            try:
                estimates[name] = est.step(inputs)
            except Exception as e:
                if name not in self.optional:
                    if isinstance(e, ValueError):
                        raise ValueError(f"frame {frame.index}: {e}") from None
                    raise
                dropped[name] = str(e)
                continue
            timings[f"{name}_ms"] = (clock() - c0) * 1e3
        for name in dropped:
            self.remove(name)
        self._frames += 1
        self._pending_odometry = frame.odometry
        step = estimates.get(PRIMARY)
        if not isinstance(step, LocalizerStep):
            step = None
        else:
            timings["localizer_ms"] = timings[f"{PRIMARY}_ms"]
        residuals = None
        view_error = None
        if self.residuals and frame.truth is not None and vision.observation is not None:
            floor, offset = self.cfg.floor.tile_size, self.cfg.camera.offset
            residuals = equivalence_residuals(frame.truth, vision.observation, floor, offset)
            view_error = observation_error(vision.observation, frame.truth, floor, offset)
        return FrameRecord(
            index=frame.index,
            t=frame.t,
            truth=frame.truth,
            odometry=frame.odometry,
            compass=frame.compass,
            image=frame.image,
            setpoint=frame.setpoint,
            vision=vision,
            residuals=residuals,
            view_error=view_error,
            timings=timings,
            step=step,
            motion=inputs.odometry,
            estimates={n: estimates[n] for n in self.estimators if n in estimates},
            dropped=dropped,
            image_name=frame.image_name,
        )

    def run(self, source: Source) -> Iterator[FrameRecord]:
        """Process every frame of ``source`` in order."""
        for frame in source:
            yield self.process(frame)
