"""Loading the robust extractor's compiled kernels before the first view is timed.

The first robust extraction in a process loads the compiled kernels (:mod:`tileviz.vision.robust.
kernel`; compiling them once after an install): a few hundred ms, which would otherwise be counted
in the first view's stage timings. :func:`warm_up` extracts :func:`synthetic_view` and drops the
result; nothing it touches is a result cache, so every later extraction computes exactly what it
computes without it. No viser, no pymunk here.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np

from tileviz.config import Config, Extractor
from tileviz.vision import extract

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


def warm_up(extractors: Iterable[Extractor] = ("robust",), cfg: Config | None = None
            ) -> None:
    """Run each of ``extractors`` once on :func:`synthetic_view` of ``cfg`` (default: the
    default configuration) with OpenCV's current thread count. A failure is ignored: the
    warm-up only moves a one-off cost, and the first real view then loads what it needs."""
    cfg = Config() if cfg is None else cfg
    view = synthetic_view(cfg)
    for extractor in extractors:
        try:
            extract(view, camera=cfg.camera, tile_size=cfg.floor.tile_size,
                    vision=replace(cfg.vision, extractor=extractor))
        except Exception:  # noqa: BLE001, S112 - an optimisation only (docstring)
            continue
