"""Baselines the interval localizer is compared with (issue 6).

- :mod:`tileviz.baselines.mcl`: Monte Carlo Localization, a vectorised particle filter on the same
  inputs (bounded odometry, compass, tile observation). numpy only: no viser, no pymunk.
"""

from __future__ import annotations

from tileviz.baselines.mcl import CHI2_2D_95, MCL, MclConfig, MclEstimate

__all__ = ["CHI2_2D_95", "MCL", "MclConfig", "MclEstimate"]
