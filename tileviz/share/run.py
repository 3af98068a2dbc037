"""A dataset replayed once for sharing: the frame records of a range of frames, as
``python -m tileviz replay`` computes them.

:func:`load_run` runs :func:`tileviz.pipeline.replay.replay` (the same reader, frame loop and
options, so every box is the one ``replay --out`` writes for that frame) from the dataset's first
frame (the localizer needs every frame before the range) to the range's last, and keeps the
records of the range without their image arrays. A frame's camera image is read again from the
dataset when it is drawn (:meth:`Run.image`), and a pipeline stage is drawn by running vision
again on it with its stage images kept (:meth:`Run.stage`: the same extractor on the same pixels
gives the same view).

Frame ranges are half-open, in frame indices: ``start`` is the first frame kept, ``end`` the
frame after the last (None: the dataset's end).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from tileviz.config import Config, Extractor, Mode
from tileviz.pipeline import FrameRecord
from tileviz.summary import RunTally

__all__ = ["Run", "Views", "check_dataset", "fit_width", "frame_range", "load_boxes", "load_run",
           "parse_frames"]


def check_dataset(folder: str | os.PathLike[str]) -> int:
    """The number of frame rows of the dataset ``folder``; DatasetError (a ValueError) in one line
    when it is not a dataset (no such folder, no ``meta.json`` or ``frames.csv``, a bad
    ``meta.json``) or has no frame (an empty recording)."""
    from tileviz.datasets import DatasetError, DatasetSource

    p = Path(folder)
    if p.is_dir() and not (p / "meta.json").is_file():
        raise DatasetError(f"{p}: not a dataset (no meta.json; a dataset is a folder with "
                           "meta.json, frames.csv and images, as record, import-bag and the "
                           "demo's Record write)")
    source = DatasetSource(p)
    n = source.row_count()
    if n == 0:
        raise DatasetError(f"{p}: the dataset has no frames (an empty recording: frames.csv has "
                           "no row)")
    return n


def frame_range(frames: int, start: int | None, end: int | None,
                names: tuple[str, str] = ("--start", "--end")) -> tuple[int, int]:
    """The half-open range [start, end) of frame indices in a run of ``frames`` frames (0 ..
    frames - 1); None: the run's first frame, its end. ValueError naming the option (``names``)
    when the range is empty or outside the run."""
    last = frames - 1
    a = 0 if start is None else int(start)
    b = frames if end is None else int(end)
    if not 0 <= a <= last:
        raise ValueError(f"{names[0]} {a} is outside the run (frames 0 to {last})")
    if b > frames:
        raise ValueError(f"{names[1]} {b} is past the run's end (frames 0 to {last}: at most "
                         f"{frames})")
    if b <= a:
        raise ValueError(f"{names[1]} {b} must be greater than {names[0]} {a} (the range "
                         "[start, end) would hold no frame)")
    return a, b


def parse_frames(text: str) -> tuple[int | None, int | None]:
    """``A:B``, ``A:`` or ``:B`` (frame indices, half-open) as (start, end), None where empty;
    ValueError naming ``--frames`` otherwise."""
    parts = text.split(":")
    if len(parts) != 2:
        raise ValueError(f"--frames must be A:B (frame indices; A or B may be left out), got "
                         f"{text!r}")
    out: list[int | None] = []
    for part in parts:
        part = part.strip()
        if not part:
            out.append(None)
            continue
        try:
            v = int(part)
        except ValueError:
            raise ValueError(f"--frames must be A:B with integers, got {text!r}") from None
        if v < 0:
            raise ValueError(f"--frames: frame indices are >= 0, got {text!r}")
        out.append(v)
    return out[0], out[1]


def fit_width(image: np.ndarray, width: int) -> np.ndarray:
    """``image`` (HxW gray or HxWx3 RGB) as HxWx3 uint8 RGB ``width`` pixels wide (same
    aspect)."""
    import cv2

    img = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2RGB)
    img = np.ascontiguousarray(img[..., :3], dtype=np.uint8)
    h, w = img.shape[:2]
    if w != width:
        height = max(1, int(round(h * width / w)))
        img = cv2.resize(img, (width, height), interpolation=cv2.INTER_AREA)
    return img


@dataclass(frozen=True)
class Views:
    """Which images :func:`load_run` keeps: the camera view and the pipeline stage ``stage``
    (None: none) of every ``every``-th kept frame, ``width`` pixels wide, as JPEG of
    ``quality``."""

    every: int = 1
    width: int = 200
    stage: str | None = None
    quality: int = 60


@dataclass
class Run:
    """The records of frames ``start`` .. ``end`` - 1 of a replayed dataset (see the module
    docstring). ``cfg``: the configuration the replay used (:func:`tileviz.datasets.replay_config`
    of the dataset's meta with the mode and extractor asked for); ``frames``: the dataset's frame
    count; ``tally``: statuses and containment over the kept records."""

    folder: Path
    name: str
    cfg: Config
    frames: int
    start: int
    end: int
    records: list[FrameRecord]
    tally: RunTally
    camera_model: bool = False
    """The dataset's images are a real camera's: :meth:`image` gives the rectified gray view
    vision reads."""
    views: dict[int, dict[str, bytes]] = field(default_factory=dict)
    """Frame index -> ``camera`` and the stage's name -> JPEG bytes (:class:`Views`); a stage
    the frame's extractor did not draw is absent."""
    table: Path | None = None
    """The replay CSV (``replay --out``) the records were read from instead of replaying
    (:func:`load_boxes`), or None (replayed). From a table, a record's ``updated`` set is the
    CSV's bounding box of the set (the set itself when it is one box: :attr:`box_counts`), its
    ``predicted`` set is empty (the CSV does not hold it) and it has no view."""
    box_counts: dict[int, int] = field(default_factory=dict)
    """From a table: frame index -> how many boxes the set had (the CSV's ``boxes``)."""
    _source: object = field(default=None, repr=False)

    @property
    def dt(self) -> float:
        """The dataset's frame period, seconds."""
        return float(self.cfg.sim.dt)

    def picks(self, every: int) -> list[FrameRecord]:
        """Every ``every``-th kept record, from the first."""
        return self.records[:: max(1, int(every))]

    def image(self, rec: FrameRecord) -> np.ndarray:
        """The image vision read for ``rec`` (HxWx3 RGB, or HxW gray for a camera model),
        read again from the dataset."""
        from tileviz.datasets import DatasetSource

        if self._source is None:
            self._source = DatasetSource(self.folder)
        src = self._source
        assert isinstance(src, DatasetSource)
        return src.load_image(rec.image_name, f"{self.folder} frame {rec.index}")

    def stage(self, rec: FrameRecord, name: str,
              image: np.ndarray | None = None) -> np.ndarray | None:
        """The pipeline stage ``name`` (HxWx3 RGB) of ``rec``'s view, or None when its extractor
        drew no such stage for this frame. ``image``: :meth:`image` of ``rec`` when already
        read."""
        from tileviz.vision import extract

        img = self.image(rec) if image is None else image
        v = extract(img, camera=self.cfg.camera, tile_size=self.cfg.floor.tile_size,
                    vision=self.cfg.vision, keep_stages=True)
        return v.stages.get(name)

    def kept_view(self, rec: FrameRecord, name: str) -> np.ndarray | None:
        """The kept image ``name`` (``camera`` or a stage) of ``rec`` as HxWx3 RGB, or None
        when it was not kept."""
        import cv2

        data = self.views.get(rec.index, {}).get(name)
        if data is None:
            return None
        bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        assert bgr is not None, "a kept view is a JPEG this process encoded"
        return np.ascontiguousarray(bgr[..., ::-1])

    def truth_path(self) -> np.ndarray:
        """(N, 2) true x, y of the kept records, metres (NaN where unknown)."""
        out = np.full((len(self.records), 2), math.nan)
        for i, r in enumerate(self.records):
            if r.truth is not None:
                out[i] = (r.truth.x, r.truth.y)
        return out

    def summary(self) -> str:
        """The run's one-line summary (as ``replay`` prints it), for the kept frames."""
        return "; ".join(self.tally.parts())


def load_run(dataset: str | os.PathLike[str], *, start: int | None = None,
             end: int | None = None, mode: Mode | None = None,
             extractor: Extractor | None = None, jobs: int | None = None,
             names: tuple[str, str] = ("--start", "--end"),
             views: Views | None = None,
             on_total: Callable[[int], None] | None = None,
             on_frame: Callable[[FrameRecord], None] | None = None) -> Run:
    """Replay ``dataset`` (see the module docstring) and keep frames [start, end) and the
    ``views`` asked for (vision then runs in this process, whatever ``jobs``).
    ``mode``, ``extractor``, ``jobs``: as ``replay``'s. ``names``: how errors name ``start`` and
    ``end``. ``on_total`` gets the number of frames to replay before the first, ``on_frame``
    every record replayed (a progress bar). Errors (not a dataset, an empty one, a range outside
    the run, a bad row) raise ValueError in one line before anything is kept."""
    from tileviz.app.history import strip_record
    from tileviz.datasets import read_meta, replay_config
    from tileviz.pipeline.replay import replay

    folder = Path(dataset)
    frames = check_dataset(folder)
    a, b = frame_range(frames, start, end, names)
    meta = read_meta(folder)
    cfg = replay_config(meta, mode=mode, extractor=extractor)
    kept: list[FrameRecord] = []
    tally = RunTally()
    images: dict[int, dict[str, bytes]] = {}

    def take(rec: FrameRecord) -> None:
        if a <= rec.index < b:
            if views is not None and len(kept) % max(1, views.every) == 0:
                images[rec.index] = _views_of(rec, views)
            kept.append(strip_record(rec))
            tally.add(rec)
        if on_frame is not None:
            on_frame(rec)

    if on_total is not None:
        on_total(b)
    replay(folder, mode=mode, extractor=extractor, jobs=jobs, on_frame=take, until=b - 1,
           keep_stages=views is not None and views.stage is not None)
    if not kept:
        raise ValueError(f"{folder}: no frame of the range {a}:{b} was replayed")
    return Run(folder=folder, name=meta.name or folder.name, cfg=cfg, frames=frames, start=a,
               end=kept[-1].index + 1, records=kept, tally=tally,
               camera_model=meta.camera_model is not None, views=images)


def load_boxes(dataset: str | os.PathLike[str], table: str | os.PathLike[str], *,
               start: int | None = None, end: int | None = None,
               names: tuple[str, str] = ("--start", "--end"), option: str = "--boxes") -> Run:
    """The run of ``dataset`` (frames [start, end)) as the replay CSV ``table`` recorded it
    (docs/dataset-format.md, "Replay output"), without replaying: the statuses and sets from
    the CSV, the truth and times from the dataset's frames.csv (see :attr:`Run.table`). The CSV
    must be the replay of this dataset: one row per frame, the same indices in order and the
    same times; otherwise, or on a bad row, ValueError (OSError when it cannot be read) in one
    line naming ``option``, the file and the problem."""
    import csv

    from tileviz.core.localizer import LocalizerStep
    from tileviz.datasets import DatasetSource, read_meta, replay_config
    from tileviz.datasets.format import parse_float
    from tileviz.pipeline.outputs import REPLAY_COLUMNS
    from tileviz.types import STATUSES, Box, BoxSet
    from tileviz.vision.result import VisionResult

    folder = Path(dataset)
    frames = check_dataset(folder)
    a, b = frame_range(frames, start, end, names)
    meta = read_meta(folder)
    path = Path(table)
    name = f"{option} {path}"
    inputs = [fi for fi, _ in DatasetSource(folder).frames_without_images()]
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except UnicodeDecodeError:
        raise ValueError(f"{name}: not UTF-8 text (a replay CSV: replay --out writes one)"
                         ) from None
    except csv.Error as e:
        raise ValueError(f"{name}: not a CSV file ({e})") from None
    except OSError as e:
        raise OSError(f"{name}: cannot be read ({e.strerror or e})") from None
    header = [c.strip() for c in rows[0]] if rows else []
    missing = [c for c in REPLAY_COLUMNS if c not in header]
    if missing:
        raise ValueError(f"{name}: not a replay CSV (no column {', '.join(missing)}; replay "
                         "--out writes one)")
    rows = [r for r in rows[1:] if any(c.strip() for c in r)]
    if len(rows) != len(inputs):
        raise ValueError(f"{name}: {len(rows)} frame rows, but {folder} has {len(inputs)} "
                         f"frames: not the replay of this dataset (python -m tileviz replay "
                         f"{folder} --out {path} writes it)")
    col = {c: header.index(c) for c in REPLAY_COLUMNS}
    kept: list[FrameRecord] = []
    tally = RunTally()
    counts: dict[int, int] = {}
    no_view = VisionResult(observation=None, accepted=False, reason="no lines")
    for line, (cells, fi) in enumerate(zip(rows, inputs, strict=True), start=2):
        if len(cells) < len(header):
            raise ValueError(f"{name} line {line}: truncated ({len(cells)} of {len(header)} "
                             "columns)")
        cell = {c: cells[i].strip() for c, i in col.items()}
        where = f"{name} line {line}"
        if cell["index"] != str(fi.index):
            raise ValueError(f"{where}: frame index {cell['index']!r}, but {folder}'s frame "
                             f"there is {fi.index}: not the replay of this dataset")
        if parse_float(cell["t"], "t", where) != fi.t:
            raise ValueError(f"{where}: t = {cell['t']}, but {folder}'s frame {fi.index} has "
                             f"t = {fi.t!r}: not the replay of this dataset")
        if not a <= fi.index < b:
            continue
        status = cell["status"]
        if status not in STATUSES:
            raise ValueError(f"{where}: status {status!r} is not one of {', '.join(STATUSES)}")
        bounds = [cell[c] for c in REPLAY_COLUMNS[3:9]]
        if all(v.lower() == "nan" for v in bounds):
            updated = BoxSet(())
        else:
            box = Box(*(parse_float(v, c, where) for v, c in zip(bounds, REPLAY_COLUMNS[3:9],
                                                                  strict=True)))
            if not (box.x_lo <= box.x_hi and box.y_lo <= box.y_hi
                    and box.t_lo <= box.t_hi):
                raise ValueError(f"{where}: a bound's low end is above its high end")
            updated = BoxSet((box,))
        try:
            counts[fi.index] = int(cell["boxes"])
        except ValueError:
            raise ValueError(f"{where}: boxes is not an integer ({cell['boxes']!r})") from None
        rec = FrameRecord(index=fi.index, t=fi.t, truth=fi.truth, odometry=fi.odometry,
                          compass=fi.compass, image=fi.image, setpoint=None, vision=no_view,
                          residuals=None,
                          step=LocalizerStep(BoxSet(()), updated, status, 0),
                          image_name=fi.image_name)
        kept.append(rec)
        tally.add(rec)
    return Run(folder=folder, name=meta.name or folder.name, cfg=replay_config(meta),
               frames=frames, start=a, end=b, records=kept, tally=tally,
               camera_model=meta.camera_model is not None, table=path, box_counts=counts)


def _views_of(rec: FrameRecord, views: Views) -> dict[str, bytes]:
    """The JPEG images of ``rec`` that ``views`` asks for (its record still holds its image
    and, with a stage, its stage images)."""
    from tileviz.app.history import encode_jpeg

    out: dict[str, bytes] = {}
    if rec.image.size:
        out["camera"] = encode_jpeg(fit_width(rec.image, views.width), views.quality)
    name = views.stage
    stage = rec.vision.stages.get(name) if name is not None else None
    if name is not None and stage is not None:
        out[name] = encode_jpeg(fit_width(stage, views.width), views.quality)
    return out


def with_room(cfg: Config, half: float) -> Config:
    """``cfg`` with a room of half side ``half`` metres (the floor drawn under a dataset)."""
    return replace(cfg, sim=replace(cfg.sim, room_half_size=half))


def bounds_of(points: Sequence[tuple[float, float]] | np.ndarray,
              at_least: float = 1.0) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1), metres: the finite points' bounding box, grown to at least
    ``at_least`` on each side around its centre ((-1, -1, 1, 1) x at_least / 2 without points)."""
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        h = at_least / 2.0
        return (-h, -h, h, h)
    (x0, y0), (x1, y1) = pts.min(axis=0), pts.max(axis=0)
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    hx, hy = max((x1 - x0) / 2.0, at_least / 2.0), max((y1 - y0) / 2.0, at_least / 2.0)
    return (float(cx - hx), float(cy - hy), float(cx + hx), float(cy + hy))
