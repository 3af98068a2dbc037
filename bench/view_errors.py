"""Measure the view extractor's errors against the truth on simulated runs and fit MCL's model.

    python bench/view_errors.py [--runs 3] [--seconds 60] [--presets default,seed] [--write]

For each preset and run (simulator seed 100 + r, so not the evaluation's seeds 0..), the robot
drives as in ``tileviz evaluate``; every frame's view (the configured extractor, robust by
default) is compared with the exact view of the true pose (``tileviz.vision.observation_error``)
and normalised by its declared bound. Prints the error percentiles, the share outside the bound,
the lag-1 correlation over consecutive frames, the slow part of the autocorrelation (share and
decay, ``fit_slow_component``) and the fitted Student-t
(``tileviz.baselines.errormodel``); ``--write`` stores the model where the calibrated MCL reads
it (``tileviz/baselines/view_error_model.json``). Rerun with ``--write`` whenever the extractor
changes.
"""

from __future__ import annotations

import argparse
import itertools
import math
import time

import numpy as np

from tileviz.baselines.errormodel import MODEL_PATH, fit_view_errors
from tileviz.config import preset
from tileviz.sim.source import SimSource
from tileviz.vision import extract, observation_error, set_opencv_threads

set_opencv_threads()  # as every tileviz entry point


def one_run(name: str, seed: int, seconds: float) -> np.ndarray:
    """(n, 3) normalised errors of one run (NaN rows: no view)."""
    from dataclasses import replace

    cfg = preset(name)
    cfg = replace(cfg, sim=replace(cfg.sim, seed=seed), floor=replace(cfg.floor, seed=seed + 1))
    n = int(round(seconds / cfg.sim.dt))
    L, off = cfg.floor.tile_size, cfg.camera.offset
    out = np.full((n, 3), np.nan)
    for k, frame in enumerate(itertools.islice(SimSource(cfg), n)):
        obs = extract(frame.image, camera=cfg.camera, tile_size=L, vision=cfg.vision).observation
        if obs is None:
            continue
        e = observation_error(obs, frame.truth, L, off)
        out[k] = (e[0] / obs.position_error, e[1] / obs.position_error, e[2] / obs.heading_error)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--presets", default="default,seed")
    ap.add_argument("--write", action="store_true", help=f"write the model to {MODEL_PATH}")
    args = ap.parse_args()
    runs: list[np.ndarray] = []
    t0 = time.perf_counter()
    for name in args.presets.split(","):
        mine = [one_run(name, 100 + r, args.seconds) for r in range(args.runs)]
        z = np.concatenate(mine)
        z = z[np.all(np.isfinite(z), axis=1)]
        q = (50, 90, 99, 100)
        print(f"preset {name}: {z.shape[0]} views of {sum(m.shape[0] for m in mine)} frames")
        print("  |position| / bound p50/p90/p99/max: "
              + " ".join(f"{v:.3f}" for v in np.percentile(np.abs(z[:, :2]), q)))
        print("  |heading|  / bound p50/p90/p99/max: "
              + " ".join(f"{v:.3f}" for v in np.percentile(np.abs(z[:, 2]), q)))
        print(f"  mean position {z[:, :2].mean():+.4f}, heading {z[:, 2].mean():+.4f}")
        runs += mine
    cmd = (f"python bench/view_errors.py --runs {args.runs} --seconds {args.seconds:g} "
           f"--presets {args.presets}")
    model = fit_view_errors(runs, source=cmd)

    def t(s) -> str:
        return f"Student-t nu = {s.nu:g}, scale = {s.scale:.4f}"

    print(f"fit over {model.samples} views ({time.perf_counter() - t0:.0f} s):")
    for which in ("position", "heading"):
        a, r = getattr(model, f"slow_{which}")
        print(f"  {which}: {t(getattr(model, which))}; lag-1 correlation "
              f"{getattr(model, f'correlation_{which}'):.3f}; slow part: share {a:.3f}, decay "
              f"{r:.4f} a frame (variance of the mean x {model.inflation(which):.2f})")
    print(f"  outlier probability {model.outlier_probability:.4f}")
    gauss = [math.sqrt(np.nanmean(np.concatenate([r[:, i] for r in runs]) ** 2)) for i in (0, 2)]
    print(f"  (Gaussian rms: position {gauss[0]:.4f}, heading {gauss[1]:.4f})")
    if args.write:
        MODEL_PATH.write_text(model.to_json(), encoding="utf-8")
        print(f"wrote {MODEL_PATH}")


if __name__ == "__main__":
    main()
