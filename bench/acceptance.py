"""Acceptance figures, measured over recorded runs.

For each case, a preset (default: L = 1 m, 200 px/m, 320x240; seed: the original's constants)
with an optional floor style (``preset:style``, the styles of ``record --floor-style``; by
default the plain default floor, the default preset on the ``photo`` floor (a photograph of
gravel on the tiles) and the seed preset), it records a simulated run of ``--minutes`` minutes
as a dataset, replays it in autonomous and odometry modes and
prints: share of frames whose truth is inside the reported set, count of each status, median and
p95 box widths (x, y in cm, heading in degrees). Then it times, on the same images, the replay per
frame (``replay`` itself, with 2 worker processes and with 1, and the CPU time of each of its
steps: reading rows, PNG decoding, vision, localizer and loop, output) against the bare OpenCV
calls of the original pipeline with its constants (cvtColor, Laplacian, Canny, close, dilate,
HoughLinesP) on the same images, decoded and in memory, in the same run (:func:`timing`).

    python bench/acceptance.py --minutes 10            # the figures of docs/figures.md
    python bench/acceptance.py --minutes 1 --cases default default:photo
    python -m bench.acceptance --minutes 0.5 --cases default --write-figures

``--write-figures`` also writes the figures into ``docs/figures.md`` (``figures:acceptance``).
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from tileviz.config import FLOOR_STYLES, Config, preset, with_floor_style
from tileviz.datasets import DatasetMeta, DatasetSource, DatasetWriter, replay_config
from tileviz.pipeline import FrameLoop, FrameRecord
from tileviz.pipeline.heap import keep_freed_memory
from tileviz.pipeline.outputs import replay_row
from tileviz.pipeline.replay import replay
from tileviz.sim.source import SimSource
from tileviz.testing.figures import Machine, write_block
from tileviz.vision import extract, set_opencv_threads

set_opencv_threads()  # as every tileviz entry point (workers re-run this on import)
keep_freed_memory()  # as the replay command and its workers: the bare calls get it too


def record(cfg: Config, folder: Path, frames: int) -> None:
    with DatasetWriter(folder, DatasetMeta.from_config(cfg)) as w:
        for frame in itertools.islice(SimSource(cfg), frames):
            w.write(frame)


def replay_stats(folder: Path, mode: str, base: Config | None = None) -> dict[str, float]:
    """``base``: the configuration under the meta's geometry (None: the one tileviz stored;
    ``Config()``: what a dataset written by another program gets, its camera not a preset)."""
    src = DatasetSource(folder)
    cfg = src.meta.to_config(base)
    cfg = replace(cfg, localizer=replace(cfg.localizer, mode=mode))
    runner = FrameLoop(cfg)
    inside = vouched = 0
    statuses: dict[str, int] = {}
    wx, wy, wt, boxes = [], [], [], []
    for rec in runner.run(src):
        statuses[rec.status] = statuses.get(rec.status, 0) + 1
        hull = rec.updated.hull()
        if rec.status != "lost" and hull is not None:
            vouched += 1
            inside += rec.updated.contains(*rec.truth.as_tuple())
            w = hull.widths
            wx.append(w[0])
            wy.append(w[1])
            wt.append(w[2])
            boxes.append(len(rec.updated))

    def pct(v: list[float], q: float) -> float:
        return float(np.percentile(v, q)) if v else math.nan

    n = sum(statuses.values())
    return {
        "frames": n,
        "inside_pct": 100.0 * inside / vouched if vouched else math.nan,
        "vouched_pct": 100.0 * vouched / n,
        **{f"n_{k}": statuses.get(k, 0) for k in ("contracted", "predicted", "rejected", "lost")},
        "med_wx_cm": 100 * pct(wx, 50), "med_wy_cm": 100 * pct(wy, 50),
        "med_wpos_cm": 100 * pct([max(a, b) for a, b in zip(wx, wy, strict=True)], 50),
        "p95_wpos_cm": 100 * pct([max(a, b) for a, b in zip(wx, wy, strict=True)], 95),
        "med_wt_deg": math.degrees(pct(wt, 50)), "p95_wt_deg": math.degrees(pct(wt, 95)),
        "max_boxes": max(boxes) if boxes else 0,
    }


def bare_opencv(rgb: np.ndarray) -> object:
    """The original pipeline's OpenCV calls with its constants (docs/seed-code.md), only."""
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    lap = cv2.Laplacian(gray, cv2.CV_8U, ksize=1, scale=1, delta=0)
    edges = cv2.Canny(lap, 50, 255, apertureSize=3)
    closed = cv2.morphologyEx(edges, cv2.MORPH_CLOSE, np.ones((1, 1), np.uint8))
    dil = cv2.dilate(closed, np.ones((3, 3), np.uint8), iterations=1)
    return cv2.HoughLinesP(dil, 1, np.pi / 180, 60, minLineLength=100, maxLineGap=50)


def first_frames(folder: Path, limit: int, into: Path) -> Path:
    """A dataset of the first ``limit`` frames of ``folder`` under ``into`` (its meta.json and
    the first rows of frames.csv; the images read from ``folder``'s through a link), so the
    timed replays are the product's own ``replay``."""
    into.mkdir(parents=True, exist_ok=True)
    shutil.copy(folder / "meta.json", into / "meta.json")
    with open(folder / "frames.csv", encoding="utf-8") as f:
        lines = f.readlines()[:limit + 1]
    (into / "frames.csv").write_text("".join(lines), encoding="utf-8")
    for entry in {line.split(",")[2].split("/")[0] for line in lines[1:]}:
        if not (into / entry).exists():
            (into / entry).symlink_to((folder / entry).resolve())
    return into


def process_cpu() -> dict[str, float]:
    """CPU seconds so far (user + system, Linux ``/proc``) of this process's replay helpers:
    ``server``, the workers' fork server (a child of this process; all of it is its start-up:
    the imports and the warm-up of :mod:`tileviz.pipeline.worker_start`, after which it only
    forks), ``tracker``, multiprocessing's resource tracker, and ``workers``, the live vision
    workers (the fork server's children) together."""
    from multiprocessing import forkserver, resource_tracker

    server = getattr(forkserver._forkserver, "_forkserver_pid", None)
    tracker = getattr(resource_tracker._resource_tracker, "_pid", None)
    tick = os.sysconf("SC_CLK_TCK")
    out = {"server": 0.0, "tracker": 0.0, "workers": 0.0}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # gone meanwhile
            continue
        pid, ppid = int(stat.parent.name), int(fields[1])
        cpu = (int(fields[11]) + int(fields[12])) / tick  # utime, stime
        if pid == server:
            out["server"] += cpu
        elif pid == tracker:
            out["tracker"] += cpu
        elif ppid == server:
            out["workers"] += cpu
    return out


def timing(folder: Path, repeats: int = 3, limit: int = 600) -> dict[str, float]:
    """Per-frame costs in milliseconds over the first ``limit`` frames (a dataset of those
    frames, :func:`first_frames`), best of ``repeats`` passes, the cases interleaved so they see
    the same load. Wall clock:

    - ``jobs2``: ``python -m tileviz replay --jobs 2`` (:func:`tileviz.pipeline.replay.replay`,
      its output CSV written; decoding and vision in 2 worker processes, the localizer in
      order in this one; ``replay``'s default on a 2-core machine), from its first frame on:
      the workers' start-up (``jobs2_startup_s``, seconds, once per replay) is left out;
    - ``command1_s``, ``command2_s``: seconds of the whole command ``python -m tileviz replay``
      with ``--jobs 1``, ``--jobs 2`` on the first 8 frames, in a new process (its start-up, as
      a user sees it: imports, the workers' fork server loading the vision code and the
      compiled kernels, the workers);
    - ``command``: the whole command ``python -m tileviz replay`` (its default jobs) on all the
      frames, in a new process, per frame: what a user waits for, start-up included;
    - ``jobs1``: the same with ``--jobs 1`` (images decoded ahead on a thread);
    - ``bare``: the bare OpenCV calls of the original pipeline on the decoded images (already
      in memory: no file is read), with OpenCV on its default thread count (one per CPU, as
      the original ran; tileviz runs it on one thread, see tileviz.vision).

    CPU time (``*_cpu``; the work a frame costs, which a loaded machine inflates less than
    wall time):

    - ``jobs2_cpu``: ``--jobs 2``, this process and its 2 workers together (the workers' own
      start-up included: forked from the fork server, a few milliseconds each);
    - ``jobs2_main_cpu``: the part of it in this process (reading rows, handing the frames to
      the workers and taking their results, the localizer, the output);
    - ``jobs2_workers_cpu``: the part of it in the 2 workers (reading and decoding the PNG,
      vision, taking the tasks and sending the results back);
    - ``server_cpu_s``: seconds, the workers' fork server (its start-up: the imports and the
      warm-up; once per process, not per replay, so not per frame);
    - ``rows``, ``decode``, ``vision``, ``loop``, ``output``: one pass of the replay's steps on
      one thread, each step clocked in the same pass (``time.thread_time``): reading and
      checking frames.csv's rows; reading, checking and decoding the PNG as replay does
      (``DatasetSource.load_image``); the extractor; the frame loop with the vision result
      given (the localizer's step, the record, the equivalence residuals); the output rows;
    - ``parts``: their sum, the work of a replay on one thread;
    - ``bare1``: the bare OpenCV calls with OpenCV on one thread (the work of the original
      chain, without the idle spinning of OpenCV's thread pool)."""
    with tempfile.TemporaryDirectory(prefix="tileviz-timing-") as tmp:
        return _timing(folder, Path(tmp), repeats, limit)


def _timing(folder: Path, tmp: Path, repeats: int, limit: int) -> dict[str, float]:
    data = first_frames(folder, limit, tmp / "frames")
    src = DatasetSource(data)
    cfg = replay_config(src.meta)
    n = sum(1 for _ in src.frames_without_images())
    images = [f.image for f in src]
    out = tmp / "out.csv"
    parts = ("rows", "decode", "vision", "loop", "output")
    best: dict[str, float] = {}

    def keep(key: str, ms: float) -> None:
        best[key] = min(best.get(key, math.inf), ms)

    def replay_wall(jobs: int) -> tuple[float, float]:
        """(ms per frame from the first frame on, seconds to the first frame)."""
        first: list[float] = []

        def on_frame(_rec: FrameRecord) -> None:
            if not first:
                first.append(time.perf_counter())

        t0 = time.perf_counter()
        replay(data, out=out, jobs=jobs, on_frame=on_frame)
        end = time.perf_counter()
        return (end - first[0]) / (n - 1) * 1e3, first[0] - t0

    def replay_cpu() -> tuple[float, float, float]:
        """(this process, its workers, the fork server) CPU of a --jobs 2 replay: the first two
        in ms per frame, the workers' read at the last frame (still alive then), this
        process's over the whole replay; the fork server's in seconds (all of it start-up)."""
        seen: list[dict[str, float]] = []

        def on_frame(rec: FrameRecord) -> None:
            if rec.index == n - 1:
                seen.append(process_cpu())

        c0 = time.process_time()
        replay(data, out=out, jobs=2, on_frame=on_frame)
        return ((time.process_time() - c0) / n * 1e3, seen[0]["workers"] / n * 1e3,
                seen[0]["server"])

    eight = first_frames(folder, 8, tmp / "eight")

    def command(jobs: int | None, dataset: Path = eight) -> float:
        """Seconds of ``python -m tileviz replay`` on ``dataset`` in a new process."""
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "tileviz", "replay", str(dataset), "--out",
                        str(tmp / "command.csv"), "--quiet",
                        *(["--jobs", str(jobs)] if jobs else [])],
                       check=True, stdout=subprocess.DEVNULL)
        return time.perf_counter() - t0

    def one_thread() -> None:
        """The replay's steps on one thread, each clocked."""
        source = DatasetSource(data)
        loop = FrameLoop(cfg)
        spent = dict.fromkeys(parts, 0.0)
        clock = time.thread_time
        jobs = source.frames_without_images()
        while True:
            c0 = clock()
            try:
                frame, where = next(jobs)
            except StopIteration:
                break
            c1 = clock()
            image = source.load_image(frame.image_name, where)
            c2 = clock()
            vision = extract(image, camera=cfg.camera, tile_size=cfg.floor.tile_size,
                             vision=cfg.vision)
            c3 = clock()
            rec = loop.process(replace(frame, image=image), vision)
            c4 = clock()
            replay_row(rec)
            c5 = clock()
            for key, a, b in zip(parts, (c0, c1, c2, c3, c4), (c1, c2, c3, c4, c5), strict=True):
                spent[key] += b - a
        for key in parts:
            keep(f"{key}_cpu", spent[key] / n * 1e3)
        keep("parts_cpu", sum(spent.values()) / n * 1e3)

    def bare(threads: int) -> tuple[float, float]:
        """(wall, CPU) ms per frame of the bare OpenCV calls on ``threads`` threads."""
        tileviz_threads = cv2.getNumThreads()
        cv2.setNumThreads(threads)
        try:
            c0, t0 = time.process_time(), time.perf_counter()
            for g in images:
                bare_opencv(g)
            return (time.perf_counter() - t0) / n * 1e3, (time.process_time() - c0) / n * 1e3
        finally:
            cv2.setNumThreads(tileviz_threads)

    for _ in range(repeats):
        wall, startup = replay_wall(2)
        keep("jobs2", wall)
        keep("jobs2_startup_s", startup)
        keep("jobs1", replay_wall(1)[0])
        keep("command1_s", command(1))
        keep("command2_s", command(2))
        keep("command", command(None, data) / n * 1e3)
        main, workers, server = replay_cpu()
        keep("jobs2_cpu", main + workers)
        keep("jobs2_main_cpu", main)
        keep("jobs2_workers_cpu", workers)
        keep("server_cpu_s", server)
        one_thread()
        keep("bare1_cpu", bare(1)[1])
        keep("bare", bare(cv2.getNumberOfCPUs())[0])  # OpenCV's default
    return best


def timing_table(tm: dict[str, float], load0: float, load1: float) -> str:
    """:func:`timing`'s figures as lines of text, each part of a replay on its own line."""
    bare, bare1 = tm["bare"], tm["bare1_cpu"]
    jobs2_parts = tm["jobs2_workers_cpu"] + tm["jobs2_main_cpu"]
    best2 = max(0.5 * tm["jobs2_cpu"], tm["jobs2_main_cpu"])  # 2 idle cores, perfect overlap
    one = ("rows", "PNG decoding", "vision", "localizer and loop", "output")
    keys = ("rows_cpu", "decode_cpu", "vision_cpu", "loop_cpu", "output_cpu")
    return "\n".join([
        f"wall ms/frame (load average {load0:.2f} before, {load1:.2f} after; best of 3):",
        f"  replay --jobs 2, from its first frame   {tm['jobs2']:7.3f}  "
        f"{tm['jobs2'] / bare:.2f}x the bare chain",
        f"  replay --jobs 1                         {tm['jobs1']:7.3f}  "
        f"{tm['jobs1'] / bare:.2f}x",
        f"  python -m tileviz replay, whole command {tm['command']:7.3f}  "
        f"{tm['command'] / bare:.2f}x   (start-up included)",
        f"  bare OpenCV chain, default threads      {bare:7.3f}",
        f"  start-up: the command on 8 frames {tm['command2_s']:.2f} s (--jobs 2), "
        f"{tm['command1_s']:.2f} s (--jobs 1); to the first frame of replay() in a warm "
        f"process {tm['jobs2_startup_s']:.2f} s",
        "CPU ms/frame:",
        "  replay's steps on one thread: " + " + ".join(
            f"{name} {tm[k]:.3f}" for name, k in zip(one, keys, strict=True))
        + f" = {tm['parts_cpu']:.3f}  ({tm['parts_cpu'] / bare1:.2f}x the bare chain on one "
        f"thread, {bare1:.3f})",
        f"  replay --jobs 2: workers {tm['jobs2_workers_cpu']:.3f} (decoding + vision on one "
        f"thread {tm['decode_cpu'] + tm['vision_cpu']:.3f}) + this process "
        f"{tm['jobs2_main_cpu']:.3f} = {jobs2_parts:.3f}; on 2 idle cores at best "
        f"{best2:.3f} ms/frame ({best2 / bare1:.2f}x); the workers' fork server "
        f"{tm['server_cpu_s']:.2f} s at its start (once per process)",
    ])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--cases", nargs="+", default=["default", "default:photo", "seed"],
                    metavar="PRESET[:STYLE]",
                    help=f"floor styles: {', '.join(FLOOR_STYLES)}")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", help="keep the datasets under this folder")
    ap.add_argument("--timing-only", action="store_true",
                    help="only the timings (no accuracy figures)")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:acceptance)")
    args = ap.parse_args()
    machine = Machine()
    rows: list[tuple[str, str]] = []
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="tileviz-accept-"))
    for case in args.cases:
        name, _, style = case.partition(":")
        try:
            cfg = preset(name)
            if style:
                cfg = with_floor_style(cfg, style)
        except ValueError as exc:
            ap.error(f"case {case!r}: {exc}")
        cfg = replace(cfg, sim=replace(cfg.sim, seed=args.seed))
        frames = int(args.minutes * 60 / cfg.sim.dt)
        folder = root / f"{name}-{style or 'floor'}-{args.seed}"
        t0 = time.perf_counter()
        if not (folder / "frames.csv").exists():
            record(cfg, folder, frames)
        print(f"\n== preset {name}, floor style {style or '(preset)'}: {frames} frames "
              f"({args.minutes} min simulated), "
              f"recorded in {time.perf_counter() - t0:.0f} s -> {folder}")
        for mode, base in () if args.timing_only else (
                ("autonomous", None), ("odometry", None),
                ("autonomous, camera not a preset", Config())):
            s = replay_stats(folder, mode.split(",")[0], base)
            print(f"{mode:>10}: " + "  ".join(
                f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in s.items()))
            rows += stats_rows(f"{case}, {args.minutes:g} min, {mode}", s)
        load0 = os.getloadavg()[0]
        tm = timing(folder)
        print(timing_table(tm, load0, os.getloadavg()[0]))
        rows += timing_rows(case, tm)
    print(f"\n(datasets in {root}; timings are the best of 3 passes; wall clock unless "
          "marked CPU)")
    if args.write_figures:
        write_block("acceptance", "Acceptance runs and replay speed", rows, machine=machine,
                    note="Replay timings: best of 3 passes over the first 600 frames.")


def stats_rows(label: str, s: dict[str, float]) -> list[tuple[str, str]]:
    """:func:`replay_stats` as figure rows."""
    if label.endswith("odometry"):
        return [(f"{label}: truth inside the set", f"{s['inside_pct']:.1f} %"),
                (f"{label}: median box x / y", f"{s['med_wx_cm'] / 100:.1f} / "
                 f"{s['med_wy_cm'] / 100:.1f} m")]
    return [
        (f"{label}: truth inside the set", f"{s['inside_pct']:.1f} % of {s['frames']:.0f}"),
        (f"{label}: contracted / lost frames", f"{s['n_contracted']} / {s['n_lost']}"),
        (f"{label}: median box x / y", f"{s['med_wx_cm']:.2f} / {s['med_wy_cm']:.2f} cm"),
        (f"{label}: median heading width", f"{s['med_wt_deg']:.2f} deg"),
        (f"{label}: p95 box, heading", f"{s['p95_wpos_cm']:.2f} cm, {s['p95_wt_deg']:.2f} deg"),
    ]


def timing_rows(case: str, tm: dict[str, float]) -> list[tuple[str, str]]:
    """:func:`timing`'s headline figures as rows."""
    bare = tm["bare"]
    return [
        (f"{case}: replay --jobs 2, wall ms/frame", f"{tm['jobs2']:.2f} "
         f"({tm['jobs2'] / bare:.2f}x the bare chain)"),
        (f"{case}: replay --jobs 1, wall ms/frame", f"{tm['jobs1']:.2f} "
         f"({tm['jobs1'] / bare:.2f}x)"),
        (f"{case}: whole replay command, ms/frame", f"{tm['command']:.2f} "
         f"({tm['command'] / bare:.2f}x)"),
        (f"{case}: bare OpenCV chain of the original, ms/frame", f"{bare:.2f}"),
        (f"{case}: replay steps on one thread, CPU ms/frame", f"{tm['parts_cpu']:.2f} "
         f"(vision {tm['vision_cpu']:.2f}, PNG {tm['decode_cpu']:.2f})"),
        (f"{case}: command start-up on 8 frames", f"{tm['command2_s']:.2f} s"),
    ]


if __name__ == "__main__":
    main()
