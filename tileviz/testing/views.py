"""One view of the vision study, drawn from a seed and read by the robust extractor.

Each view is rendered by :mod:`tileviz.testing.floorgen` from a generator seeded with
``[seed, FAMILY_SALT[family], kind]`` (kind 0: a clean view, 1: a corrupted one, 2: a cable along
a grout line, 3: a short motion blur, 4: a cable crossing a grout line at a small angle), so a
test and a bench that name the same seed and family see the same view. Each function returns a
dict of the outcome: accepted, the refusal reason, the error of the accepted observation and its
declared bound in px (position: the worse of y1, y2, modulo the floor's symmetries) and whether
the truth is inside that bound.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tileviz.config import CameraConfig, FloorModel, VisionConfig
from tileviz.testing import floorgen
from tileviz.types import Pose
from tileviz.vision import VisionResult, extract, observation_error

__all__ = ["DETAILS", "FAMILY_SALT", "cable_view", "crossing_cable_view", "motion_view",
           "study_view"]

FAMILY_SALT = {f: i + 1 for i, f in enumerate(floorgen.ALL_FAMILIES)}
"""The second word of every view's seed, by family."""

DETAILS = ("position_se_px", "heading_se", "straightness_px", "spacing_residual_px", "rise",
           "noise_sigma", "width", "step", "heading_parts", "position_parts", "tilt_gap", "depth",
           "feasible")
"""The robust extractor's details a study view keeps (NaN where the extractor gave none)."""


def study_view(seed: int, family: str, corruption: str | None,
               vision: VisionConfig | None = None, declare_kind: bool = True) -> dict[str, Any]:
    """A view of ``family`` from ``seed`` (with ``corruption``, one of
    :data:`floorgen.CORRUPTIONS`, or clean), extracted with ``vision`` (default: the robust
    extractor), its floor declared (without its kind when not ``declare_kind``: a
    checkerboard is then left for the extractor to recognise): the outcome with the view's
    floor, whether it is readable (:func:`floorgen.readable`), the extraction time (ms) and the
    extractor's :data:`DETAILS`."""
    rng = np.random.default_rng([seed, FAMILY_SALT[family], 0 if corruption is None else 1])
    spec = floorgen.draw_floor(family, rng)
    cx, cy, th = floorgen.draw_view(rng)
    img = floorgen.render(spec, cx, cy, th, rng, corruption)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    model = (spec.model if declare_kind
             else FloorModel(lattice_tolerance=spec.model.lattice_tolerance))
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=vision or VisionConfig(extractor="robust"), floor=model)
    out: dict[str, Any] = {
        "seed": seed, "family": family, "corruption": corruption or "",
        "readable": floorgen.readable(spec, cx, cy, th), "accepted": res.accepted,
        "reason": res.reason, "err_px": math.nan, "err_rad": math.nan, "bound_px": math.nan,
        "bound_rad": math.nan, "inside": True, "ms": sum(res.timings.values()),
        "ppm": spec.ppm, "tile": spec.tile_size, "grout_px": spec.grout_px,
    }
    for k in DETAILS:
        out[k] = float(res.details.get(k, math.nan))
    if res.accepted:
        ep, eh, bp, bh, inside = _errors(res, spec, Pose(cx, cy, th))
        out.update(err_px=ep, err_rad=eh, bound_px=bp, bound_rad=bh, inside=inside)
    return out


def cable_view(seed: int, family: str) -> dict[str, Any]:
    """A view of ``family`` from ``seed`` with a straight cable (2..10 px wide, dark or light)
    parallel to the grout line of one family nearest the view's centre, its centre ``delta`` px
    (uniform in [-25, 25]) from the line's; ``gap``: px between the cable's and the grout's
    edges (negative: they overlap)."""
    rng = np.random.default_rng([seed, FAMILY_SALT[family], 2])
    spec = floorgen.draw_floor(family, rng)
    cx, cy, th = floorgen.draw_view(rng)
    k = int(rng.integers(2))
    delta = float(rng.uniform(-25.0, 25.0))
    width = float(rng.uniform(2.0, 10.0))
    shade = float(rng.uniform(10, 60) if rng.uniform() < 0.7 else rng.uniform(200, 250))
    normal, s = floorgen.line_offset(spec, cx, cy, th, k)
    img = floorgen.render(spec, cx, cy, th, rng,
                          overlay=floorgen.band(spec, normal, s + delta, width, shade))
    out: dict[str, Any] = {
        "seed": seed, "family": family, "delta": delta, "width": width, "shade": shade,
        "grout_px": spec.grout_px, "gap": abs(delta) - 0.5 * (width + spec.grout_px),
        "line_s": s}
    return _outcome(out, img, spec, Pose(cx, cy, th))


def crossing_cable_view(seed: int, family: str) -> dict[str, Any]:
    """A view of ``family`` from ``seed`` with a straight cable of the grout's shade, 0.8..1.6
    times its width, crossing the grout line of one family nearest the view's centre at
    ``angle`` (rad, 0.02..0.08 either way) ``t0`` px along it (uniform in [-60, 60] from the
    point nearest the centre): over the view it lies on that line, then beside it."""
    rng = np.random.default_rng([seed, FAMILY_SALT[family], 4])
    spec = floorgen.draw_floor(family, rng)
    cx, cy, th = floorgen.draw_view(rng)
    k = int(rng.integers(2))
    angle = float(rng.uniform(0.02, 0.08)) * (1.0 if rng.uniform() < 0.5 else -1.0)
    width = float(rng.uniform(0.8, 1.6)) * spec.grout_px
    t0 = float(rng.uniform(-60.0, 60.0))
    (gu, gv), s = floorgen.line_offset(spec, cx, cy, th, k)
    pu, pv = gu * s - gv * t0, gv * s + gu * t0  # the crossing, on the grout line
    ca, sa = math.cos(angle), math.sin(angle)
    nu, nv = ca * gu - sa * gv, sa * gu + ca * gv  # the cable's normal
    img = floorgen.render(spec, cx, cy, th, rng,
                          overlay=floorgen.band(spec, (nu, nv), nu * pu + nv * pv, width,
                                                spec.grout_shade))
    out: dict[str, Any] = {"seed": seed, "family": family, "angle": angle, "width": width,
                           "t0": t0, "grout_px": spec.grout_px}
    return _outcome(out, img, spec, Pose(cx, cy, th))


def motion_view(seed: int, family: str) -> dict[str, Any]:
    """A view of ``family`` from ``seed`` under a short motion blur (``length`` 2..15 px, at
    ``angle`` rad, any)."""
    rng = np.random.default_rng([seed, FAMILY_SALT[family], 3])
    spec = floorgen.draw_floor(family, rng)
    cx, cy, th = floorgen.draw_view(rng)
    length = float(rng.uniform(2.0, 15.0))
    ang = float(rng.uniform(0.0, math.pi))
    img = floorgen.render(spec, cx, cy, th, rng, motion=(length, ang))
    out: dict[str, Any] = {"seed": seed, "family": family, "length": length, "angle": ang,
                           "grout_px": spec.grout_px}
    return _outcome(out, img, spec, Pose(cx, cy, th))


def _outcome(out: dict[str, Any], img: np.ndarray, spec: floorgen.FloorSpec,
             pose: Pose) -> dict[str, Any]:
    """``out`` with the robust extractor's outcome on ``img`` (camera at ``pose``)."""
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"), floor=spec.model)
    out.update(accepted=res.accepted, reason=res.reason, err_px=math.nan, bound_px=math.nan,
               err_rad=math.nan, bound_rad=math.nan, inside=True)
    if res.accepted:
        ep, eh, bp, bh, inside = _errors(res, spec, pose)
        out.update(err_px=ep, bound_px=bp, err_rad=eh, bound_rad=bh, inside=inside)
    return out


def _errors(res: VisionResult, spec: floorgen.FloorSpec,
            pose: Pose) -> tuple[float, float, float, float, bool]:
    """An accepted view's position error (px), heading error (rad), their declared bounds and
    whether both errors are within them."""
    obs = res.observation
    assert obs is not None
    e1, e2, e3 = observation_error(obs, pose, spec.tile_size, (0.0, 0.0))
    ep = max(abs(e1), abs(e2))
    inside = ep <= obs.position_error and abs(e3) <= obs.heading_error
    return ep * spec.ppm, abs(e3), obs.position_error * spec.ppm, obs.heading_error, inside
