"""Vision timings: per stage at 320x240 and 640x480, the full faithful chain against the bare
OpenCV calls with the seed constants (same run, interleaved), and the robust extractor.

    python bench/bench_vision.py [--frames 200] [--threads N] [--clock wall|cpu]

OpenCV runs on one thread (importing tileviz.vision sets it, for reproducible edges) unless
``--threads N`` is given; both chains then run on N threads.

Frames are rendered once (default floor, random poses, camera noise on) and reused, so only the
vision is timed. Each figure is the median over frames of the per-frame time. The bare chain is
exactly what the original called (report chapter 4, ``shared/seed-code-facts.md``): cvtColor,
Laplacian(CV_8U, ksize 1), Canny(50, 255, 3), morphologyEx(CLOSE, 1x1), dilate(3x3), and
HoughLinesP(1, pi/180, 60, 100, 50); ours adds everything around them (input checks, segment
parameters, medians, bags, offsets, the observation) and skips the 1x1 close (an identity).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tileviz.config import CameraConfig, FloorConfig, VisionConfig, preset  # noqa: E402
from tileviz.sim.camera import FloorRenderer  # noqa: E402
from tileviz.types import Pose  # noqa: E402

clock = time.perf_counter
"""The clock every figure is read from (``--clock``)."""
from tileviz.vision import extract  # noqa: E402

SEED_KERNEL_1 = np.ones((1, 1), np.uint8)


def bare_chain(rgb: np.ndarray) -> object:
    """The original's OpenCV calls with its constants, nothing else."""
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    lap = cv2.Laplacian(gray, cv2.CV_8U, ksize=1, scale=1, delta=0)
    edges = cv2.Canny(lap, 50, 255, apertureSize=3)
    closed = cv2.morphologyEx(edges, cv2.MORPH_CLOSE, SEED_KERNEL_1)
    dil = cv2.dilate(closed, None)
    return cv2.HoughLinesP(dil, 1, math.pi / 180, 60, minLineLength=100, maxLineGap=50)


def frames(cam: CameraConfig, floor: FloorConfig, n: int) -> list[np.ndarray]:
    r = FloorRenderer(floor, cam)
    rng = np.random.default_rng(7)
    return [
        r.render(Pose(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4)), rng)
        for _ in range(n)
    ]


def med(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def stage_table(imgs: list[np.ndarray], cam: CameraConfig, floor: FloorConfig,
                vision: VisionConfig) -> tuple[dict[str, float], float]:
    per: dict[str, list[float]] = {}
    total = []
    for img in imgs:
        t0 = clock()
        res = extract(img, camera=cam, tile_size=floor.tile_size, vision=vision)
        total.append((clock() - t0) * 1e3)
        for k, v in res.timings.items():
            per.setdefault(k, []).append(v)
    return {k: med(v) for k, v in per.items()}, med(total)


def compare(imgs: list[np.ndarray], cam: CameraConfig, tile_size: float,
            vision: VisionConfig) -> tuple[float, float]:
    """Median ms per frame of (our faithful chain, the bare calls), interleaved: each frame
    runs both, in an order that alternates, four times over."""
    ours: list[float] = []
    bare: list[float] = []
    for rep in range(4):
        for i, img in enumerate(imgs):
            for which in ((0, 1) if (i + rep) % 2 else (1, 0)):
                t0 = clock()
                if which == 0:
                    extract(img, camera=cam, tile_size=tile_size, vision=vision)
                else:
                    bare_chain(img)
                (ours if which == 0 else bare).append((clock() - t0) * 1e3)
    return med(ours), med(bare)


def parse(doc: str, argv: list[str] | None, threads: bool = False) -> argparse.Namespace:
    """The options shared by the benchmarks (``--frames``, ``--clock``), applied: with
    ``--clock cpu`` this module's ``clock`` becomes the thread's CPU time (OpenCV runs on this
    thread alone: importing tileviz.vision set one thread)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="wall: time.perf_counter; cpu: this thread's CPU time "
                    "(time.thread_time) with OpenCV on one thread, which a busy shared machine "
                    "does not inflate")
    if threads:
        ap.add_argument("--threads", type=int, default=None,
                        help="cv2.setNumThreads for both chains (default: 1, as tileviz.vision "
                        "sets it)")
    args = ap.parse_args(argv)
    global clock
    if args.clock == "cpu":
        clock = time.thread_time
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse(__doc__, argv, threads=True)
    if args.threads is not None:
        cv2.setNumThreads(args.threads)
    print(f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads, {args.clock} clock; "
          f"numpy {np.__version__}; {args.frames} frames per case; medians in ms")
    base = preset("default")
    for w, h in ((320, 240), (640, 480)):
        cam = replace(base.camera, width=w, height=h)
        imgs = frames(cam, base.floor, args.frames)
        for ext in ("faithful", "robust"):
            stages, total = stage_table(imgs, cam, base.floor, replace(base.vision, extractor=ext))
            row = "  ".join(f"{k} {v:.3f}" for k, v in stages.items())
            print(f"{w}x{h} {ext:<8} total {total:.3f} | {row}")
    # the robust extractor per floor family of the vision study (bench/floorgen.py)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import floorgen

    for fam in floorgen.FAMILIES:
        times = []
        for i in range(min(args.frames, 60)):
            rng = np.random.default_rng([i, 77])
            spec = floorgen.draw_floor(fam, rng)
            img = floorgen.render(spec, *floorgen.draw_view(rng), rng)
            cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height,
                               offset=(0.0, 0.0))
            vis = VisionConfig(extractor="robust")
            for _ in range(3):
                t0 = clock()
                extract(img, camera=cam, tile_size=spec.tile_size, vision=vis)
                times.append((clock() - t0) * 1e3)
        print(f"320x240 robust, floor family {fam:<12} median {med(times):.3f} ms, "
              f"p90 {float(np.percentile(times, 90)):.3f} ms")
    # the faithful chain vs the bare OpenCV calls, seed constants, interleaved
    for name, (w, h) in (("seed 256x384", (256, 384)), ("default 320x240", (320, 240)),
                         ("default 640x480", (640, 480))):
        cfg = preset("seed") if name.startswith("seed") else preset("default")
        cam = replace(cfg.camera, width=w, height=h)
        vision = replace(cfg.vision, extractor="faithful")  # VisionConfig defaults = seed's
        imgs = frames(cam, cfg.floor, args.frames)
        o, b = compare(imgs, cam, cfg.floor.tile_size, vision)
        print(f"faithful chain vs bare OpenCV calls, {name}: ours {o:.3f} ms, bare {b:.3f} ms, "
              f"ratio {o / b:.3f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
