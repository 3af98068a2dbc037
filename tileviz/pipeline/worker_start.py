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

from dataclasses import replace

import numpy as np

import tileviz.pipeline.workers  # noqa: F401 - what a worker runs, imported once in the server
from tileviz.config import Config
from tileviz.pipeline.heap import keep_freed_memory
from tileviz.vision import extract, set_opencv_threads

__all__ = ["synthetic_view", "warm_up"]


def synthetic_view(cfg: Config) -> np.ndarray:
    """An HxW uint8 gray view of ``cfg``'s camera: a light, slightly noisy floor crossed by dark
    4 px grout lines every tile (``tile_size * ppm`` px) in both image directions."""
    h, w = cfg.camera.height, cfg.camera.width
    rng = np.random.default_rng(0)
    view = (170.0 + rng.normal(0.0, 4.0, (h, w))).clip(0, 255).astype(np.uint8)
    period = max(8, round(cfg.floor.tile_size * cfg.camera.ppm))
    for x0 in range(period // 3, w, period):
        view[:, x0:x0 + 4] = 60
    for y0 in range(period // 2, h, period):
        view[y0:y0 + 4, :] = 60
    return view


def warm_up() -> None:
    """Run both extractors once on :func:`synthetic_view` of the default configuration, on one
    OpenCV thread (a process that forks must not hold OpenCV's thread pool). A failure is
    ignored: the warm-up only saves time, and a worker then loads what it needs itself."""
    set_opencv_threads(1)
    cfg = Config()
    view = synthetic_view(cfg)
    for extractor in ("robust", "faithful"):
        try:
            extract(view, camera=cfg.camera, tile_size=cfg.floor.tile_size,
                    vision=replace(cfg.vision, extractor=extractor))
        except Exception:  # noqa: BLE001, S112 - an optimisation only (docstring)
            continue


keep_freed_memory()
warm_up()
