"""The candidate readings of a view, tried in order by one loop (:func:`decide`), and the pure
function that reads a view for one reading (:func:`read`).

A reading (:class:`~tileviz.vision.decision.Reading`, an immutable value) is a heading to
measure the lines at, a polarity of the grout (decided from the profiles, or imposed), and
whether the one part that alone keeps the lines from straight is left out. :func:`read` builds
its own working state (:class:`~tileviz.vision.robust.state.ReadingState`) from the view's
immutable data (:class:`~tileviz.vision.robust.state.View`), measures the lines, runs the line
checks and, when they pass, the lattice, the bound and the foreign-edge checks, and returns
an immutable :class:`Outcome`. Nothing is shared between readings but the view.

The plan (:func:`plan`), in two passes: the first without leaving out a stray part, the second
(only when the first refused the view after some reading found its lines not straight) the
same with it left out (:func:`~tileviz.vision.robust.fit.drop_stray_part`: a texture's dip
measured beside the grout in one part). In each pass:

1. the first heading (the gradient votes, :func:`~tileviz.vision.robust.heading.first_heading`);
2. when its lines fail a line check of :data:`RETRY_REASONS` (the gradient directions can be
   outvoted by texture: a heading a few degrees off smears every line's profile), the
   headings at which the view repeats with the tile period
   (:func:`~tileviz.vision.robust.heading.lattice_headings`), then the gradient votes on the
   smoothed view (:func:`~tileviz.vision.robust.heading.smoothed_headings`), then, when the
   first found no lines or only faint ones (:data:`UNSEEN_REASONS`), the headings near
   those read at which the lines are sharpest
   (:func:`~tileviz.vision.robust.heading.sharpened_headings`: not after a foreign line,
   which a blunter heading may smear out of sight), each skipped when within
   ``heading.same_heading`` of one read;
3. when every heading failed and the first failed with a reason of :data:`UNSEEN_REASONS`
   (a bright tile cut by the border of a view of strongly shaded tiles is a narrow peak: the
   polarity can be misjudged), each heading read again with the other polarity;
4. when every reading failed, each one refused for a line unlike the others in width or
   contrast (:data:`UNLIKE_CHECKS`) again without the one line of a family most unlike that
   family's others (:func:`~tileviz.vision.robust.fit.leave_out_unlike`: a panel's seam or a
   cable along a joint), in a family where ``lines.unlike_others`` lines or more remain;
5. when every reading failed, each one whose lines failed only for a shoulder again with its
   shouldered lines bounded by their band at a quarter of its depth
   (:func:`~tileviz.vision.robust.fit.part_spreads`): a shoulder-free reading, and one
   without a line left out, is preferred.

A pass stops at the first reading whose lines pass the line checks: its lattice, bound and
foreign-edge checks decide the pass (a reading of the imposed polarity also
``foreign_line.polarity``, :func:`decide`); when that is the first reading and its lines miss the
lattice (:data:`OFF_LATTICE_REASONS`), the view is read once more at the other polarity, which
decides the pass when accepted (else the first reading's refusal stands). The result is the
first pass's unless the second accepts the view. When no reading of a pass passes, the pass
refuses with its first reading's reason and shows the lines of its last heading read
(:func:`conclude`).

Adding a reading: a field of :class:`~tileviz.vision.decision.Reading` that
:class:`~tileviz.vision.robust.state.ReadingState` (or a step) acts on, and one line in
:data:`STAGES` (a stage: its kind, the refusals of the first reading it answers, the
function that yields its readings), e.g. ``Stage("checker", RETRY_REASONS,
checker_readings)``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from types import MappingProxyType

import numpy as np

from tileviz.vision.decision import CheckResult, Reading
from tileviz.vision.geometry import QUARTER, family_normals
from tileviz.vision.robust.checks import (
    ANGLE_STRAIGHT,
    CROSSINGS,
    CROSSINGS_READ,
    CROSSINGS_UNREAD,
    FOREIGN_CONTRAST,
    FOREIGN_POLARITY,
    FOREIGN_SHOULDER,
    FOREIGN_WIDTH,
    Record,
    Refusal,
)
from tileviz.vision.robust.fit import check_lines, drop_stray_part, fit_tilt, leave_out_unlike
from tileviz.vision.robust.foreign import foreign_edges
from tileviz.vision.robust.heading import (
    lattice_headings,
    sharpened_headings,
    smoothed_headings,
)
from tileviz.vision.robust.lattice import lattice_offsets
from tileviz.vision.robust.periodic import on_lattice
from tileviz.vision.robust.profiles import measure, select_lines
from tileviz.vision.robust.state import Line, ReadingState, View

__all__ = ["OFF_LATTICE_REASONS", "RETRY_REASONS", "STAGES", "UNSEEN_REASONS", "Outcome",
           "Stage", "decide", "plan", "read", "read_lines"]

RETRY_REASONS = frozenset(
    {"no lines", "low contrast", "one family", "blurred", "step edge", "inconsistent angle",
     "foreign line"}
)
"""Refusals of the first heading's line checks after which other headings are read."""

UNSEEN_REASONS = frozenset({"no lines", "low contrast", "one family"})
"""Refusals of the first heading's line checks that say its lines were not seen (none, only
faint ones, one family), unlike a foreign line or a bent one: after them the sharpest headings
near those read are read, and then, every heading having failed, each heading again with the
grout's other polarity (reading dark grout as lighter, or the reverse, finds no line, or only
shallow ones)."""

OFF_LATTICE_REASONS = frozenset({"inconsistent spacing"})
"""Refusals of a first reading whose lines passed the line checks but do not make one lattice
(a predicted line not seen, a line off the spacing): the view is then read once more at the
grout's other polarity. The polarity is decided from the profiles' narrow peaks and dips, and
joints filled with a material of the other polarity (light dirt in a mosaic's dark joints)
make strong narrow peaks of their own: the lines read are then those joints, not the grout."""


@dataclass(frozen=True, eq=False)
class Outcome:
    """What reading a view for one :class:`~tileviz.vision.decision.Reading` gave: the
    ``checks`` run in order, the ``refusal`` (the failed check's result, None when every check
    passed) and its ``reason`` (``ok`` when none failed); whether the lines passed the line
    checks (``lines_passed``: the pass stops at this reading), whether some fit found them not
    straight (``not_straight``), the polarity read (``inverted``: lighter grout), its
    ``details`` and stage ``timings`` (ms). For the result and the stage images: the heading
    after the fit ``y3`` (rad; None when no line was measured), the warp ``centre``, each
    family's line positions on the warp (``positions``, px), each family's lattice offset at
    the view's centre (``offsets``, px, as ``s`` in
    :func:`~tileviz.vision.robust.lattice.lattice_offsets`: set once measured, before the
    spacing checks, None before), the observation ``y`` (when the lattice was read), the
    ``warped`` view, the Canny ``edges``, the ``free_edges`` off the lattice and the
    ``foreign`` straight edges among them (rows x1, y1, x2, y2, px)."""

    reading: Reading
    checks: tuple[CheckResult, ...]
    refusal: CheckResult | None
    reason: str
    lines_passed: bool
    not_straight: bool
    inverted: bool
    details: Mapping[str, float]
    timings: Mapping[str, float]
    y3: float | None
    centre: tuple[float, float]
    positions: tuple[tuple[float, ...], tuple[float, ...]]
    offsets: tuple[float, float] | None
    y: tuple[float, float, float] | None
    warped: np.ndarray | None
    edges: np.ndarray | None
    free_edges: np.ndarray | None
    foreign: np.ndarray


def read(view: View, reading: Reading) -> Outcome:
    """Read ``view`` for ``reading``: measure the lines (:func:`read_lines`), run the line
    checks and, when they pass, the lattice and bound checks and the foreign-edge check; the
    outcome. Reads nothing but the view and the reading; changes neither."""
    run = ReadingState(view, reading)
    refusal: Refusal | None = None
    lines_passed = False
    t = time.perf_counter()
    try:
        lines, y3, t = read_lines(run, reading.heading, t)
        check_lines(run, lines)
        lines_passed = True
        t = run.lap("checks", t)
        lattice_offsets(run, lines, y3)
        t = run.lap("lattice", t)
        foreign_edges(run)
        run.lap("foreign", t)
    except Refusal as r:
        refusal = r
    return Outcome(
        reading=reading, checks=tuple(run.record.results),
        refusal=None if refusal is None else refusal.result,
        reason="ok" if refusal is None else refusal.reason, lines_passed=lines_passed,
        not_straight=run.not_straight, inverted=run.inverted,
        details=MappingProxyType(run.details), timings=MappingProxyType(run.tm), y3=run.y3,
        centre=run.centre,
        positions=(tuple(ln.pos for ln in run.lines[0]), tuple(ln.pos for ln in run.lines[1])),
        offsets=run.offsets, y=run.y, warped=run.warped, edges=run.edges, free_edges=run.free_edges,
        foreign=run.foreign)


def read_lines(run: ReadingState, y3: float, t: float) -> tuple[list[list[Line]], float, float]:
    """Measure and select the lines at heading ``y3``, fit the residual tilt, and measure again
    (up to ``heading.max_warps`` warps) while the correction exceeds ``heading.refine_tilt``;
    the lines, the corrected heading and the time (perf_counter) after the "profiles" lap. A
    band wider than the measurement window is measured again with a wider one (for one family
    alone only at a settled heading, :func:`_settled`, or at the last warp). Sets ``run.lines``,
    ``run.y3`` and ``run.not_straight``."""
    last = run.st.heading.max_warps - 1
    for attempt in range(last + 1):
        lines = on_lattice(run, select_lines(run, measure(run, y3, attempt)))
        # a window too narrow for the grout (a wide band): measure again with a wider one
        width = run.details.get("width", math.nan) if lines[0] or lines[1] else math.nan
        if math.isfinite(run.unmeasured_width):
            # the deepest dip was too wide for the window: the lines kept are shallower
            # ones (a texture's), the grout band is measured with a window fitting it
            width = max(width, run.unmeasured_width) if math.isfinite(width) else width
        need = _fitting(run, width) if math.isfinite(width) else run.widest
        if need > run.window:
            run.window = need
            lines = on_lattice(run, select_lines(run, measure(run, y3, attempt + 1)))
        # a family whose strong bands the window could not measure (its grout wider than the
        # other family's), at a heading needing no further warp: that family alone is
        # measured again in a window fitting them
        wider = tuple(_fitting(run, w) for w in run.unmeasured_family)
        if any(r > run.window_of(k) for k, r in enumerate(wider)) and (
                attempt == last or _settled(run, lines)):
            run.family_window = (max(run.family_window[0], wider[0]),
                                 max(run.family_window[1], wider[1]))
            lines = on_lattice(run, select_lines(run, measure(run, y3, attempt + 1)))
        if run.reading.unlike:
            leave_out_unlike(run, lines)
        tilt = fit_tilt(run, lines)
        if run.details["straightness_px"] > ANGLE_STRAIGHT.limit(run):
            run.not_straight = True
            if run.drop_stray and drop_stray_part(run, lines, tilt):
                tilt = fit_tilt(run, lines)  # without the part that kept them from straight
        t = run.lap("profiles", t)
        y3 += tilt
        if abs(tilt) <= run.st.heading.refine_tilt or attempt == last:
            break
    run.lines = lines
    run.y3 = y3
    return lines, y3, t


def _settled(run: ReadingState, lines: list[list[Line]]) -> bool:
    """Whether the heading the lines were measured at needs no further warp (the tilt their
    fit finds is within ``heading.refine_tilt``): a long line measured at a heading off by
    eps spreads over its length x eps across its profile, so a band reads wide for the window
    only once the heading is settled. The fit's results on ``run`` are those of a provisional
    fit, which the reading's own fit replaces."""
    kept = [list(f) for f in lines]
    if run.reading.unlike:
        leave_out_unlike(run, kept)
    return abs(fit_tilt(run, kept)) <= run.st.heading.refine_tilt


def _fitting(run: ReadingState, width: float) -> int:
    """The half-window (samples) that measures a band of half-depth ``width`` px (0 for
    NaN), at most the widest."""
    if not math.isfinite(width):
        return 0
    pst = run.st.profiles
    return min(int(math.ceil(pst.window_per_width * width + pst.window_margin)), run.widest)


class Headings:
    """The view's other headings, each computed once when first asked for (both passes read
    them): :func:`~tileviz.vision.robust.heading.lattice_headings` and
    :func:`~tileviz.vision.robust.heading.smoothed_headings`; their time is added to
    ``timings["heading"]`` (ms)."""

    def __init__(self, view: View, timings: dict[str, float]) -> None:
        self.view = view
        self.tm = timings
        self._lattice: list[float] | None = None
        self._smoothed: list[tuple[float, float]] | None = None
        self._sharpened: list[float] | None = None

    def _timed(self, fn: Callable[[View], list]) -> list:
        t = time.perf_counter()
        out = fn(self.view)
        self.tm["heading"] = self.tm.get("heading", 0.0) + (time.perf_counter() - t) * 1e3
        return out

    def lattice(self) -> list[float]:
        if self._lattice is None:
            self._lattice = self._timed(lattice_headings)
        return self._lattice

    def smoothed(self) -> list[tuple[float, float]]:
        if self._smoothed is None:
            self._smoothed = self._timed(smoothed_headings)
        return self._smoothed

    def sharpened(self, around: list[float]) -> list[float]:
        """:func:`~tileviz.vision.robust.heading.sharpened_headings` near ``around``, computed
        on the first call (both passes read the same headings first)."""
        if self._sharpened is None:
            self._sharpened = self._timed(lambda v: sharpened_headings(v, around))
        return self._sharpened


def lattice_readings(first: Reading, tried: Sequence[Outcome], headings: Headings
                     ) -> Iterator[Reading]:
    """The headings at which the view repeats with the tile period (trend-blind first)."""
    for y, source in zip(headings.lattice(), ("lattice heading (trend-blind)",
                                              "lattice heading"), strict=True):
        yield replace(first, heading=y, source=source, kind="heading")


def smoothed_readings(first: Reading, tried: Sequence[Outcome], headings: Headings
                      ) -> Iterator[Reading]:
    """The gradient votes on the view smoothed by each ``heading.smoothing`` std."""
    for sigma, y in headings.smoothed():
        yield replace(first, heading=y, source=f"smoothed heading ({sigma:g} px)",
                      kind="heading")


def sharpened_readings(first: Reading, tried: Sequence[Outcome], headings: Headings
                       ) -> Iterator[Reading]:
    """The headings near those read where the lines are sharpest (best first)."""
    for y in headings.sharpened([o.reading.heading for o in tried]):
        yield replace(first, heading=y, source="sharpened heading", kind="heading")


def polarity_readings(first: Reading, tried: Sequence[Outcome], headings: Headings
                      ) -> Iterator[Reading]:
    """Each heading read so far in this pass, again with the other polarity of the grout."""
    for o in tried:
        yield replace(o.reading, polarity="dark" if o.inverted else "light",
                      kind="polarity")


def shoulder_readings(first: Reading, tried: Sequence[Outcome], headings: Headings
                      ) -> Iterator[Reading]:
    """Each reading of this pass whose lines failed only for a shoulder
    (``foreign_line.shoulder``), again with the shouldered lines bounded by their band at a
    quarter of its depth (:func:`~tileviz.vision.robust.fit.part_spreads`)."""
    for o in tried:
        if o.refusal is not None and o.refusal.check == FOREIGN_SHOULDER.id:
            yield replace(o.reading, shoulder=True, kind="shoulder")


UNLIKE_CHECKS = frozenset(c.id for c in (FOREIGN_WIDTH, FOREIGN_CONTRAST, CROSSINGS_READ,
                                         CROSSINGS, CROSSINGS_UNREAD))
"""The checks that find a line unlike the others of the view in width or contrast."""


def unlike_readings(first: Reading, tried: Sequence[Outcome], headings: Headings
                    ) -> Iterator[Reading]:
    """Each reading of this pass refused for a line unlike the others (:data:`UNLIKE_CHECKS`),
    again without the line of a family most unlike the family's others
    (:func:`~tileviz.vision.robust.fit.leave_out_unlike`)."""
    for o in tried:
        if o.refusal is not None and o.refusal.check in UNLIKE_CHECKS and not o.reading.unlike:
            yield replace(o.reading, unlike=True, kind="unlike")


@dataclass(frozen=True)
class Stage:
    """One stage of the plan after the first heading: ``kind`` (of its readings), the refusals
    of the first reading it answers (``after``) and ``readings(first, tried, headings)``: its
    readings, given the first reading, the outcomes of this pass so far and the view's other
    headings."""

    kind: str
    after: frozenset[str]
    readings: Callable[[Reading, Sequence[Outcome], Headings], Iterator[Reading]]


STAGES: tuple[Stage, ...] = (
    Stage("heading", RETRY_REASONS, lattice_readings),
    Stage("heading", RETRY_REASONS, smoothed_readings),
    Stage("heading", UNSEEN_REASONS, sharpened_readings),
    Stage("polarity", UNSEEN_REASONS, polarity_readings),
    Stage("unlike", RETRY_REASONS, unlike_readings),
    Stage("shoulder", RETRY_REASONS, shoulder_readings),
)
"""The stages of a pass after the first heading, in order (module docstring)."""


def same(a: Reading, b: Reading, tolerance: float) -> bool:
    """Whether two readings read alike: the same polarity, stray part and shoulders, headings
    within ``tolerance`` (rad, modulo pi/2)."""
    return (a.polarity == b.polarity and a.stray == b.stray and a.shoulder == b.shoulder
            and a.unlike == b.unlike
            and abs(math.remainder(a.heading - b.heading, QUARTER)) < tolerance)


def plan(view: View, done: Sequence[Outcome], timings: dict[str, float]) -> Iterator[Reading]:
    """The readings to try, one after the other (module docstring); ``done`` holds the
    outcome of every reading yielded so far (the caller appends each before asking for the
    next)."""
    headings = Headings(view, timings)
    tolerance = view.st.heading.same_heading
    for stray in (False, True):
        if stray and not (done[-1].reason != "ok" and any(o.not_straight for o in done)):
            return
        start = len(done)
        first = Reading(view.heading, "first heading", stray=stray)
        yield first
        if done[start].lines_passed:
            if done[start].reason in OFF_LATTICE_REASONS:
                yield replace(first, polarity="dark" if done[start].inverted else "light",
                              kind="polarity")
            continue
        for stage in STAGES:
            if done[start].reason not in stage.after:
                continue
            for reading in stage.readings(first, done[start:], headings):
                if any(same(reading, o.reading, tolerance) for o in done[start:]):
                    continue
                yield reading
                if done[-1].lines_passed:
                    break
            if done[-1].lines_passed:
                break


def _off_lattice(view: View, first: Outcome, out: Outcome) -> float:
    """The farthest of ``first``'s lines from ``out``'s lattice (px): each line's signed offset
    at the view's centre (``s = -(pos - centre)`` on its warp) against the offset of ``out``'s
    family whose normal is nearest its own (sign by the normals' product), modulo the period.
    Infinite when ``first`` kept no line or a line's position is not finite (its deepest dip
    is then on no line to compare), when a line's normal is farther than ``out``'s heading
    bound from both families (it is on neither), or when ``out`` read no lattice."""
    if first.y3 is None or out.y3 is None or out.offsets is None:
        return math.inf
    if not (first.positions[0] or first.positions[1]):
        return math.inf
    theirs = family_normals(out.y3)
    far = 0.0
    for j, n in enumerate(family_normals(first.y3)):
        if not first.positions[j]:
            continue
        dots = [n[0] * m[0] + n[1] * m[1] for m in theirs]
        k = 0 if abs(dots[0]) >= abs(dots[1]) else 1
        if math.acos(min(abs(dots[k]), 1.0)) > out.details["bound_rad"]:
            return math.inf
        sign = 1.0 if dots[k] > 0.0 else -1.0
        centre = first.centre[1] if j == 0 else first.centre[0]
        for pos in first.positions[j]:
            if not math.isfinite(pos):
                return math.inf
            far = max(far, abs(math.remainder(sign * (centre - pos) - out.offsets[k], view.lp)))
    return far


def _deeper_than(view: View, first: Outcome, out: Outcome) -> Outcome:
    """``out`` (a reading with the grout's polarity imposed, accepted) checked against the
    pass's first reading, at the polarity the profiles decided, when that one saw deeper lines
    (``foreign_line.polarity``, final; unchecked when it measured none or shallower ones): the
    deeper lines must agree with ``out``'s lattice (:func:`_off_lattice`): parallel to a family
    within ``out``'s heading bound and, at the view's centre, within ``out``'s position bound
    less the lattice tolerance (the most a grout line may lie off the lattice). On it they are
    the same joints, of the other polarity along part of them (light dirt in a mosaic's dark
    joints), and ``out`` stands on its own checks as any reading does; off it they are the
    grout (its reading failed for a family not seen, blurred or covered), and ``out``'s lines
    are something beside it (a bevel's shadow along a light ridge). The check compares the two
    readings' estimates, not their errors: it refuses what contradicts ``out``, it does not
    prove ``out`` right."""
    decided, own = first.details.get("depth", math.nan), out.details.get("depth", math.nan)
    if not (math.isfinite(decided) and own > 0.0) or decided <= own:
        return out  # no line measured at the decided polarity, or shallower ones
    record = Record()
    passed = record.check(FOREIGN_POLARITY, view, _off_lattice(view, first, out),
                          out.details["bound_px"])
    checks = (*out.checks, *record.results)
    if passed:
        return replace(out, checks=checks)
    return replace(out, checks=checks, refusal=record.results[-1], reason=FOREIGN_POLARITY.reason)


def decide(view: View, timings: dict[str, float]) -> list[Outcome]:
    """Every reading of :func:`plan` read in turn (:func:`read`): their outcomes, in order;
    a reading of the imposed polarity accepted after a first reading that saw its lines in part
    (:data:`UNSEEN_REASONS`) is checked against it (:func:`_deeper_than`).
    The readings' stage times are added to ``timings`` (ms)."""
    done: list[Outcome] = []
    first: Outcome | None = None
    for reading in plan(view, done, timings):
        out = read(view, reading)
        if reading.kind == "first":
            first = out
        elif (reading.polarity != "auto" and out.reason == "ok" and first is not None
              and first.reason in UNSEEN_REASONS):
            out = _deeper_than(view, first, out)
        done.append(out)
        for k, v in out.timings.items():
            timings[k] = timings.get(k, 0.0) + v
    return done
