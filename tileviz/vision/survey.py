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
``y``, ``theta``), each line's own departure from its ideal line is measured too
(:func:`line_departure`: at most ``tau`` plus the measurement's own error), which a view whose
lines all depart alike (a panel laid off the lattice; a checkerboard seen on one side of its
crossings only, whose edges lie half a faint grout band off its centre: docs/vision.md,
"Colour") shows in no residual. The tolerance recommended is the largest of these over the
views, rounded up to a tenth of a millimetre: what the views showed, so a survey should see the
whole floor the robot will drive on (a floor may depart more where no view looked). The report
names the view that sets it beside the next largest view's departure: the trial tolerance lets
a line read wrong through, and one view far above all others may show that rather than the
floor.

A floor whose kind is not given is read as a grout floor, a checkerboard recognised from each
view; when most accepted views are read as a checkerboard, or too few views are accepted,
``python -m tileviz survey`` surveys the views again as ``kind: checker`` and, when that
succeeds, recommends that kind (a declared checkerboard is read on more views, and its lines
are measured as the edges between its tiles).
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from tileviz.cliutil import CliError, Parser, positive_float, positive_int, read_json, run_cli
from tileviz.config import CameraConfig, FloorModel, VisionConfig
from tileviz.types import Pose

__all__ = ["SurveyReport", "line_departure", "main", "survey", "survey_kind"]

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
    declared period (median; NaN when no view spans a period), the recommended
    ``lattice_tolerance``, the kind the views were read as (``grout``: a checkerboard left to
    recognise) and how many accepted views were read as a checkerboard."""

    views: int
    accepted: int
    departure_rms: float
    departure_max: float
    offset_max: float | None
    period_ratio: float
    tolerance: float
    kind: str = "grout"
    checker: int = 0
    widest: int = 0
    """The view (0-based, in the order read) whose departure sets the tolerance."""
    next_widest: float = 0.0
    """The largest departure any other view showed (m): far below the tolerance, the widest
    view may hold a line read wrong at the trial tolerance rather than the floor's departure."""
    shown: float = 0.0
    """The largest departure the views showed (m), rounded up to 0.1 mm; the tolerance is it
    unless :attr:`capped`."""

    @property
    def capped(self) -> bool:
        """Whether the views showed a quarter tile or more, so that the tolerance recommended
        (just under a quarter tile, the most tileviz accepts) is less than they showed."""
        return self.tolerance < self.shown

    @property
    def reads_as_checker(self) -> bool:
        """Whether most accepted views of a floor not declared ``checker`` were read as a
        checkerboard: the floor is one, and ``kind: checker`` is the one to declare."""
        return self.kind != "checker" and 2 * self.checker > self.accepted

    def lines(self, name: Callable[[int], str] | None = None) -> list[str]:
        """The report, as a person reads it (mm); ``name`` names a view by its number
        (default "view N", counted from 1)."""
        out = [f"views read: {self.views}, accepted: {self.accepted}",
               f"lines off the lattice fitted to each view: rms {self.departure_rms * 1e3:.2f} "
               f"mm, max {self.departure_max * 1e3:.2f} mm (half the worst residual of a view)"]
        if self.offset_max is not None:
            out.append(f"lines off the ideal lattice at the true pose: max "
                       f"{self.offset_max * 1e3:.2f} mm")
        else:
            out.append("no true poses: a departure all lines of a view share (a panel laid "
                       "off the lattice) shows in no residual and is not measured")
        if math.isfinite(self.period_ratio):
            out.append(f"measured period / declared: {self.period_ratio:.4f}")
        if self.kind == "checker":
            out.append("kind: checker (its edge images read)")
        else:
            out.append(f"views read as a checkerboard: {self.checker} of {self.accepted}")
        label = name(self.widest) if name is not None else f"view {self.widest + 1}"
        following = math.ceil(round(self.next_widest * 1e4, 6)) / 10.0  # mm, rounded up too
        out.append(f"the largest departure, {self.shown * 1e3:.1f} mm, is {label}'s; the next "
                   f"largest view's: {following:.1f} mm (if far less, look at "
                   f"{label} with python -m tileviz extract IMAGE --explain: a line read wrong "
                   "there would set the tolerance)")
        if self.capped:
            out.append(f"the views showed a departure of {self.shown * 1e3:.1f} mm, a quarter "
                       "tile or more: more than tileviz accepts (is the floor a lattice of this "
                       "tile size?)")
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
    checker = 0
    dep: list[float] = []
    off: list[float] = []
    ratios: list[float] = []
    by_view: list[tuple[float, int]] = []  # each accepted view's departure, and its number
    for image, truth in views:
        n += 1
        res = extract(image, camera=camera, tile_size=tile_size, vision=vision, floor=trial)
        if not res.accepted or res.observation is None:
            continue
        d = res.details
        checker += kind == "checker" or "checker" in d
        dep.append(0.5 * max(d.get("straightness_px", 0.0), d.get("spacing_residual_px", 0.0))
                   / ppm)
        if "period_ratio" in d:
            ratios.append(d["period_ratio"])
        if truth is not None:
            e = observation_error(res.observation, truth, tile_size, camera.offset)
            off.append(max(abs(e[0]), abs(e[1]), line_departure(
                res.segments, res.bags, truth, tile_size, camera)))
        by_view.append((max(dep[-1], off[-1] if truth is not None else 0.0), n - 1))
    if len(dep) < MIN_VIEWS:
        raise ValueError(f"too few usable views: {len(dep)} of {n} accepted (at least "
                         f"{MIN_VIEWS} needed: more views of the floor, or check the tile size "
                         f"and ppm)")
    ratio = float(np.median(ratios)) if ratios else math.nan
    if math.isfinite(ratio) and abs(ratio - 1.0) > SCALE_TOLERANCE:
        raise ValueError(f"inconsistent scale: the views' tile period is {ratio:.3f} x "
                         f"tile_size x ppm ({tile_size * ppm:.1f} px): check --tile-size and "
                         "--ppm")
    arr = np.array(dep)
    by_view.sort(reverse=True)
    tol = math.ceil(by_view[0][0] * 1e4) / 1e4
    return SurveyReport(views=n, accepted=len(dep), departure_rms=float(np.sqrt(np.mean(arr**2))),
                        departure_max=float(arr.max()),
                        offset_max=float(max(off)) if off else None, period_ratio=ratio,
                        tolerance=min(tol, 0.999 * tile_size / 4), kind=kind,
                        checker=checker, widest=by_view[0][1], next_widest=by_view[1][0],
                        shown=tol)


def survey_kind(views: Callable[[], Iterable[tuple[np.ndarray, Pose | None]]], *,
                camera: CameraConfig, tile_size: float, kind: str | None = None,
                vision: VisionConfig | None = None
                ) -> tuple[SurveyReport, list[tuple[SurveyReport | None, str]]]:
    """:func:`survey` of the views ``views()`` makes (called once per survey) as the floor
    ``kind``; with no kind, as grout (a checkerboard recognised), then again as ``checker``
    when most accepted views were read as a checkerboard (:attr:`SurveyReport.reads_as_checker`)
    or too few were accepted; when that second survey fails, the first stands. The report
    returned is one survey's, as one kind: a checkerboard's edges read as grout (a view not
    recognised) are no departure of its edges. Returns the report and the other survey with
    why it was not kept (that report, or None where it failed; a sentence). ValueError (one
    line) as :func:`survey`'s; where both fail, the first's and the second's in one line."""
    try:
        report = survey(views(), camera=camera, tile_size=tile_size, vision=vision,
                        kind=kind or "grout")
    except ValueError as e:
        if kind is not None:
            raise
        # a checkerboard with a thin grout may be recognised on too few views
        try:
            report = survey(views(), camera=camera, tile_size=tile_size, vision=vision,
                            kind="checker")
        except ValueError as second:
            if str(second) == str(e):
                raise e from None
            raise ValueError(f"{e}; read as kind checker: {second}") from None
        return report, [(None, f"read as grout or a recognised checkerboard, {e}: surveyed "
                               "as kind checker")]
    if kind is None and report.reads_as_checker:
        try:
            again = survey(views(), camera=camera, tile_size=tile_size, vision=vision,
                           kind="checker")
        except ValueError as e:
            return report, [(None, f"most views read as a checkerboard, but surveyed as kind "
                                   f"checker, {e}: the survey as grout stands")]
        return again, [(report, "most views read as a checkerboard: surveyed again as kind "
                                "checker")]
    return report, []


def line_departure(segments: np.ndarray, bags: np.ndarray, truth: Pose, tile_size: float,
                   camera: CameraConfig) -> float:
    """The farthest any line a view read lies from its ideal line at the true pose ``truth``
    (metres; 0 with no line). ``segments``: each line's image endpoints (N, 4: x1, y1, x2, y2
    px, ``VisionResult.segments``), ``bags`` its family (0: not a line). Each line's point
    nearest the view's centre is put on the floor as ``camera`` sees it (docs/dataset-format.md:
    an orthographic view, ``camera.ppm`` pixels a metre, centred ``camera.offset`` ahead of and
    left of the robot at ``truth``); its departure is that point's distance to the nearest line
    of the ideal lattice (x = kL or y = kL, ``tile_size`` L) that the line runs along."""
    ct, st = math.cos(truth.theta), math.sin(truth.theta)
    fwd, left = camera.offset
    ox, oy = truth.x + fwd * ct - left * st, truth.y + fwd * st + left * ct
    centre = np.array([(camera.width - 1) / 2.0, (camera.height - 1) / 2.0])
    worst = 0.0
    for seg, bag in zip(np.asarray(segments, float), np.asarray(bags).tolist(), strict=True):
        if bag == 0:
            continue
        p, d = seg[:2], seg[2:] - seg[:2]
        length = float(np.hypot(*d))
        if length == 0.0:
            continue
        d = d / length
        foot = p + d * float(np.dot(centre - p, d))
        # an image offset (d col, d row) is (-d row, -d col) / ppm ahead and left of the camera
        af, al = -(foot[1] - centre[1]) / camera.ppm, -(foot[0] - centre[0]) / camera.ppm
        x, y = ox + af * ct - al * st, oy + af * st + al * ct
        wx, wy = -d[1] * ct + d[0] * st, -d[1] * st - d[0] * ct  # its direction on the floor
        along_x = abs(wx) >= abs(wy)
        worst = max(worst, abs(math.remainder(y if along_x else x, tile_size)))
    return worst


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
    p.add_argument("--floor-kind", choices=("grout", "checker"), default=None,
                   help="the floor's kind (default: grout, or checker when most views read "
                   "as a checkerboard)")
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


def _dataset(folder: str, every: int, seen: list[int]
             ) -> Iterator[tuple[np.ndarray, Pose | None]]:
    """Every ``every``-th frame of the dataset ``folder``, its index appended to ``seen``; the
    images of the frames skipped are not decoded (a damaged one among them is no error)."""
    from tileviz.datasets import DatasetSource

    seen.clear()
    source = DatasetSource(folder)
    for frame, where in source.frames_without_images():
        if frame.index % every == 0:
            seen.append(frame.index)
            yield source.load_image(frame.image_name, where), frame.truth


def main(command: str, argv: list[str]) -> int:
    """Entry point of ``python -m tileviz survey``; returns the exit status."""
    prog = f"tileviz {command}"
    args = _parser(prog).parse_args(argv)

    def body() -> int:
        if args.meta is not None:  # a meta.json that cannot be written is said before reading
            _meta_doc(Path(args.meta))
        first = Path(args.inputs[0])
        for path in args.inputs:
            if not Path(path).exists():
                raise CliError(f"{path}: no such file")
        if first.is_dir() and not (first / "meta.json").is_file():
            raise CliError(f"{first}: a folder with no meta.json, not a dataset (give its "
                           f"images as files, e.g. {first}/*.png)")
        if first.is_dir():
            from tileviz.datasets import DatasetSource

            if len(args.inputs) > 1:
                raise CliError("give one dataset folder, or image files")
            meta = DatasetSource(first).meta
            tile = args.tile_size or meta.tile_size
            ppm = args.ppm or meta.ppm
            cam = CameraConfig(ppm=ppm, width=meta.image_width, height=meta.image_height,
                               offset=meta.camera_offset)
            seen: list[int] = []

            def views() -> Iterable[tuple[np.ndarray, Pose | None]]:
                return _dataset(str(first), args.every, seen)

            def name(k: int) -> str:
                return f"frame {seen[k]}"
        else:
            if args.tile_size is None or args.ppm is None:
                raise CliError("images need --tile-size and --ppm")
            images = _images(args.inputs)
            view0 = next(images)  # its size is the camera's
            tile, ppm = args.tile_size, args.ppm
            cam = CameraConfig(ppm=ppm, width=view0[0].shape[1], height=view0[0].shape[0],
                               offset=(0.0, 0.0))
            def views() -> Iterable[tuple[np.ndarray, Pose | None]]:
                return itertools.chain([view0], _images(args.inputs[1:]))

            def name(k: int) -> str:
                return str(args.inputs[k])
        try:
            report, said = survey_kind(views, camera=cam, tile_size=tile, kind=args.floor_kind)
        except ValueError as e:
            raise CliError(str(e)) from None
        for before, why in said:
            if before is not None:  # the survey not kept, in one line
                print(f"read as grout, a checkerboard recognised: {before.accepted} of "
                      f"{before.views} views accepted, {before.checker} of them read as a "
                      f"checkerboard")
            print(why)
        print("\n".join(report.lines(name)))
        if args.meta is not None:
            for note in _write_meta(Path(args.meta), report.kind, report.tolerance, tile):
                print(f"{args.meta} {note}")
            print(f"wrote the floor block into {args.meta}")
        return 0

    return run_cli(prog, body)


def _meta_doc(path: Path) -> dict:
    """The JSON object in ``path`` ({} when missing); CliError when it is not one or its folder
    does not exist."""
    if not path.parent.is_dir():
        raise CliError(f"--meta: cannot write {path} (no folder {path.parent})")
    doc = read_json(str(path), "--meta") if path.exists() else {}
    if not isinstance(doc, dict):
        raise CliError(f"--meta: {path} is not a JSON object")
    return doc


def _write_meta(path: Path, kind: str, tolerance: float, tile_size: float) -> list[str]:
    """Set the ``floor`` block of the meta.json ``path`` (created when missing), written to a
    temporary file and renamed: ``kind`` and the larger of ``tolerance`` (metres) and the
    tolerance the block already declared, when that is valid (below a quarter of
    ``tile_size``, metres; docs/dataset-format.md: a declared tolerance is never taken
    smaller); the block's other keys kept. Returns what a user should be told: a declared
    tolerance kept, a declared kind replaced."""
    doc = _meta_doc(path)
    old = doc.get("floor")
    declared = old.get("lattice_tolerance") if isinstance(old, dict) else None
    notes = []
    if (isinstance(declared, int | float) and not isinstance(declared, bool)
            and math.isfinite(declared) and tolerance < declared < tile_size / 4):
        tolerance = float(declared)  # a valid declaration, larger than the survey's
        notes.append(f"declared lattice_tolerance {tolerance:.4f} m, more than this survey's: "
                     "kept (a survey measures the views it saw, the floor's maker may know more)")
    was = old.get("kind") if isinstance(old, dict) else None
    if isinstance(was, str) and was != kind:
        notes.append(f"declared kind {was}: replaced by the survey's, {kind}")
    # the block's other keys (another program's) stay
    doc["floor"] = {**(old if isinstance(old, dict) else {}), "kind": kind,
                    "lattice_tolerance": tolerance}
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
        tmp.replace(path)
    except OSError as e:
        raise CliError(f"--meta: cannot write {path} ({e.strerror or e})") from None
    return notes
