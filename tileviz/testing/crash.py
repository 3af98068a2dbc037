"""Writers killed with SIGKILL and what they leave checked (``tests/test_crash_safety.py`` with a
few kills of each, ``bench/crash_kills.py`` with as many as asked).

:class:`Rig` drives the fork server :mod:`tileviz.testing.crash_child` (tileviz loaded once, so a
kill costs milliseconds, not an interpreter start). Each ``kill_*`` function runs one job, kills
it at a random moment drawn from ``rng`` (or at a pause point) and checks what it left; a check
that fails raises AssertionError saying what was wrong. What they check:

- a dataset (the ``write`` job, ``record``, the demo's Record button): it replays through the
  dataset reader without an error; every frame the writer said it wrote is there (and at most
  the one in flight beyond them) with its very image (the ``write`` job's images are seeded, so
  pixel for pixel); the reader says in one line that the dataset ended early;
- ``replay --out --mcap``: the CSV's whole rows are the uninterrupted replay's first rows, the
  MCAP file read without its summary holds whole frames only, the uninterrupted file's first
  ones, at most one frame behind the CSV;
- ``evaluate``'s run store: after every kill ``--resume`` opens it and reads back the runs it
  kept; resumed to the end, the campaign's table is the uninterrupted campaign's.
"""

from __future__ import annotations

import csv
import json
import os
import queue
import random
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tileviz.datasets import DatasetSource
from tileviz.testing import REPO
from tileviz.testing.crash_child import frame

__all__ = ["EVALUATE", "HOOKS", "Outcome", "Rig", "check_folder", "data_rows", "kill_evaluate",
           "kill_record", "kill_replay", "kill_session", "kill_write", "mcap_frames",
           "replay_reference", "runs_table"]

WRITE_FRAMES, WRITE_W, WRITE_H = 40, 48, 32
"""The ``write`` job's frames and image size."""
HOOKS = ("image", "row", "setup", "none")
"""Where a ``write`` job is killed: its pause point after frame ``at``'s image (its row not yet
written), after frame ``at``'s row, between frames.csv and meta.json of the set-up, or anywhere
(a random delay after frame ``at``)."""
EVALUATE = ["evaluate", "--runs", "4", "--duration", "1", "--scenarios", "clean", "--jobs", "1",
            "--quiet"]
"""The campaign the run-store kills interrupt."""


@dataclass
class Outcome:
    wrote: int
    """Frames the writer said it wrote before it died."""
    finished: bool
    """The job ran to its end (the kill came too late)."""
    failed: str | None


class Rig:
    """The fork server :mod:`tileviz.testing.crash_child` and the line protocol to it."""

    def __init__(self, warm: bool = False) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tileviz.testing.crash_child", *(["--warm"] if warm else [])],
            cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        assert self._next(900) == "ready"

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if line.startswith("@@ "):  # a protocol line, not what a job printed
                self.lines.put(line[3:].rstrip("\n"))
        self.lines.put("eof")

    def _next(self, timeout: float) -> str:
        line = self.lines.get(timeout=timeout)
        assert line != "eof", "the fork server died"
        return line

    def run(self, *, kill_after: float | None = None, on_hook: bool = False,
            kill_at: tuple[int, float] | None = None, timeout: float = 600,
            **job: object) -> Outcome:
        """Run one job; SIGKILL it ``kill_after`` seconds after it started, when it reaches its
        pause point (``on_hook``), ``kill_at[1]`` seconds after it said it wrote ``kill_at[0]``
        frames, or never; wait for it to end."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(job) + "\n")
        first = self._next(timeout)
        assert first.startswith("pid "), first
        pid = int(first.split()[1])
        start = time.monotonic()
        wrote, finished, failed = 0, False, None

        def take(line: str) -> None:
            nonlocal wrote, finished, failed
            if line.startswith("wrote "):
                wrote = int(line.split()[1])
            elif line == "done":
                finished = True
            elif line.startswith("failed "):
                failed = line

        killing = kill_after is not None or on_hook or kill_at is not None
        while killing:
            left = (start + kill_after - time.monotonic()) if kill_after is not None else timeout
            if left <= 0:
                break
            try:
                line = self._next(left)
            except queue.Empty:
                break
            if line == "hook" and on_hook:
                break
            take(line)
            if finished or failed:
                break
            if kill_at is not None and wrote >= kill_at[0]:
                time.sleep(kill_at[1])
                break
        if killing:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.proc.stdin.write("reap\n")
        while True:
            line = self._next(timeout)
            if line.startswith("status "):
                break
            take(line)
        return Outcome(wrote, finished, failed)

    def close(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        self.proc.wait(timeout=60)


def data_rows(path: Path) -> int:
    """Rows of a CSV file after its header (0 when it does not exist)."""
    if not path.is_file():
        return 0
    with open(path, newline="") as f:
        return max(0, sum(1 for _ in csv.reader(f)) - 1)


def check_folder(folder: Path, out: Outcome, w: int, h: int, *, seeded: bool = True) -> int:
    """Read back a folder a killed write job left (module docstring); ``seeded``: its images
    are :func:`tileviz.testing.crash_child.frame`'s. Returns its frame count (-1: killed before
    its meta.json existed, which a folder without frames is allowed to be)."""
    assert out.failed is None, out.failed
    if not (folder / "meta.json").exists():
        assert out.wrote == 0 and data_rows(folder / "frames.csv") == 0
        return -1
    src = DatasetSource(folder)
    frames = list(src)  # a bad row or image would raise here
    n = len(frames)
    # every frame the writer vouched for, and at most the one in flight beyond them
    assert out.wrote <= n <= out.wrote + 1, (out, n)
    for f in frames:
        assert f.image.shape == (h, w, 3), f"frame {f.index}: image {f.image.shape}"
        if seeded:
            want = frame(f.index, w, h)
            assert np.array_equal(f.image, want.image), f"frame {f.index}: not its image"
            assert (f.t, f.compass, f.truth, f.faults) == (want.t, want.compass, want.truth,
                                                          want.faults)
    leftovers = [p.name for p in (folder / "images").iterdir() if p.name.endswith(".tmp")]
    assert len(leftovers) <= 1  # at most the image being written when it died: never read
    if out.finished:
        assert src.ended_early is None
    elif src.meta.complete:
        # killed after the writer closed the dataset (meta.json says complete, every frame
        # written) but before the job could say it had finished
        assert src.ended_early is None and n == out.wrote, (out, n)
    else:
        assert src.ended_early is not None and f"it has {n} whole frame(s)" in src.ended_early
    return n


def kill_write(rig: Rig, folder: Path, hook: str, rng: random.Random) -> int:
    """Kill a ``write`` job at ``hook`` (:data:`HOOKS`) and check its folder; its frame count."""
    at = rng.randrange(WRITE_FRAMES)
    job: dict[str, Any] = {"job": "write", "folder": str(folder), "frames": WRITE_FRAMES,
                           "w": WRITE_W, "h": WRITE_H}
    if hook == "none":  # anywhere in the frame after frame `at` (a frame takes ~ms)
        out = rig.run(**job, kill_at=(at, rng.uniform(0.0, 0.004)))
    else:
        out = rig.run(**job, hook=hook, at=at, on_hook=True)
    n = check_folder(folder, out, WRITE_W, WRITE_H)
    if hook == "image":  # its image in place, its row not written: the frames before it
        assert n == at, (hook, at, n)
    elif hook == "row":
        assert n == at + 1, (hook, at, n)
    elif hook == "setup":
        assert n == -1, (hook, n)
    else:
        assert n >= at, (hook, at, n)
    return n


def kill_record(rig: Rig, folder: Path, rng: random.Random) -> int:
    """Kill ``record`` (64x48 views) a moment after a random frame; its folder's frame count."""
    out = rig.run(job="cli", argv=["record", str(folder), "--duration", "20", "--quiet",
                                   "--width", "64", "--height", "48"],
                  kill_at=(rng.randrange(1, 60), rng.uniform(0.0, 0.01)))
    assert not out.finished, "record ended before the kill"
    return check_folder(folder, out, 64, 48, seeded=False)


def kill_session(rig: Rig, out_dir: Path, rng: random.Random) -> int:
    """Kill the demo's Record button (a live session recording) after a random frame."""
    out = rig.run(job="session", out_dir=str(out_dir), frames=400,
                  kill_at=(rng.randrange(1, 40), rng.uniform(0.0, 0.02)))
    assert not out.finished, "the session ended before the kill"
    (folder,) = [p for p in out_dir.iterdir() if p.is_dir()]
    src = DatasetSource(folder)
    return check_folder(folder, out, src.meta.image_width, src.meta.image_height, seeded=False)


def mcap_frames(path: Path) -> list[dict[str, Any]]:
    """The /status messages of an MCAP file read record by record, without its summary, up to
    where it breaks (a killed writer's file); every frame read must have all its topics."""
    from mcap.stream_reader import StreamReader

    topics: dict[int, str] = {}
    per_frame: dict[int, set[str]] = {}
    status: list[dict[str, Any]] = []
    with open(path, "rb") as f:
        records: Iterator[Any] = iter(StreamReader(f).records)
        while True:
            try:
                rec = next(records)
            except StopIteration:
                break
            except Exception:  # noqa: BLE001 - the cut
                break
            kind = type(rec).__name__
            if kind == "Channel":
                topics[rec.id] = rec.topic
            elif kind == "Message":
                per_frame.setdefault(rec.sequence, set()).add(topics[rec.channel_id])
                if topics[rec.channel_id] == "/status":
                    status.append(json.loads(rec.data))
    whole = {"/camera/image", "/truth", "/set/prediction", "/set/contraction", "/status"}
    assert all(per_frame[k] == whole for k in range(len(status))), per_frame
    assert sorted(per_frame) == list(range(len(status)))  # no frame with only some topics
    return status


def replay_reference(rig: Rig, dataset: Path, folder: Path) -> tuple[list[list[str]],
                                                                        list[dict[str, Any]]]:
    """The uninterrupted replay's CSV rows and MCAP /status messages (``rig`` warm)."""
    clean = rig.run(job="replay", dataset=str(dataset), out=str(folder / "c.csv"),
                    mcap=str(folder / "c.mcap"))
    assert clean.finished, clean
    with open(folder / "c.csv", newline="") as f:
        want = list(csv.reader(f))
    return want, mcap_frames(folder / "c.mcap")


def kill_replay(rig: Rig, dataset: Path, csv_path: Path, mcap_path: Path,
                want: tuple[list[list[str]], list[dict[str, Any]]],
                rng: random.Random) -> int:
    """Kill ``replay --out --mcap`` a moment after a random frame and check both files against
    the uninterrupted replay's ``want`` (:func:`replay_reference`); the whole CSV rows kept."""
    rows_want, status_want = want
    out = rig.run(job="replay", dataset=str(dataset), out=str(csv_path), mcap=str(mcap_path),
                  kill_at=(rng.randrange(len(status_want)), rng.uniform(0.0, 0.03)))
    assert out.failed is None, out.failed
    text = csv_path.read_text() if csv_path.exists() else ""
    whole = text[: text.rfind("\n") + 1]  # a last line without its end: cut by the kill
    rows = list(csv.reader(whole.splitlines()))
    assert rows == rows_want[: len(rows)]  # each whole row as the uninterrupted replay's
    status = mcap_frames(mcap_path) if mcap_path.exists() else []
    assert status == status_want[: len(status)]
    # every frame the replay finished is in both; the MCAP file is at most one frame behind
    # the CSV (its messages are written right after the row)
    assert out.wrote <= len(status) <= max(0, len(rows) - 1) <= out.wrote + 1, (
        out, len(status), len(rows))
    return max(0, len(rows) - 1)


def runs_table(out: Path) -> list[list[str]]:
    """runs.csv without the CPU time column (a time, not a result)."""
    with open(out / "runs.csv", newline="") as f:
        rows = list(csv.reader(f))
    cpu = rows[0].index("cpu_us_per_frame")
    return [r[:cpu] + r[cpu + 1:] for r in rows]


def kill_evaluate(rig: Rig, out: Path, span: float, rng: random.Random) -> int:
    """Start (or ``--resume``) :data:`EVALUATE` into ``out``, kill it after a random part of
    ``span`` (an uninterrupted campaign's seconds) and check that ``--resume`` reads back what
    it kept; the runs kept."""
    from tileviz.evaluation.store import RunStore

    args = ["--resume", str(out)] if (out / "runs.csv").exists() else ["--out", str(out)]
    res = rig.run(job="cli", argv=[*EVALUATE, *args], kill_after=rng.uniform(0.1, 0.9) * span)
    assert res.failed is None, res.failed
    if not (out / "runs.csv").exists() or not (out / "campaign.json").exists():
        return 0  # killed before its store existed: the next start is a fresh one
    # the settings the campaign stored (the store checks them against its own)
    settings = json.loads((out / "campaign.json").read_text(encoding="utf-8"))
    settings.pop("tileviz", None)
    store = RunStore.open(out, settings, resume=True)
    return len(store.results())
