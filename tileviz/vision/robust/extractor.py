"""The robust extractor's entry point: runs the steps in order on one frame, then builds the
:class:`~tileviz.vision.result.VisionResult` and, on request, the stage images."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import replace

import cv2
import numpy as np

from tileviz.config import CameraConfig, VisionConfig
from tileviz.types import Observation
from tileviz.vision import draw
from tileviz.vision.geometry import QUARTER, family_normals
from tileviz.vision.result import BAG_HORIZONTAL, BAG_VERTICAL, VisionResult
from tileviz.vision.robust import lattice_kernel
from tileviz.vision.robust.checks import Refusal
from tileviz.vision.robust.fit import check_lines, drop_stray_part, fit_tilt
from tileviz.vision.robust.foreign import foreign_edges
from tileviz.vision.robust.heading import first_heading, lattice_headings, smoothed_headings
from tileviz.vision.robust.lattice import lattice_offsets
from tileviz.vision.robust.periodic import on_lattice
from tileviz.vision.robust.profiles import measure, select_lines
from tileviz.vision.robust.settings import DEFAULT_SETTINGS, RobustSettings
from tileviz.vision.robust.state import Line, RobustRun
from tileviz.vision.robust.statistics import gray_statistics, noise_sigma

__all__ = ["build_result", "clip_all", "execute", "extract_robust", "stage_images"]


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
) -> VisionResult:
    """Run the robust extractor on ``gray`` (HxW uint8); see the module docstring.

    ``image`` (the RGB input) is only used for the overlays when ``keep_stages``; ``timings``
    (ms) may already hold the gray conversion's time."""
    tm = {} if timings is None else timings
    run = RobustRun(gray, camera, tile_size, vision, settings, tm)
    reason = "ok"
    # missing data is NaN throughout (profiles beyond the view, unmeasured parts): arithmetic
    # on it is expected and its warnings are noise
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        try:
            execute(run)
        except Refusal as f:
            reason = f.reason
        if reason != "ok" and run.not_straight:
            # refused after lines found not straight: read again leaving out the one part
            # that alone kept them from straight (fit.drop_stray_part); kept only when that
            # reading passes every check (a view read the first time is read as before)
            again = RobustRun(gray, camera, tile_size, vision, settings, tm)
            again.drop_stray = True
            try:
                execute(again)
                run, reason = again, "ok"
            except Refusal:
                pass
    t0 = time.perf_counter()
    res = build_result(run, reason)
    tm["result"] = (time.perf_counter() - t0) * 1e3
    if keep_stages:
        t1 = time.perf_counter()
        stages = stage_images(run, image, res)
        tm["stages"] = (time.perf_counter() - t1) * 1e3
        res = replace(res, stages=stages)
    return res


def execute(run: RobustRun) -> None:
    """Run every step; raises Refusal with the reason of the first failed check."""
    t = time.perf_counter()
    gray_statistics(run)
    t = run.lap("statistics", t)
    dx = cv2.Scharr(run.gray, cv2.CV_16S, 1, 0)
    dy = cv2.Scharr(run.gray, cv2.CV_16S, 0, 1)
    run.dxy = (dx, dy)
    noise_sigma(run)
    t = run.lap("edges", t)
    y0 = first_heading(run, dx, dy)
    t = run.lap("heading", t)
    start = (run.mean, run.window, run.inverted)
    lines, y3, t = read_lines(run, y0, t)
    try:
        check_lines(run, lines)
    except Refusal as first:
        # The gradient directions can be outvoted by texture (chips, grain, a photograph): a
        # heading a few degrees off smears every line's profile. The view's periodicity with
        # the tile period decides then; its lines must pass every check as before.
        if first.reason not in RETRY_REASONS:
            raise
        tried = [(y0, run.inverted)]
        for alt in retry_headings(run):
            t = run.lap("heading", t)
            if any(abs(math.remainder(alt - y, QUARTER)) < run.st.heading.same_heading
                   for y, _ in tried):
                continue
            run.details["heading_retry"] = float(len(tried))
            lines, y3, t, ok = read_again(run, start, alt, t)
            tried.append((alt, run.inverted))
            if ok:
                break
        else:
            if first.reason not in POLARITY_REASONS:
                raise first from None
            # The grout's polarity can be misjudged too (a bright tile cut by the border of
            # a view of strongly shaded tiles is a narrow peak): each heading is read again
            # with the other polarity; its lines must pass every check as before. When all
            # fail, the result shows the lines read before (as without this retry).
            kept = snapshot(run)
            for y, inverted in tried:
                run.force_inverted = not inverted
                run.details["polarity_retry"] = 1.0
                lines, y3, t, ok = read_again(run, start, y, t)
                if ok:
                    break
            else:
                restore(run, kept)
                run.details["polarity_retry"] = 1.0
                raise first from None
    t = run.lap("checks", t)
    lattice_offsets(run, lines, y3)
    t = run.lap("lattice", t)
    foreign_edges(run)
    run.lap("foreign", t)


def retry_headings(run: RobustRun) -> Iterator[float]:
    """The headings (rad) tried when the first one's lines fail: the view's periodicity
    (:func:`lattice_headings`), then the gradient votes on the smoothed view
    (:func:`smoothed_headings`: strong noise can outvote thin grout), computed as needed."""
    yield from lattice_headings(run)
    yield from smoothed_headings(run)


POLARITY_REASONS = frozenset({"no lines", "low contrast", "one family"})
"""Refusals (at the first heading) after which, every heading having failed, the lines are
read again with the grout's other polarity: reading dark grout as lighter (or the reverse)
finds no line, or only shallow ones."""

_READ_STATE = ("lines", "y3", "mean", "window", "inverted", "projection", "warped", "centre",
               "part_bound", "force_inverted")
"""The attributes of a RobustRun that reading the lines at one heading sets."""


def snapshot(run: RobustRun) -> dict[str, object]:
    """What reading the lines has set on ``run`` (for :func:`restore`)."""
    out: dict[str, object] = {k: getattr(run, k) for k in _READ_STATE}
    out["details"] = dict(run.details)
    return out


def restore(run: RobustRun, state: dict[str, object]) -> None:
    """Put back what :func:`snapshot` took."""
    for k in _READ_STATE:
        setattr(run, k, state[k])
    run.details.clear()
    run.details.update(state["details"])  # type: ignore[call-overload]


RETRY_REASONS = frozenset(
    {"no lines", "low contrast", "one family", "blurred", "step edge", "inconsistent angle",
     "foreign line"}
)
"""Refusals of the line checks after which the heading is sought from the view's periodicity
(``lattice_heading``) and the lines read again."""


def read_again(
    run: RobustRun, start: tuple[float, int, bool], y3: float, t: float
) -> tuple[list[list[Line]], float, float, bool]:
    """Read the lines at heading ``y3`` (rad) again from ``start`` (``run.mean``,
    ``run.window`` and ``run.inverted`` as the first reading began), as :func:`read_lines`
    does; also True when they pass every check (:func:`check_lines`)."""
    run.mean, run.window, run.inverted = start
    lines, y3, t = read_lines(run, y3, t)
    try:
        check_lines(run, lines)
    except Refusal:
        return lines, y3, t, False
    return lines, y3, t, True


def read_lines(run: RobustRun, y3: float, t: float) -> tuple[list[list[Line]], float, float]:
    """Measure and select the lines at heading ``y3``, fit the residual tilt, and measure again
    (up to three times) while the correction exceeds ``refine_tilt``; the lines, the corrected
    heading and the time (perf_counter) after the "profiles" lap. Sets ``run.lines`` and
    ``run.y3``."""
    pst = run.st.profiles
    last = run.st.heading.max_warps - 1
    for attempt in range(last + 1):
        lines = on_lattice(run, select_lines(run, measure(run, y3, attempt)))
        # a window too narrow for the grout (a wide band): measure again with a wider one
        width = run.details.get("width", math.nan) if lines[0] or lines[1] else math.nan
        if math.isfinite(run.unmeasured_width):
            # the deepest dip was too wide for the window: the lines kept are shallower
            # ones (a texture's), the grout band is measured with a window fitting it
            width = max(width, run.unmeasured_width) if math.isfinite(width) else width
        need = run.widest
        if math.isfinite(width):
            need = min(int(math.ceil(pst.window_per_width * width + pst.window_margin)), need)
        if need > run.window:
            run.window = need
            lines = on_lattice(run, select_lines(run, measure(run, y3, attempt + 1)))
        tilt = fit_tilt(run, lines)
        if run.details["straightness_px"] > run.st.lines.straight_fraction * run.bound_px:
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


def build_result(run: RobustRun, reason: str) -> VisionResult:
    """The VisionResult of this run (segments = the measured lines, clipped to the view)."""
    segs: list[np.ndarray] = []
    bags: list[int] = []
    offsets: list[float] = []
    if run.y3 is not None:
        normals = family_normals(run.y3)
        x0, y0 = run.centre
        for k, fam in enumerate(run.lines):
            s_px = [-(ln.pos - (y0 if k == 0 else x0)) for ln in fam if math.isfinite(ln.pos)]
            seg, hit = clip_all(normals[k], s_px, run.w, run.h)
            segs.append(seg[hit])
            for s, h in zip(s_px, hit.tolist(), strict=True):
                if h:
                    bags.append(BAG_HORIZONTAL if k == 0 else BAG_VERTICAL)
                    offsets.append(s / run.ppm)
    seg_arr = np.concatenate(segs) if segs else np.zeros((0, 4))
    ang = np.arctan2(seg_arr[:, 3] - seg_arr[:, 1], seg_arr[:, 2] - seg_arr[:, 0])
    dis = np.stack([np.cos(4.0 * ang), np.sin(4.0 * ang)], axis=1).reshape(-1, 2)
    med = None if run.y3 is None else (math.cos(4.0 * run.y3), math.sin(4.0 * run.y3))
    obs = None
    if reason == "ok" and run.y is not None:
        obs = Observation(
            y1=run.y[0],
            y2=run.y[1],
            y3=run.y[2],
            position_error=run.details["bound_px"] / run.ppm,
            heading_error=run.details["bound_rad"],
        )
    return VisionResult(
        observation=obs,
        accepted=obs is not None,
        reason="ok" if obs is not None else ("no lines" if reason == "ok" else reason),
        extractor="robust",
        segments=seg_arr,
        angles=ang,
        bags=np.array(bags, np.int8),
        disambiguation=dis,
        offsets=np.array(offsets, np.float64),
        median=med,
        timings=run.tm,
        details=run.details,
    )


def clip_all(n: tuple[float, float], s: list[float], width: int, height: int
             ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~tileviz.vision.robust.lattice.clip_line` of the lines ``n . (p - centre) = s``
    for every offset of ``s`` (px): their endpoints (k, 4) and whether each meets the view
    (its row is unset otherwise); compiled when numba is present
    (:func:`~tileviz.vision.robust.lattice_kernel.clip_lines`, bit-identical)."""
    return lattice_kernel.clip_lines(n[0], n[1], np.array(s, np.float64), width, height)


def stage_images(
    run: RobustRun, image: np.ndarray | None, res: VisionResult
) -> dict[str, np.ndarray]:
    """Stage images (HxWx3 uint8 RGB): input, gray, edges, warped (the view turned by the
    heading: grout lines along rows and columns), lines (by bag), distances (each line's
    signed offset from the centre), lattice (the lines the observation predicts), foreign
    (unexplained edges and the straight ones among them), disambiguation ((cos 4a, sin 4a)
    of the lines and the heading)."""
    rgb = draw.to_rgb(run.gray if image is None else image)
    out: dict[str, np.ndarray] = {"input": rgb, "gray": draw.to_rgb(run.gray)}
    if run.edges is not None:
        out["edges"] = draw.to_rgb(run.edges)
    if run.warped is not None:
        wv = cv2.normalize(run.warped, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
        out["warped"] = draw.to_rgb(cv2.resize(wv, (run.w, run.h)))
    out["lines"] = draw.draw_segments(rgb.copy(), res.segments, res.bags)
    out["distances"] = draw.draw_offsets(
        draw.draw_segments(rgb.copy(), res.segments, res.bags, thickness=1), res.bags,
        res.offsets, run.y3, ppm=run.ppm,
    )
    if run.y is not None:
        out["lattice"] = draw.draw_lattice(
            rgb.copy(), run.y, ppm=run.ppm, tile_size=run.tile_size
        )
    if run.free_edges is not None:
        out["foreign"] = draw.draw_segments(draw.to_rgb(run.free_edges), run.foreign, None)
    out["disambiguation"] = draw.disambiguation_plot(
        res.disambiguation, res.bags, res.median, size=int(run.side)
    )
    return out
