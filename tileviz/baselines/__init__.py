"""Baselines the interval localizer is compared with.

- :mod:`tileviz.baselines.mcl`: Monte Carlo Localization, a vectorised particle filter on the same
  inputs (bounded odometry, compass, tile observation). numpy only: no viser, no pymunk.
- :mod:`tileviz.baselines.estimator`: that filter behind the common estimator interface.
"""

from __future__ import annotations

from tileviz.baselines.estimator import MclEstimator
from tileviz.baselines.mcl import CHI2_2D_95, MCL, MclConfig, MclEstimate

__all__ = ["CHI2_2D_95", "MCL", "MclConfig", "MclEstimate", "MclEstimator"]
