"""What a dataset's PNG compression level costs: file size, write time, decode time.

Renders ``--frames`` camera images of a preset (noise, blur, vignetting on, as ``record`` writes
them), encodes each at every zlib level the writer offers (level 0 with no row filter, as
``DatasetWriter`` writes it), and decodes them with libspng (pyspng, what a replay uses in its
own thread and in ``--jobs`` workers) and OpenCV (what the decode-ahead thread uses). CPU time of
this thread, best of three passes, per frame.

    python bench/png_levels.py [--frames 200] [--preset default|seed]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import cv2
import numpy as np
import pyspng

from tileviz.config import preset
from tileviz.sim.camera import FloorRenderer
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Pose


def best_ms(work: Callable[[bytes], object], blobs: list[bytes]) -> float:
    best = float("inf")
    for _ in range(3):
        t0 = time.thread_time()
        for b in blobs:
            work(b)
        best = min(best, (time.thread_time() - t0) / len(blobs) * 1e3)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--preset", default="default", choices=("default", "seed"))
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:png_levels)")
    args = ap.parse_args()
    machine = Machine()
    rows: list[tuple[str, ...]] = []
    cfg = preset(args.preset)
    renderer = FloorRenderer(cfg.floor, cfg.camera)
    rng = np.random.default_rng(1)
    bgr = [np.ascontiguousarray(renderer.render(
        Pose(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4)), rng)[:, :, ::-1])
        for _ in range(args.frames)]
    print(f"preset {args.preset}: {cfg.camera.width}x{cfg.camera.height}, {args.frames} frames; "
          "ms of CPU per frame")
    cases: list[tuple[str, list[int]]] = [("OpenCV's default", [])]
    cases += [(f"level {level}", [cv2.IMWRITE_PNG_COMPRESSION, 0, cv2.IMWRITE_PNG_FILTER,
                                  cv2.IMWRITE_PNG_FILTER_NONE] if level == 0
               else [cv2.IMWRITE_PNG_COMPRESSION, level]) for level in range(10)]
    for label, params in cases:
        t0 = time.thread_time()
        blobs = [cv2.imencode(".png", im, params)[1].tobytes() for im in bgr]
        write = (time.thread_time() - t0) / len(bgr) * 1e3
        assert all(np.array_equal(pyspng.load(b, "RGB"), im[:, :, ::-1])
                   for b, im in zip(blobs, bgr, strict=True)), "a decoder changed the pixels"
        spng = best_ms(lambda b: pyspng.load(b, "RGB"), blobs)
        ocv = best_ms(lambda b: cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_COLOR),
                      blobs)
        size = sum(len(b) for b in blobs) / len(blobs) / 1024
        print(f"{label:>34}: {size:6.1f} KB  write {write:6.2f}  decode libspng {spng:.3f}  "
              f"OpenCV {ocv:.3f}")
        rows.append((label, f"{size:.1f}", f"{write:.2f}", f"{spng:.3f}", f"{ocv:.3f}"))
    if args.write_figures:
        write_block("png_levels", "What a dataset's PNG compression level costs", rows,
                    machine=machine, header=("PNG level", "KB a frame", "write ms",
                                             "decode ms, libspng", "decode ms, OpenCV"),
                    note=f"{args.preset} preset, {cfg.camera.width}x{cfg.camera.height}, "
                    f"{args.frames} frames, CPU of one thread.")


if __name__ == "__main__":
    main()
