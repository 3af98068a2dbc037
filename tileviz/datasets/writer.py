"""Writing a tileviz-dataset/1 folder frame by frame (:class:`DatasetWriter`)."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import IO, TYPE_CHECKING

import cv2

from tileviz.datasets.format import FAULTS_FILE, FRAME_COLUMNS, DatasetMeta, num_text
from tileviz.datasets.images import to_rgb
from tileviz.types import FrameInput

if TYPE_CHECKING:
    from tileviz.pipeline import FrameRecord

__all__ = ["DatasetWriter", "dataset_mb"]


class DatasetWriter:
    """Write a dataset frame by frame; every row is flushed as soon as it is written, so a crash
    leaves a valid (shorter) dataset.

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
        image = to_rgb(frame.image)
        if not cv2.imwrite(str(self.folder / name), image[:, :, ::-1], self._params):
            raise OSError(f"cannot write {self.folder / name}")
        odo = frame.odometry
        truth = frame.truth
        self._csv.writerow([
            self.count,
            num_text(frame.t),
            name,
            num_text(odo.speed) if odo is not None else "0.0",
            num_text(odo.yaw_rate) if odo is not None else "0.0",
            num_text(frame.compass) if frame.compass is not None else "",
            *((num_text(truth.x), num_text(truth.y), num_text(truth.theta)) if truth
              else ("", "", "")),
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
