"""What rectifying a real camera's image costs, and what the ways of doing it cost.

Builds the ``webcam`` lens preset (640x480 raw, tilted, distorted) for a rectified view of
``--width`` x ``--height`` at the default preset's ppm scaled to keep its field of view, renders
``--frames`` raw RGB images through it and times each ``--variant`` on them: CPU time of this
thread (``time.thread_time``), best of ``--passes`` passes, per frame. OpenCV runs on one
thread, as every tileviz entry point sets it (with worker threads this thread's CPU time would
leave out their work). Also prints the one-time cost of the tables, the load average, and for
each variant the largest difference from the exact bilinear sample (float64, at the camera
model's source points) of the raw gray levels, in gray levels, and how far it may move a sample.

Variants (``all`` runs every one):

- ``vision`` (default): what replay, the server and ``extract`` do for vision,
  :meth:`tileviz.datasets.camera_model.Rectifier.gray` on the raw RGB image: its gray
  conversion (which vision needs without a camera model too, then on the view) and one remap
  of one channel with float tables;
- ``remap``: that remap alone, on the raw gray image (the cost the camera model adds);
- ``convert``: the gray conversion of the raw RGB image alone;
- ``rgb``: the colour view the demo shows (:class:`Rectifier` called on the RGB image; OpenCV's
  fixed-point tables, its faster path for three channels);
- ``fixed``: one channel with fixed-point tables (``CV_16SC2``: sample points rounded to 1/32
  px, weights to 1/32768), the previous way;
- ``float2``: one channel with one interleaved float table (``CV_32FC2``);
- ``roi``: the gray conversion of only the raw pixels the view samples (a sub-array) and the
  remap from it;
- ``nearest``: nearest neighbour: moves a sample by up to 0.71 px, beyond the 0.5 px
  resampling term the view bound accounts for (docs/dataset-format.md): not usable, a floor;
- ``perspective``: one ``cv2.warpPerspective`` of the gray image (bilinear, no table read): not
  a rectification (it cannot undo the lens), the cost of one bilinear sample per view pixel
  without a table.

    python bench/bench_rectify.py [--variant vision remap ... | all] [--width 640 --height 480]
        [--frames 100] [--passes 5]
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from dataclasses import replace

import cv2
import numpy as np

from tileviz.config import preset
from tileviz.datasets.camera_model import Rectifier, rectified_floor_points
from tileviz.sim.lens import LensRenderer, webcam_model
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Pose

VARIANTS = ("vision", "remap", "convert", "rgb", "fixed", "float2", "roi", "nearest",
            "perspective")


def exact_sample(gray: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear sample of ``gray`` at raw points (u, v), float64, 0 outside the image."""
    g = np.pad(gray.astype(np.float64), 1)
    iu, iv = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - iu, v - iv
    iu, iv = np.clip(iu + 1, 0, g.shape[1] - 2), np.clip(iv + 1, 0, g.shape[0] - 2)
    top = g[iv, iu] * (1 - fu) + g[iv, iu + 1] * fu
    bottom = g[iv + 1, iu] * (1 - fu) + g[iv + 1, iu + 1] * fu
    return top * (1 - fv) + bottom * fv


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", nargs="+", default=["vision"], choices=(*VARIANTS, "all"),
                    help="what to time (default: vision; all: every variant)")
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--passes", type=int, default=5)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:rectify_WxH)")
    a = ap.parse_args()
    machine = Machine()
    rows: list[tuple[str, str]] = []
    variants = VARIANTS if "all" in a.variant else tuple(dict.fromkeys(a.variant))
    cv2.setNumThreads(1)  # as every tileviz entry point; thread_time() counts this thread only
    cfg = preset("default")
    cam = replace(cfg.camera, width=a.width, height=a.height,
                  ppm=cfg.camera.ppm * a.width / cfg.camera.width)
    model = webcam_model(cam)
    renderer = LensRenderer(cfg.floor, cam, model)
    rng = np.random.default_rng(0)
    raws = [renderer.render(Pose(*rng.uniform(-3, 3, 2), rng.uniform(-3, 3)), rng=rng)
            for _ in range(a.frames)]
    grays = [cv2.cvtColor(r, cv2.COLOR_RGB2GRAY) for r in raws]
    t0 = time.perf_counter()
    rect = Rectifier(model, ppm=cam.ppm, width=cam.width, height=cam.height,
                     camera_offset=cam.offset)
    tables_ms = (time.perf_counter() - t0) * 1e3

    # the camera model's source points, unrounded, for the reference and the other tables
    floor = rectified_floor_points(cam.ppm, cam.width, cam.height, cam.offset)
    src, seen = model.floor_to_raw(floor.reshape(-1, 2))
    src = src.reshape(cam.height, cam.width, 2)
    src[~seen.reshape(cam.height, cam.width)] = -10.0
    pts = src.astype(np.float32)
    fixed = cv2.convertMaps(pts[..., 0], pts[..., 1], cv2.CV_16SC2)
    lo = np.floor(pts[seen.reshape(pts.shape[:2])].min(0)).astype(int)
    hi = np.floor(pts[seen.reshape(pts.shape[:2])].max(0)).astype(int) + 2
    roi = (slice(max(lo[1], 0), hi[1]), slice(max(lo[0], 0), hi[0]))
    roi_x = np.ascontiguousarray(pts[..., 0] - np.float32(roi[1].start))
    roi_y = np.ascontiguousarray(pts[..., 1] - np.float32(roi[0].start))
    hom = np.eye(3)

    run: dict[str, tuple[Callable[[np.ndarray], np.ndarray], list[np.ndarray], str]] = {
        "vision": (rect.gray, raws, "RGB -> gray view (Rectifier.gray)"),
        "remap": (lambda g: cv2.remap(g, rect.map_x, rect.map_y, cv2.INTER_LINEAR), grays,
                  "gray -> gray view, float tables (32FC1 x2)"),
        "convert": (lambda r: cv2.cvtColor(r, cv2.COLOR_RGB2GRAY), raws,
                    "RGB -> gray raw (cvtColor)"),
        "rgb": (rect, raws, "RGB -> RGB view, fixed-point tables (shown)"),
        "fixed": (lambda g: cv2.remap(g, fixed[0], fixed[1], cv2.INTER_LINEAR), grays,
                  "gray -> gray view, fixed-point tables (16SC2)"),
        "float2": (lambda g: cv2.remap(g, pts, None, cv2.INTER_LINEAR), grays,
                   "gray -> gray view, one interleaved float table (32FC2)"),
        "roi": (lambda r: cv2.remap(cv2.cvtColor(r[roi], cv2.COLOR_RGB2GRAY), roi_x, roi_y,
                                    cv2.INTER_LINEAR), raws,
                "RGB footprint -> gray -> gray view"),
        "nearest": (lambda g: cv2.remap(g, fixed[0], None, cv2.INTER_NEAREST), grays,
                    "gray -> gray view, nearest neighbour (not usable)"),
        "perspective": (lambda g: cv2.warpPerspective(g, hom, (cam.width, cam.height)), grays,
                        "gray -> warpPerspective (not a rectification)"),
    }
    moves = {"vision": 1 / 512, "remap": 1 / 512, "fixed": 1 / 64 * 2 ** 0.5, "roi": 0.0,
             "float2": 0.0, "rgb": 1 / 64 * 2 ** 0.5, "nearest": 0.5 * 2 ** 0.5}
    load = os.getloadavg()
    print(f"OpenCV {cv2.__version__}, threads {cv2.getNumThreads()}; load average "
          f"{load[0]:.1f} {load[1]:.1f} {load[2]:.1f}; raw {model.raw_width}x"
          f"{model.raw_height} RGB -> rectified {cam.width}x{cam.height}; tables (once) "
          f"{tables_ms:.1f} ms; CPU ms a frame, best of {a.passes} passes over {len(raws)} "
          "frames")
    ref = exact_sample(grays[0], src[..., 0], src[..., 1])
    for name in variants:
        fn, inputs, what = run[name]
        best = float("inf")
        for _ in range(a.passes):
            t0 = time.thread_time()
            for x in inputs:
                fn(x)
            best = min(best, (time.thread_time() - t0) / len(inputs) * 1e3)
        extra = ""
        if name not in ("convert", "perspective"):
            out = fn(inputs[0])
            if out.ndim == 3:
                out = cv2.cvtColor(out, cv2.COLOR_RGB2GRAY)
            err = float(np.abs(out - ref).max())
            extra = (f"  max |view - exact sample| {err:.2f} gray levels; a sample moves "
                     f"<= {moves[name]:.3f} px")
        print(f"{name:12s} {best:6.3f} ms  {what}{extra}")
        rows.append((f"{name}: {what}", f"{best:.2f} ms CPU"))
    if a.write_figures:
        write_block(f"rectify_{cam.width}x{cam.height}", "Rectifying a 640x480 raw camera image "
                    f"into a {cam.width}x{cam.height} view", rows, machine=machine,
                    note=f"Tables computed once: {tables_ms:.1f} ms. Best of {a.passes} passes "
                    f"over {len(raws)} frames, one OpenCV thread.")


if __name__ == "__main__":
    main()
