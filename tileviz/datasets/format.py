"""tileviz-dataset/1, the format: ``meta.json`` (:class:`DatasetMeta`), the columns of
``frames.csv`` and how their numbers are written and parsed.

The contract is ``docs/dataset-format.md``. A dataset is a folder with ``meta.json``,
``frames.csv`` and images. Row k of ``frames.csv``: the image taken at pose k, the compass measured
at frame k, and the odometry (speed, yaw rate) describing the motion from frame k to frame k+1,
held over ``t[k+1] - t[k]`` seconds (``meta.dt`` when ``t`` is missing on the next row or there is
no next row).

Errors are :class:`DatasetError` (a ValueError) whose message names the file and, for rows, the
line of the file (1-based, the header is line 1) and the frame (its ``index``) once that is read:
``frames.csv line 52 (frame 50)``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from tileviz.config import FLOOR_KINDS, PERFECT_FLOOR, Config, Extractor, FloorModel, Mode
from tileviz.core.constants import LIMIT, MAX_PPM, MAX_TILE_PX, MIN_TILE_PX
from tileviz.datasets.camera_model import CameraModel, CameraModelError, Rectifier, view_margin
from tileviz.datasets.images import MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE

__all__ = [
    "FAULTS_FILE", "FORMAT", "FRAME_COLUMNS", "MAX_MAGNITUDE", "REQUIRED_COLUMNS",
    "DatasetError", "DatasetMeta", "csv_line", "floor_block", "json_file", "num_text",
    "parse_float", "read_meta", "replay_config",
]

FORMAT = "tileviz-dataset/1"
FRAME_COLUMNS = ("index", "t", "image", "speed", "yaw_rate", "compass", "x", "y", "theta")
REQUIRED_COLUMNS = ("index", "t", "image", "speed", "yaw_rate")
MAX_MAGNITUDE = LIMIT
"""Largest magnitude of a number in meta.json (the localizer's)."""
FAULTS_FILE = "faults.csv"
"""Optional tileviz extension: ``index,faults`` with ``;``-separated labels of injected faults."""


class DatasetError(ValueError):
    """A dataset that does not follow tileviz-dataset/1; the message names file and row."""


def num_text(x: float) -> str:
    """A float written so that it round-trips exactly (``repr``)."""
    return repr(float(x))


def csv_line(cells: list[Any] | tuple[Any, ...]) -> bytes:
    """One CSV line (the ``csv`` module's quoting, ``\r\n`` line end) as UTF-8 bytes."""
    buf = io.StringIO()
    csv.writer(buf).writerow(cells)
    return buf.getvalue().encode("utf-8")


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
    complete: bool | None = None
    """The writer's own word on the dataset (``docs/dataset-format.md``, "A dataset being
    written"): False while it is written (or when its writer stopped before closing it), True once
    closed; None when meta.json does not say (a dataset written by a program that does not keep
    this key: taken as whole)."""
    frames: int | None = None
    """The number of rows the writer wrote to frames.csv, once ``complete``; None when not said."""
    floor: FloorModel | None = None
    """The ``floor`` block: the floor's kind and lattice tolerance; None: no block (a perfect
    grout lattice)."""

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
            floor=cfg.floor.model if cfg.floor.model != PERFECT_FLOOR else None,
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
        if self.complete is not None:
            d["complete"] = self.complete
        if self.frames is not None:
            d["frames"] = self.frames
        if self.floor is not None:
            d["floor"] = {"kind": self.floor.kind,
                          "lattice_tolerance": self.floor.lattice_tolerance}
        return d

    @classmethod
    def from_json(cls, d: Any, where: str = "meta.json") -> DatasetMeta:
        """Validate and parse; errors name the key."""
        if not isinstance(d, dict):
            raise DatasetError(f"{where}: must be a JSON object")
        if d.get("format") != FORMAT:
            got = as_json(d["format"]) if "format" in d else "nothing (no format key)"
            raise DatasetError(f"{where}: format must be {as_json(FORMAT)}, got {got}")
        known = {
            "format", "name", "tile_size", "ppm", "image_width", "image_height", "camera_offset",
            "dt", "initial_pose", "initial_pose_error", "speed_error", "yaw_rate_error",
            "compass_error", "camera_model", "complete", "frames", "floor",
        }
        missing = sorted(k for k in known - {"name", "camera_model", "complete", "frames", "floor"}
                         if k not in d)
        if missing:
            raise DatasetError(f"{where}: missing key(s) {', '.join(missing)}")

        def number(key: str, *, positive: bool) -> float:
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise DatasetError(f"{where}: {key} must be a finite number, got {as_json(v)}")
            if abs(v) > MAX_MAGNITUDE:
                raise DatasetError(f"{where}: {key} must be within +-{MAX_MAGNITUDE:g}, "
                                   f"got {as_json(v)}")
            if positive and v <= 0 or not positive and v < 0:
                raise DatasetError(f"{where}: {key} must be {'> 0' if positive else '>= 0'}, "
                                   f"got {as_json(v)}")
            return float(v)

        def integer(key: str) -> int:
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise DatasetError(f"{where}: {key} must be an integer > 0, got {as_json(v)}")
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
                                   f"within +-{MAX_MAGNITUDE:g}, got {as_json(v)}")
            return tuple(float(e) for e in v)

        if number("ppm", positive=True) > MAX_PPM:
            raise DatasetError(f"{where}: ppm must be <= {MAX_PPM:g}, got {as_json(d['ppm'])}")
        tile_px = number("tile_size", positive=True) * number("ppm", positive=True)
        if not MIN_TILE_PX <= tile_px <= MAX_TILE_PX:
            most = (f"at least {MIN_TILE_PX:g}" if tile_px < MIN_TILE_PX
                    else f"at most {MAX_TILE_PX:g}")
            raise DatasetError(f"{where}: a tile must span {most} pixels (tile_size * ppm), "
                               f"got {tile_px!r}")
        name = d.get("name", "")
        complete = d.get("complete")
        if complete is not None and not isinstance(complete, bool):
            raise DatasetError(f"{where}: complete must be true or false, got {as_json(complete)}")
        frames = d.get("frames")
        if frames is not None and (isinstance(frames, bool) or not isinstance(frames, int)
                                   or frames < 0):
            raise DatasetError(f"{where}: frames must be an integer >= 0, got {as_json(frames)}")
        width, height = integer("image_width"), integer("image_height")
        if max(width, height) > MAX_IMAGE_SIDE or width * height > MAX_IMAGE_PIXELS:
            # before anything is sized by them (the rectification's tables, the views)
            raise DatasetError(f"{where}: image_width x image_height is {width}x{height}, more "
                               f"than tileviz reads (at most {MAX_IMAGE_SIDE} a side and "
                               f"{MAX_IMAGE_PIXELS} pixels in all)")
        try:
            camera_model = (CameraModel.from_json(d["camera_model"], where)
                            if d.get("camera_model") is not None else None)
        except CameraModelError as e:
            raise DatasetError(str(e)) from None
        floor = (floor_block(d["floor"], number("tile_size", positive=True), where)
                 if d.get("floor") is not None else None)
        return cls(
            name=str(name),
            tile_size=number("tile_size", positive=True),
            ppm=number("ppm", positive=True),
            image_width=width,
            image_height=height,
            camera_offset=vector("camera_offset", 2),  # type: ignore[arg-type]
            dt=number("dt", positive=True),
            initial_pose=vector("initial_pose", 3),  # type: ignore[arg-type]
            initial_pose_error=vector("initial_pose_error", 3, nonneg=True),  # type: ignore[arg-type]
            speed_error=number("speed_error", positive=False),
            yaw_rate_error=number("yaw_rate_error", positive=False),
            compass_error=number("compass_error", positive=False),
            extra={k: v for k, v in d.items() if k not in known},
            camera_model=camera_model,
            complete=complete,
            frames=frames,
            floor=floor,
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
        vision = base.vision
        rectifier = self.rectifier()
        if rectifier is not None:  # the view bound grows by what the rectification may move
            px, rad = view_margin(rectifier.model, rectifier)
            vision = replace(vision, position_error_px=vision.position_error_px + px,
                             heading_error=vision.heading_error + rad)
        floor = (base.floor.with_tile_size(self.tile_size)
                 if base.floor.tile_size != self.tile_size else base.floor)
        model = self.floor or PERFECT_FLOOR  # no block: a perfect grout lattice
        if (floor.kind, floor.lattice_tolerance) != (model.kind, model.lattice_tolerance):
            floor = replace(floor, kind=model.kind, lattice_tolerance=model.lattice_tolerance)
        return replace(
            base,
            vision=vision,
            floor=floor,
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


def as_json(value: Any) -> str:
    """``value`` (read from a JSON file) as JSON writes it (``null``, ``true``, ``"text"``),
    for an error naming what the file holds; ``repr`` for what JSON cannot write."""
    try:
        return json.dumps(value, allow_nan=True)
    except (TypeError, ValueError):
        return repr(value)


def floor_block(block: Any, tile_size: float, where: str) -> FloorModel:
    """The ``floor`` block of a meta.json (``docs/dataset-format.md``): ``kind`` (default
    ``grout``) and ``lattice_tolerance`` (metres, default 0, below a quarter of ``tile_size``);
    other keys are ignored. DatasetError naming the key otherwise."""
    if not isinstance(block, dict):
        raise DatasetError(f"{where}: floor must be a JSON object, got {as_json(block)}")
    kind = block.get("kind", "grout")
    if kind not in FLOOR_KINDS:
        raise DatasetError(f"{where}: floor.kind must be one of {', '.join(FLOOR_KINDS)}, got "
                           f"{as_json(kind)}")
    tol = block.get("lattice_tolerance", 0.0)
    if (isinstance(tol, bool) or not isinstance(tol, int | float) or not math.isfinite(tol)
            or tol < 0):
        raise DatasetError(f"{where}: floor.lattice_tolerance must be a finite number >= 0 "
                           f"(metres), got {as_json(tol)}")
    if tol >= tile_size / 4:
        raise DatasetError(f"{where}: floor.lattice_tolerance must be below a quarter of the "
                           f"tile ({tile_size / 4:g} m), got {as_json(tol)}")
    return FloorModel(kind, float(tol))


def read_meta(folder: str | os.PathLike[str]) -> DatasetMeta:
    """Read and validate ``folder/meta.json``."""
    path = Path(folder) / "meta.json"
    if not Path(folder).is_dir():
        what = "not a directory" if Path(folder).exists() else "no such directory"
        raise DatasetError(f"{folder}: {what} (a dataset is a folder with meta.json, frames.csv "
                           "and images)")
    return DatasetMeta.from_json(json_file(path), where=str(path))


def json_file(path: str | os.PathLike[str], label: str = "") -> Any:
    """The JSON value in the file ``path``; DatasetError naming it (after ``label``, e.g.
    ``"--camera-model: "``) when it cannot be read, is not UTF-8 text or not JSON (nested
    too deeply included)."""
    where = f"{label}{path}"
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as e:
        raise DatasetError(f"{where}: cannot read ({e.strerror or e})") from None
    except UnicodeDecodeError:
        raise DatasetError(f"{where}: not UTF-8 text") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise DatasetError(f"{where}: not valid JSON ({e.msg} at line {e.lineno})") from None
    except RecursionError:
        raise DatasetError(f"{where}: not valid JSON (nested too deeply)") from None


def parse_float(text: str, column: str, where: str) -> float:
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


def replay_config(meta: DatasetMeta, *, mode: Mode | None = None,
                  extractor: Extractor | None = None, base: Config | None = None,
                  where: str = "meta.json") -> Config:
    """The configuration ``python -m tileviz replay`` uses for a dataset: the meta's floor,
    camera, bounds and start (over ``base``, or the stored tileviz config), then ``mode`` and
    ``extractor`` when given. A meta the configuration refuses (a view or a tile tileviz
    cannot work with) raises DatasetError naming ``where`` (the meta.json)."""
    try:
        cfg = meta.to_config(base)
    except DatasetError:
        raise
    except ValueError as e:
        raise DatasetError(f"{where}: {e}") from None
    if mode is not None:
        cfg = replace(cfg, localizer=replace(cfg.localizer, mode=mode))
    if extractor is not None:
        cfg = replace(cfg, vision=replace(cfg.vision, extractor=extractor))
    return cfg
