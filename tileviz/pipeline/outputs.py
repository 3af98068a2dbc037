"""The replay's output files: the replay CSV (``docs/dataset-format.md``, "Replay output") and
the equivalence-residual CSV, written row by row from frame records."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tileviz.datasets.format import csv_line, num_text
from tileviz.safefile import LineLog, write_atomic

if TYPE_CHECKING:
    from tileviz.pipeline.frame_loop import FrameRecord

__all__ = ["REPLAY_COLUMNS", "RESIDUAL_COLUMNS", "CsvOut", "replay_row", "residual_row"]

REPLAY_COLUMNS = (
    "index", "t", "status", "x_lo", "x_hi", "y_lo", "y_hi", "theta_lo", "theta_hi", "boxes",
)
RESIDUAL_COLUMNS = ("index", "t", "r1", "r2", "r3", "r4", "r5", "r6")


class CsvOut:
    """A CSV file written row by row, each row whole as soon as it is written
    (:class:`tileviz.safefile.LineLog`): a run that stops, is killed or meets a full disk leaves
    the file readable up to its last row. The header is in place (whole) before the first row."""

    def __init__(self, path: str | os.PathLike[str], columns: tuple[str, ...]) -> None:
        p = Path(path)
        if p.parent and not p.parent.exists():
            raise OSError(f"{p.parent}: output directory does not exist")
        if p.is_dir():
            raise OSError(f"{p}: is a directory")
        write_atomic(p, csv_line(columns), durable=False)
        self._log = LineLog(p)

    def row(self, values: list[Any]) -> None:
        self._log.append(csv_line(values))

    def close(self) -> None:
        self._log.close()


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
