"""What an extractor returns: :class:`VisionResult`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tileviz.types import Observation
from tileviz.vision.decision import Decision

__all__ = ["BAG_HORIZONTAL", "BAG_REJECTED", "BAG_VERTICAL", "REASONS", "VisionResult"]

BAG_REJECTED = 0
"""Bag of a segment rejected as an outlier (or in neither family)."""
BAG_HORIZONTAL = 1
"""Bag of the family that gives y1: lines along the direction y3 (horizontal when y3 = 0)."""
BAG_VERTICAL = 2
"""Bag of the family that gives y2: lines along y3 + pi/2 (vertical when y3 = 0)."""

REASONS = (
    "ok",
    "constant image",
    "no lines",
    "too few segments",
    "one family",
    "low contrast",
    "glare",
    "blurred",
    "step edge",
    "foreign line",
    "inconsistent angle",
    "inconsistent spacing",
    "imprecise",
)
"""Every ``reason`` an extractor gives; ``ok`` exactly when ``accepted``."""


def _empty(shape: tuple[int, ...], dtype: type) -> np.ndarray:
    a: np.ndarray = np.zeros(shape, dtype)
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class VisionResult:
    """The outcome of one image.

    Pixel coordinates: x = column, y = row (docs/dataset-format.md). Segment angles are
    ``atan2(y2 - y1, x2 - x1)`` in radians; a grout line of the family giving y1 has angle
    y3 (mod pi), one of the family giving y2 has angle y3 + pi/2 (mod pi).

    - ``observation``: the tile parameters (docs/method.md convention), or None when refused.
    - ``accepted``/``reason``: ``reason`` is ``"ok"`` when accepted, else one of :data:`REASONS`.
    - ``segments`` (N, 4) float pixel endpoints x1, y1, x2, y2; ``angles`` (N,) rad;
      ``bags`` (N,) int8 (0 rejected, 1 horizontal/y1, 2 vertical/y2);
      ``disambiguation`` (N, 2) = (cos 4a, sin 4a) (report eq. 4.4).
    - ``offsets`` (N,) metres: each line's signed offset from the camera centre along its family's
      normal (NaN when rejected); the line sits where ``y_i + offset`` is a multiple of L.
    - ``median``: the component-wise median of the kept (cos 4a, sin 4a) (report eq. 4.5), or None.
    - ``stages``: ordered name -> HxWx3 uint8 RGB image (empty unless ``keep_stages``).
    - ``timings``: milliseconds per stage. ``details``: extractor-specific numbers (e.g. the
      robust extractor's measured spacing residual in pixels).
    - ``decision``: how the robust extractor decided (every check run with its value and
      limit, the readings tried, the refusing check; :class:`~tileviz.vision.decision.
      Decision`); None for the faithful extractor.
    """

    observation: Observation | None
    accepted: bool
    reason: str
    extractor: str = ""
    segments: np.ndarray = field(default_factory=lambda: _empty((0, 4), np.float64))
    angles: np.ndarray = field(default_factory=lambda: _empty((0,), np.float64))
    bags: np.ndarray = field(default_factory=lambda: _empty((0,), np.int8))
    disambiguation: np.ndarray = field(default_factory=lambda: _empty((0, 2), np.float64))
    offsets: np.ndarray = field(default_factory=lambda: _empty((0,), np.float64))
    median: tuple[float, float] | None = None
    stages: dict[str, np.ndarray] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    details: dict[str, float] = field(default_factory=dict)
    decision: Decision | None = None

    @property
    def lines(self) -> int:
        """How many segments were used (in a bag)."""
        return int(np.count_nonzero(self.bags))

    def as_dict(self) -> dict[str, object]:
        """A JSON-able summary: y1, y2, y3 (None when refused), accepted, reason, lines, ...,
        and ``decision`` (:meth:`~tileviz.vision.decision.Decision.as_dict`) when the
        extractor gives one."""
        obs = self.observation
        out: dict[str, object] = {
            "y1": None if obs is None else obs.y1,
            "y2": None if obs is None else obs.y2,
            "y3": None if obs is None else obs.y3,
            "accepted": self.accepted,
            "reason": self.reason,
            "lines": self.lines,
            "segments": int(len(self.segments)),
            "extractor": self.extractor,
            "position_error": None if obs is None else obs.position_error,
            "heading_error": None if obs is None else obs.heading_error,
            "timings_ms": {k: round(v, 4) for k, v in self.timings.items()},
        }
        if self.decision is not None:
            out["decision"] = self.decision.as_dict()
        return out
