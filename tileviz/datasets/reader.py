"""Reading a tileviz-dataset/1 folder as frames (:class:`DatasetSource`), every row validated as
it is reached; images decoded ahead on a thread when asked. A dataset that ended early (its writer
stopped before closing it, a last row cut off) replays up to its last whole row and says so
(:attr:`DatasetSource.ended_early`; ``docs/dataset-format.md``, "A dataset being written")."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tileviz.datasets.camera_model import Rectifier
from tileviz.datasets.format import (
    FAULTS_FILE,
    REQUIRED_COLUMNS,
    DatasetError,
    parse_float,
    read_meta,
)
from tileviz.datasets.images import (
    decode_image,
    depth_problem,
    header_size,
    size_problem,
    truncated,
)
from tileviz.pipeline.parallel import results_in_order
from tileviz.types import FrameInput, Odometry, Pose

__all__ = ["DatasetSource"]

_NO_IMAGE = np.zeros((0, 0, 3), np.uint8)
_TAIL_BYTES = 1 << 16
"""How much of the end of frames.csv is read to find its last line."""


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


class DatasetSource:
    """Read a dataset as :class:`FrameInput` objects, validating every row as it goes.

    Images may be PNG or JPEG with any names; they are returned as HxWx3 uint8 RGB, except
    those of a dataset with a ``camera_model`` when ``rectify``: the rectified gray view (HxW
    uint8, :meth:`~tileviz.datasets.camera_model.Rectifier.gray`), the pixels vision reads.
    """

    def __init__(self, folder: str | os.PathLike[str], *, prefetch: int = 0,
                 rectify: bool = True) -> None:
        """``prefetch``: images decoded ahead of the frame being delivered, on a background
        thread (OpenCV's decoder releases the GIL, so decoding overlaps the caller's vision);
        0 decodes each image when its frame is asked for. Errors still arrive in row order.
        ``rectify``: with a ``camera_model``, deliver the rectified gray view (True) or the
        raw images as stored (False: the caller rectifies, e.g. to show both)."""
        if not isinstance(prefetch, int) or prefetch < 0:
            raise ValueError(f"prefetch must be an integer >= 0, got {prefetch!r}")
        self.prefetch = prefetch
        self.rectify = bool(rectify)
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
        except csv.Error as e:
            raise DatasetError(f"{self.frames_path} line 1: not a CSV header ({e})") from None
        if header is None:
            raise DatasetError(f"{self.frames_path}: empty (no header row)")
        header = [h.strip() for h in header]
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing:
            raise DatasetError(f"{self.frames_path}: missing column(s) {', '.join(missing)}")
        self.columns = header
        self._line = 1
        """The line of frames.csv the row parser is at (for an error the csv module raises)."""
        self._cut_line = self._cut_last_line()
        """The line of frames.csv (1-based) that is a cut-off last row, not read; or None."""
        self.faults = self._read_faults()
        self._rectifier: Rectifier | None = None
        self.ended_early = self._ended_early()
        """One line saying that the dataset ended early and how many whole frames it has (its
        writer stopped before closing it, its last row is cut off, or it has fewer rows than
        meta.json lists), or None for a whole dataset. The frames up to the last whole row
        replay either way."""

    def _cut_last_line(self) -> int | None:
        """The line number of a last line of frames.csv without a line end that is not a whole
        row: cut off by a writer that stopped mid-write. A dataset that says it was written by a
        tileviz writer (meta.json's ``complete``) ends every row with a line end, so there any
        such line is cut; another program's last row may lack the line end and still be whole
        (all its columns)."""
        with open(self.frames_path, "rb") as f:
            size = f.seek(0, os.SEEK_END)
            if size == 0:
                return None
            f.seek(max(0, size - _TAIL_BYTES))
            window = f.read()
            if window.endswith(b"\n"):
                return None
            start = window.rfind(b"\n")
            if start < 0 and size > len(window):  # a last line longer than the window: cut
                start = -1
            tail = window[start + 1:]
            f.seek(0)
            lines = sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 20), b""))
        if lines == 0 or not tail.strip():  # the header itself, or a blank last line
            return None
        try:
            cells = next(csv.reader([tail.decode("utf-8", "replace")]), [])
        except csv.Error:
            cells = []
        if self.meta.complete is None and len(cells) >= len(self.columns):
            return None
        return lines + 1

    def _ended_early(self) -> str | None:
        reasons = []
        if self.meta.complete is False:
            reasons.append("its writer stopped before closing it")
        if self._cut_line is not None:
            reasons.append(f"its last row, line {self._cut_line} of frames.csv, is cut off")
        rows = self._count_rows()
        if self.meta.frames is not None and rows is not None and rows < self.meta.frames:
            reasons.append(f"meta.json lists {self.meta.frames}")
        if not reasons:
            return None
        count = (f"{rows} whole frame(s)" if rows is not None
                 else "the frames up to its first bad row")
        return f"{self.folder} ended early: it has {count} ({'; '.join(reasons)})"

    def _read_faults(self) -> dict[int, tuple[str, ...]]:
        path = self.folder / FAULTS_FILE
        if not path.is_file():
            return {}
        out: dict[int, tuple[str, ...]] = {}
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise DatasetError(f"{path}: not UTF-8 text") from None
        # a last line without its line end was cut off mid-write: a writer writes a frame's
        # labels before its row, so that frame has no row either
        lines = text.split("\n")[:-1]  # the last piece: empty, or that cut line
        rows = csv.reader(lines)
        lineno = 1
        try:
            for cells in rows:
                lineno = rows.line_num  # the line where the row ends (quotes may span lines)
                if lineno == 1 or not cells:
                    continue
                try:
                    out[int(cells[0])] = tuple(x for x in cells[1].split(";") if x)
                except (ValueError, IndexError):
                    raise DatasetError(f"{path} line {lineno}: expected 'index,labels'") from None
        except csv.Error as e:
            raise DatasetError(f"{path} line {lineno + 1}: not a CSV row ({e})") from None
        return out

    def row_count(self) -> int:
        """How many non-blank data rows frames.csv has, a cut-off last row not counted (for a
        progress bar: the rows are not checked here; a bad one still stops the frames at its
        turn); 0 when frames.csv cannot be read through."""
        return self._count_rows() or 0

    def _count_rows(self) -> int | None:
        try:
            with open(self.frames_path, newline="", encoding="utf-8") as f:
                rows = csv.reader(f)
                next(rows, None)
                n = 0
                for cells in rows:
                    if self._cut_line is not None and rows.line_num >= self._cut_line:
                        break
                    n += any(c.strip() for c in cells)
                return n
        except (UnicodeDecodeError, csv.Error, OSError):
            return None

    def _rows(self) -> Iterator[_Row]:
        try:
            yield from self._parse_rows()
        except UnicodeDecodeError:
            raise DatasetError(f"{self.frames_path}: not UTF-8 text") from None
        except csv.Error as e:  # e.g. a cell longer than the csv module takes
            raise DatasetError(f"{self.frames_path} line {self._line + 1}: not a CSV row "
                               f"({e})") from None

    def _parse_rows(self) -> Iterator[_Row]:
        with open(self.frames_path, newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            next(reader)
            expected_index = 0
            last_t = -math.inf
            self._line = 1
            for cells in reader:
                lineno = reader.line_num  # the line where the row ends (quotes may span lines)
                self._line = lineno
                if self._cut_line is not None and lineno >= self._cut_line:
                    return  # a cut-off last row (ended_early says so)
                where = self._where(lineno)
                if not cells or all(not c.strip() for c in cells):
                    continue
                if len(cells) < len(self.columns):
                    first = self.columns.index("index")
                    given = cells[first].strip() if first < len(cells) else ""
                    if given.isdigit():  # the frame, when its index is there to read
                        where = self._where(lineno, int(given))
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
                where = self._where(lineno, index)
                t = parse_float(rec["t"], "t", where)
                if t <= last_t:
                    raise DatasetError(f"{where}: t={t!r} does not increase")
                last_t = t
                if not rec["image"]:
                    raise DatasetError(f"{where}: image is empty")
                speed = parse_float(rec["speed"], "speed", where)
                yaw_rate = parse_float(rec["yaw_rate"], "yaw_rate", where)
                comp_text = rec.get("compass", "")
                compass = parse_float(comp_text, "compass", where) if comp_text else None
                if compass is not None and not -math.pi - 1e-9 <= compass <= math.pi + 1e-9:
                    raise DatasetError(f"{where}: compass {compass!r} is not in (-pi, pi]")
                cells_truth = [rec.get(c, "") for c in ("x", "y", "theta")]
                truth = None
                if any(cells_truth):
                    if not all(cells_truth):
                        raise DatasetError(f"{where}: x, y, theta must be all given or all empty")
                    truth = Pose(*(parse_float(v, c, where)
                                   for v, c in zip(cells_truth, ("x", "y", "theta"), strict=True)))
                yield _Row(lineno, index, t, rec["image"], speed, yaw_rate, compass, truth)

    def _where(self, line: int, index: int | None = None) -> str:
        """How an error names a row of frames.csv: its line in the file (the header is line 1)
        and, once its index is read, the frame (``frames.csv line 52 (frame 50)``)."""
        frame = f" (frame {index})" if index is not None else ""
        return f"{self.frames_path} line {line}{frame}"

    def load_image(self, name: str, where: str) -> np.ndarray:
        """Read one image as HxWx3 RGB uint8 (rectified: HxW gray, see the class docstring);
        errors name the row and the file."""
        path = (self.folder / name)
        if not path.is_file():
            raise DatasetError(f"{where}: image {name!r} is missing")
        try:
            raw = path.read_bytes()
        except OSError as e:
            raise DatasetError(f"{where}: image {name!r} cannot be read "
                               f"({e.strerror or e})") from None
        if truncated(raw):
            raise DatasetError(f"{where}: image {name!r} is truncated (no end marker)")
        cm = self.meta.camera_model
        size = (cm.raw_width, cm.raw_height) if cm else (self.meta.image_width,
                                                         self.meta.image_height)

        def wrong_size(w: int, h: int) -> DatasetError:
            return DatasetError(f"{where}: image {name!r} is {w}x{h}, meta.json says "
                                f"{size[0]}x{size[1]}{' (camera_model raw size)' if cm else ''}")

        declared = header_size(raw)  # before any pixel is decoded
        if declared is not None and declared != size:
            raise wrong_size(*declared)
        problem = depth_problem(raw) or size_problem(raw)
        if problem is not None:
            raise DatasetError(f"{where}: image {name!r}: {problem}")
        # a prefetching source decodes on a thread: OpenCV's decoder lets the caller run
        complaints: list[str] = []
        image = decode_image(raw, spng=self.prefetch == 0, complaints=complaints)
        if image is None:
            why = f" ({complaints[0]})" if complaints else ""
            raise DatasetError(f"{where}: image {name!r} is not a readable PNG/JPEG{why}")
        h, w = image.shape[:2]
        if (w, h) != size:
            raise wrong_size(w, h)
        if cm is not None and self.rectify:  # to the orthographic view; tables made once
            if self._rectifier is None:
                self._rectifier = self.meta.rectifier()
            image = self._rectifier.gray(image)  # type: ignore[union-attr]
        return image

    def _jobs(self) -> Iterator[tuple[_Row, Odometry | None, str]]:
        """(row, its odometry, where) in order. A bad row raises DatasetError after the row
        before it was given (without odometry: it has no successor)."""
        rows = self._rows()
        current = next(rows, None)
        while current is not None:
            where = self._where(current.line, current.index)
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
        (:mod:`tileviz.pipeline.workers`). A bad row raises DatasetError as :meth:`__iter__`
        does."""
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
