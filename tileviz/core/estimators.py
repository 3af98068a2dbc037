"""One interface for every pose estimator, and the interval localizer behind it.

An estimator is stepped once per frame, in frame order (Gymnasium-like):

- ``reset(initial)``: start again from a box known to hold the true pose;
- ``step(inputs) -> estimate``: one frame's :class:`StepInputs` (the motion since the previous
  frame, then this frame's compass and tile observation) in, the estimator's own estimate out.

The frame loop (:class:`tileviz.pipeline.FrameLoop`) is the only caller in the product; it hands
every estimator the same inputs and keeps each estimate in the frame's record. The interval
localizer in each of its modes (``autonomous``, ``truth``, ``odometry``: the odometry-only
method) is an :class:`IntervalEstimator` whose estimate is a
:class:`tileviz.core.localizer.LocalizerStep`; the Monte Carlo baseline is
:class:`tileviz.baselines.estimator.MclEstimator` (estimate:
:class:`tileviz.baselines.mcl.MclEstimate`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol, TypeVar, runtime_checkable

from tileviz.config import Config, LocalizerConfig, Mode
from tileviz.core.localizer import Localizer, LocalizerStep
from tileviz.types import Box, BoxSet, Observation, Odometry, Pose, SensorBounds

__all__ = ["Estimator", "IntervalEstimator", "StepInputs", "sensor_bounds"]


@dataclass(frozen=True, slots=True)
class StepInputs:
    """What every estimator receives at frame k.

    ``odometry``: the measured motion from frame k-1 to frame k (None at the first frame or after
    a reset: no motion). ``compass``: heading measured at frame k, rad, or None. ``observation``:
    the tile parameters vision found in image k, or None (refused). ``truth``: the true pose k
    when known (only the interval localizer's ``truth`` mode uses it).
    """

    odometry: Odometry | None
    compass: float | None
    observation: Observation | None
    truth: Pose | None = None


EstimateT_co = TypeVar("EstimateT_co", covariant=True)


@runtime_checkable
class Estimator(Protocol[EstimateT_co]):
    """A pose estimator stepped once per frame (module docstring)."""

    def reset(self, initial: Box) -> None:
        """Start again from ``initial`` (metres, radians), a box holding the true pose."""

    def step(self, inputs: StepInputs) -> EstimateT_co:
        """One frame; raises ValueError naming the quantity on a bad input (NaN, inf, dt < 0),
        the state then unchanged."""
        ...


def sensor_bounds(cfg: Config) -> SensorBounds:
    """The declared sensor error bounds of ``cfg`` (its ``noise`` section)."""
    return SensorBounds(cfg.noise.speed_error, cfg.noise.yaw_rate_error, cfg.noise.compass_error)


class IntervalEstimator:
    """The guaranteed interval localizer (:class:`tileviz.core.localizer.Localizer`) as an
    :class:`Estimator`; its estimate is the frame's
    :class:`~tileviz.core.localizer.LocalizerStep`."""

    def __init__(self, localizer: Localizer) -> None:
        self.localizer = localizer

    @classmethod
    def from_config(
        cls,
        cfg: Config,
        *,
        initial: Box,
        bounds: SensorBounds | None = None,
        mode: Mode | None = None,
        max_slip: tuple[float, float] | None = None,
    ) -> IntervalEstimator:
        """The localizer of ``cfg`` (floor, camera, localizer sections; bounds from its noise
        section unless given) starting from ``initial``; ``mode`` and ``max_slip`` override the
        localizer section's."""
        loc: LocalizerConfig = cfg.localizer
        if mode is not None:
            loc = replace(loc, mode=mode)
        if max_slip is not None:
            loc = replace(loc, max_slip=max_slip)
        return cls(Localizer(tile_size=cfg.floor.tile_size, camera_offset=cfg.camera.offset,
                             bounds=bounds if bounds is not None else sensor_bounds(cfg),
                             config=loc, initial=initial))

    def reset(self, initial: Box) -> None:
        self.localizer.reset(initial)

    def step(self, inputs: StepInputs) -> LocalizerStep:
        return self.localizer.step(inputs.odometry, inputs.compass, inputs.observation,
                                   inputs.truth)

    @property
    def current(self) -> BoxSet:
        """The set after the last step (or the initial box)."""
        return self.localizer.current

    @property
    def lost(self) -> bool:
        """True once the localizer declared itself lost (until :meth:`reset`)."""
        return self.localizer.lost
