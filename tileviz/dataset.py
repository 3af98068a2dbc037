"""tileviz-dataset/1: write, read and validate datasets; write replay outputs.

The contract is ``shared/dataset-format.md``. A dataset is a folder with ``meta.json``,
``frames.csv`` and images. Row k of ``frames.csv``: the image taken at pose k, the compass measured
at frame k, and the odometry (speed, yaw rate) describing the motion from frame k to frame k+1,
held over ``t[k+1] - t[k]`` seconds (``meta.dt`` when ``t`` is missing on the next row or there is
no next row).

Errors are :class:`DatasetError` (a ValueError) whose message names the file and, for rows, the
row number (1-based line number of ``frames.csv`` counting the header as line 1).
"""

from __future__ import annotations

import csv
import json
import math
import os
import zlib
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, TypeVar

import cv2
import numpy as np
import pyspng

from tileviz.config import Config
from tileviz.datasets.camera_model import CameraModel, CameraModelError, Rectifier, view_margin
from tileviz.types import FrameInput, Odometry, Pose

if TYPE_CHECKING:
    from tileviz.runner import FrameRecord

FORMAT = "tileviz-dataset/1"
FRAME_COLUMNS = ("index", "t", "image", "speed", "yaw_rate", "compass", "x", "y", "theta")
REQUIRED_COLUMNS = ("index", "t", "image", "speed", "yaw_rate")
REPLAY_COLUMNS = (
    "index", "t", "status", "x_lo", "x_hi", "y_lo", "y_hi", "theta_lo", "theta_hi", "boxes",
)
RESIDUAL_COLUMNS = ("index", "t", "r1", "r2", "r3", "r4", "r5", "r6")
MAX_MAGNITUDE = 1e9
"""Largest magnitude of a number in meta.json (the localizer's ``LIMIT``)."""
MIN_TILE_PX = 4.0
"""A tile must span at least this many pixels (tile_size * ppm): finer is no floor to see."""
MAX_PPM = 1e5
"""Largest ppm (10 micrometres a pixel): beyond it the image stages' kernels (sized in pixels
from metres) would not fit in memory."""
T = TypeVar("T")
R = TypeVar("R")
_NO_IMAGE = np.zeros((0, 0, 3), np.uint8)
"""The image of a frame whose image is read elsewhere."""
FAULTS_FILE = "faults.csv"
"""Optional tileviz extension: ``index,faults`` with ``;``-separated labels of injected faults."""


class DatasetError(ValueError):
    """A dataset that does not follow tileviz-dataset/1; the message names file and row."""


def _num(x: float) -> str:
    """A float written so that it round-trips exactly (``repr``)."""
    return repr(float(x))


@dataclass(frozen=True)
class DatasetMeta:
    """The contents of ``meta.json`` (units: metres, seconds, radians, pixels)."""

    name: str
    tile_size: float
    ppm: float
    image_width: int
    image_height: int
    camera_offset: tuple[float, float]
    dt: float
    initial_pose: tuple[float, float, float]
    initial_pose_error: tuple[float, float, float]
    speed_error: float
    yaw_rate_error: float
    compass_error: float
    extra: dict[str, Any] = field(default_factory=dict)
    """Unknown keys, kept and ignored."""
    camera_model: CameraModel | None = None
    """A real camera whose stored images are rectified to the orthographic view, or None."""

    @classmethod
    def from_config(cls, cfg: Config, name: str = "tileviz run") -> DatasetMeta:
        return cls(
            name=name,
            tile_size=cfg.floor.tile_size,
            ppm=cfg.camera.ppm,
            image_width=cfg.camera.width,
            image_height=cfg.camera.height,
            camera_offset=tuple(cfg.camera.offset),  # type: ignore[arg-type]
            dt=cfg.sim.dt,
            initial_pose=tuple(cfg.sim.initial_pose),  # type: ignore[arg-type]
            initial_pose_error=tuple(cfg.sim.initial_pose_error),  # type: ignore[arg-type]
            speed_error=cfg.noise.speed_error,
            yaw_rate_error=cfg.noise.yaw_rate_error,
            compass_error=cfg.noise.compass_error,
            extra={"tileviz_config": cfg.to_dict()},
        )

    def to_json(self) -> dict[str, Any]:
        d: dict[str, Any] = dict(self.extra)
        d.update(
            format=FORMAT,
            name=self.name,
            tile_size=self.tile_size,
            ppm=self.ppm,
            image_width=self.image_width,
            image_height=self.image_height,
            camera_offset=list(self.camera_offset),
            dt=self.dt,
            initial_pose=list(self.initial_pose),
            initial_pose_error=list(self.initial_pose_error),
            speed_error=self.speed_error,
            yaw_rate_error=self.yaw_rate_error,
            compass_error=self.compass_error,
        )
        if self.camera_model is not None:
            d["camera_model"] = self.camera_model.to_json()
        return d

    @classmethod
    def from_json(cls, d: Any, where: str = "meta.json") -> DatasetMeta:
        """Validate and parse; errors name the key."""
        if not isinstance(d, dict):
            raise DatasetError(f"{where}: must be a JSON object")
        if d.get("format") != FORMAT:
            raise DatasetError(
                f"{where}: format must be {FORMAT!r}, got {d.get('format', '(missing)')!r}"
            )
        known = {
            "format", "name", "tile_size", "ppm", "image_width", "image_height", "camera_offset",
            "dt", "initial_pose", "initial_pose_error", "speed_error", "yaw_rate_error",
            "compass_error", "camera_model",
        }
        missing = sorted(k for k in known - {"name", "camera_model"} if k not in d)
        if missing:
            raise DatasetError(f"{where}: missing key(s) {', '.join(missing)}")

        def number(key: str, *, positive: bool) -> float:
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise DatasetError(f"{where}: {key} must be a finite number, got {v!r}")
            if abs(v) > MAX_MAGNITUDE:
                raise DatasetError(f"{where}: {key} must be within +-{MAX_MAGNITUDE:g}, got {v!r}")
            if positive and v <= 0 or not positive and v < 0:
                raise DatasetError(f"{where}: {key} must be {'> 0' if positive else '>= 0'}, "
                                   f"got {v!r}")
            return float(v)

        def integer(key: str) -> int:
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise DatasetError(f"{where}: {key} must be an integer > 0, got {v!r}")
            return v

        def vector(key: str, n: int, *, nonneg: bool = False) -> tuple[float, ...]:
            v = d[key]
            ok = isinstance(v, list) and len(v) == n and all(
                not isinstance(e, bool) and isinstance(e, int | float) and math.isfinite(e)
                and abs(e) <= MAX_MAGNITUDE and (e >= 0 or not nonneg) for e in v
            )
            if not ok:
                what = "non-negative " if nonneg else ""
                raise DatasetError(f"{where}: {key} must be a list of {n} finite {what}numbers "
                                   f"within +-{MAX_MAGNITUDE:g}, got {v!r}")
            return tuple(float(e) for e in v)

        if number("ppm", positive=True) > MAX_PPM:
            raise DatasetError(f"{where}: ppm must be <= {MAX_PPM:g}, got {d['ppm']!r}")
        tile_px = number("tile_size", positive=True) * number("ppm", positive=True)
        if tile_px < MIN_TILE_PX:
            raise DatasetError(f"{where}: a tile must span at least {MIN_TILE_PX:g} pixels "
                               f"(tile_size * ppm), got {tile_px!r}")
        name = d.get("name", "")
        try:
            camera_model = (CameraModel.from_json(d["camera_model"], where)
                            if d.get("camera_model") is not None else None)
        except CameraModelError as e:
            raise DatasetError(str(e)) from None
        return cls(
            name=str(name),
            tile_size=number("tile_size", positive=True),
            ppm=number("ppm", positive=True),
            image_width=integer("image_width"),
            image_height=integer("image_height"),
            camera_offset=vector("camera_offset", 2),  # type: ignore[arg-type]
            dt=number("dt", positive=True),
            initial_pose=vector("initial_pose", 3),  # type: ignore[arg-type]
            initial_pose_error=vector("initial_pose_error", 3, nonneg=True),  # type: ignore[arg-type]
            speed_error=number("speed_error", positive=False),
            yaw_rate_error=number("yaw_rate_error", positive=False),
            compass_error=number("compass_error", positive=False),
            extra={k: v for k, v in d.items() if k not in known},
            camera_model=camera_model,
        )

    def rectifier(self) -> Rectifier | None:
        """The rectification of this dataset's stored images (maps computed now), or None
        without a camera_model."""
        if self.camera_model is None:
            return None
        return Rectifier(self.camera_model, ppm=self.ppm, width=self.image_width,
                         height=self.image_height, camera_offset=self.camera_offset)

    def to_config(self, base: Config | None = None) -> Config:
        """A Config for replaying: geometry, bounds and start from the meta, the rest from
        ``base`` (or, for datasets tileviz recorded, from the stored ``tileviz_config``)."""
        if base is None:
            stored = self.extra.get("tileviz_config")
            base = Config()
            if isinstance(stored, dict):
                try:
                    base = Config.from_dict(stored)
                except (ValueError, TypeError):
                    base = Config()
        floor_grout = min(base.floor.grout_width, self.tile_size / 4)
        vision = base.vision
        rectifier = self.rectifier()
        if rectifier is not None:  # the view bound grows by what the rectification may move
            px, rad = view_margin(rectifier.model, rectifier)
            vision = replace(vision, position_error_px=vision.position_error_px + px,
                             heading_error=vision.heading_error + rad)
        return replace(
            base,
            vision=vision,
            floor=replace(base.floor, tile_size=self.tile_size, grout_width=floor_grout)
            if base.floor.tile_size != self.tile_size else base.floor,
            camera=replace(
                base.camera, ppm=self.ppm, width=self.image_width, height=self.image_height,
                offset=self.camera_offset,
            ),
            noise=replace(
                base.noise, speed_error=self.speed_error, yaw_rate_error=self.yaw_rate_error,
                compass_error=self.compass_error,
            ),
            sim=replace(
                base.sim, dt=self.dt, initial_pose=self.initial_pose,
                initial_pose_error=self.initial_pose_error,
            ),
        )


def read_meta(folder: str | os.PathLike[str]) -> DatasetMeta:
    """Read and validate ``folder/meta.json``."""
    path = Path(folder) / "meta.json"
    if not Path(folder).is_dir():
        what = "not a directory" if Path(folder).exists() else "no such directory"
        raise DatasetError(f"{folder}: {what} (a dataset is a folder with meta.json, frames.csv "
                           "and images)")
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise DatasetError(f"{path}: cannot read ({e.strerror or e})") from None
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not UTF-8 text") from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path}: not valid JSON ({e.msg} at line {e.lineno})") from None
    return DatasetMeta.from_json(d, where=str(path))


def _rgb(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2RGB)
    return image


class DatasetWriter:
    """Write a dataset frame by frame; every row is flushed as soon as it is written, so a crash
    leaves a valid (shorter) dataset.

    ``image_format``: ``png`` (lossless, replays bit-exactly) or ``jpg``. ``png_level``: zlib
    compression 0..9 of the PNGs. The default 0 stores the pixels, as a robot log keeps raw
    camera images: a noisy 320x240 camera image shrinks only 1.8x with OpenCV's default
    compression (127 vs 226 KB), while level 0 writes 7x faster (0.39 vs 2.75 ms) and decodes
    25x faster (libspng 0.03 vs 0.91 ms; ``python bench/png_levels.py``), which was most of a
    replay's decoding time.
    """

    def __init__(
        self,
        folder: str | os.PathLike[str],
        meta: DatasetMeta,
        *,
        image_format: str = "png",
        png_level: int = 0,
        overwrite: bool = False,
    ) -> None:
        if image_format not in ("png", "jpg"):
            raise ValueError(f"image_format must be 'png' or 'jpg', got {image_format!r}")
        if not isinstance(png_level, int) or not 0 <= png_level <= 9:
            raise ValueError(f"png_level must be an integer 0..9, got {png_level!r}")
        self.folder = Path(folder)
        if self.folder.exists() and any(self.folder.iterdir()) and not overwrite:
            raise ValueError(f"{self.folder}: output folder exists and is not empty")
        (self.folder / "images").mkdir(parents=True, exist_ok=True)
        self.meta = meta
        self.image_format = image_format
        self._params = (
            [cv2.IMWRITE_JPEG_QUALITY, 95] if image_format == "jpg" else
            # stored pixels: filtering only costs the reader time
            [cv2.IMWRITE_PNG_COMPRESSION, 0, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE]
            if png_level == 0 else [cv2.IMWRITE_PNG_COMPRESSION, png_level])
        (self.folder / "meta.json").write_text(
            json.dumps(meta.to_json(), indent=2) + "\n", encoding="utf-8"
        )
        self._file: IO[str] | None = open(  # noqa: SIM115 - closed in close()
            self.folder / "frames.csv", "w", newline="", encoding="utf-8"
        )
        self._csv = csv.writer(self._file)
        self._csv.writerow(FRAME_COLUMNS)
        self._file.flush()
        self._faults_file: IO[str] | None = None
        self.count = 0

    def write(self, frame: FrameInput | FrameRecord) -> None:
        """Append one frame (its image, odometry, compass and truth)."""
        if self._file is None:
            raise ValueError("dataset writer is closed")
        name = f"images/{self.count:06d}.{self.image_format}"
        image = _rgb(frame.image)
        if not cv2.imwrite(str(self.folder / name), image[:, :, ::-1], self._params):
            raise OSError(f"cannot write {self.folder / name}")
        odo = frame.odometry
        truth = frame.truth
        self._csv.writerow([
            self.count,
            _num(frame.t),
            name,
            _num(odo.speed) if odo is not None else "0.0",
            _num(odo.yaw_rate) if odo is not None else "0.0",
            _num(frame.compass) if frame.compass is not None else "",
            *((_num(truth.x), _num(truth.y), _num(truth.theta)) if truth else ("", "", "")),
        ])
        self._file.flush()
        faults = getattr(frame, "faults", ())
        if faults:
            self._write_faults(faults)
        self.count += 1

    def _write_faults(self, faults: tuple[str, ...]) -> None:
        """``faults.csv`` (a tileviz extension other readers may ignore): index, labels."""
        if self._faults_file is None:
            self._faults_file = open(  # noqa: SIM115 - closed in close()
                self.folder / FAULTS_FILE, "w", newline="", encoding="utf-8"
            )
            self._faults_file.write("index,faults\n")
        self._faults_file.write(f"{self.count},{';'.join(faults)}\n")
        self._faults_file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
        if self._faults_file is not None:
            self._faults_file.close()
            self._faults_file = None

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class _Row:
    line: int
    index: int
    t: float
    image: str
    speed: float
    yaw_rate: float
    compass: float | None
    truth: Pose | None


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _decode(raw: bytes, spng: bool = True) -> np.ndarray | None:
    """The image in the file bytes ``raw`` as HxWx3 RGB uint8, or None if it cannot be read.

    With ``spng``, a non-interlaced PNG is decoded by libspng (pyspng): the same pixels as
    OpenCV's decoder for every PNG kind (8/16-bit, gray, RGB, alpha, palette: tested), in less
    time and without the BGR->RGB step; anything else, or a PNG libspng refuses, goes to OpenCV.
    A PNG is read only if every chunk's CRC holds: pyspng decodes damaged data as if it were
    whole, and OpenCV's libpng prints its own complaint on stderr beside the one-line error
    the caller gives. pyspng holds the GIL while it decodes and OpenCV does not, so a background
    decoding thread wants ``spng=False`` to overlap the caller's work."""
    png = raw.startswith(_PNG_SIGNATURE)
    if png and not _png_chunks_intact(raw):
        return None
    if png and spng and len(raw) > 33 and raw[28] == 0:  # IHDR's interlace byte
        try:
            image = pyspng.load(raw, "RGB")
        except Exception:  # noqa: BLE001 - OpenCV decides, and its verdict is the error
            image = None
        if image is not None and image.dtype == np.uint8 and image.ndim == 3:
            return image
    image = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_COLOR) if raw else None
    if image is None:
        return None
    # (the same pixels as image[:, :, ::-1], contiguous, 30x cheaper than numpy's copy)
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def _png_chunks_intact(raw: bytes) -> bool:
    """Whether every chunk of the PNG file ``raw`` is complete and matches its CRC, up to IEND
    (0.06 ms for a stored 320x240 image)."""
    view = memoryview(raw)
    pos = len(_PNG_SIGNATURE)
    while pos + 12 <= len(raw):
        length = int.from_bytes(view[pos:pos + 4], "big")
        end = pos + 8 + length
        if end + 4 > len(raw):
            return False
        if zlib.crc32(view[pos + 4:end]) != int.from_bytes(view[end:end + 4], "big"):
            return False
        if view[pos + 4:pos + 8] == b"IEND":
            return True
        pos = end + 4
    return False


def _truncated(raw: bytes) -> bool:
    """Whether a PNG or JPEG file (by its signature) lacks its end marker (IEND chunk, EOI): a
    cut-off file, which the decoders would half-decode or complain about on stderr."""
    if raw.startswith(_PNG_SIGNATURE):
        return raw.rfind(b"IEND") < 0
    if raw.startswith(b"\xff\xd8"):
        return raw.rfind(b"\xff\xd9") < 2
    return False


def _parse_float(text: str, column: str, where: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise DatasetError(f"{where}: {column} is not a number ({text!r})") from None
    if not math.isfinite(v):
        raise DatasetError(f"{where}: {column} is not finite ({text!r})")
    if abs(v) > MAX_MAGNITUDE:
        raise DatasetError(f"{where}: {column} is out of range ({text!r}; |value| <= "
                           f"{MAX_MAGNITUDE:g})")
    return v


def replay_config(meta: DatasetMeta, *, mode: str | None = None,
                  extractor: str | None = None, base: Config | None = None) -> Config:
    """The configuration ``python -m tileviz replay`` uses for a dataset: the meta's floor,
    camera, bounds and start (over ``base``, or the stored tileviz config), then ``mode`` and
    ``extractor`` when given."""
    cfg = meta.to_config(base)
    if mode is not None:
        cfg = replace(cfg, localizer=replace(cfg.localizer, mode=mode))
    if extractor is not None:
        cfg = replace(cfg, vision=replace(cfg.vision, extractor=extractor))
    return cfg


def results_in_order(items: Iterator[T], submit: Callable[[T], Future[R]],
                     window: int) -> Iterator[tuple[T, R]]:
    """``(item, result)`` for every item of ``items`` in order, the work of up to ``window``
    items submitted ahead (``submit`` hands one to an executor). An error raised by ``items``
    (a bad row) is raised after every earlier item was delivered; an item's own error when its
    turn comes. Work not yet taken is cancelled when the caller stops early."""
    pending: deque[tuple[T, Future[R]]] = deque()
    error: Exception | None = None
    try:
        while True:
            while error is None and len(pending) < window:
                try:
                    item = next(items)
                except StopIteration:
                    break
                except Exception as e:  # noqa: BLE001 - raised at its turn, below
                    error = e
                    break
                pending.append((item, submit(item)))
            if not pending:
                break
            item, fut = pending.popleft()
            yield item, fut.result()
    finally:
        for _, fut in pending:
            fut.cancel()
    if error is not None:
        raise error


class DatasetSource:
    """Read a dataset as :class:`FrameInput` objects, validating every row as it goes.

    Images may be PNG or JPEG with any names; they are returned as HxWx3 uint8 RGB.
    """

    def __init__(self, folder: str | os.PathLike[str], *, prefetch: int = 0) -> None:
        """``prefetch``: images decoded ahead of the frame being delivered, on a background
        thread (OpenCV's decoder releases the GIL, so decoding overlaps the caller's vision);
        0 decodes each image when its frame is asked for. Errors still arrive in row order."""
        if not isinstance(prefetch, int) or prefetch < 0:
            raise ValueError(f"prefetch must be an integer >= 0, got {prefetch!r}")
        self.prefetch = prefetch
        self.folder = Path(folder)
        self.meta = read_meta(folder)
        self.frames_path = self.folder / "frames.csv"
        if not self.frames_path.is_file():
            raise DatasetError(f"{self.frames_path}: missing")
        try:
            with open(self.frames_path, newline="", encoding="utf-8") as f:
                header = next(csv.reader(f), None)
        except UnicodeDecodeError:
            raise DatasetError(f"{self.frames_path}: not UTF-8 text") from None
        if header is None:
            raise DatasetError(f"{self.frames_path}: empty (no header row)")
        header = [h.strip() for h in header]
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing:
            raise DatasetError(f"{self.frames_path}: missing column(s) {', '.join(missing)}")
        self.columns = header
        self.faults = self._read_faults()
        self._rectifier: Rectifier | None = None

    def _read_faults(self) -> dict[int, tuple[str, ...]]:
        path = self.folder / FAULTS_FILE
        if not path.is_file():
            return {}
        out: dict[int, tuple[str, ...]] = {}
        try:
            with open(path, newline="", encoding="utf-8") as f:
                for lineno, cells in enumerate(csv.reader(f), start=1):
                    if lineno == 1 or not cells:
                        continue
                    try:
                        out[int(cells[0])] = tuple(x for x in cells[1].split(";") if x)
                    except (ValueError, IndexError):
                        raise DatasetError(
                            f"{path} row {lineno}: expected 'index,labels'") from None
        except UnicodeDecodeError:
            raise DatasetError(f"{path}: not UTF-8 text") from None
        return out

    def row_count(self) -> int:
        """How many non-blank data rows frames.csv has (for a progress bar: the rows are not
        checked here; a bad one still stops the frames at its turn)."""
        try:
            with open(self.frames_path, newline="", encoding="utf-8") as f:
                rows = csv.reader(f)
                next(rows, None)
                return sum(1 for cells in rows if any(c.strip() for c in cells))
        except (UnicodeDecodeError, csv.Error, OSError):
            return 0

    def _rows(self) -> Iterator[_Row]:
        try:
            yield from self._parse_rows()
        except UnicodeDecodeError:
            raise DatasetError(f"{self.frames_path}: not UTF-8 text") from None

    def _parse_rows(self) -> Iterator[_Row]:
        with open(self.frames_path, newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            next(reader)
            expected_index = 0
            last_t = -math.inf
            for lineno, cells in enumerate(reader, start=2):
                where = f"{self.frames_path} row {lineno}"
                if not cells or all(not c.strip() for c in cells):
                    continue
                if len(cells) < len(self.columns):
                    raise DatasetError(f"{where}: truncated ({len(cells)} of "
                                       f"{len(self.columns)} columns)")
                rec = {c: cells[i].strip() for i, c in enumerate(self.columns)}
                try:
                    index = int(rec["index"])
                except ValueError:
                    raise DatasetError(f"{where}: index is not an integer "
                                       f"({rec['index']!r})") from None
                if index != expected_index:
                    raise DatasetError(f"{where}: index {index}, expected {expected_index}")
                expected_index += 1
                t = _parse_float(rec["t"], "t", where)
                if t <= last_t:
                    raise DatasetError(f"{where}: t={t!r} does not increase")
                last_t = t
                if not rec["image"]:
                    raise DatasetError(f"{where}: image is empty")
                speed = _parse_float(rec["speed"], "speed", where)
                yaw_rate = _parse_float(rec["yaw_rate"], "yaw_rate", where)
                comp_text = rec.get("compass", "")
                compass = _parse_float(comp_text, "compass", where) if comp_text else None
                if compass is not None and not -math.pi - 1e-9 <= compass <= math.pi + 1e-9:
                    raise DatasetError(f"{where}: compass {compass!r} is not in (-pi, pi]")
                cells_truth = [rec.get(c, "") for c in ("x", "y", "theta")]
                truth = None
                if any(cells_truth):
                    if not all(cells_truth):
                        raise DatasetError(f"{where}: x, y, theta must be all given or all empty")
                    truth = Pose(*(_parse_float(v, c, where)
                                   for v, c in zip(cells_truth, ("x", "y", "theta"), strict=True)))
                yield _Row(lineno, index, t, rec["image"], speed, yaw_rate, compass, truth)

    def load_image(self, name: str, where: str) -> np.ndarray:
        """Read one image as HxWx3 RGB uint8; errors name the row and the file."""
        path = (self.folder / name)
        if not path.is_file():
            raise DatasetError(f"{where}: image {name!r} is missing")
        raw = path.read_bytes()
        if _truncated(raw):
            raise DatasetError(f"{where}: image {name!r} is truncated (no end marker)")
        # a prefetching source decodes on a thread: OpenCV's decoder lets the caller run
        image = _decode(raw, spng=self.prefetch == 0)
        if image is None:
            raise DatasetError(f"{where}: image {name!r} is not a readable PNG/JPEG")
        h, w = image.shape[:2]
        cm = self.meta.camera_model
        size = (cm.raw_width, cm.raw_height) if cm else (self.meta.image_width,
                                                         self.meta.image_height)
        if (w, h) != size:
            raise DatasetError(f"{where}: image {name!r} is {w}x{h}, meta.json says "
                               f"{size[0]}x{size[1]}{' (camera_model raw size)' if cm else ''}")
        if cm is not None:  # to the orthographic view; the tables are computed once
            if self._rectifier is None:
                self._rectifier = self.meta.rectifier()
            image = self._rectifier(image)  # type: ignore[misc]
        return image

    def _jobs(self) -> Iterator[tuple[_Row, Odometry | None, str]]:
        """(row, its odometry, where) in order. A bad row raises DatasetError after the row
        before it was given (without odometry: it has no successor)."""
        rows = self._rows()
        current = next(rows, None)
        while current is not None:
            where = f"{self.frames_path} row {current.line}"
            try:
                nxt = next(rows, None)
            except DatasetError:
                yield current, None, where
                raise
            odometry = None
            if nxt is not None:
                odometry = Odometry(current.speed, current.yaw_rate, nxt.t - current.t)
            yield current, odometry, where
            current = nxt

    def __iter__(self) -> Iterator[FrameInput]:
        """The frames in order. A bad row raises DatasetError naming it, after every frame
        before it was delivered (the one just before it without odometry, as a last frame)."""
        if self.prefetch == 0:
            for row, odometry, where in self._jobs():
                yield self._frame(row, odometry, self.load_image(row.image, where))
            return
        yield from self._prefetched()

    def frames_without_images(self) -> Iterator[tuple[FrameInput, str]]:
        """Every frame in order with an empty image (0x0x3) and the text naming its row (for
        :meth:`load_image`), for a reader that decodes the images elsewhere
        (:mod:`tileviz.parallel`). A bad row raises DatasetError as :meth:`__iter__` does."""
        for row, odometry, where in self._jobs():
            yield self._frame(row, odometry, _NO_IMAGE), where

    def _prefetched(self) -> Iterator[FrameInput]:
        """:meth:`__iter__` with up to ``prefetch`` images decoding ahead on one thread."""
        with ThreadPoolExecutor(1, thread_name_prefix="tileviz-decode") as pool:
            for (row, odometry, _), image in results_in_order(
                    self._jobs(), lambda job: pool.submit(self.load_image, job[0].image, job[2]),
                    self.prefetch):
                yield self._frame(row, odometry, image)

    def _frame(self, row: _Row, odometry: Odometry | None, image: np.ndarray) -> FrameInput:
        return FrameInput(
            index=row.index,
            t=row.t,
            image=np.ascontiguousarray(image),
            odometry=odometry,
            compass=row.compass,
            truth=row.truth,
            image_name=row.image,
            faults=self.faults.get(row.index, ()),
        )


class CsvOut:
    """A CSV file written row by row and flushed after every row (rows already written stay
    valid if the run stops)."""

    def __init__(self, path: str | os.PathLike[str], columns: tuple[str, ...]) -> None:
        p = Path(path)
        if p.parent and not p.parent.exists():
            raise OSError(f"{p.parent}: output directory does not exist")
        self._file: IO[str] = open(p, "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._csv = csv.writer(self._file)
        self._csv.writerow(columns)
        self._file.flush()

    def row(self, values: list[Any]) -> None:
        self._csv.writerow(values)
        self._file.flush()

    def close(self) -> None:
        self._file.close()


def replay_row(rec: FrameRecord) -> list[Any]:
    """One row of the replay output (dataset-format.md, 'Replay output')."""
    hull = rec.updated.hull()
    if hull is None:
        bounds = ["nan"] * 6
    else:
        bounds = [_num(v) for v in hull.as_tuple()]
    return [rec.index, _num(rec.t), rec.status, *bounds, len(rec.updated)]


def residual_row(rec: FrameRecord) -> list[Any]:
    """One row of the ``--output-file`` CSV: the six equivalence residuals (empty when there is
    no observation or no truth)."""
    r = rec.residuals
    return [rec.index, _num(rec.t), *([_num(v) for v in r] if r is not None else [""] * 6)]
