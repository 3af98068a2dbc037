"""A campaign's finished runs on disk, written as they finish, so nothing finished is lost.

Layout of the output folder ``OUT`` (:class:`RunStore`):

- ``OUT/campaign.json``: the per-run settings (duration, MCL options) and the tileviz version;
  a resumed campaign must use the same ones.
- ``OUT/runs/<scenario>-r<run>-s<seed>.pkl``: one finished run (:class:`RunResult`, pickled),
  written to a temporary name and renamed, so a file there is complete.
- ``OUT/runs.csv``: one row per run and method (:data:`RUN_COLUMNS`), appended right after the
  run's file is in place, in the order runs finish; a run already there is never added twice,
  whatever retries a cluster made. At the end of a campaign the report rewrites it in
  (scenario, run) order.

``--resume OUT`` (:meth:`RunStore.open` with ``resume=True``) reads ``OUT/runs.csv``: its runs
are not made again; their results are read back from their files for the final tables.
"""

from __future__ import annotations

import csv
import json
import os
import pickle
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

from tileviz import __version__
from tileviz.evaluation.metrics import COLUMNS, metrics
from tileviz.evaluation.simulate import METHODS, RunResult

__all__ = ["RUN_COLUMNS", "RunKey", "RunStore", "run_key", "run_rows"]

RUN_COLUMNS = COLUMNS[:2] + ("run", "seed") + COLUMNS[2:]
"""Columns of ``runs.csv``: those of ``results.csv`` with ``run`` and ``seed`` after
``method``."""

RunKey = tuple[str, int, int]
"""A run's identity: (scenario, run index, simulator seed)."""


def run_key(res: RunResult) -> RunKey:
    """The :data:`RunKey` of a finished run."""
    return (res.scenario, int(res.run), int(res.seed))


def run_rows(res: RunResult) -> list[dict[str, Any]]:
    """The ``runs.csv`` rows of one run, one per method of :data:`METHODS`."""
    return [{"scenario": res.scenario, "method": m, "run": res.run, "seed": res.seed,
             **metrics([res], m)} for m in METHODS]


def csv_value(v: Any) -> str:
    """A CSV cell: floats with ``repr``, None and NaN empty."""
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if v != v else repr(v)
    return str(v)


class RunStore:
    """The finished runs of a campaign in ``out`` (module docstring). Use :meth:`open`."""

    def __init__(self, out: Path, done: dict[RunKey, Path]) -> None:
        self.out = out
        self.dir = out / "runs"
        self.csv = out / "runs.csv"
        self._done = done

    @classmethod
    def open(cls, out: Path, settings: Mapping[str, Any], *, resume: bool) -> RunStore:
        """The store of ``out`` for a campaign with per-run ``settings`` (JSON values). Without
        ``resume`` it starts empty (an earlier campaign's runs there are removed); with it, the
        runs listed in ``out/runs.csv`` count as done. ValueError naming the file on a settings
        mismatch, a malformed CSV or a listed run whose file is missing."""
        out = Path(out)
        meta = {"tileviz": __version__, **settings}
        runs_dir = out / "runs"
        done: dict[RunKey, Path] = {}
        if resume:
            if not (out / "runs.csv").is_file():
                raise ValueError(f"--resume {out}: no runs.csv there to resume from")
            try:
                old = json.loads((out / "campaign.json").read_text(encoding="utf-8"))
            except (OSError, json.JSONDecodeError) as e:
                raise ValueError(f"--resume {out}: cannot read campaign.json ({e})") from None
            diff = [k for k in sorted(set(old) | set(meta)) if old.get(k) != meta.get(k)]
            if diff:
                k = diff[0]
                raise ValueError(f"--resume {out}: {k} was {old.get(k)!r} there, "
                                 f"now {meta.get(k)!r} (resume with the same settings)")
            done = cls._read_done(out)
        out.mkdir(parents=True, exist_ok=True)
        runs_dir.mkdir(exist_ok=True)
        if not resume:
            for p in runs_dir.glob("*.pkl"):
                p.unlink()
        (out / "campaign.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
        store = cls(out, done)
        if not resume:
            with open(store.csv, "w", newline="") as f:
                csv.writer(f).writerow(RUN_COLUMNS)
        return store

    @staticmethod
    def _read_done(out: Path) -> dict[RunKey, Path]:
        path = out / "runs.csv"
        done: dict[RunKey, Path] = {}
        with open(path, newline="") as f:
            rd = csv.reader(f)
            head = next(rd, None)
            if head is None or tuple(head) != RUN_COLUMNS:
                raise ValueError(f"{path}: not a runs.csv of this tileviz version "
                                 "(its header differs)")
            for line, row in enumerate(rd, start=2):
                if not row:
                    continue
                try:
                    key = (row[0], int(row[2]), int(row[3]))
                except (IndexError, ValueError):
                    raise ValueError(f"{path}, line {line}: not a run row") from None
                file = out / "runs" / _file_name(key)
                if not file.is_file():
                    raise ValueError(f"{path}, line {line}: run {key[1]} of {key[0]} is listed "
                                     f"but its results file {file} is missing")
                done[key] = file
        return done

    @property
    def done(self) -> set[RunKey]:
        """The runs already finished."""
        return set(self._done)

    def add(self, res: RunResult) -> bool:
        """Keep a finished run: its file, then its ``runs.csv`` rows. False (nothing written)
        when the run is already kept."""
        key = run_key(res)
        if key in self._done:
            return False
        file = self.dir / _file_name(key)
        tmp = file.with_suffix(".tmp")
        with open(tmp, "wb") as f:
            pickle.dump(res, f, protocol=pickle.HIGHEST_PROTOCOL)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, file)
        with open(self.csv, "a", newline="") as f:
            wr = csv.writer(f)
            for row in run_rows(res):
                wr.writerow([csv_value(row[c]) for c in RUN_COLUMNS])
            f.flush()
        self._done[key] = file
        return True

    def results(self, keys: Collection[RunKey] | None = None) -> list[RunResult]:
        """The kept runs (those of ``keys``, default all), read back from their files (order:
        as kept)."""
        out = []
        for key, file in self._done.items():
            if keys is not None and key not in keys:
                continue
            try:
                with open(file, "rb") as f:
                    res = pickle.load(f)
            except (OSError, pickle.UnpicklingError, EOFError, AttributeError) as e:
                raise ValueError(f"cannot read the results of run {key[1]} of {key[0]} "
                                 f"from {file}: {e}") from None
            out.append(res)
        return out


def _file_name(key: RunKey) -> str:
    return f"{key[0]}-r{key[1]}-s{key[2]}.pkl"
