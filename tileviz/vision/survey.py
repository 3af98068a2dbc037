"""Measuring a floor as a camera is calibrated: how far its grout lines depart from the ideal
lattice, and the lattice tolerance to declare (``python -m tileviz survey``; docs/vision.md,
"Surveying a floor").

Each view is read by the robust extractor with a trial tolerance (:data:`TRIAL_SHARE` of the
tile), wide enough for the checks that compare lines with the lattice to let an irregular floor
through. An accepted view shows two departures from the lattice fitted to it
(``VisionResult.details``): the worst part of a line off the common straight fit
(``straightness_px``) and the worst line off the lattice spacing (``spacing_residual_px``).
Lines that each lie within ``tau`` of the ideal lattice show such residuals up to ``2 tau``, so
a view shows ``tau >= max(straightness, spacing) / 2``. With the true pose (a dataset's ``x``,
``y``, ``theta``), the view's offset from the ideal lattice is measured too (its observation's
error, at most ``tau`` plus the measurement's own error). The tolerance recommended is the
largest of the two over the views, rounded up to a tenth of a millimetre: what the views showed,
so a survey should see the whole floor the robot will drive on (a floor may depart more where no
view looked).
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from tileviz.cliutil import CliError, Parser, positive_float, positive_int, read_json, run_cli
from tileviz.config import CameraConfig, FloorModel, VisionConfig
from tileviz.types import Pose

__all__ = ["SurveyReport", "main", "survey"]

TRIAL_SHARE = 1.0 / 16.0
"""The trial tolerance the views are read with, as a share of the tile."""
MIN_VIEWS = 5
"""Fewest accepted views a survey reports on."""
SCALE_TOLERANCE = 0.02
"""The period the views measure may differ from ``tile_size x ppm`` by this share at most."""


@dataclass(frozen=True)
class SurveyReport:
    """What a survey measured (lengths in metres): the views read and accepted, the departure
    each accepted view shows (rms and max over the views, :func:`survey`), the views' offsets
    from the ideal lattice where the truth was known (None otherwise), the measured over the
    declared period (median; NaN when no view spans a period), and the recommended
    ``lattice_tolerance``."""

    views: int
    accepted: int
    departure_rms: float
    departure_max: float
    offset_max: float | None
    period_ratio: float
    tolerance: float

    def lines(self) -> list[str]:
        """The report, as a person reads it (mm)."""
        out = [f"views read: {self.views}, accepted: {self.accepted}",
               f"lines off the lattice fitted to each view: rms {self.departure_rms * 1e3:.2f} "
               f"mm, max {self.departure_max * 1e3:.2f} mm (half the worst residual of a view)"]
        if self.offset_max is not None:
            out.append(f"views' lattice off the ideal lattice at the true pose: max "
                       f"{self.offset_max * 1e3:.2f} mm")
        if math.isfinite(self.period_ratio):
            out.append(f"measured period / declared: {self.period_ratio:.4f}")
        out.append(f"lattice_tolerance to declare: {self.tolerance:.4f} m")
        out.append("(the largest departure these views showed: the floor may depart more where "
                   "no view looked; survey views over the whole floor the robot drives on)")
        return out


def survey(views: Iterable[tuple[np.ndarray, Pose | None]], *, camera: CameraConfig,
           tile_size: float, vision: VisionConfig | None = None,
           kind: str = "grout") -> SurveyReport:
    """Survey the floor seen in ``views`` (image, true pose or None; images as
    :func:`tileviz.vision.extract` takes them) by a camera ``camera`` over tiles of
    ``tile_size`` m; ValueError (one line) when fewer than :data:`MIN_VIEWS` views are
    accepted or their period is not ``tile_size x ppm`` within :data:`SCALE_TOLERANCE`."""
    from tileviz.vision import extract, observation_error

    vision = replace(vision or VisionConfig(), extractor="robust")
    trial = FloorModel(kind, TRIAL_SHARE * tile_size)  # type: ignore[arg-type]
    ppm = float(camera.ppm)
    n = 0
    dep: list[float] = []
    off: list[float] = []
    ratios: list[float] = []
    for image, truth in views:
        n += 1
        res = extract(image, camera=camera, tile_size=tile_size, vision=vision, floor=trial)
        if not res.accepted or res.observation is None:
            continue
        d = res.details
        dep.append(0.5 * max(d.get("straightness_px", 0.0), d.get("spacing_residual_px", 0.0))
                   / ppm)
        if "period_ratio" in d:
            ratios.append(d["period_ratio"])
        if truth is not None:
            e = observation_error(res.observation, truth, tile_size, camera.offset)
            off.append(max(abs(e[0]), abs(e[1])))
    if len(dep) < MIN_VIEWS:
        raise ValueError(f"too few usable views: {len(dep)} of {n} accepted (at least "
                         f"{MIN_VIEWS} needed; are --tile-size and --ppm the floor's?)")
    ratio = float(np.median(ratios)) if ratios else math.nan
    if math.isfinite(ratio) and abs(ratio - 1.0) > SCALE_TOLERANCE:
        raise ValueError(f"inconsistent scale: the views' tile period is {ratio:.3f} x "
                         f"tile_size x ppm ({tile_size * ppm:.1f} px): check --tile-size and "
                         "--ppm")
    arr = np.array(dep)
    tol = max(float(arr.max()), max(off, default=0.0))
    tol = math.ceil(tol * 1e4) / 1e4
    return SurveyReport(views=n, accepted=len(dep), departure_rms=float(np.sqrt(np.mean(arr**2))),
                        departure_max=float(arr.max()),
                        offset_max=float(max(off)) if off else None, period_ratio=ratio,
                        tolerance=min(tol, 0.999 * tile_size / 4))


def _parser(prog: str) -> Parser:
    p = Parser(prog=prog, description="Measure how far a floor's grout lines depart from the "
               "ideal lattice, and the lattice_tolerance to declare.")
    p.add_argument("inputs", nargs="+", metavar="IMAGE_OR_DATASET",
                   help="images of the floor, or one dataset folder (its true poses, when it "
                   "has them, are used)")
    p.add_argument("--tile-size", type=positive_float("--tile-size"), default=None,
                   help="L, metres (default: the dataset's)")
    p.add_argument("--ppm", type=positive_float("--ppm"), default=None,
                   help="pixels per metre (default: the dataset's)")
    p.add_argument("--floor-kind", choices=("grout", "checker"), default="grout")
    p.add_argument("--every", type=positive_int("--every"), default=1,
                   help="a dataset: read every Nth frame (default 1)")
    p.add_argument("--meta", metavar="META", default=None,
                   help="write the floor block (kind, lattice_tolerance) into this meta.json")
    return p


def _images(paths: list[str]) -> Iterator[tuple[np.ndarray, Pose | None]]:
    import cv2

    for path in paths:
        bgr = cv2.imread(path, cv2.IMREAD_COLOR)
        if bgr is None:
            raise CliError(f"{path}: not a readable image")
        yield cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), None


def _dataset(folder: str, every: int) -> Iterator[tuple[np.ndarray, Pose | None]]:
    from tileviz.datasets import DatasetSource

    for frame in DatasetSource(folder):
        if frame.index % every == 0:
            yield frame.image, frame.truth


def main(command: str, argv: list[str]) -> int:
    """Entry point of ``python -m tileviz survey``; returns the exit status."""
    prog = f"tileviz {command}"
    args = _parser(prog).parse_args(argv)

    def body() -> int:
        first = Path(args.inputs[0])
        if first.is_dir():
            from tileviz.datasets import DatasetSource

            if len(args.inputs) > 1:
                raise CliError("give one dataset folder, or image files")
            meta = DatasetSource(first).meta
            tile = args.tile_size or meta.tile_size
            ppm = args.ppm or meta.ppm
            cam = CameraConfig(ppm=ppm, width=meta.image_width, height=meta.image_height,
                               offset=meta.camera_offset)
            views: Iterable[tuple[np.ndarray, Pose | None]] = _dataset(
                str(first), args.every)
        else:
            if args.tile_size is None or args.ppm is None:
                raise CliError("images need --tile-size and --ppm")
            images = _images(args.inputs)
            view0 = next(images)  # its size is the camera's
            tile, ppm = args.tile_size, args.ppm
            cam = CameraConfig(ppm=ppm, width=view0[0].shape[1], height=view0[0].shape[0],
                               offset=(0.0, 0.0))
            views = itertools.chain([view0], images)
        try:
            report = survey(views, camera=cam, tile_size=tile, kind=args.floor_kind)
        except ValueError as e:
            raise CliError(str(e)) from None
        print("\n".join(report.lines()))
        if args.meta is not None:
            _write_meta(Path(args.meta), args.floor_kind, report.tolerance)
            print(f"wrote the floor block into {args.meta}")
        return 0

    return run_cli(prog, body)


def _write_meta(path: Path, kind: str, tolerance: float) -> None:
    """Set the ``floor`` block of the meta.json ``path`` (created when missing), written to a
    temporary file and renamed."""
    doc = read_json(str(path), "--meta") if path.exists() else {}
    if not isinstance(doc, dict):
        raise CliError(f"--meta: {path} is not a JSON object")
    doc["floor"] = {"kind": kind, "lattice_tolerance": tolerance}
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
        tmp.replace(path)
    except OSError as e:
        raise CliError(f"--meta: cannot write {path} ({e.strerror or e})") from None
