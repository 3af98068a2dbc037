"""Writing a tileviz-dataset/1 folder frame by frame (:class:`DatasetWriter`), readable at every
moment up to its last whole frame (``docs/dataset-format.md``, "A dataset being written")."""

from __future__ import annotations

import json
import os
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import cv2

from tileviz.datasets.format import FAULTS_FILE, FRAME_COLUMNS, DatasetMeta, csv_line, num_text
from tileviz.datasets.images import to_rgb
from tileviz.safefile import LineLog, fsync_dir, write_atomic
from tileviz.types import FrameInput

if TYPE_CHECKING:
    from tileviz.pipeline import FrameRecord

__all__ = ["SYNC_PERIOD", "DatasetWriter", "dataset_mb", "meta_bytes"]

SYNC_PERIOD = 1.0
"""Seconds between syncs of frames.csv to the disk while recording (``durable``): a power cut
loses at most the rows of about this long; a killed process loses nothing already written."""


def meta_bytes(meta: DatasetMeta) -> bytes:
    """meta.json's content for ``meta``."""
    return (json.dumps(meta.to_json(), indent=2) + "\n").encode("utf-8")


class DatasetWriter:
    """Write a dataset frame by frame, so that the folder replays at every moment up to its last
    whole frame, whenever the process dies (``docs/dataset-format.md``, "A dataset being
    written"):

    1. on opening, ``frames.csv`` (its header) and then ``meta.json`` (with ``complete: false``)
       are each written whole under a temporary name and renamed into place;
    2. each frame's image is written whole the same way (``images/.NAME.tmp``, renamed to
       ``images/NAME``), then its ``faults.csv`` line, then its ``frames.csv`` row, appended in one
       write (a write the disk refuses is cut off again: :class:`tileviz.safefile.LineLog`);
    3. :meth:`close` rewrites ``meta.json`` with ``complete: true`` and ``frames: N``.

    A row is therefore never written before its image is whole. ``durable``: also sync each image
    to the disk before its rename and frames.csv every :data:`SYNC_PERIOD` seconds (a power cut
    then leaves a readable dataset too); a killed process loses nothing either way. A write that
    fails (a full disk) raises OSError naming the folder and how many frames it keeps; the
    writer then accepts no more frames and :meth:`close` leaves ``complete: false``.

    ``image_format``: ``png`` (lossless, replays bit-exactly) or ``jpg``. ``png_level``: zlib
    compression 0..9 of the PNGs. The default 0 stores the pixels, as a robot log keeps raw
    camera images: noisy camera images compress little, and stored pixels are much faster to
    write and to decode (``python bench/png_levels.py`` measures both).
    """

    def __init__(
        self,
        folder: str | os.PathLike[str],
        meta: DatasetMeta,
        *,
        image_format: str = "png",
        png_level: int = 0,
        overwrite: bool = False,
        durable: bool = True,
    ) -> None:
        if image_format not in ("png", "jpg"):
            raise ValueError(f"image_format must be 'png' or 'jpg', got {image_format!r}")
        if not isinstance(png_level, int) or not 0 <= png_level <= 9:
            raise ValueError(f"png_level must be an integer 0..9, got {png_level!r}")
        self.folder = Path(folder)
        if self.folder.exists() and not self.folder.is_dir():
            raise ValueError(f"{self.folder}: is a file, not an output folder")
        blocking = next((p for p in self.folder.parents if p.exists() and not p.is_dir()), None)
        if blocking is not None:
            raise ValueError(f"{self.folder}: {blocking} is a file, not a folder")
        if self.folder.exists() and any(self.folder.iterdir()) and not overwrite:
            raise ValueError(f"{self.folder}: output folder exists and is not empty")
        (self.folder / "images").mkdir(parents=True, exist_ok=True)
        self.meta = replace(meta, complete=False, frames=None)
        self.image_format = image_format
        self.durable = bool(durable)
        self._ext = ".jpg" if image_format == "jpg" else ".png"
        self._params = (
            [cv2.IMWRITE_JPEG_QUALITY, 95] if image_format == "jpg" else
            # stored pixels: filtering only costs the reader time
            [cv2.IMWRITE_PNG_COMPRESSION, 0, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE]
            if png_level == 0 else [cv2.IMWRITE_PNG_COMPRESSION, png_level])
        (self.folder / FAULTS_FILE).unlink(missing_ok=True)  # an overwritten dataset's labels
        # frames.csv before meta.json: a folder with a meta.json always has the header
        write_atomic(self.folder / "frames.csv", csv_line(FRAME_COLUMNS), durable=self.durable)
        write_atomic(self.folder / "meta.json", meta_bytes(self.meta), durable=self.durable)
        if self.durable:
            fsync_dir(self.folder)
        self._rows: LineLog | None = LineLog(self.folder / "frames.csv")
        self._faults: LineLog | None = None
        self._failed: str | None = None
        self._synced = time.monotonic()
        self.count = 0
        """Frames written (rows of frames.csv)."""

    def _failure(self, e: OSError, what: str) -> OSError:
        self._failed = f"{what}: {e.strerror or e}"
        err = OSError(f"{self.folder}: cannot write {what} ({e.strerror or e}); the dataset "
                      f"keeps the {self.count} frame(s) before it")
        err.errno = e.errno
        return err

    def write(self, frame: FrameInput | FrameRecord) -> None:
        """Append one frame (its image, odometry, compass and truth). OSError naming the folder
        when the disk refuses it (the frames before it stay; the writer takes no more)."""
        if self._rows is None:
            raise ValueError("dataset writer is closed")
        if self._failed is not None:
            raise ValueError(f"{self.folder}: the writer stopped after a failed write "
                             f"({self._failed})")
        name = f"images/{self.count:06d}{self._ext}"
        image = to_rgb(frame.image)
        ok, encoded = cv2.imencode(self._ext, image[:, :, ::-1], self._params)
        if not ok:
            raise ValueError(f"{self.folder / name}: the image cannot be encoded")
        odo = frame.odometry
        truth = frame.truth
        row = csv_line([
            self.count,
            num_text(frame.t),
            name,
            num_text(odo.speed) if odo is not None else "0.0",
            num_text(odo.yaw_rate) if odo is not None else "0.0",
            num_text(frame.compass) if frame.compass is not None else "",
            *((num_text(truth.x), num_text(truth.y), num_text(truth.theta)) if truth
              else ("", "", "")),
        ])
        try:
            write_atomic(self.folder / name, encoded.tobytes(), durable=self.durable)
        except OSError as e:
            raise self._failure(e, name) from None
        faults = getattr(frame, "faults", ())
        try:
            if faults:  # before the row: a label without its row is ignored, never the reverse
                self._write_faults(faults)
        except OSError as e:
            raise self._failure(e, FAULTS_FILE) from None
        try:
            self._rows.append(row)
        except OSError as e:
            raise self._failure(e, f"frames.csv row {self.count + 2}") from None
        self.count += 1
        if self.durable and time.monotonic() - self._synced >= SYNC_PERIOD:
            self._sync()

    def _sync(self) -> None:
        for log in (self._rows, self._faults):
            if log is not None:
                log.sync()
        fsync_dir(self.folder / "images")
        self._synced = time.monotonic()

    def _write_faults(self, faults: tuple[str, ...]) -> None:
        """``faults.csv`` (a tileviz extension other readers may ignore): index, labels."""
        if self._faults is None:
            path = self.folder / FAULTS_FILE
            write_atomic(path, b"index,faults\n", durable=self.durable)
            self._faults = LineLog(path)
        self._faults.append(f"{self.count},{';'.join(faults)}\n".encode())

    def close(self, complete: bool = True) -> None:
        """Finish the dataset (idempotent): with ``complete`` and no failed write, meta.json
        becomes ``complete: true, frames: N``; otherwise it keeps ``complete: false`` (the dataset
        ended early: a reader says so). OSError when the final meta.json cannot be written (the
        dataset then still reads as ended early)."""
        rows, self._rows = self._rows, None
        if rows is None:
            return
        faults, self._faults = self._faults, None
        try:
            if self.durable and self._failed is None:
                rows.sync()
                if faults is not None:
                    faults.sync()
                fsync_dir(self.folder / "images")
        finally:
            rows.close()
            if faults is not None:
                faults.close()
        if complete and self._failed is None:
            done = replace(self.meta, complete=True, frames=self.count)
            try:
                write_atomic(self.folder / "meta.json", meta_bytes(done), durable=self.durable)
            except OSError as e:
                raise OSError(f"{self.folder / 'meta.json'}: cannot mark the dataset complete "
                              f"({e.strerror or e}); its {self.count} frame(s) read as a "
                              "dataset that ended early") from None
            self.meta = done
            if self.durable:
                fsync_dir(self.folder)

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        # a block that raised stopped the recording before its end: the dataset ended early
        self.close(complete=exc_type is None)


def dataset_mb(folder: str | os.PathLike[str]) -> float:
    """The size of the files under ``folder`` (a dataset: meta.json, frames.csv, images),
    megabytes (10^6 bytes); files that vanish while it counts are left out."""
    total = 0
    for path in Path(folder).rglob("*"):
        try:
            if path.is_file():
                total += path.stat().st_size
        except OSError:
            continue
    return total / 1e6
