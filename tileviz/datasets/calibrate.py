"""``python -m tileviz calibrate IMAGE... --board COLSxROWS --square S --board-pose X,Y,YAW``:
a real camera's ``camera_model`` block from checkerboard images (``docs/dataset-format.md``).

The board: ``COLS`` x ``ROWS`` inner corners (OpenCV's pattern size; they must differ, or the
board's orientation is ambiguous), squares of ``S`` metres. The **first** image shows the board
lying flat on the floor at ``--board-pose X,Y,YAW``: its centre (the centre of the inner
corners) at (forward X, left Y) metres in the robot frame, and its COLS direction (along a row
of COLS corners) at YAW radians counter-clockwise from the robot's forward axis. With three or
more images the intrinsics and distortion come from all of them (OpenCV's calibration; the
others may show the board anywhere, tilted, to constrain the lens); with one image they are the
``--meta`` file's when it has a camera_model, else zero distortion with a nominal focal length
(the homography then takes raw pixels as they are). The floor homography is fitted to the first
image's undistorted corners and their floor points.

Prints the calibration's RMS reprojection error in pixels (intrinsics, over every image) and the
floor fit's RMS error in pixels and in millimetres on the floor; writes the block into
``--meta`` (other keys kept) or prints it as JSON (the errors then on stderr, so that the
output can be saved as the file ``import-bag --camera-model`` takes). ``--meta`` is a dataset's
meta.json (it has a ``format`` key; the view it describes is then checked against what the
camera sees) or a camera file: any other JSON object, or a file that does not exist yet, which
is created (with its folder) holding the ``camera_model`` block alone, the file
``import-bag --camera-model`` takes (a dataset's meta.json also needs the floor, the view and
the sensor bounds, which calibration cannot know). One-line errors: an
image where the board is not found (named), two images (too few for intrinsics, one is enough
for the floor alone), a degenerate pose (the board too small or seen edge-on, a homography that
sees no floor).
"""

from __future__ import annotations

import json
import math
import re
import sys
from pathlib import Path

import cv2
import numpy as np

from tileviz.cliutil import CliError, Parser, positive_float, read_json, run_cli
from tileviz.datasets.camera_model import CameraModel, CameraModelError, Rectifier

__all__ = ["board_floor_points", "calibrate", "main"]

MIN_INTRINSIC_IMAGES = 3
"""OpenCV's calibration needs views from three or more board poses for focal length, principal
point and distortion together."""
MIN_BOARD_AREA = 0.02
"""The board's corners must span at least this fraction of the image (degenerate pose below)."""


def board_floor_points(cols: int, rows: int, square: float,
                       pose: tuple[float, float, float]) -> np.ndarray:
    """(cols * rows, 2) floor points (forward, left), metres, robot frame, of the board's inner
    corners in OpenCV's order (row by row, COLS a row), the board centred at ``pose[:2]`` with
    its COLS direction at ``pose[2]`` rad from forward."""
    i, j = np.meshgrid(np.arange(cols) - (cols - 1) / 2.0, np.arange(rows) - (rows - 1) / 2.0)
    bx, by = i.ravel() * square, j.ravel() * square
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.c_[pose[0] + c * bx - s * by, pose[1] + s * bx + c * by]


def _board_object_points(cols: int, rows: int, square: float) -> np.ndarray:
    i, j = np.meshgrid(np.arange(cols), np.arange(rows))
    return np.c_[i.ravel() * square, j.ravel() * square, np.zeros(cols * rows)].astype(
        np.float32)


def _find_board(path: str, cols: int, rows: int) -> tuple[np.ndarray, tuple[int, int]]:
    """The inner corners (N, 2) of the board in an image file and the image's (w, h)."""
    gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if gray is None or gray.size == 0:
        raise CliError(f"{path}: cannot read it as an image")
    found, corners = cv2.findChessboardCorners(
        gray, (cols, rows), flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found or corners is None:
        raise CliError(f"{path}: no {cols}x{rows} checkerboard found (inner corners)")
    corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1),
                               (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4))
    return corners.reshape(-1, 2).astype(np.float64), (gray.shape[1], gray.shape[0])


def _orient(corners: np.ndarray, cols: int, rows: int, yaw: float) -> np.ndarray:
    """The corners in the order whose COLS and ROWS directions, seen in the image (image up =
    forward, image left = left), point along the board pose's (``yaw`` and ``yaw`` + 90 deg)
    rather than against them (OpenCV may start from any corner of the board)."""
    grid = corners.reshape(rows, cols, 2)

    def along(d: np.ndarray, angle: float) -> float:
        return -d[1] * math.cos(angle) - d[0] * math.sin(angle)

    if along(grid[0, -1] - grid[0, 0], yaw) < 0:
        grid = grid[:, ::-1]
    if along(grid[-1, 0] - grid[0, 0], yaw + math.pi / 2) < 0:
        grid = grid[::-1]
    return np.ascontiguousarray(grid.reshape(-1, 2))


def calibrate(images: list[str], *, cols: int, rows: int, square: float,
              pose: tuple[float, float, float], given: CameraModel | None = None,
              ) -> tuple[CameraModel, dict[str, float]]:
    """The camera model and its errors (``intrinsics_px``: RMS over every image, or None with
    one image; ``floor_px`` and ``floor_mm``: RMS of the first image's corners against the
    board pose, pixels and millimetres on the floor). CliError for bad input."""
    if cols == rows:
        raise CliError("--board: COLS and ROWS must differ (a square board's orientation is "
                       "ambiguous)")
    if len(images) == 2 or (len(images) < MIN_INTRINSIC_IMAGES and len(images) != 1):
        raise CliError(f"too few images for intrinsics: {len(images)} (give "
                       f"{MIN_INTRINSIC_IMAGES} or more, or 1 for the floor homography alone "
                       "with the --meta file's or zero distortion)")
    found = [_find_board(p, cols, rows) for p in images]
    size = found[0][1]
    for p, (_, s) in zip(images, found, strict=True):
        if s != size:
            raise CliError(f"{p}: image is {s[0]}x{s[1]}, the first is {size[0]}x{size[1]}")
    first = _orient(found[0][0], cols, rows, pose[2])
    hull = cv2.convexHull(first.astype(np.float32))
    if cv2.contourArea(hull) < MIN_BOARD_AREA * size[0] * size[1]:
        raise CliError(f"degenerate pose: the board covers under {MIN_BOARD_AREA:.1%} of "
                       f"{images[0]} (bring the camera closer or use a bigger board)")
    errors: dict[str, float] = {}
    if len(images) >= MIN_INTRINSIC_IMAGES:
        obj = _board_object_points(cols, rows, square)
        rms, k, dist, _, _ = cv2.calibrateCamera(
            [obj] * len(found), [c.astype(np.float32).reshape(-1, 1, 2) for c, _ in found],
            size, None, None)
        errors["intrinsics_px"] = float(rms)
        dist = dist.ravel()
    elif given is not None and (given.raw_width, given.raw_height) == size:
        k, dist = given.k, given.dist
    else:
        f = float(max(size))
        k = np.array([[f, 0.0, (size[0] - 1) / 2.0], [0.0, f, (size[1] - 1) / 2.0], [0, 0, 1.0]])
        dist = np.zeros(5)
    floor = board_floor_points(cols, rows, square, pose)
    und = cv2.undistortPoints(first.reshape(-1, 1, 2), k, dist, None, None, k).reshape(-1, 2)
    hom, _ = cv2.findHomography(und, floor, 0)
    if hom is None or not np.isfinite(hom).all() or abs(np.linalg.det(hom)) < 1e-15:
        raise CliError(f"degenerate pose: no floor homography from {images[0]} (the board is "
                       "seen edge-on)")
    hom = hom / hom[2, 2]
    block = {
        "raw_width": size[0], "raw_height": size[1],
        "camera_matrix": [[float(k[0, 0]), 0.0, float(k[0, 2])],
                          [0.0, float(k[1, 1]), float(k[1, 2])], [0.0, 0.0, 1.0]],
        "dist_coeffs": [float(v) for v in dist],
        "floor_homography": [[float(v) for v in r] for r in hom],
    }
    try:
        model = CameraModel.from_json(block, "calibration")
    except CameraModelError as e:
        raise CliError(f"degenerate pose: {e}") from None
    fitted = model.raw_to_floor(first)
    errors["floor_mm"] = 1e3 * float(np.sqrt(np.mean(np.sum((fitted - floor) ** 2, axis=1))))
    raw, seen = model.floor_to_raw(floor)
    if not seen.all():
        raise CliError("degenerate pose: the fitted camera does not see the board it was fitted "
                       "to (check --board-pose)")
    errors["floor_px"] = float(np.sqrt(np.mean(np.sum((raw - first) ** 2, axis=1))))
    rep = max(errors["floor_px"], errors.get("intrinsics_px", 0.0))
    model = CameraModel.from_json({**block, "reprojection_error_px": rep}, "calibration")
    return model, errors


def _pose(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise CliError(f"--board-pose must be X,Y,YAW (three finite numbers), got {text!r}")
    return values


def _read_meta(path: str) -> tuple[dict[str, object], CameraModel | None]:
    """The ``--meta`` file's JSON object and its camera model (None when it has none): a
    dataset's meta.json (a ``format`` key) is checked whole, a camera file's block alone.
    CliError naming the file."""
    from tileviz.datasets import DatasetMeta

    doc = read_json(path, "--meta")
    if not isinstance(doc, dict):
        raise CliError(f"--meta: {path} is not a JSON object")
    if "format" in doc:
        return doc, DatasetMeta.from_json(doc, where=path).camera_model
    if doc.get("camera_model") is None:
        return doc, None
    try:
        return doc, CameraModel.from_json(doc["camera_model"], path)
    except CameraModelError as e:
        raise CliError(str(e)) from None


def _write(path: str, doc: dict[str, object]) -> None:
    """Write ``doc`` as ``path`` (its folder made when missing) as a whole: a write that fails
    or is killed leaves the previous file; CliError when it cannot."""
    from tileviz.safefile import write_atomic

    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(target, (json.dumps(doc, indent=2) + "\n").encode("utf-8"))
    except OSError as e:
        raise CliError(f"--meta: cannot write {path} ({e.strerror or e})") from None


def _parser(prog: str) -> Parser:
    p = Parser(prog=prog, description="Calibrate a downward camera from checkerboard images: "
               "intrinsics, distortion and the floor homography (meta.json's camera_model).")
    p.add_argument("images", nargs="+", metavar="IMAGE",
                   help="board images; the first shows the board on the floor at --board-pose")
    p.add_argument("--board", required=True, metavar="COLSxROWS",
                   help="inner corners of the checkerboard, e.g. 9x6")
    p.add_argument("--square", required=True, type=positive_float("--square"),
                   help="side of a square, metres")
    p.add_argument("--board-pose", required=True, metavar="X,Y,YAW",
                   help="board centre (forward, left; metres, robot frame) and the direction "
                   "of its COLS axis (rad from forward) in the first image")
    p.add_argument("--meta", default=None, metavar="META",
                   help="a dataset's meta.json or a camera file: write the camera_model block "
                   "into it (and take its camera for a single image); a file that does not "
                   "exist is created with the block alone (what import-bag --camera-model "
                   "takes)")
    return p


def main(command: str, argv: list[str]) -> int:
    """Entry point of ``python -m tileviz calibrate``."""
    prog = f"tileviz {command}"
    args = _parser(prog).parse_args(argv)

    def body() -> int:
        m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", args.board)
        if not m or int(m.group(1)) < 2 or int(m.group(2)) < 2:
            raise CliError(f"--board must be COLSxROWS inner corners (each >= 2), got "
                           f"{args.board!r}")
        pose = _pose(args.board_pose)
        meta_doc: dict[str, object] | None = None
        given = None
        created = args.meta is not None and not Path(args.meta).exists()
        if created:
            meta_doc = {}
        elif args.meta is not None:
            meta_doc, given = _read_meta(args.meta)
        model, errors = calibrate(args.images, cols=int(m.group(1)), rows=int(m.group(2)),
                                  square=args.square, pose=pose, given=given)
        # without --meta, stdout is the block alone (to save as a file) and the errors go to stderr
        report = sys.stdout if meta_doc is not None else sys.stderr
        if "intrinsics_px" in errors:
            print(f"intrinsics: {errors['intrinsics_px']:.3f} px RMS reprojection error over "
                  f"{len(args.images)} images", file=report)
        print(f"floor: {errors['floor_px']:.3f} px RMS, {errors['floor_mm']:.2f} mm RMS on the "
              "floor", file=report)
        if meta_doc is None:
            print(json.dumps({"camera_model": model.to_json()}, indent=2))
            return 0
        from tileviz.datasets import DatasetMeta

        meta_doc["camera_model"] = model.to_json()
        if "format" not in meta_doc:  # a camera file: the block, no view to check
            _write(args.meta, meta_doc)
            print(f"created {args.meta} with the camera_model block alone (for import-bag "
                  "--camera-model; a dataset's meta.json also needs the floor, view and bounds)"
                  if created else f"wrote camera_model into {args.meta}")
            return 0
        meta = DatasetMeta.from_json(meta_doc, where=args.meta)
        rect = Rectifier(model, ppm=meta.ppm, width=meta.image_width, height=meta.image_height,
                         camera_offset=meta.camera_offset)
        _write(args.meta, meta_doc)
        print(f"wrote camera_model into {args.meta}")
        if rect.seen_fraction < 1.0:
            print(f"note: {1 - rect.seen_fraction:.1%} of the {meta.image_width}x"
                  f"{meta.image_height} view at ppm {meta.ppm:g} is outside what the camera "
                  "sees (flat there); a smaller view or ppm avoids it", file=sys.stderr)
        return 0

    return run_cli(prog, body)
