"""The replay's output files: the replay CSV (``docs/dataset-format.md``, "Replay output") and
the equivalence-residual CSV, written row by row from frame records."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from tileviz.datasets.format import num_text

if TYPE_CHECKING:
    from tileviz.pipeline.frame_loop import FrameRecord

__all__ = ["REPLAY_COLUMNS", "RESIDUAL_COLUMNS", "CsvOut", "replay_row", "residual_row"]

REPLAY_COLUMNS = (
    "index", "t", "status", "x_lo", "x_hi", "y_lo", "y_hi", "theta_lo", "theta_hi", "boxes",
)
RESIDUAL_COLUMNS = ("index", "t", "r1", "r2", "r3", "r4", "r5", "r6")


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
    """One row of the replay output (docs/dataset-format.md, 'Replay output')."""
    hull = rec.updated.hull()
    if hull is None:
        bounds = ["nan"] * 6
    else:
        bounds = [num_text(v) for v in hull.as_tuple()]
    return [rec.index, num_text(rec.t), rec.status, *bounds, len(rec.updated)]


def residual_row(rec: FrameRecord) -> list[Any]:
    """One row of the ``--output-file`` CSV: the six equivalence residuals (empty when there is
    no observation or no truth)."""
    r = rec.residuals
    return [rec.index, num_text(rec.t), *([num_text(v) for v in r] if r is not None else [""] * 6)]
