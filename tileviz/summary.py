"""The one-line summary of a run that ``replay`` and ``serve --frames`` print: frames, statuses,
median set size and, when the truth is known, how often the set held it."""

from __future__ import annotations

import math
import statistics
from collections import Counter
from dataclasses import dataclass, field
from typing import Protocol

from tileviz.types import BoxSet

__all__ = ["FAITHFUL_NOTE", "SCALE_FRAMES", "SCALE_TOLERANCE", "RunTally", "counted",
           "extractor_note", "frame_ranges", "outside_region"]

FAITHFUL_NOTE = ("the faithful extractor's views can break their declared bounds, so with it the "
                 "set can miss the truth (containment below 100 % is expected, not a broken "
                 "guarantee)")
"""What every summary of a run with the faithful extractor says (docs/guarantees.md, H4)."""


def extractor_note(extractor: str) -> str:
    """The sentence a summary or a status adds for views made by ``extractor`` (a
    ``VisionConfig.extractor`` name): :data:`FAITHFUL_NOTE` for ``faithful``, "" otherwise."""
    return FAITHFUL_NOTE if extractor == "faithful" else ""


class _Record(Protocol):
    """What the tally reads of a frame record (``tileviz.pipeline.FrameRecord``)."""

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
    periods: list[float] = field(default_factory=list)
    """The tile period each view's lines showed over the declared one (robust extractor,
    views with two lines of a family or more: ``details["period_ratio"]``)."""
    extractors: Counter[str] = field(default_factory=Counter)
    """Frames by the extractor that made their view (``VisionResult.extractor``)."""
    refused: Counter[str] = field(default_factory=Counter)
    """Views the extractor refused, by the check that refused them (the robust extractor's
    ``decision.refusal.check``, e.g. ``foreign_line.contrast``; else the reason)."""
    recognised: int = 0
    """Views read as a checkerboard the floor does not declare (``details["checker"]``:
    docs/vision.md, "Colour")."""
    outside_region: list[int] = field(default_factory=list)
    """Frame indices at which the localizer held re-localization candidates cut to a region
    (``LocalizerStep.region``) while the true pose, where known, was outside that region: the
    hypothesis of re-localization was broken there (docs/guarantees.md)."""

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
        if outside_region(rec):
            self.outside_region.append(int(getattr(rec, "index", self.frames - 1)))
        vision = getattr(rec, "vision", None)
        extractor = getattr(vision, "extractor", "")
        if extractor:
            self.extractors[extractor] += 1
        if extractor and getattr(vision, "accepted", True) is False:  # a view read, refused
            refusal = getattr(getattr(vision, "decision", None), "refusal", None)
            self.refused[str(getattr(refusal, "check", "") or getattr(vision, "reason", "?"))] += 1
        details = getattr(vision, "details", {})
        ratio = details.get("period_ratio")
        if ratio is not None and math.isfinite(ratio):
            self.periods.append(float(ratio))
        self.recognised += "checker" in details

    def parts(self) -> list[str]:
        """The summary's pieces: statuses, the views refused by the check that refused them
        (the three most frequent), median set size, containment (when known), what the
        extractor's views promise (:func:`extractor_note`), the frames outside the
        re-localization region, the scale warning."""
        out = [f"statuses: {', '.join(f'{n} {k}' for k, n in self.statuses.most_common())}"
               if self.statuses else "no frame"]
        if self.refused:
            top = self.refused.most_common(3)
            more = ", ..." if len(self.refused) > len(top) else ""
            out.append(f"views refused: {sum(self.refused.values())} ("
                       f"{', '.join(f'{k} {n}' for k, n in top)}{more}: extract IMAGE --explain "
                       f"says why)")
        finite = [w for w in self.widths if all(math.isfinite(v) for v in w)]
        if finite:
            wx, wy, wt = (statistics.median(w[i] for w in finite) for i in range(3))
            out.append(f"median set {100 * wx:.2f} x {100 * wy:.2f} cm, heading "
                       f"{math.degrees(wt):.2f} deg")
        if self.vouched:
            out.append(f"truth inside the set in {100.0 * self.inside / self.vouched:.1f} % of "
                       f"the {self.vouched} frames it vouched for")
        out += [note for note in map(extractor_note, sorted(self.extractors)) if note]
        if self.outside_region:
            out.append(f"the robot was outside the re-localization region at "
                       f"{len(self.outside_region)} frames ({frame_ranges(self.outside_region)}):"
                       f" the set could not vouch for the truth there")
        out += [note for note in (self.scale_warning(), self.checker_note()) if note]
        return out

    def checker_note(self) -> str:
        """Advice when :data:`SCALE_FRAMES` views or more were read as a checkerboard the floor
        does not declare: declare it, with its surveyed tolerance (a faint grout along a
        checkerboard's edges moves the edges a view sees off the lattice, which no single view
        shows: docs/guarantees.md, H4); "" otherwise."""
        if self.recognised < SCALE_FRAMES:
            return ""
        return (f"note: {self.recognised} views were read as a checkerboard the floor does not "
                f"declare: declare its kind (checker) and tolerance, as `python -m tileviz "
                f"survey` measures them (a faint grout along its edges moves them off the "
                f"lattice where no single view shows it)")

    def scale_warning(self) -> str:
        """A warning when the grout lines of the run's views lie consistently closer together
        or farther apart than ``tile_size`` x ``ppm`` says (:data:`SCALE_FRAMES` views or more
        measured it, their median off by more than :data:`SCALE_TOLERANCE`); "" otherwise.
        The views' bounds assume the scale exact (docs/vision.md, "What it reads"). A short run
        over a floor laid off the lattice (a mosaic's panels) can show the same few lines in
        every view: their departure is not averaged out, and may read as a scale error."""
        if len(self.periods) < SCALE_FRAMES:
            return ""
        ratio = statistics.median(self.periods)
        if abs(ratio - 1.0) <= SCALE_TOLERANCE:
            return ""
        way = "farther apart" if ratio > 1.0 else "closer together"
        return (f"WARNING: the grout lines of {len(self.periods)} views lie "
                f"{100.0 * abs(ratio - 1.0):.1f} % {way} than tile_size x ppm says (median): "
                f"check the camera's ppm and the tile size (views read at a wrong scale can "
                f"lie outside their bound)")


def outside_region(rec: object) -> bool:
    """True when ``rec`` (a frame record) knows the true pose and its localizer step cut the set
    to a re-localization region (``LocalizerStep.region``) that does not hold the truth's x, y."""
    step = getattr(rec, "step", None)
    truth = getattr(rec, "truth", None)
    region = getattr(step, "region", None)
    if region is None or truth is None:
        return False
    x0, y0, x1, y1 = region
    return not (x0 <= truth.x <= x1 and y0 <= truth.y <= y1)


def counted(n: int, singular: str, plural: str | None = None) -> str:
    """``n`` and the noun in the right number: ``1 box``, ``2 boxes`` (``plural`` defaults to
    ``singular + "s"``)."""
    return f"{n} {singular if n == 1 else (plural or singular + 's')}"


def frame_ranges(frames: list[int], most: int = 3) -> str:
    """Sorted frame indices as at most ``most`` ranges, e.g. ``245-256, 300, ...``."""
    runs: list[list[int]] = []
    for k in frames:
        if runs and k == runs[-1][1] + 1:
            runs[-1][1] = k
        else:
            runs.append([k, k])
    text = ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs[:most])
    return text + (", ..." if len(runs) > most else "")


SCALE_FRAMES = 5
"""Views that measured the tile period before :meth:`RunTally.scale_warning` speaks."""
SCALE_TOLERANCE = 0.003
"""Largest relative difference of the measured tile period from the declared one that
:meth:`RunTally.scale_warning` lets pass, far above what a view's lines read on a correct scale:
at 0.3 % a line 100 px from the view's centre is read 0.3 px off, most of a clean view's bound."""
