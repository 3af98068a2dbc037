"""The declared observation bounds of the presets, measured on each preset's own camera.

    python bench/preset_bounds.py [--poses 2000] [--seed 0] [--write-figures]
    python -m bench.preset_bounds --poses 300

For each preset: random poses (uniform over a 40 m square, every heading) on floors of the preset's
look with a random appearance seed, rendered by the simulator's camera with the preset's noise,
blur and vignetting; the robust extractor reads them. Prints the acceptance rate, the error
percentiles of accepted observations (position in px, the worse of y1, y2; heading in rad) and the
share outside the preset's declared bound (``config.PRESET_VISION``).
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace

import numpy as np

from tileviz.config import preset
from tileviz.sim.camera import FloorRenderer
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Pose
from tileviz.vision import extract, observation_error, set_opencv_threads

set_opencv_threads()  # as every tileviz entry point (workers re-run this on import)


def study(name: str, poses: int, seed: int) -> list[tuple[str, str]]:
    """Print the study of preset ``name``; its figure rows."""
    cfg = preset(name)
    rng = np.random.default_rng(seed)
    pos: list[float] = []
    head: list[float] = []
    bpx: list[float] = []
    brad: list[float] = []
    reasons: dict[str, int] = {}
    renderers: dict[int, FloorRenderer] = {}
    t0 = time.perf_counter()
    for _ in range(poses):
        floor_seed = int(rng.integers(0, 20))
        if floor_seed not in renderers:
            renderers[floor_seed] = FloorRenderer(replace(cfg.floor, seed=floor_seed), cfg.camera)
        pose = Pose(*rng.uniform(-20, 20, 2), rng.uniform(-math.pi, math.pi))
        image = renderers[floor_seed].render(pose, rng)
        r = extract(image, camera=cfg.camera, tile_size=cfg.floor.tile_size, vision=cfg.vision)
        if r.observation is None:
            reasons[r.reason] = reasons.get(r.reason, 0) + 1
            continue
        e = observation_error(r.observation, pose, cfg.floor.tile_size, cfg.camera.offset)
        pos.append(max(abs(e[0]), abs(e[1])) * cfg.camera.ppm)
        head.append(abs(e[2]))
        bpx.append(r.observation.position_error * cfg.camera.ppm)
        brad.append(r.observation.heading_error)
    p, h = np.asarray(pos), np.asarray(head)
    bound_px, bound_rad = np.asarray(bpx), np.asarray(brad)  # each view's own bound
    print(f"\n== preset {name}: {poses} poses in {time.perf_counter() - t0:.0f} s; "
          f"limits {cfg.vision.position_error_px} px / {cfg.vision.heading_error} rad")
    print(f"accepted {len(p)} ({100 * len(p) / poses:.1f} %); refused: {reasons}")
    q = [50, 90, 99, 99.9, 100]
    print("position error px  p50/p90/p99/p99.9/max: "
          + " ".join(f"{v:.3f}" for v in np.percentile(p, q)))
    print("heading error rad  p50/p90/p99/p99.9/max: "
          + " ".join(f"{v:.5f}" for v in np.percentile(h, q)))
    print("declared bound px  p50/p90/p99/p99.9/max: "
          + " ".join(f"{v:.3f}" for v in np.percentile(bound_px, q)))
    print("declared bound rad p50/p90/p99/p99.9/max: "
          + " ".join(f"{v:.5f}" for v in np.percentile(bound_rad, q)))
    out = int(np.sum((p > bound_px) | (h > bound_rad)))
    print(f"outside its own declared bound: {out} of {len(p)}; largest error / bound "
          f"{(p / bound_px).max():.2f} (position), {(h / bound_rad).max():.2f} (heading)")
    return [
        (f"{name}: views accepted", f"{100 * len(p) / poses:.1f} % of {poses}"),
        (f"{name}: median declared bound", f"{np.median(bound_px):.2f} px / "
         f"{np.median(bound_rad):.4f} rad"),
        (f"{name}: largest error / own bound (position, heading)",
         f"{(p / bound_px).max():.2f}, {(h / bound_rad).max():.2f}"),
        (f"{name}: accepted outside their own bound", f"{out}"),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--presets", nargs="+", default=["default", "seed"])
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:preset_bounds)")
    args = ap.parse_args()
    machine = Machine()
    rows = [row for name in args.presets for row in study(name, args.poses, args.seed)]
    if args.write_figures:
        write_block("preset_bounds", "Per-view bounds on the presets' cameras", rows,
                    machine=machine)


if __name__ == "__main__":
    main()
