"""Replay with vision in worker processes: the frames of a dataset decoded and their tile
observations extracted on ``jobs`` processes, handed back in frame order.

Vision of one frame does not depend on any other frame, so a replay (a batch job) can run it for
several frames at once; the localizer, which does depend on the previous frame, stays in the
calling process and takes the frames in order. Where the platform has it, the workers are forked
from a fork server (:mod:`tileviz.pipeline.worker_server`) that imported the vision code and
loaded the robust extractor's compiled kernels once (:mod:`tileviz.pipeline.worker_start`),
rather than each worker importing and loading them again before its first frame; the server
serves every later replay of the calling process too. Each worker runs OpenCV with the calling
process's thread count (one, as every entry point sets it, unless the caller changed it:
OpenCV's multi-threaded Canny gives edges that depend on the count), so the results are bit for
bit those
of :func:`tileviz.vision.extract` in the calling process;
an error (a missing or unreadable image, an image of the wrong size) is raised when its frame's
turn comes, after every frame before it was delivered, as :class:`tileviz.datasets.DatasetSource`
does.

No viser, no pymunk here.
"""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import TypeVar

import cv2

from tileviz.config import Config
from tileviz.datasets import DatasetSource
from tileviz.pipeline.heap import keep_freed_memory
from tileviz.pipeline.parallel import results_in_order
from tileviz.pipeline.worker_server import worker_context
from tileviz.types import FrameInput
from tileviz.vision import VisionResult, extract, set_opencv_threads

__all__ = ["CHUNK", "vision_ahead", "worker_context"]

CHUNK = 8
"""Frames per task handed to a worker: each task costs both sides the executor's queues and
wake-ups once, so several frames share that cost; more would leave a worker idle longer at the
end of a dataset (docs/replay.md)."""

T = TypeVar("T")

_worker: tuple[DatasetSource, Config] | None = None
"""The dataset and configuration of this worker process (set by :func:`_init`)."""


def _init(folder: str, cfg: Config, threads: int) -> None:
    global _worker
    # OpenCV's thread count as in the calling process (the entry point set one): Canny's edges
    # depend on it, and a replay must give the same sets whatever --jobs
    set_opencv_threads(threads)
    keep_freed_memory()  # (already so when forked from the fork server)
    _worker = (DatasetSource(folder), cfg)


def _vision(name: str, where: str) -> VisionResult:
    """Decode one image of the worker's dataset and extract its observation."""
    assert _worker is not None, "worker not initialised"
    source, cfg = _worker
    image = source.load_image(name, where)
    return extract(image, camera=cfg.camera, tile_size=cfg.floor.tile_size, vision=cfg.vision,
                   floor=cfg.floor.model)


def _vision_chunk(jobs: list[tuple[str, str]]) -> list[VisionResult | Exception]:
    """:func:`_vision` of each (image name, row text) in order; an image's error ends the list
    (the frames after it are not reached: the replay stops there)."""
    out: list[VisionResult | Exception] = []
    for name, where in jobs:
        try:
            out.append(_vision(name, where))
        except Exception as e:  # noqa: BLE001 - raised in the caller at the frame's turn
            out.append(e)
            break
    return out


def _chunks(items: Iterator[T], size: int) -> Iterator[list[T]]:
    """``items`` in lists of ``size`` (the last one shorter); an error raised by ``items`` is
    raised after the list of the items before it."""
    chunk: list[T] = []
    while True:
        try:
            item = next(items)
        except StopIteration:
            break
        except Exception:
            if chunk:
                yield chunk
            raise
        chunk.append(item)
        if len(chunk) == size:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


def vision_ahead(source: DatasetSource, cfg: Config, jobs: int,
                 window: int | None = None) -> Iterator[tuple[FrameInput, VisionResult]]:
    """``(frame, vision)`` for every frame of ``source`` in order, vision computed on ``jobs``
    worker processes (``jobs`` >= 1) with ``cfg``'s camera, floor and vision options, in tasks
    of :data:`CHUNK` frames, at most ``window`` tasks ahead (default 2 per job). The frames
    carry no image (an empty array): the image stayed in the worker. A bad row or image raises
    DatasetError at its turn, after every frame before it."""
    if not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    ahead = 2 * jobs if window is None else max(1, int(window))
    with ProcessPoolExecutor(jobs, mp_context=worker_context(), initializer=_init,
                             initargs=(str(Path(source.folder)), cfg, cv2.getNumThreads()),
                             ) as pool:
        for chunk, results in results_in_order(
                _chunks(source.frames_without_images(), CHUNK),
                lambda c: pool.submit(_vision_chunk, [(f.image_name, w) for f, w in c]),
                ahead):
            for (frame, _), vision in zip(chunk, results, strict=False):
                if isinstance(vision, Exception):
                    raise vision
                yield frame, vision
