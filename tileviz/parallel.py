"""Replay with vision in worker processes: the frames of a dataset decoded and their tile
observations extracted on ``jobs`` processes, handed back in frame order.

Vision of one frame does not depend on any other frame, so a replay (a batch job) can run it for
several frames at once; the localizer, which does depend on the previous frame, stays in the
calling process and takes the frames in order. Each worker runs OpenCV with the calling process's
thread count (one, as :mod:`tileviz.vision` sets it, unless the caller changed it: OpenCV's
multi-threaded Canny gives edges that depend on the count), so the results are bit for bit those
of :func:`tileviz.vision.extract` in the calling process;
an error (a missing or unreadable image, an image of the wrong size) is raised when its frame's
turn comes, after every frame before it was delivered, as :class:`tileviz.dataset.DatasetSource`
does.

No viser, no pymunk here.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import cv2

from tileviz.config import Config
from tileviz.dataset import DatasetSource, results_in_order
from tileviz.types import FrameInput
from tileviz.vision import VisionResult, extract

__all__ = ["vision_ahead"]

_worker: tuple[DatasetSource, Config] | None = None
"""The dataset and configuration of this worker process (set by :func:`_init`)."""


def _init(folder: str, cfg: Config, threads: int) -> None:
    global _worker
    # OpenCV's thread count as in the calling process (importing tileviz.vision set one):
    # Canny's edges depend on it, and a replay must give the same sets whatever --jobs
    cv2.setNumThreads(threads)
    _worker = (DatasetSource(folder), cfg)


def _vision(name: str, where: str) -> VisionResult:
    """Decode one image of the worker's dataset and extract its observation."""
    assert _worker is not None, "worker not initialised"
    source, cfg = _worker
    image = source.load_image(name, where)
    return extract(image, camera=cfg.camera, tile_size=cfg.floor.tile_size, vision=cfg.vision)


def vision_ahead(source: DatasetSource, cfg: Config, jobs: int,
                 window: int | None = None) -> Iterator[tuple[FrameInput, VisionResult]]:
    """``(frame, vision)`` for every frame of ``source`` in order, vision computed on ``jobs``
    worker processes (``jobs`` >= 1) with ``cfg``'s camera, floor and vision options, at most
    ``window`` frames ahead (default 4 per job). The frames carry no image (an empty array):
    the image stayed in the worker. A bad row or image raises DatasetError at its turn."""
    if not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    ahead = 4 * jobs if window is None else max(1, int(window))
    ctx = multiprocessing.get_context("spawn")  # no fork of a process with OpenCV threads
    with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_init,
                             initargs=(str(Path(source.folder)), cfg, cv2.getNumThreads()),
                             ) as pool:
        for (frame, _), vision in results_in_order(
                source.frames_without_images(),
                lambda job: pool.submit(_vision, job[0].image_name, job[1]), ahead):
            yield frame, vision
