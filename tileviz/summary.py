"""The one-line summary of a run that ``replay`` and ``serve --frames`` print: frames, statuses,
median set size and, when the truth is known, how often the set held it."""

from __future__ import annotations

import math
import statistics
from collections import Counter
from dataclasses import dataclass, field
from typing import Protocol

from tileviz.types import BoxSet

__all__ = ["RunTally"]


class _Record(Protocol):
    """What the tally reads of a frame record (``tileviz.runner.FrameRecord``)."""

    @property
    def status(self) -> str: ...

    @property
    def updated(self) -> BoxSet: ...

    def truth_inside(self) -> bool | None: ...


@dataclass
class RunTally:
    """Counts over every frame of a run: ``statuses`` frames by status; ``vouched`` frames whose
    truth is known and status not ``lost``, ``inside`` those whose set held the truth; the hull
    widths of each frame's set (x, y in m, heading in rad)."""

    statuses: Counter[str] = field(default_factory=Counter)
    vouched: int = 0
    inside: int = 0
    widths: list[tuple[float, float, float]] = field(default_factory=list)

    @property
    def frames(self) -> int:
        return sum(self.statuses.values())

    def add(self, rec: _Record) -> None:
        """Count one frame record."""
        self.statuses[rec.status] += 1
        inside = rec.truth_inside()
        if inside is not None:
            self.vouched += 1
            self.inside += int(inside)
        hull = rec.updated.hull()
        if hull is not None and rec.status != "lost":
            self.widths.append(hull.widths)

    def parts(self) -> list[str]:
        """The summary's pieces: statuses, median set size, containment (when known)."""
        out = [f"statuses: {', '.join(f'{n} {k}' for k, n in self.statuses.most_common())}"
               if self.statuses else "no frame"]
        finite = [w for w in self.widths if all(math.isfinite(v) for v in w)]
        if finite:
            wx, wy, wt = (statistics.median(w[i] for w in finite) for i in range(3))
            out.append(f"median set {100 * wx:.2f} x {100 * wy:.2f} cm, heading "
                       f"{math.degrees(wt):.2f} deg")
        if self.vouched:
            out.append(f"truth inside the set in {100.0 * self.inside / self.vouched:.1f} % of "
                       f"the {self.vouched} frames it vouched for")
        return out
