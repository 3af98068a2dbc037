"""MCL calibration: nominal confidence regions against how often they hold the truth.

    python bench/mcl_calibration.py [--runs 2] [--seconds 60] [--presets default,seed]
                                    [--variants untuned,calibrated] [--cache DIR]

Simulates ``--runs`` runs per preset (simulator seeds 0.., as ``tileviz evaluate``), runs vision
once per frame (cached in ``--cache`` so variants can be compared again quickly), then steps each
MCL variant on the same inputs and prints, per preset and variant, the share of frames whose true
(x, y) lies in the nominal 50/90/95/99 % ellipse, the median x width of the 95 % box, the RMSE
and the CPU per frame. Variants: ``untuned`` (``MclConfig()``, 1000 particles), ``calibrated``
(``calibrated_config()``), or ``name:key=value,...`` for a calibrated config with fields replaced
(e.g. ``r0:roughening=0``).
"""

from __future__ import annotations

import argparse
import itertools
import math
import pickle
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from tileviz.baselines.mcl import CALIBRATION_LEVELS, MCL, MclConfig, calibrated_config, chi2_2d
from tileviz.config import preset
from tileviz.pipeline import initial_box
from tileviz.sim.source import SimSource
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Box, SensorBounds
from tileviz.vision import extract, set_opencv_threads

set_opencv_threads()  # as every tileviz entry point


def inputs(name: str, seed: int, seconds: float, cache: Path | None) -> list:
    path = cache / f"{name}-{seed}-{seconds:g}.pkl" if cache else None
    if path and path.exists():
        return pickle.loads(path.read_bytes())
    cfg = preset(name)
    cfg = replace(cfg, sim=replace(cfg.sim, seed=seed), floor=replace(cfg.floor, seed=seed + 1))
    n = int(round(seconds / cfg.sim.dt))
    out = []
    pending = None
    for frame in itertools.islice(SimSource(cfg), n):
        v = extract(frame.image, camera=cfg.camera, tile_size=cfg.floor.tile_size,
                    vision=cfg.vision)
        out.append((pending, frame.compass, v.observation, frame.truth.as_tuple()))
        pending = frame.odometry
    if path:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(out))
    return out


def variant(text: str) -> tuple[str, MclConfig]:
    if text == "untuned":
        return text, MclConfig()
    if text == "calibrated":
        return text, calibrated_config()
    name, _, kv = text.partition(":")
    cfg = calibrated_config()
    changes = {}
    for item in filter(None, kv.split(",")):
        k, _, v = item.partition("=")
        cur = getattr(cfg, k)
        changes[k] = type(cur)(float(v)) if not isinstance(cur, str) else v
    return name, replace(cfg, **changes)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--presets", default="default,seed")
    ap.add_argument("--variants", default="untuned,calibrated")
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the table into docs/figures.md (figures:mcl_calibration)")
    args = ap.parse_args()
    machine = Machine()
    rows: list[tuple[str, ...]] = []
    print("| preset | MCL | " + " | ".join(f"{100 * lv:g} %" for lv in CALIBRATION_LEVELS)
          + " | 95 % box x median (cm) | RMSE xy (cm) | particles (mean) | CPU µs/frame |")
    print("|---|---|" + "---|" * (len(CALIBRATION_LEVELS) + 4))
    for name in args.presets.split(","):
        cfg = preset(name)
        runs = [inputs(name, r, args.seconds, args.cache) for r in range(args.runs)]
        bounds = SensorBounds(cfg.noise.speed_error, cfg.noise.yaw_rate_error,
                              cfg.noise.compass_error)
        room = cfg.sim.room_half_size
        for text in args.variants.split(";") if ";" in args.variants \
                else args.variants.split(","):
            label, mc = variant(text)
            d2, wx, err, npart = [], [], [], []
            cpu = 0.0
            for r, run in enumerate(runs):
                mcl = MCL(tile_size=cfg.floor.tile_size, camera_offset=cfg.camera.offset,
                          bounds=bounds, initial=initial_box(cfg), config=mc, seed=1000 + r,
                          region=Box(-room, room, -room, room, -math.pi, math.pi))
                for odo, comp, obs, truth in run:
                    c0 = time.thread_time()
                    est = mcl.step(odo, comp, obs)
                    cpu += time.thread_time() - c0
                    d2.append(est.mahalanobis2(truth[0], truth[1]))
                    wx.append(2 * est.half_widths()[0])
                    err.append(math.hypot(est.mean[0] - truth[0], est.mean[1] - truth[1]))
                    npart.append(est.particles.shape[0])
            d2a = np.asarray(d2)
            cells = [f"{100 * float(np.mean(d2a <= chi2_2d(lv))):.1f}" for lv in CALIBRATION_LEVELS]
            row = (name, label, *cells, f"{100 * np.median(wx):.2f}",
                   f"{100 * math.sqrt(np.mean(np.square(err))):.2f}", f"{np.mean(npart):.0f}",
                   f"{1e6 * cpu / d2a.size:.0f}")
            print("| " + " | ".join(row) + " |", flush=True)
            rows.append(row)
    if args.write_figures:
        write_block("mcl_calibration", "MCL calibration: share of frames whose nominal ellipse "
                    "holds the truth", rows, machine=machine,
                    header=("preset", "MCL", *(f"{100 * lv:g} %" for lv in CALIBRATION_LEVELS),
                            "95 % box x median (cm)", "RMSE xy (cm)", "particles (mean)",
                            "CPU µs/frame"),
                    note=f"{args.runs} runs of {args.seconds:g} s per preset.")


if __name__ == "__main__":
    main()
