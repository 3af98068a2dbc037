"""Renderer timings: ms per frame at 320x240 and 640x480, with the default camera effects
(noise, blur, vignetting), with JPEG, and with a fault.

    python bench/bench_camera.py [--frames 200] [--clock wall|cpu] [--write-figures]
    python -m bench.bench_camera --clock cpu

Each figure is the median over frames of ``FloorRenderer.render`` (random poses, one rng);
the floor's appearance is computed once per renderer (its time is printed too).
"""

from __future__ import annotations

import statistics
from dataclasses import replace

import cv2
import numpy as np

from tileviz.config import preset
from tileviz.sim.camera import Fault, FloorRenderer
from tileviz.testing import timing
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Pose


def main(argv: list[str] | None = None) -> int:
    ap = timing.parser(__doc__)
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:renderer)")
    args = ap.parse_args(argv)
    timing.use_clock(args.clock)
    machine = Machine()
    rows: list[tuple[str, str]] = []
    cfg = preset("default")
    print(f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads, {args.clock} clock; "
          f"{args.frames} frames per case; medians in ms")
    for w, h in ((320, 240), (640, 480)):
        base = replace(cfg.camera, width=w, height=h)
        cases = {
            "default effects": (base, None),
            "no effects": (replace(base, noise_sigma=0.0, blur_sigma=0.0, vignetting=0.0), None),
            "JPEG q80": (replace(base, jpeg_quality=80), None),
            "cable fault": (base, [Fault("cable")]),
            "motion blur fault": (base, [Fault("motion_blur")]),
        }
        for name, (cam, faults) in cases.items():
            t0 = timing.clock()
            r = FloorRenderer(cfg.floor, cam)
            init = (timing.clock() - t0) * 1e3
            rng = np.random.default_rng(1)
            times = []
            for _ in range(args.frames):
                pose = Pose(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4))
                t0 = timing.clock()
                r.render(pose, rng, faults=faults)
                times.append((timing.clock() - t0) * 1e3)
            print(f"{w}x{h} {name:<18} {statistics.median(times):6.3f} ms/frame "
                  f"(renderer init {init:.0f} ms)")
            rows.append((f"{w}x{h}, {name}", f"{statistics.median(times):.2f} ms/frame"))
    if args.write_figures:
        write_block("renderer", "The simulator's floor renderer", rows, machine=machine,
                    note=f"Medians over {args.frames} frames, {args.clock} clock.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
