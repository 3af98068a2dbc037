"""How an extractor decided on one view, as immutable records a person can follow: every check
run (:class:`CheckResult`: id, measured value, limit, passed), the candidate readings tried in
order (:class:`Reading`, :class:`Tried`) and the refusal (:class:`Decision`), with a text
table (:func:`explain_lines`, ``python -m tileviz extract --explain``), a Markdown table
(:func:`explain_markdown`, the demo's "Camera and stages" panel) and a JSON-able form
(:meth:`Decision.as_dict`, ``--json``).

The robust extractor fills them in (:mod:`tileviz.vision.robust`; its check ids and their
settings are listed in :mod:`tileviz.vision.robust.checks`); the faithful extractor gives
none. This module imports neither numba nor OpenCV.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

__all__ = ["CheckResult", "Decision", "Reading", "Tried", "explain_lines", "explain_markdown",
           "number", "summary"]


class CheckResult(NamedTuple):
    """One check run: its ``check`` id (dotted, e.g. ``foreign_line.beside``), the measured
    ``value``, the ``limit`` it was compared with (``relation``: how the value must compare to
    pass, e.g. ``<=``), whether it ``passed``, and ``subject`` (which line family, for a check
    run per family; else empty)."""

    check: str
    value: float
    limit: float
    relation: str
    passed: bool
    subject: str = ""


@dataclass(frozen=True)
class Reading:
    """One candidate reading of a view by the robust extractor: the ``heading`` (rad, modulo
    pi/2) its lines are measured at first, ``source`` (how that heading was found: the
    gradient votes, the view's periodicity, the votes on a smoothed view), ``polarity``
    (``auto``: the grout's polarity decided from the profiles; ``dark`` / ``light``: imposed),
    ``stray`` (the one part that alone keeps the lines from straight is left out),
    ``shoulder`` (a line with a shoulder in every part is bounded by its band at a quarter of
    its depth instead of refused), ``unlike`` (the one line most unlike the others of its
    family in contrast and width is left out) and ``kind`` (the stage of the plan it belongs
    to: ``first``, ``heading``, ``polarity``, ``shoulder``, ``unlike``)."""

    heading: float
    source: str
    polarity: str = "auto"
    stray: bool = False
    shoulder: bool = False
    unlike: bool = False
    kind: str = "first"

    def label(self) -> str:
        """One line naming the reading (heading in degrees)."""
        out = f"{self.source} {math.degrees(self.heading):.3f} deg"
        if self.polarity != "auto":
            out += f", {self.polarity} grout imposed"
        if self.stray:
            out += ", without the stray part"
        if self.shoulder:
            out += ", shoulders bounded"
        if self.unlike:
            out += ", without the unlike line"
        return out


@dataclass(frozen=True)
class Tried:
    """A reading tried and its outcome: every check it ran (in order) and ``reason``
    (``ok`` when it passed them all, else the reason of the check that failed)."""

    reading: Reading
    checks: tuple[CheckResult, ...]
    reason: str


@dataclass(frozen=True)
class Decision:
    """The decision path of one view: the checks on the whole view (``view_checks``, before
    any reading), the ``readings`` tried in order, which of them the result shows (``shown``:
    its lines are the result's segments; None when none was read), the final ``reason`` and
    the check that refused the view (``refusal``, None when accepted) in reading
    ``refused_in`` (None: a check on the whole view). ``image``: which image of the view the
    readings read (the luma, a colour projection, an edge image; empty: not said), and
    ``images``: every image of the view read, in order, each with its outcome in one line
    (empty: not said)."""

    view_checks: tuple[CheckResult, ...]
    readings: tuple[Tried, ...]
    shown: int | None
    reason: str
    refusal: CheckResult | None
    refused_in: int | None
    image: str = ""
    images: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, object]:
        """JSON-able: ``reason``, ``image``, ``images``, ``refusal`` ({check, value, limit,
        relation, subject, reading} or null), ``view_checks``, ``readings`` (each: heading in
        rad, source, polarity, stray, shoulder, reason, checks) and ``shown``; a value or limit
        that is not finite is null."""
        ref = None
        if self.refusal is not None:
            ref = {**_check_dict(self.refusal), "reading": self.refused_in}
            del ref["passed"]
        return {
            "reason": self.reason,
            "image": self.image,
            "images": list(self.images),
            "refusal": ref,
            "view_checks": [_check_dict(c) for c in self.view_checks],
            "readings": [
                {"heading": t.reading.heading, "source": t.reading.source,
                 "polarity": t.reading.polarity, "stray": t.reading.stray,
                 "shoulder": t.reading.shoulder, "unlike": t.reading.unlike,
                 "reason": t.reason,
                 "checks": [_check_dict(c) for c in t.checks]}
                for t in self.readings],
            "shown": self.shown,
        }


def _finite(v: float) -> float | None:
    return v if math.isfinite(v) else None


def _check_dict(c: CheckResult) -> dict[str, object]:
    return {"check": c.check, "value": _finite(c.value), "limit": _finite(c.limit),
            "relation": c.relation, "passed": c.passed, "subject": c.subject}


def number(v: float) -> str:
    """``v`` for a table: 4 significant digits, integers as integers, inf and nan by name."""
    if not math.isfinite(v):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if v == int(v) and abs(v) < 1e6:
        return str(int(v))
    return f"{v:.4g}"


def _outcome(c: CheckResult, refusal: CheckResult | None) -> str:
    if c.passed:
        return "pass"
    return "FAIL: refused" if c == refusal else "fail"


def _rows(decision: Decision) -> list[tuple[str, list[CheckResult], CheckResult | None]]:
    """(heading, checks, the refusing check when in them) for the view and each reading."""
    ref = decision.refusal
    out = [("view", list(decision.view_checks),
            ref if decision.refused_in is None else None)]
    for i, t in enumerate(decision.readings):
        mark = " (shown)" if i == decision.shown else ""
        out.append((f"reading {i + 1}: {t.reading.label()} -> {t.reason}{mark}", list(t.checks),
                    ref if decision.refused_in == i else None))
    return out


def _image_lines(decision: Decision) -> list[str]:
    """Which image of the view the readings below read, and, when several were read, each of
    them with its outcome (indented lines; none when the image is not said)."""
    if not decision.image:
        return []
    out = [f"  the readings below read the {decision.image}" if decision.readings
           else f"  the image read: the {decision.image}"]
    if len(decision.images) > 1:
        out.append("  images of the view read, in order:")
        out += [f"    {line}" for line in decision.images]
    return out


def summary(decision: Decision) -> str:
    """One line: accepted, or which check refused the view with its value and limit."""
    ref = decision.refusal
    if ref is None:
        return f"accepted ({len(decision.readings)} reading(s) tried)"
    where = "the view" if decision.refused_in is None else f"reading {decision.refused_in + 1}"
    subject = f" ({ref.subject})" if ref.subject else ""
    return (f"refused ({decision.reason}) by {ref.check}{subject} in {where}: value "
            f"{number(ref.value)}, must be {ref.relation} {number(ref.limit)}")


def explain_lines(decision: Decision, what: Mapping[str, str] | None = None) -> list[str]:
    """The decision path as text lines: a summary, then per block (the view, each reading)
    one row per check: id, value, relation and limit, pass / fail, and, with ``what`` (check
    id -> what its value is, with its unit), that."""
    what = what or {}
    out = [summary(decision), *_image_lines(decision),
           f"    {'check':<34} {'value':>10}  limit{'':<8} {'result':<13}"
           + ("  value is" if what else "")]
    for head, checks, ref in _rows(decision):
        out.append(f"  {head}")
        for c in checks:
            name = c.check + (f" ({c.subject})" if c.subject else "")
            row = (f"    {name:<34} {number(c.value):>10}  {c.relation:>2} "
                   f"{number(c.limit):<10} {_outcome(c, ref):<13}")
            out.append((row + "  " + what[c.check]) if c.check in what else row.rstrip())
    return out


def explain_markdown(decision: Decision) -> str:
    """The decision path as Markdown: the summary, then one table per block (the view, each
    reading) with the check, value, limit and result; the refusing check in bold."""
    parts = [f"**{summary(decision)}**"]
    if decision.image:
        parts.append("\n".join(line.strip() + "  " for line in _image_lines(decision)))
    for head, checks, ref in _rows(decision):
        if not checks:
            continue
        rows = [f"*{head}*", "", "| check | value | limit | result |",
                "| --- | ---: | ---: | --- |"]
        for c in checks:
            name = c.check + (f" ({c.subject})" if c.subject else "")
            cells = [name, number(c.value), f"{c.relation} {number(c.limit)}", _outcome(c, ref)]
            if c == ref:
                cells = [f"**{x}**" for x in cells]
            rows.append("| " + " | ".join(cells) + " |")
        parts.append("\n".join(rows))
    return "\n\n".join(parts)
