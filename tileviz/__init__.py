"""tileviz: guaranteed robot localization on tiled floors with interval analysis."""

__version__ = "0.1.0"
