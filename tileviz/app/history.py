"""The bounded history of processed frames the live server shows, steps back through and scrubs.

Each :class:`Entry` holds one immutable :class:`tileviz.pipeline.FrameRecord` and the images shown
for it, JPEG-encoded once when the frame was made (the camera view, then every pipeline stage).
Showing an old frame re-sends those same bytes and the same record: nothing is recomputed, so a
frame looks exactly the same live and from the history.

To keep 2000+ frames in memory the stored record drops its raw arrays (the camera image and the
stage images, ~2 MB a frame at 320x240); their JPEG copies (~80 kB a frame) stay in the entry.
Per-frame numbers for the plots and the trails live in ring arrays (:class:`Series`).

Threads: the loop thread appends; readers (tests, a publisher) may read at any time. A lock guards
the ring so a reader never sees a half-written frame.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from tileviz.pipeline import FrameRecord
from tileviz.types import STATUSES

__all__ = [
    "Encoder", "Entry", "History", "ParticleView", "Series", "encode_images", "encode_jpeg",
    "metrics_of", "strip_record",
]

JPEG_QUALITY = 85
"""Quality of the stored (and streamed) camera and stage images."""

_EMPTY_IMAGE = np.zeros((0, 0, 3), np.uint8)
_EMPTY_IMAGE.flags.writeable = False

METRIC_NAMES = (
    "t",
    "view_x", "view_y", "view_heading",
    "width_x", "width_y", "width_theta",
    "error_xy", "error_theta",
    "truth_x", "truth_y", "est_x", "est_y",
    "inside", "status", "boxes", "frame_ms",
    "mcl_error_xy", "mcl_covered",
)
"""Columns of :class:`Series`. Units: t s; view_x, view_y, view_heading the view's error from
the true pose (``FrameRecord.view_error``) over its declared bound, dimensionless (<= 1: the view
agrees with the truth within its bound); widths m, m, rad (hull of the
updated set); error_xy m (distance from the truth to the hull centre), error_theta rad (wrapped
to [-pi, pi]); truth/est x, y m; inside 1/0 (NaN when unknown or ``lost``); status the index in
``tileviz.types.STATUSES``; boxes count; frame_ms the vision + localizer time; mcl_error_xy m
(truth to the particle mean), mcl_covered 1/0 (truth inside the 95 % ellipse; NaN without MCL)."""


@dataclass(frozen=True)
class ParticleView:
    """What the live server keeps of the Monte Carlo Localization baseline for one frame
    (:mod:`tileviz.baselines.mcl`): ``particles`` (N, 3) float32 x, y m and theta rad; ``mean``
    (3,) the weighted mean; ``ellipse`` (K, 2) float32 points of its 95 % confidence ellipse in
    (x, y); ``covered``: the true (x, y) is inside that ellipse (None when the truth is unknown).
    """

    particles: np.ndarray
    mean: np.ndarray
    ellipse: np.ndarray
    covered: bool | None

    @classmethod
    def of(cls, estimate: Any, truth: Any) -> ParticleView:
        """From an ``MclEstimate`` and the true Pose (or None)."""
        covered = None if truth is None else bool(estimate.ellipse_contains(truth.x, truth.y))
        return cls(np.asarray(estimate.particles, np.float32).copy(),
                   np.asarray(estimate.mean, np.float64).copy(),
                   np.asarray(estimate.ellipse(points=64), np.float32), covered)


def encode_jpeg(image: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    """JPEG bytes of an HxWx3 uint8 RGB image (or HxW gray, shown as RGB)."""
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2RGB)
    bgr = cv2.cvtColor(np.ascontiguousarray(image[..., :3]), cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f"cannot JPEG-encode an image of shape {image.shape}")
    return buf.tobytes()


def strip_record(rec: FrameRecord) -> FrameRecord:
    """The record without its raw image arrays (camera image and stage images)."""
    vision = rec.vision
    if vision.stages:
        vision = replace(vision, stages={})
    return replace(rec, image=_EMPTY_IMAGE, vision=vision)


_METRIC = {name: i for i, name in enumerate(METRIC_NAMES)}


def metrics_of(rec: FrameRecord, mcl: ParticleView | None = None) -> np.ndarray:
    """One row of :data:`METRIC_NAMES` for ``rec`` and its MCL view (NaN where unknown)."""
    nan = math.nan
    row = np.full(len(METRIC_NAMES), nan)
    c = _METRIC
    row[c["t"]] = rec.t
    obs = rec.vision.observation
    if rec.view_error is not None and obs is not None:
        e1, e2, e3 = rec.view_error
        pos, head = obs.position_error, obs.heading_error
        row[c["view_x"]] = abs(e1) / pos if pos > 0 else math.inf
        row[c["view_y"]] = abs(e2) / pos if pos > 0 else math.inf
        row[c["view_heading"]] = abs(e3) / head if head > 0 else math.inf
    hull = rec.updated.hull()
    if hull is not None:
        row[[c["width_x"], c["width_y"], c["width_theta"]]] = hull.widths
        cx, cy, ct = hull.centre
        row[c["est_x"]], row[c["est_y"]] = cx, cy
        if rec.truth is not None:
            row[c["error_xy"]] = math.hypot(rec.truth.x - cx, rec.truth.y - cy)
            row[c["error_theta"]] = math.remainder(rec.truth.theta - ct, 2.0 * math.pi)
    if rec.truth is not None:
        row[c["truth_x"]], row[c["truth_y"]] = rec.truth.x, rec.truth.y
    inside = rec.truth_inside()
    row[c["inside"]] = nan if inside is None else float(inside)
    row[c["status"]] = STATUSES.index(rec.status) if rec.status in STATUSES else nan
    row[c["boxes"]] = len(rec.updated)
    row[c["frame_ms"]] = rec.timings.get("vision_ms", 0.0) + rec.timings.get("localizer_ms", 0.0)
    if mcl is not None and rec.truth is not None:
        row[c["mcl_error_xy"]] = math.hypot(rec.truth.x - mcl.mean[0], rec.truth.y - mcl.mean[1])
        row[c["mcl_covered"]] = float(bool(mcl.covered))
    return row


Images = tuple[tuple[str, bytes], ...]
"""Ordered (name, JPEG bytes) pairs."""


def encode_images(image: np.ndarray, stages: dict[str, np.ndarray]) -> Images:
    """(name, JPEG bytes) pairs: ``camera`` (when ``image`` is not empty), then ``stages``."""
    images: list[tuple[str, bytes]] = []
    camera = encode_jpeg(image) if image.size else b""
    if camera:
        images.append(("camera", camera))
    for name, img in stages.items():
        # the extractors' "input" stage is the camera image again: encode it once
        same = camera and img.shape == image.shape and np.array_equal(img, image)
        images.append((name, camera if same else encode_jpeg(img)))
    return tuple(images)


@dataclass(frozen=True)
class Entry:
    """One frame of the history: the (stripped) record and its images as JPEG bytes.

    ``images``: ordered (name, JPEG bytes) pairs; ``camera`` first, then the pipeline stages in
    the extractor's order (none when the display was off for this frame). They may still be
    being encoded on the :class:`Encoder`'s thread: reading ``images`` then waits for them."""

    record: FrameRecord
    encoded: Images | Future[Images]
    mcl: ParticleView | None = None
    """The MCL baseline's particles at this frame (None when it was off)."""

    @property
    def index(self) -> int:
        return self.record.index

    @property
    def images(self) -> Images:
        e = self.encoded
        return e.result() if isinstance(e, Future) else e

    @property
    def ready(self) -> bool:
        """True when the images are encoded (reading them will not wait)."""
        e = self.encoded
        return not isinstance(e, Future) or e.done()

    @classmethod
    def make(cls, rec: FrameRecord, *, stages: bool = True, encoder: Encoder | None = None,
             mcl: ParticleView | None = None,
             before: dict[str, np.ndarray] | None = None) -> Entry:
        """The entry of ``rec``: its images encoded (now, or on ``encoder``'s thread) and the
        record stripped of its raw arrays. ``before``: stage images shown before the
        extractor's (e.g. a lens camera's raw and rectified image), kept only with ``stages``."""
        st = {**(before or {}), **rec.vision.stages} if stages else {}
        if encoder is None:
            return cls(strip_record(rec), encode_images(rec.image, st), mcl)
        return cls(strip_record(rec), encoder.submit(rec.image, st), mcl)


class Encoder:
    """JPEG-encodes frames' images on one worker thread (OpenCV releases the GIL, so this runs
    beside the frame loop on another core). At most ``max_pending`` frames wait; past that,
    :meth:`submit` waits for the oldest (the raw arrays of waiting frames stay in memory)."""

    def __init__(self, max_pending: int = 8) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="tileviz-jpeg")
        self._pending: deque[Future[Images]] = deque()
        self.max_pending = int(max_pending)

    def submit(self, image: np.ndarray, stages: dict[str, np.ndarray]) -> Future[Images]:
        while self._pending and (self._pending[0].done()
                                 or len(self._pending) >= self.max_pending):
            self._pending.popleft().result()
        fut = self._pool.submit(encode_images, image, stages)
        self._pending.append(fut)
        return fut

    def close(self) -> None:
        """Finish the queued work and stop the thread."""
        self._pool.shutdown(wait=True)


class Series:
    """Per-frame numbers (:data:`METRIC_NAMES`) in ring arrays of ``capacity`` rows."""

    def __init__(self, capacity: int) -> None:
        self.capacity = int(capacity)
        self._rows = np.full((self.capacity, len(METRIC_NAMES)), math.nan)

    def put(self, position: int, row: np.ndarray) -> None:
        self._rows[position % self.capacity] = row

    def window(self, first: int, last: int) -> np.ndarray:
        """Rows for positions first..last (inclusive), in order; a copy."""
        if last < first:
            return np.empty((0, len(METRIC_NAMES)))
        idx = np.arange(first, last + 1) % self.capacity
        return self._rows[idx].copy()


class History:
    """The last ``capacity`` frames of a run, by *position*: 0 for the first frame appended, then
    1, 2, ... (the source's frame index stays in each record; the two differ when a frame failed
    and left a gap). :meth:`clear` starts a new run at position 0.
    """

    def __init__(self, capacity: int = 2000) -> None:
        if int(capacity) != capacity or capacity < 2:
            raise ValueError(f"history capacity must be an integer >= 2, got {capacity!r}")
        self.capacity = int(capacity)
        self._lock = threading.Lock()
        self._entries: list[Entry | None] = [None] * self.capacity
        self.series = Series(self.capacity)
        self._first = 0
        self._last = -1

    def clear(self) -> None:
        """Forget every frame (a new run starts)."""
        with self._lock:
            self._entries = [None] * self.capacity
            self.series = Series(self.capacity)
            self._first = 0
            self._last = -1

    def append(self, entry: Entry) -> int:
        """Add the next frame; returns its position. Its frame index must be larger than the
        previous frame's."""
        with self._lock:
            if self._last >= 0:
                prev = self._entries[self._last % self.capacity]
                assert prev is not None
                if entry.index <= prev.index:
                    raise ValueError(f"history: frame {entry.index} does not follow frame "
                                     f"{prev.index}")
            pos = self._last + 1
            self._entries[pos % self.capacity] = entry
            self.series.put(pos, metrics_of(entry.record, entry.mcl))
            self._last = pos
            if self._last - self._first + 1 > self.capacity:
                self._first = self._last - self.capacity + 1
            return pos

    def __len__(self) -> int:
        return self._last - self._first + 1

    @property
    def first(self) -> int:
        """Position of the oldest frame kept (0 when empty)."""
        return self._first

    @property
    def last(self) -> int:
        """Position of the newest frame (-1 when empty)."""
        return self._last

    def __contains__(self, position: int) -> bool:
        return self._first <= position <= self._last

    def get(self, position: int) -> Entry:
        """The frame at that position; KeyError when it is not (or no longer) kept."""
        with self._lock:
            if not self._first <= position <= self._last:
                raise KeyError(f"position {position} is not in the history "
                               f"({self._first}..{self._last})")
            entry = self._entries[position % self.capacity]
        assert entry is not None
        return entry

    def window(self, last: int, n: int) -> np.ndarray:
        """Metric rows of the (up to) ``n`` frames ending at position ``last`` (clamped to the
        history), oldest first."""
        with self._lock:
            hi = min(last, self._last)
            lo = max(self._first, hi - n + 1)
            return self.series.window(lo, hi)
