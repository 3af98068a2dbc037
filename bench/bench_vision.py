"""Vision timings: per stage at 320x240 and 640x480, the robust extractor per floor family, and
the full faithful chain against the bare OpenCV calls with the seed constants (same run,
interleaved).

    python bench/bench_vision.py [--frames 200] [--threads N] [--clock wall|cpu]
                                 [--only stages,families,chain] [--write-figures]
    python -m bench.bench_vision --only families --clock cpu

OpenCV runs on one thread unless ``--threads N`` is given (this script sets it: importing
tileviz.vision leaves OpenCV's thread count alone); both chains then run on N threads. With
``--clock cpu`` every total is this thread's CPU time (``time.thread_time``), which a busy
shared machine inflates far less than wall time; on one OpenCV thread it is the whole cost.
The per-stage figures are the extractor's own timings (``VisionResult.timings``, wall clock).

Frames are rendered once (default floor, random poses, camera noise on) and reused, so only the
vision is timed. Each figure is the median over frames of the per-frame time. Per floor family
(``tileviz/testing/floorgen.py``, all nine), ``min(frames, 60)`` clean views, each extracted 3
times: median and 90th percentile of those times, the bare chain's median on the same views and
the costliest stages; a family that cannot be rendered (scikit-image missing for ``photo``) is
reported as skipped, the others still run. The bare chain is
exactly what the original called (report chapter 4, ``docs/seed-code.md``): cvtColor,
Laplacian(CV_8U, ksize 1), Canny(50, 255, 3), morphologyEx(CLOSE, 1x1), dilate(3x3), and
HoughLinesP(1, pi/180, 60, 100, 50); ours adds everything around them (input checks, segment
parameters, medians, bags, offsets, the observation) and skips the 1x1 close (an identity).
"""

from __future__ import annotations

import argparse
import math
import statistics
from dataclasses import replace

import cv2
import numpy as np

from tileviz.config import CameraConfig, FloorConfig, VisionConfig, preset
from tileviz.sim.camera import FloorRenderer
from tileviz.testing import timing
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Pose
from tileviz.vision import OPENCV_THREADS, extract, set_opencv_threads

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
        t0 = timing.clock()
        res = extract(img, camera=cam, tile_size=floor.tile_size, vision=vision)
        total.append((timing.clock() - t0) * 1e3)
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
                t0 = timing.clock()
                if which == 0:
                    extract(img, camera=cam, tile_size=tile_size, vision=vision)
                else:
                    bare_chain(img)
                (ours if which == 0 else bare).append((timing.clock() - t0) * 1e3)
    return med(ours), med(bare)


def parse(argv: list[str] | None) -> argparse.Namespace:
    """This bench's options (``--frames``, ``--clock``, ``--only``, ``--threads``), the clock
    applied (:func:`tileviz.testing.timing.use_clock`)."""
    ap = timing.parser(__doc__)
    ap.add_argument("--only", default="stages,families,chain",
                    help="comma-separated parts to run: stages, families, chain")
    ap.add_argument("--threads", type=int, default=None,
                    help="cv2.setNumThreads for both chains (default: 1, as every tileviz "
                    "entry point sets it)")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:vision_stages, "
                    "figures:vision_families, figures:vision_chain: the parts run)")
    args = ap.parse_args(argv)
    timing.use_clock(args.clock)
    return args


def family_table(frames: int) -> list[tuple[str, ...]]:
    """The robust extractor per floor family of the vision study (``tileviz/testing/floorgen.py``):
    median and 90th percentile over ``min(frames, 60)`` clean views x 3 runs, ms; the bare
    OpenCV chain on the same views (timed after them) and the extractor's four costliest
    stages. Returns the figure rows."""
    from tileviz.testing import floorgen

    rows: list[tuple[str, ...]] = []
    vis = VisionConfig(extractor="robust")
    for fam in floorgen.FAMILIES:
        try:
            views = []
            for i in range(min(frames, 60)):
                rng = np.random.default_rng([i, 77])
                spec = floorgen.draw_floor(fam, rng)
                img = floorgen.render(spec, *floorgen.draw_view(rng), rng)
                cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height,
                                   offset=(0.0, 0.0))
                views.append((img, cam, spec.tile_size))
        except ImportError as exc:  # photo needs scikit-image's sample images
            print(f"320x240 robust, floor family {fam:<12} skipped: {exc}")
            rows.append((fam, "skipped: no scikit-image", "", ""))
            continue
        times: list[float] = []
        bare: list[float] = []
        stages: dict[str, list[float]] = {}
        accepted = 0
        for img, cam, tile_size in views:
            for _ in range(3):
                t0 = timing.clock()
                res = extract(img, camera=cam, tile_size=tile_size, vision=vis)
                times.append((timing.clock() - t0) * 1e3)
                for k, v in res.timings.items():
                    stages.setdefault(k, []).append(v)
            accepted += res.accepted
        # the bare chain in a loop of its own (interleaved, each evicts the other's data
        # from the caches and both read slower)
        for img, _, _ in views:
            for _ in range(3):
                t0 = timing.clock()
                bare_chain(img)
                bare.append((timing.clock() - t0) * 1e3)
        top = sorted(stages.items(), key=lambda kv: -med(kv[1]))[:4]
        print(f"320x240 robust, floor family {fam:<12} median {med(times):.3f} ms, "
              f"p90 {float(np.percentile(times, 90)):.3f} ms "
              f"({len(views)} views x 3, {accepted} accepted); the bare OpenCV chain on the "
              f"same views {med(bare):.3f} ms ({med(times) / med(bare):.2f}x); stages "
              f"(wall clock) " + ", ".join(f"{k} {med(v):.2f}" for k, v in top))
        rows.append((fam, f"{med(times):.2f} / {float(np.percentile(times, 90)):.2f}",
                     f"{med(bare):.2f}", ", ".join(f"{k} {med(v):.2f}" for k, v in top[:3])))
    return rows


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    set_opencv_threads(args.threads if args.threads is not None else OPENCV_THREADS)
    print(f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads, {args.clock} clock; "
          f"numpy {np.__version__}; {args.frames} frames per case; medians in ms")
    machine = Machine()
    blocks: dict[str, list[tuple[str, ...]]] = {}
    parts = set(args.only.split(","))
    unknown = parts - {"stages", "families", "chain"}
    if unknown:
        print(f"bench_vision: unknown --only part(s): {', '.join(sorted(unknown))}")
        return 2
    base = preset("default")
    for w, h in ((320, 240), (640, 480)) if "stages" in parts else ():
        cam = replace(base.camera, width=w, height=h)
        imgs = frames(cam, base.floor, args.frames)
        for ext in ("faithful", "robust"):
            stages, total = stage_table(imgs, cam, base.floor, replace(base.vision, extractor=ext))
            row = "  ".join(f"{k} {v:.3f}" for k, v in stages.items())
            print(f"{w}x{h} {ext:<8} total {total:.3f} | stages (wall clock) {row}")
            blocks.setdefault("vision_stages", []).append(
                (f"{w}x{h}, {ext} extractor, per frame", f"{total:.2f} ms"))
    if "families" in parts:
        blocks["vision_families"] = family_table(args.frames)
    # the faithful chain vs the bare OpenCV calls, seed constants, interleaved
    chains = (("seed 256x384", (256, 384)), ("default 320x240", (320, 240)),
              ("default 640x480", (640, 480)))
    for name, (w, h) in chains if "chain" in parts else ():
        cfg = preset("seed") if name.startswith("seed") else preset("default")
        cam = replace(cfg.camera, width=w, height=h)
        vision = replace(cfg.vision, extractor="faithful")  # VisionConfig defaults = seed's
        imgs = frames(cam, cfg.floor, args.frames)
        o, b = compare(imgs, cam, cfg.floor.tile_size, vision)
        print(f"faithful chain vs bare OpenCV calls, {name}: ours {o:.3f} ms, bare {b:.3f} ms, "
              f"ratio {o / b:.3f}x")
        blocks.setdefault("vision_chain", []).append(
            (f"{name}: faithful chain / bare OpenCV calls", f"{o:.2f} / {b:.2f} ms "
             f"({o / b:.2f}x)"))
    titles = {"vision_stages": "Vision per frame, by image size",
              "vision_families": "The robust extractor per floor family, 320x240",
              "vision_chain": "The faithful chain against the original's bare OpenCV calls"}
    headers = {"vision_families": ("floor family", "robust extractor, median / p90 (ms)",
                                   "the original's bare OpenCV chain (ms)",
                                   "costliest stages (ms, wall clock)")}
    for name, rows in blocks.items() if args.write_figures else ():
        write_block(name, titles[name], rows, machine=machine,
                    header=headers.get(name, ("what", "figure")),
                    note=f"Medians, {args.clock} clock, {cv2.getNumThreads()} OpenCV thread(s).")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
