"""The pipeline: the one frame loop (:mod:`tileviz.pipeline.frame_loop`) that drives every
estimator over a source of frames, and what runs it in batch.

The frame loop's names are loaded on first use, so that a light module of this package
(:mod:`tileviz.pipeline.worker_server`, which the replay command calls before anything else) can
be imported without the vision and localizer code."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tileviz.pipeline.frame_loop import PRIMARY, FrameLoop, FrameRecord, Source, initial_box

__all__ = ["PRIMARY", "FrameLoop", "FrameRecord", "Source", "initial_box"]


def __getattr__(name: str) -> Any:
    """The frame loop's exported names, loaded from :mod:`tileviz.pipeline.frame_loop` on first
    use (PEP 562)."""
    if name in __all__:
        value = getattr(importlib.import_module("tileviz.pipeline.frame_loop"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
