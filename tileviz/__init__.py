"""tileviz: guaranteed robot localization on tiled floors with interval analysis.

``tileviz.show(DATASET)`` and ``tileviz.replay(DATASET)`` study a run in a notebook
(:mod:`tileviz.share.notebook`; loaded on first use)."""

from __future__ import annotations

import os as _os
from typing import Any

__version__ = "0.1.0"

# OpenCV reads this once, when it loads: its decoders then refuse an image file whose header
# declares more pixels than tileviz reads (tileviz.datasets.images.MAX_IMAGE_PIXELS; for PNG and
# JPEG tileviz reads the header itself first)
_os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(1 << 26))

__all__ = ["replay", "show"]


def __getattr__(name: str) -> Any:
    """``show`` and ``replay`` from :mod:`tileviz.share.notebook`, loaded on first use (PEP 562)
    so that ``import tileviz`` stays light."""
    if name in __all__:
        from tileviz.share import notebook

        value = getattr(notebook, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
