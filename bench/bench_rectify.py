"""What rectifying a real camera's image costs: one ``cv2.remap`` with tables computed once.

Builds the ``webcam`` lens preset (640x480 raw, tilted, distorted) for a rectified view of
``--width`` x ``--height`` at the default preset's ppm scaled to keep its field of view, renders
``--frames`` raw images through it, and times :class:`tileviz.datasets.camera_model.Rectifier`
on them (CPU time of this thread, best of five passes, per frame). OpenCV runs on one thread, as
every tileviz entry point sets it: with worker threads this thread's CPU time would leave out
their work. Also prints the one-time cost of the tables.

    python bench/bench_rectify.py [--frames 100] [--width 640 --height 480] [--gray]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import cv2
import numpy as np

from tileviz.config import preset
from tileviz.datasets.camera_model import Rectifier
from tileviz.sim.lens import LensRenderer, webcam_model
from tileviz.types import Pose


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--gray", action="store_true", help="rectify one channel instead of RGB")
    a = ap.parse_args()
    cv2.setNumThreads(1)  # as every tileviz entry point; thread_time() counts this thread only
    cfg = preset("default")
    cam = replace(cfg.camera, width=a.width, height=a.height,
                  ppm=cfg.camera.ppm * a.width / cfg.camera.width)
    model = webcam_model(cam)
    renderer = LensRenderer(cfg.floor, cam, model)
    rng = np.random.default_rng(0)
    raws = [renderer.render(Pose(*rng.uniform(-3, 3, 2), rng.uniform(-3, 3)), rng=rng)
            for _ in range(a.frames)]
    if a.gray:
        raws = [cv2.cvtColor(r, cv2.COLOR_RGB2GRAY) for r in raws]
    t0 = time.perf_counter()
    rect = Rectifier(model, ppm=cam.ppm, width=cam.width, height=cam.height,
                     camera_offset=cam.offset)
    tables_ms = (time.perf_counter() - t0) * 1e3
    best = float("inf")
    for _ in range(5):
        t0 = time.thread_time()
        for r in raws:
            rect(r)
        best = min(best, (time.thread_time() - t0) / len(raws) * 1e3)
    print(f"OpenCV threads {cv2.getNumThreads()}; raw {model.raw_width}x{model.raw_height} -> "
          f"rectified {cam.width}x{cam.height} {'gray' if a.gray else 'RGB'}")
    print(f"tables (once): {tables_ms:.1f} ms; rectify: {best:.3f} ms CPU a frame "
          f"(best of 5 passes over {len(raws)} frames)")


if __name__ == "__main__":
    main()
