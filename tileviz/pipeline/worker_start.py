"""What the replay's fork server loads before it forks any vision worker
(:mod:`tileviz.pipeline.workers`): importing this module sets the allocator to keep freed memory
(:func:`tileviz.pipeline.heap.keep_freed_memory`, inherited by every worker), imports everything
a worker runs and extracts one synthetic tiled view with each extractor, on one OpenCV thread,
so that the robust
extractor's compiled kernels (:mod:`tileviz.vision.robust.kernel`) are loaded once in the server
and every worker forked from it starts with them. A worker computes exactly what it computes
without this: the warm-up's results are dropped, and nothing it touches is a result cache.

No viser, no pymunk here.
"""

from __future__ import annotations

import tileviz.pipeline.workers  # noqa: F401 - what a worker runs, imported once in the server
from tileviz.pipeline.heap import keep_freed_memory
from tileviz.vision import set_opencv_threads, warmup

__all__ = ["warm_up"]


def warm_up() -> None:
    """Run both extractors once on :func:`~tileviz.vision.warmup.synthetic_view` of the default
    configuration, on one OpenCV thread (a process that forks must not hold OpenCV's thread
    pool). A failure is ignored: the warm-up only saves time, and a worker then loads what it
    needs itself."""
    set_opencv_threads(1)
    warmup.warm_up(("robust", "faithful"))


keep_freed_memory()
warm_up()
