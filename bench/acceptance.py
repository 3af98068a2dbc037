"""Acceptance figures of issue 4, measured over recorded runs.

For each case, a preset (default: L = 1 m, 200 px/m, 320x240; seed: the original's constants)
with an optional floor style (``preset:style``, the styles of ``record --floor-style``; by
default the plain default floor, the default preset on the ``photo`` floor (a photograph of
gravel on the tiles) and the seed preset), it records a simulated run of ``--minutes`` minutes
as a dataset, replays it in autonomous and odometry modes and
prints: share of frames whose truth is inside the reported set, count of each status, median and
p95 box widths (x, y in cm, heading in degrees). Then it times, on the same images, the replay per
frame (PNG decode + vision + localizer, as ``replay`` runs it, and its parts) against the bare
OpenCV calls of the original pipeline with its constants (cvtColor, Laplacian, Canny, close,
dilate, HoughLinesP).

    python bench/acceptance.py --minutes 10            # the issue's figures
    python bench/acceptance.py --minutes 1 --cases default default:photo
"""

from __future__ import annotations

import argparse
import itertools
import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from tileviz.config import FLOOR_STYLES, Config, preset, with_floor_style
from tileviz.datasets import DatasetMeta, DatasetSource, DatasetWriter
from tileviz.pipeline import FrameLoop
from tileviz.pipeline.workers import vision_ahead
from tileviz.sim.source import SimSource
from tileviz.vision import extract, set_opencv_threads

set_opencv_threads()  # as every tileviz entry point (workers re-run this on import)


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


def timing(folder: Path, repeats: int = 3, limit: int = 600) -> dict[str, float]:
    """Wall ms per frame over the first ``limit`` frames, best of ``repeats`` passes, the
    cases interleaved so they see the same load:

    - ``jobs2``: ``python -m tileviz replay --jobs 2`` (decode + vision in 2 worker processes,
      the localizer in order in this one; ``replay``'s default on a 2-core machine), from its
      first frame on: the workers' start-up
      (``jobs2_startup_s``, seconds, once per replay) is left out, as it is spread over
      12000 frames in a 10-minute replay;
    - ``replay``: what ``python -m tileviz replay --jobs 1`` does (images decoded ahead on a
      thread);
    - ``serial``: the same with every image decoded when its frame is asked for;
    - ``decode``: reading and decoding the images alone;
    - ``bare``: the bare OpenCV calls of the original pipeline on the decoded images, with
      OpenCV on its default thread count (one per CPU, as the original ran; tileviz runs it on
      one thread, see tileviz.vision);
    - ``bare1``: the same bare calls with OpenCV on one thread (its CPU time is the work of
      the original chain, without the idle spinning of OpenCV's thread pool);
    - ``vision``: the extractor alone on the decoded images.

    Each ``<case>_cpu`` (all but jobs2) is the same pass in CPU time of this process (all its
    threads, ``time.process_time``): the work a frame costs, which a loaded machine does not
    inflate as it does wall time."""
    cfg = DatasetSource(folder).meta.to_config()
    names = [f.image_name for f in itertools.islice(DatasetSource(folder), limit)]
    images = [f.image for f in itertools.islice(DatasetSource(folder), limit)]
    keys = ("jobs2", "jobs2_startup_s", "replay", "serial", "decode", "bare", "bare1", "vision")
    best = dict.fromkeys(keys + tuple(f"{k}_cpu" for k in keys[2:]), math.inf)

    def clocked(key: str, work: object) -> None:
        t0 = time.perf_counter()
        c0 = time.process_time()
        work()  # type: ignore[operator]
        c1 = time.process_time()
        best[key] = min(best[key], (time.perf_counter() - t0) / len(images) * 1e3)
        best[f"{key}_cpu"] = min(best[f"{key}_cpu"], (c1 - c0) / len(images) * 1e3)

    def vision() -> None:
        for g in images:
            extract(g, camera=cfg.camera, tile_size=cfg.floor.tile_size, vision=cfg.vision)

    def replay(prefetch: int) -> None:
        for _rec in FrameLoop(cfg).run(
                itertools.islice(DatasetSource(folder, prefetch=prefetch), limit)):
            pass

    def parallel() -> None:
        src = DatasetSource(folder)
        runner = FrameLoop(cfg)
        t0 = time.perf_counter()
        first = 0.0
        for k, (frame, vision) in enumerate(itertools.islice(vision_ahead(src, cfg, 2), limit)):
            if k == 0:
                first = time.perf_counter()
            runner.process(frame, vision)
        end = time.perf_counter()
        best["jobs2"] = min(best["jobs2"], (end - first) / (len(images) - 1) * 1e3)
        best["jobs2_startup_s"] = min(best["jobs2_startup_s"], first - t0)

    def bare() -> None:
        tileviz_threads = cv2.getNumThreads()
        cv2.setNumThreads(cv2.getNumberOfCPUs())  # OpenCV's default
        try:
            clocked("bare", lambda: [bare_opencv(g) for g in images])
        finally:
            cv2.setNumThreads(tileviz_threads)

    for _ in range(repeats):
        parallel()
        clocked("replay", lambda: replay(8))
        clocked("serial", lambda: replay(0))
        clocked("decode", lambda: [cv2.imdecode(np.fromfile(folder / n, np.uint8),
                                                cv2.IMREAD_COLOR) for n in names])
        clocked("vision", vision)
        clocked("bare1", lambda: [bare_opencv(g) for g in images])
        bare()
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--cases", nargs="+", default=["default", "default:photo", "seed"],
                    metavar="PRESET[:STYLE]",
                    help=f"floor styles: {', '.join(FLOOR_STYLES)}")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", help="keep the datasets under this folder")
    args = ap.parse_args()
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
        for mode, base in (("autonomous", None), ("odometry", None),
                           ("autonomous, camera not a preset", Config())):
            s = replay_stats(folder, mode.split(",")[0], base)
            print(f"{mode:>10}: " + "  ".join(
                f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in s.items()))
        tm = timing(folder)
        print(f"replay --jobs 2 {tm['jobs2']:.3f} ms/frame once started (ratio to the bare "
              f"calls {tm['jobs2'] / tm['bare']:.2f}; start-up {tm['jobs2_startup_s']:.2f} s)")
        print(f"replay --jobs 1 (decode+vision+localizer) {tm['replay']:.3f} ms/frame "
              f"({tm['serial']:.3f} without decoding ahead; decoding alone "
              f"{tm['decode']:.3f}); bare OpenCV calls of the original pipeline "
              f"{tm['bare']:.3f} ms/frame; ratio {tm['replay'] / tm['bare']:.2f}")
        # CPU time: the work per frame; with 2 workers, decoding and vision split over two
        # processes and the localizer stays in order in this one
        loc = max(tm["replay_cpu"] - tm["decode_cpu"] - tm["vision_cpu"], 0.0)
        two = max(0.5 * (tm["decode_cpu"] + tm["vision_cpu"]), loc)
        print(f"CPU ms/frame: replay --jobs 1 {tm['replay_cpu']:.3f} (decoding "
              f"{tm['decode_cpu']:.3f}, vision {tm['vision_cpu']:.3f}, localizer and loop "
              f"{loc:.3f}); bare OpenCV calls on one thread {tm['bare1_cpu']:.3f}; ratio "
              f"{tm['replay_cpu'] / tm['bare1_cpu']:.2f}; with 2 workers on 2 idle cores at "
              f"best {two:.3f} ms/frame, ratio {two / tm['bare1_cpu']:.2f}")
    print(f"\n(datasets in {root}; timings are the best of 3 passes; wall clock unless "
          "marked CPU)")


if __name__ == "__main__":
    main()
