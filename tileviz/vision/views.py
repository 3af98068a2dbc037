"""The images of a view the robust extractor reads, in turn (docs/vision.md, "Colour"): the
luma, then, while it shows no grout, the colour projections; on a floor declared ``checker``,
their edge images instead; on a floor not declared so whose grout reading was refused, their
edge images again, a reading of them kept only when its lines are a checkerboard's tile edges
(:func:`tileviz.vision.robust.checker.tile_edges`); last, when the luma's reading did not show
the lattice or saw a second dip beside a line, the luma's joints image (joints of either
polarity, or of both along them).

Importing this module loads neither numba nor the robust extractor: they are imported on the
first reading (:func:`read_robust`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from functools import cache

import numpy as np

from tileviz.config import CameraConfig, FloorModel, VisionConfig
from tileviz.types import Observation, Pose
from tileviz.vision.colour import (
    PROJECTIONS,
    RETRY_REASONS,
    SAME_AS_LUMA,
    correlation,
    edges_and_strength,
    joints_image,
)
from tileviz.vision.decision import CheckResult, summary
from tileviz.vision.geometry import family_normals, observation_error, wrap_quarter
from tileviz.vision.result import VisionResult

__all__ = ["VIEW_REASONS", "read_robust"]

VIEW_REASONS = frozenset({"constant image", "glare"})
"""Refusals of a whole view, before any line is read: no checkerboard is looked for."""

FIRST_LINES = "first.lines"
"""The check that a reading accepted on another image explains the first reading's lines
(:func:`_explains_first`); its refusal is final."""

VIEW_CHECKS_WHAT = {
    FIRST_LINES: "worst line of the first reading off this lattice / its limit",
    "checker.pieces": "pieces of the lines measured",
    "checker.steps": "pieces that are no one step between two tiles",
    "checker.band": "farthest steepest point or back slope from a line (px)",
    "checker.sides": "least swap of the tiles' sides at a crossing / least step",
}
"""What the value of each check run here is (``extract --explain``), with its unit."""

LINES_PASSED = frozenset({"inconsistent spacing", "too few segments", "imprecise"})
"""Refusals of a reading whose lines passed the line checks (refused by the lattice or the
bound): grout-like lines, which a later reading on another image must explain (``first.lines``)."""

JOINTS = float(len(PROJECTIONS) + 1)
"""The number of the joints image (``details["projection"]``): after the colour projections."""

BESIDE = "foreign_line.beside"
"""The line check after whose refusal in the luma the joints image is read too: a second dip
beside a line. In the joints image the two are one band only when what lies between them
differs from the tiles as well (light dirt between a joint's dark edges); a cable beside the
grout, the tiles between them, stays two bands there, refused again."""

Reader = Callable[[np.ndarray, dict[str, float], FloorModel, float], VisionResult]
"""Reads an image of a view (the robust extractor): the image, its stage timings (ms), the
floor declared and the image's number (``details["projection"]``)."""

Candidate = tuple[float, Callable[[], np.ndarray]]
"""A view to read: its number (``details["projection"]``) and how to make it (HxW uint8)."""


def read_robust(gray: np.ndarray, image: np.ndarray, camera: CameraConfig, tile_size: float,
                vision: VisionConfig, keep_stages: bool, timings: dict[str, float],
                floor: FloorModel) -> VisionResult:
    """The robust extractor on the luma ``gray``, then, while it shows no grout
    (:data:`~tileviz.vision.colour.RETRY_REASONS`), on the colour projections of ``image``
    (RGB only); on a floor declared ``checker`` (no grout: its lines are the edges between
    the tiles), on the edge images of the luma and of the colour projections instead. On a
    grout floor whose reading was refused for its lines (not :data:`VIEW_REASONS`), the edge
    images are read too, and one accepted only when every piece of its lines is one step
    between two tiles' levels (a checkerboard not declared: ``details["checker"]``, the pieces
    measured); last, the joints image of the luma
    (:func:`~tileviz.vision.colour.joints_image`: joints of either polarity, or of both along
    them), when the luma's reading did not show the lattice
    (:data:`~tileviz.vision.colour.RETRY_REASONS`) or saw a second dip beside a line
    (:data:`BESIDE`: a refusal for anything else the view shows, a foreign line, a step edge,
    blur or glare, is final). The first accepted reading is the result
    (its ``details["projection"]``: 0 the luma, 1.. the colour projections in order, then the
    joints image, -1 the luma's edge image, -2.. the projections' edge images in order);
    otherwise the first reading's refusal, or a later image's refused by ``first.lines``."""
    from tileviz.vision.robust import extract_robust
    from tileviz.vision.robust.statistics import noise_sigma

    luma_noise: list[float] = []  # measured once: by the luma's reading, or here

    def noise_floor(number: float) -> float:
        # a colour projection cancels the noise its channels share, not the camera's: its
        # contrast limit assumes the luma's noise at least (a dip is trusted in no image of the
        # view that the camera's noise explains)
        if number <= 0.0:
            return 0.0
        if not luma_noise:
            luma_noise.append(noise_sigma(gray))
        return luma_noise[0]

    def read(view: np.ndarray, tm: dict[str, float], as_floor: FloorModel,
             number: float) -> VisionResult:
        got = extract_robust(view, camera=camera, tile_size=tile_size, vision=vision,
                             keep_stages=keep_stages, image=image, timings=tm,
                             floor=as_floor, noise_floor=noise_floor(number))
        noise = got.details.get("noise_sigma", math.nan)
        if number == 0.0 and not luma_noise and math.isfinite(noise):
            luma_noise.append(noise)
        return got

    views: list[Candidate] = [(0.0, lambda: gray)]
    if image.ndim == 3:
        # each projection made once, however many readings and checks look at it
        views += [(float(k), cache(lambda p=proj: p(image)))
                  for k, proj in enumerate(PROJECTIONS.values(), start=1)]
    lp = camera.ppm * tile_size
    if floor.kind == "checker":
        source = _edge_sources(views)
        got, first = _first_accepted(
            _edge_images(views, gray), gray, timings, floor, read, camera.ppm, lp,
            lambda number, r: _sides_swap(source[number](), r, lp))
        return got or first
    got, first = _first_accepted(views, gray, timings, floor, read, camera.ppm, lp)
    refusal = first.decision.refusal if first.decision is not None else None
    if got is not None or first.reason in VIEW_REASONS or (
            refusal is not None and refusal.check == FIRST_LINES):
        return got or first
    recognised, tried = _recognise(views, gray, camera.ppm, lp, timings, floor, read)
    before = (first.decision.images if first.decision is not None else ()) + tried
    if recognised is not None or not (first.reason in RETRY_REASONS or (
            refusal is not None and refusal.check == BESIDE)):
        return _with_images(recognised or first, before)
    # the joints image: read as the other images are, after the luma's refusal (``first``)
    got, shown = _first_accepted([(JOINTS, lambda: joints_image(gray, lp))], gray, timings,
                                 floor, read, camera.ppm, lp, earlier=first)
    out = got or shown
    return _with_images(out, before + (out.decision.images if out.decision is not None else ()))


def image_name(number: float) -> str:
    """The image of a view that ``number`` names (``details["projection"]``): 0 the luma,
    1.. the colour projections in order, then the joints image (:data:`JOINTS`), -1 the
    luma's edge image, -2.. the projections'."""
    names = ["luma", *(f"colour projection {name}" for name in PROJECTIONS), "joints image"]
    if number >= 0:
        return names[int(number)]
    return f"edge image of the {names[int(-1 - number)]}"


def _label(number: float, recognising: bool) -> str:
    """The image ``number`` (:func:`image_name`), said to be read as an undeclared
    checkerboard when ``recognising``."""
    return image_name(number) + (", read as an undeclared checkerboard" if recognising else "")


def _outcome(number: float, got: VisionResult, recognising: bool) -> str:
    """One line: the image ``number`` and what reading it gave."""
    name = _label(number, recognising)
    if got.accepted:
        return f"{name}: accepted"
    if got.decision is None:
        return f"{name}: refused ({got.reason})"
    return f"{name}: {summary(got.decision)}"


def _with_images(got: VisionResult, images: tuple[str, ...]) -> VisionResult:
    """``got`` with its decision's list of the view's images read (``Decision.images``)."""
    if got.decision is None:
        return got
    return replace(got, decision=replace(got.decision, images=images))


def _named(got: VisionResult, number: float, recognising: bool) -> VisionResult:
    """``got`` with its decision naming the image ``number`` it read (``Decision.image``)."""
    if got.decision is None:
        return got
    return replace(got, decision=replace(got.decision, image=_label(number, recognising)))


def _first_accepted(candidates: list[Candidate], gray: np.ndarray, timings: dict[str, float],
                    floor: FloorModel,
                    read: Reader,
                    ppm: float, lp: float,
                    accept: Callable[[float, VisionResult], VisionResult] | None = None,
                    recognising: bool = False, earlier: VisionResult | None = None
                    ) -> tuple[VisionResult | None, VisionResult]:
    """The ``candidates`` read in turn while refused for not showing the lattice
    (:data:`~tileviz.vision.colour.RETRY_REASONS`; a projection nearly the luma again,
    :data:`~tileviz.vision.colour.SAME_AS_LUMA`, is skipped): the first accepted (``accept``,
    when given, checks an accepted reading further and may refuse it; after a first reading
    whose lines passed the line checks, :data:`LINES_PASSED`, :func:`_explains_first` too), and
    the refusal to report:
    a later reading's refused by those further checks (final: a foreign line), else the first
    reading's (its timings join ``timings``). ``ppm``: the view's pixels per metre, ``lp`` the
    tile period, px. Each result's decision names the image it read, and both returned list
    every image read with its outcome (``Decision.image``, ``images``; ``recognising``: the
    edge images are read as an undeclared checkerboard). ``earlier``: the refusal of an image
    read before (by another call), which stands as the first reading's."""
    first: VisionResult | None = earlier
    tried: list[str] = []

    def done(got: VisionResult | None, shown: VisionResult) -> tuple[VisionResult | None,
                                                                      VisionResult]:
        lines = tuple(tried)
        return (None if got is None else _with_images(got, lines)), _with_images(shown, lines)

    for number, make in candidates:
        t1 = time.perf_counter()
        view = make()
        if 0.0 < number < JOINTS and abs(correlation(view, gray)) >= SAME_AS_LUMA:
            continue  # a colour projection that is the luma again: nothing new to read
        tm = dict(timings)
        if number != 0.0:
            tm["projection"] = (time.perf_counter() - t1) * 1e3
        got = _named(read(view, tm, floor, number), number, recognising)
        if got.accepted:
            if number != 0.0:
                got = replace(got, details={**got.details, "projection": number})
            if accept is not None:
                got = _named(accept(number, got), number, recognising)
            if got.accepted and first is not None and first.reason in LINES_PASSED:
                got = _explains_first(first, got, gray.shape, ppm, lp, floor)
            tried.append(_outcome(number, got, recognising))
            if got.accepted:
                return done(got, first or got)
            if first is not None:
                timings.update(tm)
                return done(None, got)
        else:
            tried.append(_outcome(number, got, recognising))
        if first is None:
            first = got
            timings.update(tm)
        if got.reason not in RETRY_REASONS:
            break
    assert first is not None
    return done(None, first)


def _edge_images(candidates: list[Candidate], gray: np.ndarray) -> list[Candidate]:
    """The edge images of the ``candidates`` (the luma 0, the projections 1..) that differ
    from the luma ``gray``, numbered -1 - number, strongest edges first
    (:func:`~tileviz.vision.colour.edges_and_strength`; the luma's first among equals)."""
    out = []
    for number, make in candidates:
        view = make()
        if number > 0 and abs(correlation(view, gray)) >= SAME_AS_LUMA:
            continue
        edges, strength = edges_and_strength(view)
        out.append((-strength, -1.0 - number, edges))
    out.sort(key=lambda c: c[0])
    return [(n, lambda e=e: e) for _, n, e in out]  # type: ignore[misc]


def _edge_sources(views: list[Candidate]) -> dict[float, Callable[[], np.ndarray]]:
    """How to make the image each edge image of ``views`` was made from, by the edge
    image's number (-1 - the view's: :func:`_edge_images`)."""
    return {-1.0 - number: make for number, make in views}


def _recognise(views: list[Candidate], gray: np.ndarray, ppm: float, lp: float,
               timings: dict[str, float], floor: FloorModel,
               read: Reader
               ) -> tuple[VisionResult | None, tuple[str, ...]]:
    """A checkerboard the user did not declare: the edge images of ``views`` read as on a
    floor declared ``checker`` (its tolerance kept), a reading accepted only when every piece
    of its lines is one step on the view it was made from, its reach short
    (:func:`~tileviz.vision.robust.checker.tile_edges`; ``ppm`` the view's pixels per metre,
    ``lp`` the tile period, px); the decision then shows the checks ``checker.pieces``,
    ``checker.steps`` and ``checker.band`` (the largest reach, px). The line read may lie off
    the tile edge, or a thin grout's centre, by the reach: the edge image is read again with
    the floor's tolerance widened by it (``details["checker_band"]``, px), and when that
    reading passes with no larger reach, the first is kept, its bounds widened to cover the
    second's (the wider tolerance loosens the checks too). None when none is recognised;
    with the edge images read and their outcomes (``Decision.images``)."""
    from tileviz.vision.robust.checker import tile_edges
    from tileviz.vision.robust.settings import DEFAULT_SETTINGS

    st = DEFAULT_SETTINGS.checker
    source = _edge_sources(views)
    edges = _edge_images(views, gray)
    edge_of = dict(edges)
    as_checker = FloorModel("checker", floor.lattice_tolerance)

    def steps_checked(number: float, got: VisionResult, widest: float) -> tuple[
            VisionResult, float]:
        view = source[number]()
        steps = tile_edges(view, got.segments, got.bags, lp, st)
        checks = (CheckResult("checker.pieces", steps.measured, st.min_pieces, ">=",
                              steps.measured >= st.min_pieces),
                  CheckResult("checker.steps", steps.failed, 0, "<=", steps.failed == 0),
                  CheckResult("checker.band", steps.band, widest, "<=",
                              steps.band <= widest))
        got = replace(got, details={**got.details, "checker": float(steps.measured)})
        got = _with_checks(got, checks)
        return (_sides_swap(view, got, lp) if got.accepted else got), steps.band

    def accept(number: float, got: VisionResult) -> VisionResult:
        got, band = steps_checked(number, got, st.max_band * lp)
        if not got.accepted or band <= 0.0:
            return got
        widened = FloorModel("checker", floor.lattice_tolerance + band / ppm)
        again = read(edge_of[number](), dict(timings), widened, number)
        if not again.accepted:
            return again
        again = steps_checked(number, again, band)[0]
        if not again.accepted or got.observation is None or again.observation is None:
            return again
        # the first reading passed the checks at the declared tolerance: keep it, its bound
        # widened to cover the second's (a looser tolerance loosens the checks as well)
        obs = _covering(got.observation, again.observation, lp / ppm)
        return replace(got, observation=obs, details={**got.details, "checker_band": band})

    got, shown = _first_accepted(edges, gray, dict(timings), as_checker, read, ppm, lp, accept,
                                 recognising=True)
    return got, (shown.decision.images if shown.decision is not None else ())


def _covering(first: Observation, other: Observation, tile_size: float) -> Observation:
    """``first`` with its bounds widened to cover ``other``'s (an observation of the same
    view): the truth within ``other``'s bounds of ``other`` is within the returned bounds of
    ``first``. ``other`` is compared in the quarter turn of the lattice nearest ``first``
    (:func:`~tileviz.vision.geometry.observation_error`, ``first`` as the truth); metres and
    radians."""
    e1, e2, e3 = observation_error(other, Pose(first.y1, first.y2, first.y3), tile_size,
                                   (0.0, 0.0))
    head, pos = abs(e3), max(abs(e1), abs(e2))
    return replace(first, position_error=max(first.position_error, other.position_error + pos),
                   heading_error=max(first.heading_error, other.heading_error + head))


def _sides_swap(view: np.ndarray, got: VisionResult, lp: float) -> VisionResult:
    """``got``, an accepted reading of the edge image of ``view`` (HxW uint8) on a
    checkerboard (``lp`` the tile period, px), checked by ``checker.sides``: at each crossing
    of a line read, the tiles on both its sides swap shades
    (:func:`~tileviz.vision.robust.checker.sides_alternate`: the smallest change of a side the
    way that swaps them, over the least step between two tiles; at least 1, inf when no
    crossing is measured; ``details["checker_sides"]``); refused (``foreign line``) when it
    fails: a line with one side unchanged is the edge of something lying on the floor."""
    from tileviz.vision.robust.checker import sides_alternate
    from tileviz.vision.robust.settings import DEFAULT_SETTINGS

    st = DEFAULT_SETTINGS.checker
    _, swap = sides_alternate(view, got.segments, got.bags, lp, st)
    check = CheckResult("checker.sides", swap, 1.0, ">=", swap >= 1.0)
    got = replace(got, details={**got.details, "checker_sides": swap})
    return _with_checks(got, (check,))


def _explains_first(first: VisionResult, got: VisionResult, shape: tuple[int, ...],
                    ppm: float, lp: float, floor: FloorModel) -> VisionResult:
    """``got``, a reading accepted on another image of the view (``shape``: its rows and
    columns; ``ppm`` its pixels per metre, ``lp`` the tile period, px) after the ``first`` was
    refused with its lines past the line checks (:data:`LINES_PASSED`: a line the lattice
    predicts not seen, one off the lattice, too little of them, or too wide a bound), checked
    by ``first.lines``: every line the first reading
    measured lies on the lattice ``got`` reads. Were it a grout line, it would lie within the
    largest bound a view may declare (the limits of ``got``'s checks ``bound.position`` and
    ``bound.heading``) of the true lattice, which lies within ``got``'s own bound of ``got``'s:
    a line farther off in direction, or in position at its midpoint in view (plus its distance
    from the view's centre along the line times both heading bounds, and twice the floor's
    lattice tolerance), shows something the reading does not explain, an edge read as the
    lattice in its place (the edge of a box on a checkerboard whose colour projection hides the
    tiles' edges). Value: the largest ratio of a line's discrepancy to its limit (0 without
    lines); refused (``foreign line``) above 1. Pixel frame as
    :class:`~tileviz.vision.result.VisionResult`'s."""
    obs, decision = got.observation, got.decision
    assert obs is not None and decision is not None and decision.shown is not None
    limits = {c.check: c.limit for c in decision.readings[decision.shown].checks}
    head = obs.heading_error + float(limits["bound.heading"])
    pos = (obs.position_error * ppm + float(limits["bound.position"])
           + 2.0 * floor.lattice_tolerance * ppm)
    normals = family_normals(obs.y3)
    cx, cy = (shape[1] - 1) / 2.0, (shape[0] - 1) / 2.0
    worst = 0.0
    for (x1, y1, x2, y2), angle, bag in zip(first.segments.tolist(), first.angles.tolist(),
                                             first.bags.tolist(), strict=True):
        if bag == 0:
            continue
        turn = wrap_quarter(angle - obs.y3)
        # the family whose direction the line is nearest: y3 (mod pi) for family 1
        k = 0 if abs(math.remainder(angle - obs.y3, math.pi)) <= 0.25 * math.pi else 1
        mx, my = 0.5 * (x1 + x2) - cx, 0.5 * (y1 + y2) - cy
        n = normals[k]
        s = n[0] * mx + n[1] * my + (obs.y1, obs.y2)[k] * ppm
        off = abs(s - lp * round(s / lp))
        along = abs(-n[1] * mx + n[0] * my)
        worst = max(worst, abs(turn) / head, off / (pos + along * head))
    return _with_checks(got, (CheckResult(FIRST_LINES, worst, 1.0, "<=", worst <= 1.0),))


def _with_checks(got: VisionResult, checks: tuple[CheckResult, ...]) -> VisionResult:
    """``got`` (accepted) with ``checks`` run after its reading's own (the decision shows them
    in the reading shown); refused (``foreign line``, without an observation) by the first
    that failed."""
    failed = next((c for c in checks if not c.passed), None)
    decision = got.decision
    if decision is not None and decision.shown is not None:
        readings = list(decision.readings)
        tried = readings[decision.shown]
        readings[decision.shown] = replace(
            tried, checks=tried.checks + checks,
            reason=tried.reason if failed is None else "foreign line")
        decision = replace(decision, readings=tuple(readings))
        if failed is not None:
            decision = replace(decision, reason="foreign line", refusal=failed,
                               refused_in=decision.shown)
    if failed is None:
        return replace(got, decision=decision)
    return replace(got, observation=None, accepted=False, reason="foreign line",
                   decision=decision)
