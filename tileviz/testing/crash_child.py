"""A fork server of writers to kill (:mod:`tileviz.testing.crash`, for
``tests/test_crash_safety.py`` and ``bench/crash_kills.py``): loads tileviz once, then forks one
writer per job so that a test can SIGKILL dozens of real writer processes in seconds. Run as
``python -m tileviz.testing.crash_child [--warm]`` (``--warm``: also load the vision kernels, for
replay jobs). Protocol, one line each way (the server's and the children's lines start with
``@@ ``; anything else on stdout is what a job printed):

- stdin ``{"job": NAME, ...}`` (JSON): fork a child that runs ``JOBS[NAME](**rest)``; the child
  says ``pid N`` first, ``wrote K`` after each frame a DatasetWriter (or, for a replay job, the
  replay) wrote (the frames it vouches for), ``hook``
  when it reached the pause point it was asked for (then it sleeps until killed) and ``done``
  when its job ended (``failed TEXT`` when the job raised).
- stdin ``reap``: wait for the last child; stdout ``status S`` (its wait status).

Frame k of a ``write`` job is :func:`frame` (k, w, h): its image is seeded by k, so a test can
check every replayed image pixel for pixel.
"""

from __future__ import annotations

import json
import os
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

import tileviz.datasets.writer as writer_module
from tileviz.config import preset
from tileviz.datasets import DatasetMeta, DatasetWriter
from tileviz.safefile import LineLog
from tileviz.types import FrameInput, Odometry, Pose
from tileviz.vision import set_opencv_threads


def say(text: str) -> None:
    """A protocol line (``@@ TEXT``: what the job itself prints is not one)."""
    os.write(1, f"@@ {text}\n".encode())


def pause() -> None:
    say("hook")
    time.sleep(3600)


def frame(k: int, w: int, h: int) -> FrameInput:
    """Frame k of a write job: a seeded noise image, a known odometry, compass and truth."""
    image = np.random.default_rng(k).integers(0, 256, (h, w, 3), dtype=np.uint8)
    return FrameInput(index=k, t=0.05 * k, image=image, odometry=Odometry(0.1, 0.01 * k, 0.05),
                      compass=0.001 * k, truth=Pose(0.005 * k, 0.0, 0.001 * k),
                      faults=("slip",) if k % 3 == 0 else ())


def meta(w: int, h: int) -> DatasetMeta:
    """The default preset's meta with w x h images."""
    return replace(DatasetMeta.from_config(preset("default"), name="crash test"),
                   image_width=w, image_height=h)


def job_write(folder: str, frames: int, w: int = 48, h: int = 32, hook: str = "none",
              at: int = 0) -> None:
    """Write ``frames`` frames with DatasetWriter; ``hook``: pause ``setup`` (frames.csv
    written, meta.json not yet), ``image`` (frame ``at``'s image in place, its row not yet) or
    ``row`` (frame ``at``'s row written, the next image not yet)."""
    real_atomic = writer_module.write_atomic
    real_append = LineLog.append

    def atomic(path: Any, data: bytes, *, durable: bool = True) -> None:
        name = os.path.basename(str(path))
        if hook == "setup" and name == "meta.json":
            pause()
        real_atomic(path, data, durable=durable)
        if hook == "image" and name == f"{at:06d}.png":
            pause()

    def append(self: LineLog, data: bytes) -> None:
        real_append(self, data)
        if hook == "row" and self.path.name == "frames.csv" and data.startswith(f"{at},".encode()):
            pause()

    writer_module.write_atomic = atomic
    LineLog.append = append  # type: ignore[method-assign]
    w_ = DatasetWriter(folder, meta(w, h))
    for k in range(frames):
        w_.write(frame(k, w, h))
    w_.close()


def job_cli(argv: list[str]) -> None:
    """``python -m tileviz ARGV`` in this process."""
    from tileviz.__main__ import main

    code = main(argv)
    if code:
        raise SystemExit(code)


def job_replay(dataset: str, out: str, mcap: str) -> None:
    """``replay DATASET --out OUT --mcap MCAP`` with vision in this process (one job)."""
    from tileviz.pipeline.replay import replay

    n = 0

    def on_frame(_: object) -> None:
        nonlocal n
        n += 1
        say(f"wrote {n}")

    replay(dataset, out=out, mcap=mcap, jobs=1, on_frame=on_frame)


def job_session(out_dir: str, frames: int) -> None:
    """The demo's Record button: a live session (no browser) recording ``frames`` new frames to
    ``out_dir/live`` (its folder name as the Record panel's default)."""
    from pathlib import Path

    from tileviz.app import commands as C
    from tileviz.app.session import Session, SessionOptions

    cfg = preset("default")
    s = Session(cfg, SessionOptions(out_dir=Path(out_dir), display=False, history=50))
    s.apply(C.StartRecording("live"))
    for _ in range(frames):
        s.compute()
    s.apply(C.StopRecording())
    s.close()


def say_progress() -> None:
    """Every DatasetWriter of the job says ``wrote K`` once its K-th frame is written."""
    real = DatasetWriter.write

    def write(self: DatasetWriter, frame: Any) -> None:
        real(self, frame)
        say(f"wrote {self.count}")

    DatasetWriter.write = write  # type: ignore[method-assign]


JOBS: dict[str, Callable[..., None]] = {
    "write": job_write, "cli": job_cli, "replay": job_replay, "session": job_session}


def main() -> None:
    set_opencv_threads()
    if "--warm" in sys.argv:
        from tileviz.app.session import Session  # noqa: F401 - loaded before the forks
        from tileviz.datasets.mcap_export import McapExport  # noqa: F401
        from tileviz.evaluation.cli import main as _evaluate  # noqa: F401
        from tileviz.pipeline.replay import replay as _replay  # noqa: F401
        from tileviz.sim.source import SimSource  # noqa: F401
        from tileviz.vision.warmup import warm_up

        warm_up(("robust", "faithful"))
    say("ready")
    child = None
    for line in sys.stdin:
        line = line.strip()
        if line == "reap":
            assert child is not None
            _, status = os.waitpid(child, 0)
            child = None
            say(f"status {status}")
            continue
        spec = json.loads(line)
        pid = os.fork()
        if pid == 0:
            code = 0
            try:
                say(f"pid {os.getpid()}")
                say_progress()
                JOBS[spec.pop("job")](**spec)
                say("done")
            except BaseException as e:  # noqa: BLE001 - reported to the test
                traceback.print_exc()
                say(f"failed {type(e).__name__}: {e}".replace("\n", " "))
                code = 1
            finally:
                os._exit(code)
        child = pid


if __name__ == "__main__":
    main()
