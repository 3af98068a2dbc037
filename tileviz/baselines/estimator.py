"""The Monte Carlo Localization baseline behind the common estimator interface
(:class:`tileviz.core.estimators.Estimator`)."""

from __future__ import annotations

import math

from tileviz.baselines.mcl import MCL, MclConfig, MclEstimate
from tileviz.config import Config
from tileviz.core.estimators import StepInputs, sensor_bounds
from tileviz.types import Box, SensorBounds

__all__ = ["MclEstimator", "room_box"]


def room_box(cfg: Config) -> Box:
    """The simulated room as a pose box (x, y within +- ``room_half_size`` metres, heading in
    [-pi, pi]): where MCL draws injected particles."""
    room = cfg.sim.room_half_size
    return Box(-room, room, -room, room, -math.pi, math.pi)


class MclEstimator:
    """:class:`tileviz.baselines.mcl.MCL` as an estimator; its estimate is the step's
    :class:`~tileviz.baselines.mcl.MclEstimate`. It ignores ``StepInputs.truth``."""

    def __init__(self, mcl: MCL) -> None:
        self.mcl = mcl

    @classmethod
    def from_config(cls, cfg: Config, *, initial: Box, config: MclConfig,
                    bounds: SensorBounds | None = None) -> MclEstimator:
        """A filter for ``cfg``'s floor and camera (bounds from its noise section unless given),
        particles drawn in ``initial``, injected ones in the room (:func:`room_box`)."""
        return cls(MCL(tile_size=cfg.floor.tile_size, camera_offset=cfg.camera.offset,
                       bounds=bounds if bounds is not None else sensor_bounds(cfg),
                       initial=initial, config=config, region=room_box(cfg)))

    def reset(self, initial: Box) -> None:
        self.mcl.reset(initial)

    def step(self, inputs: StepInputs) -> MclEstimate:
        return self.mcl.step(inputs.odometry, inputs.compass, inputs.observation)
