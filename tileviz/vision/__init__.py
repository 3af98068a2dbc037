"""Vision: camera image -> grout lines -> tile parameters (an Observation) or a refusal.

``extract(image, camera=..., tile_size=..., vision=...)`` runs the extractor that
``vision.extractor`` names:

- ``faithful`` (:mod:`tileviz.vision.faithful`): the original pipeline of report chapter 4 with
  its constants, corrected (signed offsets, circular medians, docs/method.md's convention).
- ``robust`` (:mod:`tileviz.vision.robust`): sub-pixel line positions from gray-level profiles,
  and checks that refuse a frame (``accepted=False``, a ``reason``) rather than return an
  observation outside its declared bound.

Both return a :class:`VisionResult`. Image frame: x = column, y = row; the observation follows
docs/method.md (see :mod:`tileviz.vision.geometry`). No viser, no pymunk here.

OpenCV's thread count (:func:`set_opencv_threads`): importing this module leaves it alone; every
entry point sets it to :data:`OPENCV_THREADS` (one) before any image is processed: the commands
(``tileviz.cliutil.run_cli``: record, replay, extract, evaluate, serve), the replay's and the
evaluation's worker processes, the bench scripts and the tests (``tests/conftest.py``). OpenCV's
multi-threaded Canny splits the image into stripes and its edges depend on the stripe count, so
an observation can differ between thread counts in its last digits; on one thread it is the same
on every machine, and a replay reproduces the live run whatever the core count. A program that
calls :func:`extract` without that set-up gets OpenCV's own count and gives up that
reproducibility.
"""

from __future__ import annotations

import math
import time

import cv2
import numpy as np

from tileviz.config import PERFECT_FLOOR, CameraConfig, FloorModel, VisionConfig
from tileviz.core.constants import MAX_TILE_PX, MIN_TILE_PX
from tileviz.vision.faithful import extract_faithful
from tileviz.vision.geometry import observation_error
from tileviz.vision.result import REASONS, VisionResult
from tileviz.vision.views import read_robust

OPENCV_THREADS = 1
"""The OpenCV thread count every tileviz entry point sets (module docstring)."""


def set_opencv_threads(threads: int = OPENCV_THREADS) -> None:
    """Run OpenCV's functions on ``threads`` threads in this process (module docstring)."""
    cv2.setNumThreads(int(threads))



__all__ = [
    "OPENCV_THREADS", "REASONS", "VisionResult", "check_tile_span", "extract",
    "observation_error", "set_opencv_threads", "to_gray",
]


def check_tile_span(tile_size: float, ppm: float) -> None:
    """ValueError unless a tile of ``tile_size`` metres spans ``MIN_TILE_PX`` to ``MAX_TILE_PX``
    pixels at ``ppm`` pixels per metre (what the extractor can read)."""
    tile_px = tile_size * ppm
    if not MIN_TILE_PX <= tile_px <= MAX_TILE_PX:
        raise ValueError(
            f"a tile must span {MIN_TILE_PX:g} to {MAX_TILE_PX:g} pixels (tile_size * ppm), "
            f"got {tile_px:g}"
        )


def to_gray(image: np.ndarray) -> np.ndarray:
    """An HxW uint8 gray image from HxW, HxWx1, HxWx3 (RGB) or HxWx4 (RGBA) uint8.

    Raises ValueError naming the problem (type, dtype, shape, empty)."""
    if not isinstance(image, np.ndarray):
        raise ValueError(f"image must be a numpy array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise ValueError(f"image must be uint8, got dtype {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] not in (3, 4)):
        raise ValueError(f"image must be HxW, HxWx3 or HxWx4, got shape {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"image is empty (shape {image.shape})")
    if image.ndim == 2:
        return np.ascontiguousarray(image)
    code = cv2.COLOR_RGB2GRAY if image.shape[2] == 3 else cv2.COLOR_RGBA2GRAY
    return cv2.cvtColor(np.ascontiguousarray(image), code)


def extract(
    image: np.ndarray,
    *,
    camera: CameraConfig,
    tile_size: float,
    vision: VisionConfig,
    keep_stages: bool = False,
    floor: FloorModel = PERFECT_FLOOR,
) -> VisionResult:
    """Extract the tile parameters seen in ``image`` (HxWx3 uint8 RGB, or HxW gray).

    ``camera``: ppm and the image size, which the image must match. ``tile_size``: L, metres.
    ``vision``: the extractor and its constants. ``floor``: what is declared of the floor (its kind
    and lattice tolerance, ``docs/dataset-format.md``: the robust extractor's view bound includes
    the tolerance; the faithful extractor reads every floor as a perfect lattice). ``keep_stages``:
    also return every stage image (HxWx3 uint8 RGB) for display. Bad arguments raise ValueError
    naming the quantity; a frame that gives no trustworthy observation is returned with
    ``accepted=False`` and a ``reason``.
    """
    if not isinstance(camera, CameraConfig):
        raise ValueError(f"camera must be a CameraConfig, got {type(camera).__name__}")
    if not isinstance(vision, VisionConfig):
        raise ValueError(f"vision must be a VisionConfig, got {type(vision).__name__}")
    if not isinstance(floor, FloorModel):
        raise ValueError(f"floor must be a FloorModel, got {type(floor).__name__}")
    if (
        not isinstance(tile_size, (int, float))
        or not math.isfinite(tile_size)
        or tile_size <= 0
    ):
        raise ValueError(f"tile_size must be a finite number > 0, got {tile_size!r}")
    check_tile_span(tile_size, camera.ppm)
    t0 = time.perf_counter()
    gray = to_gray(image)
    if gray.shape != (camera.height, camera.width):
        raise ValueError(
            f"image is {gray.shape[1]}x{gray.shape[0]} but the camera is "
            f"{camera.width}x{camera.height} (width x height)"
        )
    timings = {"gray": (time.perf_counter() - t0) * 1e3}
    if vision.extractor == "robust":
        return read_robust(gray, image, camera, float(tile_size), vision, keep_stages,
                           timings, floor)
    return extract_faithful(gray, camera=camera, tile_size=float(tile_size), vision=vision,
                            keep_stages=keep_stages, image=image, timings=timings)
