"""The robust extractor's entry point: measures the view (:func:`prepare`), reads it for each
candidate reading in turn (:func:`~tileviz.vision.robust.readings.decide`), keeps the outcome
the plan decides on (:func:`conclude`), and builds the
:class:`~tileviz.vision.result.VisionResult` with its :class:`~tileviz.vision.decision.Decision`
and, on request, the stage images."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from types import MappingProxyType

import cv2
import numpy as np

from tileviz.config import PERFECT_FLOOR, CameraConfig, FloorModel, VisionConfig
from tileviz.types import Observation
from tileviz.vision import draw
from tileviz.vision.decision import Decision, Tried
from tileviz.vision.geometry import family_normals
from tileviz.vision.result import BAG_HORIZONTAL, BAG_VERTICAL, VisionResult
from tileviz.vision.robust import lattice_kernel
from tileviz.vision.robust.checks import Record, Refusal
from tileviz.vision.robust.heading import first_heading
from tileviz.vision.robust.readings import OFF_LATTICE_REASONS, Outcome, decide
from tileviz.vision.robust.settings import DEFAULT_SETTINGS, RobustSettings
from tileviz.vision.robust.state import Scale, View, check_scale
from tileviz.vision.robust.statistics import gray_statistics, noise_sigma

__all__ = ["Conclusion", "build_result", "clip_all", "conclude", "extract_robust", "prepare",
           "stage_images"]


def extract_robust(
    gray: np.ndarray,
    *,
    camera: CameraConfig,
    tile_size: float,
    vision: VisionConfig,
    keep_stages: bool = False,
    image: np.ndarray | None = None,
    timings: dict[str, float] | None = None,
    settings: RobustSettings = DEFAULT_SETTINGS,
    floor: FloorModel = PERFECT_FLOOR,
    noise_floor: float = 0.0,
) -> VisionResult:
    """Run the robust extractor on ``gray`` (HxW uint8); see the package docstring.

    ``floor``: what is declared of the floor (its lattice tolerance widens the checks that compare
    lines with the lattice and is part of the view's bound: docs/vision.md). ``image`` (the RGB
    input) is only used for the overlays when ``keep_stages``; ``timings`` (ms) may already hold
    the gray conversion's time. ``noise_floor``: the least noise std (gray levels) the contrast
    limit assumes (the camera's, measured on the luma, for an image that cancels some of it)."""
    tm = {} if timings is None else timings
    # missing data is NaN throughout (profiles beyond the view, unmeasured parts): arithmetic
    # on it is expected and its warnings are noise
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        view, refusal = prepare(gray, camera, tile_size, vision, settings, tm,
                                tol_px=floor.lattice_tolerance * float(camera.ppm),
                                noise_floor=noise_floor)
        done = [] if refusal is not None else decide(view, tm)
    t0 = time.perf_counter()
    end = conclude(view, refusal, done)
    res = build_result(view, end, tm)
    tm["result"] = (time.perf_counter() - t0) * 1e3
    if keep_stages:
        t1 = time.perf_counter()
        stages = stage_images(view, end.shown, image, res)
        tm["stages"] = (time.perf_counter() - t1) * 1e3
        res = replace(res, stages=stages)
    return res


def prepare(gray: np.ndarray, camera: CameraConfig, tile_size: float, vision: VisionConfig,
            settings: RobustSettings, tm: dict[str, float], tol_px: float = 0.0,
            noise_floor: float = 0.0) -> tuple[View, Refusal | None]:
    """The view, measured once for every reading: the gray statistics (refusing a
    ``constant image`` or ``glare``), the Scharr gradients, the noise level and the first
    heading (refusing ``no lines`` when no gradient votes); the refusal, if any. Stage times
    are added to ``tm`` (ms); ``tol_px``: the floor's lattice tolerance in the view, px;
    ``noise_floor``: the least noise std the contrast limit assumes, gray levels (the view's
    own noise still scales the foreign-edge and grout-level searches)."""
    h, w = gray.shape
    ctx = Scale(settings, check_scale(vision, settings)[0], float(min(h, w)), vision, math.nan,
                tol_px)
    rec = Record()
    details: dict[str, float] = {}
    mean, noise, dxy, heading = 0.0, math.nan, None, math.nan
    refusal = None
    t = time.perf_counter()
    try:
        mean = gray_statistics(gray, ctx, rec, details)
        t = _lap(tm, "statistics", t)
        dx = cv2.Scharr(gray, cv2.CV_16S, 1, 0)
        dy = cv2.Scharr(gray, cv2.CV_16S, 0, 1)
        dxy = (dx, dy)
        noise = noise_sigma(gray)
        details["noise_sigma"] = noise
        t = _lap(tm, "edges", t)
        heading = first_heading(ctx, dx, dy, rec, details)
        _lap(tm, "heading", t)
    except Refusal as r:
        refusal = r
    if noise_floor > 0.0:
        details["noise_floor"] = noise_floor
    view = View.of(gray, camera, tile_size, vision, settings, tol_px, mean=mean, noise=noise,
                   noise_floor=noise_floor,
                   dxy=dxy, heading=heading, details=MappingProxyType(details),
                   checks=tuple(rec.results))
    return view, refusal


def _lap(tm: dict[str, float], name: str, t0: float) -> float:
    """Add the time since ``t0`` (perf_counter, s) to stage ``name`` of ``tm`` (ms)."""
    t = time.perf_counter()
    tm[name] = tm.get(name, 0.0) + (t - t0) * 1e3
    return t


@dataclass(frozen=True, eq=False)
class Conclusion:
    """What the plan decided: the ``reason`` (``ok`` when accepted), the outcome whose lines
    the result shows (``shown``; None when refused before any reading), the result's
    ``details`` and the :class:`~tileviz.vision.decision.Decision`."""

    reason: str
    shown: Outcome | None
    details: dict[str, float]
    decision: Decision


def conclude(view: View, refusal: Refusal | None, done: Sequence[Outcome]) -> Conclusion:
    """The decision on ``view`` from the outcomes of its readings in order (``done``,
    :func:`~tileviz.vision.robust.readings.plan`'s passes), or from the ``refusal`` of the
    view's own checks.

    Per pass: when a reading's lines passed (the last of the pass), its outcome decides,
    unless it is the other polarity read after a first reading whose lines passed, and is
    refused: the first reading's refusal then stands;
    otherwise the pass refuses with its first reading's reason and shows its last reading
    that imposed no polarity. The first pass decides unless the second (without the stray
    part) accepts. ``details``: the view's, then each reading's up to the one shown, in order
    (a later value replaces an earlier; ``profile_noise`` keeps the largest), with
    ``heading_retry`` (headings read after the first) and ``polarity_retry`` (1 when readings
    with the other polarity were tried)."""
    view_checks = view.checks
    if refusal is not None:
        dec = Decision(view_checks, (), None, refusal.reason, refusal.result, None)
        return Conclusion(refusal.reason, None, dict(view.details), dec)
    if len(done) == 1:  # the first reading decided (most views): its own details
        only = done[0]
        refused_in = None if only.reason == "ok" else 0
        dec = Decision(view_checks, (Tried(only.reading, only.checks, only.reason),), 0,
                       only.reason, only.refusal, refused_in)
        return Conclusion(only.reason, only, {**view.details, **only.details}, dec)
    passes = [[i for i, o in enumerate(done) if o.reading.stray == s] for s in (False, True)]
    chosen = _pass(done, passes[0])
    if passes[1]:
        second = _pass(done, passes[1])
        if second[0] == "ok":
            chosen = second
    reason, shown, refused_in, merged = chosen
    details = dict(view.details)
    for i in merged:
        for k, v in done[i].details.items():
            details[k] = max(details.get(k, 0.0), v) if k == "profile_noise" else v
    pass_readings = [done[i].reading.kind for i in passes[1 if done[shown].reading.stray else 0]]
    if "heading" in pass_readings:
        details["heading_retry"] = float(pass_readings.count("heading"))
    if "polarity" in pass_readings:
        details["polarity_retry"] = 1.0
    tried = tuple(Tried(o.reading, o.checks, o.reason) for o in done)
    ref = None if refused_in is None else done[refused_in].refusal
    dec = Decision(view_checks, tried, shown, reason, ref, refused_in)
    return Conclusion(reason, done[shown], details, dec)


def _pass(done: Sequence[Outcome], idx: list[int]) -> tuple[str, int, int | None, list[int]]:
    """One pass's decision (the outcomes ``done[i]`` for i in ``idx``): its reason, the
    reading shown, the reading whose check refused (None when accepted) and the readings whose
    details the result merges (see :func:`conclude`)."""
    last = idx[-1]
    if done[last].lines_passed:
        first = done[idx[0]]
        if (done[last].reason != "ok" and done[last].reading.kind == "polarity"
                and first.lines_passed and first.reason in OFF_LATTICE_REASONS):
            # the other polarity read after the first's lines missed the lattice, refused
            # too: the view read at its own polarity tells why
            return first.reason, idx[0], idx[0], [idx[0]]
        ok = done[last].reason == "ok"
        return done[last].reason, last, None if ok else last, idx
    shown = max(i for i in idx if done[i].reading.kind != "polarity")
    return done[idx[0]].reason, shown, idx[0], [i for i in idx if i <= shown]


def build_result(view: View, end: Conclusion, tm: dict[str, float]) -> VisionResult:
    """The VisionResult of the conclusion (segments = the lines shown, clipped to the view)."""
    segs: list[np.ndarray] = []
    bags: list[int] = []
    offsets: list[float] = []
    out = end.shown
    y3 = None if out is None else out.y3
    if out is not None and y3 is not None:
        normals = family_normals(y3)
        x0, y0 = out.centre
        for k, fam in enumerate(out.positions):
            s_px = [-(pos - (y0 if k == 0 else x0)) for pos in fam if math.isfinite(pos)]
            seg, hit = clip_all(normals[k], s_px, view.w, view.h)
            segs.append(seg[hit])
            for s, h in zip(s_px, hit.tolist(), strict=True):
                if h:
                    bags.append(BAG_HORIZONTAL if k == 0 else BAG_VERTICAL)
                    offsets.append(s / view.ppm)
    seg_arr = np.concatenate(segs) if segs else np.zeros((0, 4))
    ang = np.arctan2(seg_arr[:, 3] - seg_arr[:, 1], seg_arr[:, 2] - seg_arr[:, 0])
    dis = np.stack([np.cos(4.0 * ang), np.sin(4.0 * ang)], axis=1).reshape(-1, 2)
    med = None if y3 is None else (math.cos(4.0 * y3), math.sin(4.0 * y3))
    obs = None
    if end.reason == "ok" and out is not None and out.y is not None:
        obs = Observation(
            y1=out.y[0],
            y2=out.y[1],
            y3=out.y[2],
            position_error=end.details["bound_px"] / view.ppm,
            heading_error=end.details["bound_rad"],
        )
    return VisionResult(
        observation=obs,
        accepted=obs is not None,
        reason="ok" if obs is not None else ("no lines" if end.reason == "ok" else end.reason),
        extractor="robust",
        segments=seg_arr,
        angles=ang,
        bags=np.array(bags, np.int8),
        disambiguation=dis,
        offsets=np.array(offsets, np.float64),
        median=med,
        timings=tm,
        details=end.details,
        decision=end.decision,
    )


def clip_all(n: tuple[float, float], s: list[float], width: int, height: int
             ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~tileviz.vision.robust.lattice.clip_line` of the lines ``n . (p - centre) = s``
    for every offset of ``s`` (px): their endpoints (k, 4) and whether each meets the view
    (its row is unset otherwise), compiled
    (:func:`~tileviz.vision.robust.lattice_kernel.clip_lines`)."""
    return lattice_kernel.clip_lines(n[0], n[1], np.array(s, np.float64), width, height)


def stage_images(
    view: View, out: Outcome | None, image: np.ndarray | None, res: VisionResult
) -> dict[str, np.ndarray]:
    """Stage images (HxWx3 uint8 RGB) of the outcome shown: input, gray, edges, warped (the
    view turned by the heading: grout lines along rows and columns), lines (by bag), distances
    (each line's signed offset from the centre), lattice (the lines the observation predicts),
    foreign (unexplained edges and the straight ones among them), disambiguation ((cos 4a,
    sin 4a) of the lines and the heading)."""
    rgb = draw.to_rgb(view.gray if image is None else image)
    out_img: dict[str, np.ndarray] = {"input": rgb, "gray": draw.to_rgb(view.gray)}
    if out is not None and out.edges is not None:
        out_img["edges"] = draw.to_rgb(out.edges)
    if out is not None and out.warped is not None:
        wv = cv2.normalize(out.warped, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
        out_img["warped"] = draw.to_rgb(cv2.resize(wv, (view.w, view.h)))
    out_img["lines"] = draw.draw_segments(rgb.copy(), res.segments, res.bags)
    out_img["distances"] = draw.draw_offsets(
        draw.draw_segments(rgb.copy(), res.segments, res.bags, thickness=1), res.bags,
        res.offsets, None if out is None else out.y3, ppm=view.ppm,
    )
    if out is not None and out.y is not None:
        out_img["lattice"] = draw.draw_lattice(
            rgb.copy(), out.y, ppm=view.ppm, tile_size=view.tile_size
        )
    if out is not None and out.free_edges is not None:
        out_img["foreign"] = draw.draw_segments(draw.to_rgb(out.free_edges), out.foreign, None)
    out_img["disambiguation"] = draw.disambiguation_plot(
        res.disambiguation, res.bags, res.median, size=int(view.side)
    )
    return out_img

