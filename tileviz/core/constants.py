"""Constants and limits shared by several modules: one definition each."""

from __future__ import annotations

import math

__all__ = ["HALF_PI", "LIMIT", "MAX_PPM", "MAX_TILE_PX", "MIN_TILE_PX", "TWO_PI"]

TWO_PI = 2.0 * math.pi
"""The float nearest 2 pi, the heading period (radians). Interval code that must enclose the real
2 pi uses ``tileviz.core.intervals.TWO_PI_ERROR`` beside it."""
HALF_PI = 0.5 * math.pi
"""The float nearest pi/2, the period of the tile observation's heading branches (radians)."""

LIMIT = 1e9
"""Largest magnitude of any number the localizer accepts or produces (metres, radians, m/s,
rad/s, seconds) and of any number in a dataset's meta.json: beyond it the lattice arithmetic would
need more than float64's 52 bits to tell one tile (or one turn) from the next."""

MIN_TILE_PX = 4.0
"""A tile must span at least this many pixels (tile_size x ppm): finer is no floor to see."""
MAX_TILE_PX = 1e5
"""Largest tile period in pixels: beyond it the image is far smaller than a tile."""
MAX_PPM = 1e5
"""Largest ppm, pixels per metre (10 micrometres a pixel): beyond it the image stages' kernels
(sized in pixels from metres) would not fit in memory."""
