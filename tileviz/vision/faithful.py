"""The original pipeline (report chapter 4, constants in ``docs/seed-code.md``), corrected.

Stages, each constant from :class:`~tileviz.config.VisionConfig` (defaults = the original's):
gray -> Laplacian (8-bit, ksize 1) -> Canny (50, 255, aperture 3) -> morphology (close 1x1,
dilate 3x3 once) -> probabilistic Hough (1 px, pi/180, 60, 100, 50) -> per segment the angle a
and (cos 4a, sin 4a) (eq. 4.4) -> component-wise median, L1 outlier filter < 0.15 (eq. 4.2),
median again, ``y3 = atan2(y, x) / 4`` (eq. 4.5) -> horizontal/vertical bags after de-rotation
-> displacement per bag (eq. 4.6).

Corrections (where the original was wrong):

- Offsets are *signed*, along a fixed normal per family (:func:`~tileviz.vision.geometry.
  family_normals`), instead of eq. 4.1's unsigned distance and its ad-hoc ``1 - dd`` flips.
- Each bag's displacement is a circular median modulo L, so a family whose lines straddle the
  camera centre (offsets near 0 and near L) does not average to L/2.
- The output follows docs/method.md's convention (:mod:`tileviz.vision.geometry`), and a frame
  without both families is refused (``one family``) instead of producing a NaN.

The chain does no work the bare OpenCV calls skip: a 1x1 close is the identity and is not
run, and stage images are only built when asked (``keep_stages``).
"""

from __future__ import annotations

import math
import time
from functools import lru_cache

import cv2
import numpy as np

from tileviz.config import CameraConfig, VisionConfig
from tileviz.types import Observation
from tileviz.vision import draw
from tileviz.vision.geometry import circular_median, median
from tileviz.vision.result import BAG_HORIZONTAL, BAG_VERTICAL, VisionResult

__all__ = ["extract_faithful"]


@lru_cache(maxsize=8)
def _kernel(k: int) -> np.ndarray:
    return np.ones((k, k), np.uint8)


def extract_faithful(
    gray: np.ndarray,
    *,
    camera: CameraConfig,
    tile_size: float,
    vision: VisionConfig,
    keep_stages: bool = False,
    image: np.ndarray | None = None,
    timings: dict[str, float] | None = None,
) -> VisionResult:
    """Run the corrected original pipeline on ``gray`` (HxW uint8).

    ``image`` (the RGB input) is only used for the overlays when ``keep_stages``; ``timings``
    (ms) may already hold the gray conversion's time.
    """
    tm = {} if timings is None else timings
    t0 = time.perf_counter()
    lap = cv2.Laplacian(gray, cv2.CV_8U, ksize=vision.laplacian_ksize, scale=1, delta=0)
    t1 = time.perf_counter()
    edges = cv2.Canny(lap, vision.canny_low, vision.canny_high, apertureSize=vision.canny_aperture)
    t2 = time.perf_counter()
    morph = edges
    if vision.close_kernel > 1:
        morph = cv2.morphologyEx(morph, cv2.MORPH_CLOSE, _kernel(vision.close_kernel))
    if vision.dilate_kernel > 1 and vision.dilate_iterations > 0:
        # (None is OpenCV's default 3x3 rectangle, the original's call)
        kern = None if vision.dilate_kernel == 3 else _kernel(vision.dilate_kernel)
        morph = cv2.dilate(morph, kern, iterations=vision.dilate_iterations)
    t3 = time.perf_counter()
    lines = cv2.HoughLinesP(
        morph,
        vision.hough_rho,
        vision.hough_theta,
        vision.hough_threshold,
        minLineLength=vision.hough_min_line_length,
        maxLineGap=vision.hough_max_line_gap,
    )
    t4 = time.perf_counter()
    # OpenCV >= 5 returns (N, 4); older versions (N, 1, 4); no line: None.
    seg = (
        np.empty((0, 4), np.float64)
        if lines is None
        else np.asarray(lines, dtype=np.float64).reshape(-1, 4)
    )
    out = _parameters(seg, camera=camera, tile_size=tile_size, vision=vision)
    t5 = time.perf_counter()
    tm["laplacian"] = (t1 - t0) * 1e3
    tm["canny"] = (t2 - t1) * 1e3
    tm["morphology"] = (t3 - t2) * 1e3
    tm["hough"] = (t4 - t3) * 1e3
    tm["parameters"] = (t5 - t4) * 1e3
    stages: dict[str, np.ndarray] = {}
    if keep_stages:
        rgb = draw.to_rgb(gray if image is None else image)
        stages["input"] = rgb
        stages["gray"] = draw.to_rgb(gray)
        # (the 8-bit Laplacian is mostly small values: stretched to 0..255 for display)
        stages["laplacian"] = draw.to_rgb(cv2.normalize(lap, None, 0, 255, cv2.NORM_MINMAX))
        stages["canny"] = draw.to_rgb(edges)
        stages["morphology"] = draw.to_rgb(morph)
        stages["hough"] = draw.draw_segments(rgb.copy(), seg)
        stages["bags"] = draw.draw_segments(rgb.copy(), seg, out["bags"])
        y3 = None if out["observation"] is None else out["observation"].y3
        if y3 is None and out["median"] is not None:
            y3 = math.atan2(out["median"][1], out["median"][0]) / 4.0
        stages["distances"] = draw.draw_offsets(
            draw.draw_segments(rgb.copy(), seg, out["bags"], thickness=1), out["bags"],
            out["offsets"], y3, ppm=camera.ppm,
        )
        if out["observation"] is not None:
            o = out["observation"]
            stages["lattice"] = draw.draw_lattice(
                rgb.copy(), (o.y1, o.y2, o.y3), ppm=camera.ppm, tile_size=tile_size
            )
        stages["disambiguation"] = draw.disambiguation_plot(
            out["disambiguation"], out["bags"], out["median"], radius=vision.l1_threshold,
            size=min(camera.height, camera.width),
        )
        tm["stages"] = (time.perf_counter() - t5) * 1e3
    return VisionResult(extractor="faithful", stages=stages, timings=tm, **out)


def _parameters(
    seg: np.ndarray, *, camera: CameraConfig, tile_size: float, vision: VisionConfig
) -> dict:
    """Segments -> angles, disambiguation, median, bags, offsets and the observation.

    Per segment a = atan2(y2 - y1, x2 - x1) and (cos 4a, sin 4a) (eq. 4.4); the component-wise
    median, the L1 filter (eq. 4.2), the median again and y3 = atan2 / 4 (eq. 4.5); bags after
    de-rotation by -y3; per bag the circular median of y_k = -s_k mod L (eq. 4.6 corrected),
    s_k the segment line's signed offset from the image centre along the family normal."""
    rows = seg.tolist()
    n = len(rows)
    cxp = (camera.width - 1) / 2.0
    cyp = (camera.height - 1) / 2.0
    hypot, atan2 = math.hypot, math.atan2
    ux: list[float] = []
    uy: list[float] = []
    ang: list[float] = []
    c4: list[float] = []
    s4: list[float] = []
    for x1, y1, x2, y2 in rows:
        dx, dy = x2 - x1, y2 - y1
        ln = hypot(dx, dy) or 1.0
        a, b = dx / ln, dy / ln
        c2, s2 = a * a - b * b, 2.0 * a * b
        ux.append(a)
        uy.append(b)
        ang.append(atan2(dy, dx))
        c4.append(c2 * c2 - s2 * s2)
        s4.append(2.0 * c2 * s2)
    bags = [0] * n
    offsets = [math.nan] * n
    res: dict = {"median": None, "observation": None, "accepted": False, "reason": "no lines"}
    y3 = 0.0
    if n:
        mx, my = median(c4), median(s4)
        thr = vision.l1_threshold
        keep = [i for i in range(n) if abs(c4[i] - mx) + abs(s4[i] - my) < thr]
        res["median"] = (mx, my)
        res["reason"] = "too few segments"
        if len(keep) >= vision.min_segments:
            mx, my = median([c4[i] for i in keep]), median([s4[i] for i in keep])
            res["median"] = (mx, my)
            y3 = math.atan2(my, mx) / 4.0  # in (-pi/4, pi/4]
            if y3 >= 0.25 * math.pi:
                y3 -= 0.5 * math.pi
            res.update(_bags(rows, keep, ux, uy, y3, bags, offsets, cxp, cyp, camera.ppm,
                             tile_size, vision))
    res["segments"] = seg
    res["angles"] = np.array(ang, np.float64)
    res["disambiguation"] = np.array((c4, s4), np.float64).T.reshape(n, 2)
    res["bags"] = np.array(bags, np.int8)
    res["offsets"] = np.array(offsets, np.float64)
    return res


def _bags(
    rows: list[list[float]],
    keep: list[int],
    ux: list[float],
    uy: list[float],
    y3: float,
    bags: list[int],
    offsets: list[float],
    cxp: float,
    cyp: float,
    ppm: float,
    tile_size: float,
    vision: VisionConfig,
) -> dict:
    """Fill ``bags`` and ``offsets`` in place; the observation or the refusal reason."""
    cy3, sy3 = math.cos(y3), math.sin(y3)
    thr = vision.bag_threshold
    fam: tuple[list[float], list[float]] = ([], [])
    for i in keep:
        # the segment de-rotated by -y3: (cos rel, sin rel)
        cr = ux[i] * cy3 + uy[i] * sy3
        sr = uy[i] * cy3 - ux[i] * sy3
        x1, y1 = rows[i][0] - cxp, rows[i][1] - cyp
        d = -uy[i] * x1 + ux[i] * y1  # the segment normal (-uy, ux) . (p1 - centre), px
        if abs(sr) < thr:  # along y3: family 1, "horizontal"; n_1 . (-uy, ux) = -cos rel
            k, sign = 0, (-1.0 if cr > 0 else 1.0)
        elif abs(cr) < thr:  # along y3 + pi/2: family 2, "vertical"; n_2 . (-uy, ux) = sin rel
            k, sign = 1, (1.0 if sr > 0 else -1.0)
        else:
            continue
        bags[i] = BAG_HORIZONTAL if k == 0 else BAG_VERTICAL
        s = sign * d / ppm
        offsets[i] = s
        fam[k].append(-s)
    if not fam[0] and not fam[1]:
        return {"reason": "too few segments"}
    if not fam[0] or not fam[1]:
        return {"reason": "one family"}
    obs = Observation(
        y1=circular_median(fam[0], tile_size),  # eq. 4.6, signed and circular
        y2=circular_median(fam[1], tile_size),
        y3=y3,
        position_error=vision.position_error_px / ppm,
        heading_error=vision.heading_error,
    )
    return {"observation": obs, "accepted": True, "reason": "ok"}
