"""Fuzzing every reader a user's file reaches (issue 33): the engine behind ``bench/fuzz.py`` and
``tests/test_fuzz.py``.

A *reader* is one file of a user's input read by a command in this process, exactly as the user
runs it (``tileviz.__main__.main``), with the rest of the input valid:

- ``meta``: a dataset's meta.json (``replay``), generic JSON: every key, a wrong type, unknown
  and missing keys, the stored tileviz configuration, the ``floor`` block
  (:func:`~tileviz.testing.fuzz_cases.floor_block`);
- ``camera_model``: the camera_model block of a dataset with raw images (``replay``);
- ``frames``: frames.csv (``replay``); ``faults``: faults.csv (``replay``);
- ``image``: one stored image of a dataset (``replay``); ``extract``: an image given to
  ``extract`` (each image its own size: the reader bounds it from the header);
- ``bag``: a ROS 1 bag, a ROS 2 MCAP file or a ROS 2 sqlite3 database (``import-bag``);
- ``store``: ``runs.csv``, ``campaign.json`` or a run's results file of an ``evaluate --resume``
  folder (the store's reader and the report's tables, :func:`tileviz.evaluation.report.aggregate`).

A *case* is the bytes of that one file, made by a hypothesis strategy (structured: valid files
with wrong pieces) or by mutating a valid file (:mod:`tileviz.testing.fuzz_cases`).
Each case runs in a worker process, its stdout and stderr captured at the file-descriptor level
(what C libraries print counts too). Outcomes:

- ``ok``: the command succeeded (at most one line on stderr, e.g. "ended early"), or ``extract``
  read the image and its extractor refused it (exit status 1, the one line on stdout naming the
  image says why);
- ``error``: exit status 2 and exactly one line on stderr that names the file (its name or its
  folder) - what the project promises for bad input;
- ``traceback``: anything else: an exception the command let through, more than one line, a line
  that does not name the file;
- ``hang``: no answer within the per-case timeout (the worker is killed and replaced);
- ``memory``: a MemoryError, or a case raising the worker's peak resident set past
  :data:`MEMORY_LIMIT_MB`
  (a worker's address space is also capped a little above that, so a case that would allocate
  gigabytes fails instead of taking the machine).
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
import pickle
import resource
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from tileviz.testing import REPO
from tileviz.testing.fuzz_cases import (
    STORE_SETTINGS,
    Templates,
    hypothesis_cases,
    mutation_cases,
)

MEMORY_LIMIT_MB = 1024
"""Peak resident set a worker may reach (the issue's bound)."""
HEADROOM_MB = 1536
"""A worker's address space is capped at its size after start-up plus this."""
OUTCOMES = ("ok", "error", "traceback", "hang", "memory")



# --------------------------------------------------------------------------------------- running
@dataclass
class Result:
    """One case's outcome (:data:`OUTCOMES`), its message, its time (s) and the worker's peak
    resident set when this case raised it (MB; 0 when the case stayed under the peak the worker
    already had, e.g. its warm-up's)."""

    outcome: str
    message: str = ""
    seconds: float = 0.0
    maxrss_mb: float = 0.0


def _copy(src: Path, dst: Path) -> None:
    import shutil

    shutil.copytree(src, dst)


@contextlib.contextmanager
def _captured(work: Path) -> Iterator[tuple[Path, Path]]:
    """stdout and stderr of this process (file descriptors 1 and 2) into two files."""
    out, err = work / "stdout.txt", work / "stderr.txt"
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    fo, fe = os.open(out, os.O_WRONLY | os.O_CREAT, 0o644), os.open(err, os.O_WRONLY | os.O_CREAT,
                                                                    0o644)
    os.dup2(fo, 1)
    os.dup2(fe, 2)
    try:
        yield out, err
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, fo, fe):
            os.close(fd)


def _command(reader: str, variant: str, data: bytes, t: Templates,
             work: Path) -> tuple[list[str], list[str]]:
    """Lay out the case's input under ``work``; returns the command line and the names one of
    which an error line must contain (the file, or its folder)."""
    ds = work / "ds"
    if reader in ("meta", "frames", "faults", "image"):
        _copy(t.dataset, ds)
        target = {"meta": ds / "meta.json", "frames": ds / "frames.csv",
                  "faults": ds / "faults.csv", "image": ds / "images/000001.png"}[reader]
        target.write_bytes(data)
        return (["replay", str(ds), "--out", str(work / "r.csv"), "--jobs", "1", "--quiet"],
                [str(ds)])
    if reader == "camera_model":
        _copy(t.lens_dataset, ds)
        (ds / "meta.json").write_bytes(data)
        return (["replay", str(ds), "--out", str(work / "r.csv"), "--jobs", "1", "--quiet"],
                [str(ds)])
    if reader == "extract":
        img = work / f"view.{'jpg' if variant == 'jpg' else 'png'}"
        img.write_bytes(data)
        return ["extract", str(img), "--tile-size", "0.25", "--ppm", "100"], [str(img)]
    if reader == "bag":
        if variant == "ros1":
            bag = work / "in.bag"
            bag.write_bytes(data)
        else:
            _copy(t.bags[variant].parent, work / "bag")
            (work / "bag" / t.bags[variant].name).write_bytes(data)
            bag = work / "bag"
        out = work / "out"
        return (["import-bag", str(bag), str(out), "--image-topic", "/camera/image",
                 "--odom-topic", "/odom", "--imu-topic", "/imu", "--tile-size", "0.25",
                 "--ppm", "100", "--camera-offset", "0,0", "--speed-error", "0.05",
                 "--yaw-rate-error", "0.05", "--compass-error", "0.05"], [str(bag), str(out)])
    if reader == "store":
        _copy(t.store, work / "store")
        (work / "store" / variant).write_bytes(data)
        return ["store", str(work / "store")], [str(work / "store")]
    raise KeyError(reader)


def _store_command(folder: Path) -> int:
    """What ``evaluate --resume FOLDER`` does with the store before it makes new runs: open it,
    read the kept runs back, tabulate them (as the report does). One line on an error."""
    from tileviz.cliutil import run_cli
    from tileviz.evaluation.report import aggregate
    from tileviz.evaluation.store import RunStore

    def body() -> int:
        store = RunStore.open(folder, STORE_SETTINGS, resume=True)
        aggregate(store.results())
        return 0

    return run_cli("tileviz evaluate", body)


def run_case(reader: str, variant: str, data: bytes, t: Templates) -> Result:
    """Run one case in this process (module docstring: the outcomes). A case passes the
    memory limit only by raising the process's peak beyond it (the worker's warm-up may have
    peaked higher: compiling the vision kernels on a fresh install does)."""
    start = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    with tempfile.TemporaryDirectory(prefix="fuzz-") as tmp:
        work = Path(tmp)
        argv, names = _command(reader, variant, data, t, work)
        exc: BaseException | None = None
        code: int | None = None
        with _captured(work) as (out_path, err_path):
            try:
                if argv[0] == "store":
                    code = _store_command(Path(argv[1]))
                else:
                    from tileviz.__main__ import main

                    code = main(argv)
            except SystemExit as e:
                code = e.code if isinstance(e.code, int) else 2
            except MemoryError as e:
                exc = e
            except BaseException as e:  # noqa: BLE001 - the finding
                exc = e
        err = err_path.read_text(errors="replace").strip().splitlines()
        out = out_path.read_text(errors="replace").strip().splitlines()
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    rss = peak if peak > before else 0.0  # the peak this case raised the worker to
    if isinstance(exc, MemoryError) or rss > MEMORY_LIMIT_MB:
        return Result("memory", f"{type(exc).__name__ if exc else 'peak RSS'} "
                      f"({peak:.0f} MB)", seconds, rss)
    if exc is not None:
        import traceback

        tb = "".join(traceback.format_exception(exc)[-3:])
        return Result("traceback", f"{type(exc).__name__}: {exc} | {tb}"[:1500], seconds, rss)
    if code == 0:
        if len(err) > 1:
            return Result("traceback", "success, but stderr has "
                          f"{len(err)} lines: {' | '.join(err[:4])}"[:1500], seconds, rss)
        return Result("ok", err[0] if err else "", seconds, rss)
    if (code == 1 and reader == "extract" and not err and len(out) == 1
            and any(n in out[0] for n in names)):
        # the image was read and the extractor refused it: the line on stdout says why
        return Result("ok", out[0][:300], seconds, rss)
    if len(err) != 1:
        return Result("traceback", f"exit {code}, stderr has {len(err)} lines: "
                      f"{' | '.join(err[:6])}"[:1500], seconds, rss)
    line = err[0]
    if code != 2 or ": error: " not in line:
        return Result("traceback", f"exit {code}: {line}"[:1500], seconds, rss)
    if not any(n in line for n in names):
        return Result("traceback", f"the error does not name the file: {line}"[:1500], seconds,
                      rss)
    return Result("error", line[:300], seconds, rss)


# ---------------------------------------------------------------------------------------- worker
def _send(f: Any, obj: Any) -> None:
    blob = pickle.dumps(obj)
    f.write(struct.pack(">Q", len(blob)) + blob)
    f.flush()


def _recv(f: Any) -> Any:
    head = f.read(8)
    if len(head) < 8:
        raise EOFError
    return pickle.loads(f.read(struct.unpack(">Q", head)[0]))


def _vm_bytes() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
    return 0


def worker_main() -> None:
    """A worker: cases in on stdin, results out on the original stdout (length-prefixed
    pickles); its own stdout goes to /dev/null between cases."""
    proto_in = os.fdopen(os.dup(0), "rb")
    proto_out = os.fdopen(os.dup(1), "wb")
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    from tileviz.vision import set_opencv_threads
    from tileviz.vision.warmup import warm_up

    set_opencv_threads()
    with tempfile.TemporaryDirectory(prefix="fuzz-templates-") as tmp:
        with _captured(Path(tmp)):
            t = Templates(Path(tmp))
            warm_up(("robust", "faithful"))
            import tileviz.datasets.bag_import  # noqa: F401
            import tileviz.evaluation.report  # noqa: F401
            import tileviz.vision.cli  # noqa: F401
        limit = _vm_bytes() + HEADROOM_MB * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        _send(proto_out, "ready")
        while True:
            try:
                reader, variant, data = _recv(proto_in)
            except EOFError:
                return
            try:
                res = run_case(reader, variant, data, t)
            except MemoryError:
                res = Result("memory", "MemoryError in the harness")
            _send(proto_out, res)


class Worker:
    """A worker process and its pipes; :meth:`run` enforces the per-case timeout."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", "from tileviz.testing.fuzzing import worker_main; "
             "worker_main()"],
            cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        self.ready = False

    def start_wait(self, timeout: float) -> None:
        self._wait(timeout)
        self.ready = True

    def _wait(self, timeout: float) -> Any:
        import select

        assert self.proc.stdout is not None
        r, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if not r:
            raise TimeoutError
        return _recv(self.proc.stdout)

    def send(self, case: tuple[str, str, bytes]) -> None:
        assert self.proc.stdin is not None
        _send(self.proc.stdin, case)

    def kill(self) -> None:
        self.proc.kill()
        self.proc.wait()

    def close(self) -> None:
        if self.proc.poll() is None:
            assert self.proc.stdin is not None
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.kill()


@dataclass
class Finding:
    reader: str
    engine: str
    index: int
    variant: str
    data: bytes
    result: Result


@dataclass
class Report:
    """A campaign: outcome counts per reader, the findings, the largest peak resident set a
    case raised a worker to (MB), its time and the slowest case (s)."""

    counts: dict[str, dict[str, int]]
    findings: list[Finding]
    peak_rss_mb: float
    seconds: float
    slowest_s: float


def campaign(readers: list[str], n: int, *, engines: tuple[str, ...] = ("hypothesis", "mutate"),
             seed: int = 0, workers: int = 2, timeout: float = 60.0,
             progress: Callable[[str], None] | None = None,
             minutes: float | None = None) -> Report:
    """``n`` cases per reader (split between ``engines``), in ``workers`` processes, each case
    given ``timeout`` seconds (then a hang: the worker is replaced). The readers' cases run
    interleaved (each reader's k-th case before any reader's k+1-th), so that ``minutes`` (a
    budget from the start, case making included: no case starts after it) stops every reader
    at about the same count; the report counts the cases that ran. ``progress`` gets a line
    every 200 cases and each finding as it is found."""
    import select

    start = time.monotonic()
    gen_root = Path(tempfile.mkdtemp(prefix="fuzz-gen-"))
    with _captured(gen_root):
        templates = Templates(gen_root)
    deadline = start + 60.0 * minutes if minutes is not None else math.inf
    per_reader: list[list[tuple[str, str, int, str, bytes]]] = []
    for reader in readers:
        mine: list[tuple[str, str, int, str, bytes]] = []
        per = [n // len(engines) + (1 if i < n % len(engines) else 0)
               for i in range(len(engines))]
        for engine, k in zip(engines, per, strict=True):
            made = (hypothesis_cases if engine == "hypothesis" else mutation_cases)(
                reader, templates, k, seed)
            if engine == "hypothesis" and len(made) < k:  # the strategy ran dry: mutate more
                made += mutation_cases(reader, templates, k - len(made), seed + 1)
            mine += [(reader, engine, i, v, d) for i, (v, d) in enumerate(made)]
        # the engines' cases alternate too
        by_engine = [[j for j in mine if j[1] == e] for e in engines]
        per_reader.append([j for group in itertools.zip_longest(*by_engine) for j in group
                           if j is not None])
    jobs = [j for group in itertools.zip_longest(*per_reader) for j in group if j is not None]
    counts = {r: dict.fromkeys(OUTCOMES, 0) for r in readers}
    findings: list[Finding] = []
    peak = 0.0
    slowest = 0.0
    pool = [Worker() for _ in range(max(1, workers))]
    for w in pool:
        w.start_wait(1800)
    busy: dict[int, tuple[int, float]] = {}  # worker slot -> (job index, started)
    todo = list(range(len(jobs)))[::-1]
    done = 0

    def record(j: int, res: Result) -> None:
        nonlocal done, peak, slowest
        reader, engine, i, v, d = jobs[j]
        counts[reader][res.outcome] += 1
        peak = max(peak, res.maxrss_mb)
        slowest = max(slowest, res.seconds)
        if res.outcome in ("traceback", "hang", "memory"):
            findings.append(Finding(reader, engine, i, v, d, res))
            if progress is not None:
                progress(describe(findings[-1]))
        done += 1
        if progress is not None and (done % 200 == 0 or done == len(jobs)):
            progress(f"{done}/{len(jobs)} cases, {len(findings)} findings, "
                     f"{time.monotonic() - start:.0f} s")

    try:
        while todo or busy:
            if todo and time.monotonic() > deadline:
                todo.clear()  # out of time: the cases under way end, no new one starts
                if progress is not None:
                    progress(f"{done + len(busy)}/{len(jobs)} cases: the time budget is over")
            for slot, w in enumerate(pool):
                if slot not in busy and todo:
                    j = todo.pop()
                    reader, _, _, v, d = jobs[j]
                    w.send((reader, v, d))
                    busy[slot] = (j, time.monotonic())
            streams: dict[IO[bytes], int] = {}
            for busy_slot in busy:
                stream_of = pool[busy_slot].proc.stdout
                assert stream_of is not None
                streams[stream_of] = busy_slot
            ready, _, _ = select.select(list(streams), [], [], 1.0)
            for stream in ready:
                slot = streams[stream]
                j, _ = busy.pop(slot)
                try:
                    res = _recv(stream)
                except (EOFError, pickle.UnpicklingError):
                    res = Result("memory" if pool[slot].proc.poll() is not None else "traceback",
                                 f"the worker died (exit {pool[slot].proc.poll()})")
                    pool[slot].kill()
                    pool[slot] = Worker()
                    pool[slot].start_wait(1800)
                record(j, res)
            now = time.monotonic()
            for slot, (j, began) in list(busy.items()):
                if now - began > timeout:
                    busy.pop(slot)
                    pool[slot].kill()
                    record(j, Result("hang", f"no answer in {timeout:g} s", now - began))
                    pool[slot] = Worker()
                    pool[slot].start_wait(1800)
    finally:
        for w in pool:
            w.close()
        import shutil

        shutil.rmtree(gen_root, ignore_errors=True)
    return Report(counts, findings, peak, time.monotonic() - start, slowest)


def describe(f: Finding) -> str:
    """One finding in a few lines (the input's first bytes as a Python literal)."""
    head = f.data[:120]
    return (f"[{f.reader} {f.engine} #{f.index} {f.variant} {len(f.data)} bytes] "
            f"{f.result.outcome}: {f.result.message}\n    input starts {head!r}")

