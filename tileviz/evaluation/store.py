"""A campaign's finished runs on disk, written as they finish, so nothing finished is lost.

Layout of the output folder ``OUT`` (:class:`RunStore`):

- ``OUT/campaign.json``: the per-run settings (duration, MCL options) and the tileviz version;
  a resumed campaign must use the same ones.
- ``OUT/runs/<scenario>-r<run>-s<seed>.pkl``: one finished run (:class:`RunResult`, pickled),
  written to a temporary name, synced and renamed, so a file there is complete.
- ``OUT/runs.csv``: one row per run and method (:data:`RUN_COLUMNS`), a run's rows appended in
  one write right after the run's file is in place, in the order runs finish; a run already
  there is never added twice, whatever retries a cluster made. At the end of a campaign the
  report rewrites it in (scenario, run) order.

Every file is written whole or cut back (:mod:`tileviz.safefile`), so a campaign killed at any
moment (SIGKILL, a full disk) resumes: ``--resume OUT`` (:meth:`RunStore.open` with
``resume=True``) reads ``OUT/runs.csv``: its runs are not made again, their results are read back
from their files for the final tables; a run whose rows were cut off mid-write is made again.
A results file is read back only as a run's results (:func:`load_run`: no other class is
unpickled).
"""

from __future__ import annotations

import csv
import io
import json
import pickle
import pickletools
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from tileviz import __version__
from tileviz.core.constants import LIMIT
from tileviz.datasets.format import csv_line
from tileviz.evaluation.metrics import COLUMNS, metrics
from tileviz.evaluation.simulate import METHODS, MethodTrace, RunResult
from tileviz.safefile import LineLog, write_atomic

__all__ = ["RUN_COLUMNS", "RunKey", "RunStore", "load_run", "run_key", "run_rows"]

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
        runs listed in ``out/runs.csv`` count as done (a campaign killed while it appended a run's
        rows: that run's rows are dropped, and it is made again). ValueError naming the file on a
        settings mismatch, a malformed CSV or a listed run whose file is missing."""
        out = Path(out)
        meta = {"tileviz": __version__, **settings}
        runs_dir = out / "runs"
        done: dict[RunKey, Path] = {}
        kept: list[bytes] = []
        if resume:
            if not (out / "runs.csv").is_file():
                raise ValueError(f"--resume {out}: no runs.csv there to resume from")
            path = out / "campaign.json"
            try:
                old = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError, ValueError, RecursionError) as e:
                why = e.strerror if isinstance(e, OSError) else type(e).__name__
                raise ValueError(f"--resume {out}: cannot read {path} ({why})") from None
            if not isinstance(old, dict):
                raise ValueError(f"--resume {out}: {path} is not a JSON object")
            diff = [k for k in sorted(set(old) | set(meta)) if old.get(k) != meta.get(k)]
            if diff:
                k = diff[0]
                name = k if k.isidentifier() else _short(k)  # a damaged key, quoted
                raise ValueError(f"--resume {out}: {name} was {_short(old.get(k))} there, "
                                 f"now {_short(meta.get(k))} (resume with the same settings)")
            done, kept = cls._read_done(out)
        out.mkdir(parents=True, exist_ok=True)
        runs_dir.mkdir(exist_ok=True)
        if not resume:
            for p in runs_dir.glob("*.pkl"):
                p.unlink()
        write_atomic(out / "campaign.json", (json.dumps(meta, indent=2) + "\n").encode())
        store = cls(out, done)
        # the header and the whole runs' rows (a resumed store drops a run cut mid-append)
        write_atomic(store.csv, csv_line(RUN_COLUMNS) + b"".join(kept))
        return store

    @staticmethod
    def _read_done(out: Path) -> tuple[dict[RunKey, Path], list[bytes]]:
        """The runs of ``out/runs.csv`` with all their rows and their file, and those rows."""
        path = out / "runs.csv"
        try:
            text = path.read_bytes().decode("utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{path}: not UTF-8 text") from None
        # the last piece: empty, or a line cut off mid-write by a killed campaign
        lines = text.split("\n")[:-1]
        rows: dict[RunKey, list[bytes]] = {}
        try:
            parsed = list(csv.reader(lines))
        except csv.Error as e:
            raise ValueError(f"{path}: not a CSV file ({e})") from None
        if not parsed or tuple(parsed[0]) != RUN_COLUMNS:
            raise ValueError(f"{path}: not a runs.csv of this tileviz version "
                             "(its header differs)")
        for line, row in enumerate(parsed[1:], start=2):
            if not row:
                continue
            try:
                key = (row[0], int(row[2]), int(row[3]))
            except (IndexError, ValueError):
                raise ValueError(f"{path}, line {line}: not a run row") from None
            if len(row) != len(RUN_COLUMNS):
                raise ValueError(f"{path}, line {line}: {len(row)} cells, a run row has "
                                 f"{len(RUN_COLUMNS)}")
            rows.setdefault(key, []).append(csv_line(row))
        done: dict[RunKey, Path] = {}
        kept: list[bytes] = []
        for key, lines_of_run in rows.items():
            if len(lines_of_run) != len(METHODS):  # its append was cut: made again
                continue
            file = out / "runs" / _file_name(key)
            if not file.is_file():
                raise ValueError(f"{path}: run {key[1]} of {key[0]} is listed but its results "
                                 f"file {file} is missing")
            done[key] = file
            kept += lines_of_run
        return done, kept

    @property
    def done(self) -> set[RunKey]:
        """The runs already finished."""
        return set(self._done)

    def add(self, res: RunResult) -> bool:
        """Keep a finished run: its file (whole, synced), then its ``runs.csv`` rows in one
        append. False (nothing written) when the run is already kept."""
        key = run_key(res)
        if key in self._done:
            return False
        file = self.dir / _file_name(key)
        write_atomic(file, pickle.dumps(res, protocol=pickle.HIGHEST_PROTOCOL))
        rows = b"".join(csv_line([csv_value(row[c]) for c in RUN_COLUMNS])
                        for row in run_rows(res))
        log = LineLog(self.csv)
        try:
            log.append(rows)
        finally:
            log.close()
        self._done[key] = file
        return True

    def results(self, keys: Collection[RunKey] | None = None) -> list[RunResult]:
        """The kept runs (those of ``keys``, default all), read back from their files (order:
        as kept). ValueError naming the file when one cannot be read as a run's results."""
        out = []
        for key, file in self._done.items():
            if keys is not None and key not in keys:
                continue
            out.append(load_run(file, key))
        return out


def _cut(text: str, n: int = 80) -> str:
    """``text`` on one line, at most ``n`` characters."""
    text = " ".join(text.split())
    return text if len(text) <= n else text[: n - 3] + "..."


def _short(v: Any) -> str:
    """``repr`` of a value, on one line, at most 80 characters."""
    return _cut(repr(v))


class _RunUnpickler(pickle.Unpickler):
    """Unpickles a run's results and nothing else: only the classes a :class:`RunResult` is made
    of (a results file edited, damaged or planted cannot call anything else)."""

    ALLOWED = {
        ("tileviz.evaluation.simulate", "RunResult"),
        ("tileviz.evaluation.simulate", "MethodTrace"),
        ("numpy", "ndarray"), ("numpy", "dtype"), ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "scalar"),
        ("numpy._core.multiarray", "scalar"), ("numpy.core.numeric", "_frombuffer"),
        ("numpy._core.numeric", "_frombuffer"), ("builtins", "bytearray"),
    }

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) not in self.ALLOWED:
            raise pickle.UnpicklingError(f"{module}.{name} is not part of a run's results")
        return super().find_class(module, name)


def load_run(file: Path, key: RunKey) -> RunResult:
    """The :class:`RunResult` in ``file``; ValueError naming the file and run when it cannot be
    read as one."""
    where = f"cannot read the results of run {key[1]} of {key[0]} from {file}"
    try:
        data = file.read_bytes()
        # the opcodes first, unexecuted: a damaged length field then cannot make the unpickler
        # allocate more than the file holds
        for _ in pickletools.genops(data):
            pass
        res = _RunUnpickler(io.BytesIO(data)).load()
    except RecursionError:
        raise ValueError(f"{where}: nested too deeply") from None
    except Exception as e:  # noqa: BLE001 - a damaged pickle raises anything; one line
        raise ValueError(f"{where}: {_cut(f'{type(e).__name__}: {e}')}") from None
    if not isinstance(res, RunResult):
        raise ValueError(f"{where}: it holds a {type(res).__name__}, not a run's results")
    problem = _run_problem(res, key)
    if problem is not None:
        raise ValueError(f"{where}: {problem}")
    return res


_RUN_ARRAYS = {"t": 1, "truth": 3, "fault": 1, "in_bounds": 1, "accepted": 1}
"""The per-frame arrays of a :class:`RunResult` and their columns (1: a vector)."""
_TRACE_ARRAYS = {"lo": 3, "hi": 3, "centre": 3, "inside": 1, "status": 1, "boxes": 1,
                 "alarm": 1, "d2": 1}
"""The per-frame arrays of a :class:`MethodTrace` and their columns (1: a vector)."""


_UNBOUNDED = frozenset({"d2"})
"""Arrays whose numbers have no magnitude limit, only a sign: MCL's squared Mahalanobis
distance grows without bound (to inf) when its particles collapse away from the truth."""


def _array_problem(obj: object, name: str, columns: int, n: int | None) -> str | None:
    v = getattr(obj, name, None)
    if not isinstance(v, np.ndarray) or v.dtype.kind not in "biuf":
        return f"{name} is not an array of numbers"
    if name in _UNBOUNDED:
        if v.dtype.kind == "f" and v.size and bool((v < 0.0).any()):
            return f"{name} holds negative numbers"
    elif v.dtype.kind == "f" and v.size and np.nanmax(np.abs(v), initial=0.0) > LIMIT:
        return f"{name} holds numbers beyond +-{LIMIT:g}"
    want = (n,) if columns == 1 else (n, columns)
    if v.ndim != len(want) or (n is not None and v.shape != want) or (
            columns != 1 and v.shape[1] != columns):
        return f"{name} has shape {v.shape}, not (frames{'' if columns == 1 else f', {columns}'})"
    return None


def _run_problem(res: RunResult, key: RunKey) -> str | None:
    """What makes an unpickled :class:`RunResult` unfit for the tables (a damaged or edited
    file: a missing field, another run, arrays of another shape, a missing method), or None."""
    ident = tuple(getattr(res, k, None) for k in ("scenario", "run", "seed"))
    if ident != key:
        return f"it holds the run {_short(ident)}, not {_short(key)}"
    t = getattr(res, "t", None)
    n = t.shape[0] if isinstance(t, np.ndarray) and t.ndim == 1 else None
    for name, columns in _RUN_ARRAYS.items():
        problem = _array_problem(res, name, columns, n)
        if problem is not None:
            return problem
    vision_s = getattr(res, "vision_s", None)
    if isinstance(vision_s, bool) or not isinstance(vision_s, int | float):
        return "vision_s is not a number"
    methods = getattr(res, "methods", None)
    if not isinstance(methods, dict):
        return "it has no methods"
    missing = [m for m in METHODS if m not in methods]
    if missing:
        return f"it has no results of the method(s) {', '.join(missing)}"
    for m in METHODS:
        trace = methods[m]
        if not isinstance(trace, MethodTrace):
            return f"method {m}: not a method's results"
        for name, columns in _TRACE_ARRAYS.items():
            problem = _array_problem(trace, name, columns, n)
            if problem is not None:
                return f"method {m}: {problem}"
        cpu = getattr(trace, "cpu_s", None)
        if isinstance(cpu, bool) or not isinstance(cpu, int | float):
            return f"method {m}: cpu_s is not a number"
    return None


def _file_name(key: RunKey) -> str:
    return f"{key[0]}-r{key[1]}-s{key[2]}.pkl"
