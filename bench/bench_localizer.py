"""Benchmark: predict + contract of one box per frame, ours against codac 2.

Usage: ``python bench/bench_localizer.py [--frames N] [--repeats R] [--clock wall|cpu]
[--no-codac] [--write-figures]`` (or ``python -m bench.bench_localizer ...``)

For each scenario (the ``default`` and ``seed`` presets' tile size, lever arm and bounds; mode
``autonomous``, i.e. tracking, and mode ``truth``, where every frame starts from the truth
+- (0.3 m, 0.3 m, 0.2 rad), report 7.1) a robot drives a smooth curve; its sensors read within
their bounds (uniform, 90 % of each bound). Per frame we time:

- ``ours step``: ``Localizer.step`` (validation, prediction, compass, contraction over the four
  branches, box-set housekeeping, the frozen result objects) -- what the runner calls;
- ``ours core``: the same maths on :class:`Box` values alone (``predict_box``, ``compass_pieces``,
  ``contract_box``);
- codac: the contraction alone of the same predicted boxes (recorded from our run) by the union
  (``CtcUnion``) over the four branches of ``CtcInverse`` of the sin constraints
  (``tileviz/testing/codac_oracle_worker.py``), single pass and to a fixpoint, with and without
  the centered form. codac runs in its own process (it switches its process to upward rounding).

Which codac figure to compare with: our contraction returns what codac's *fixpoint* variants
return (``tests/test_codac_oracle.py`` checks it to 1e-9), plus the split into lattice cells; the
single-pass variants are weaker (one forward-backward sweep). ``centered`` is codac's default
``CtcInverse``; ``plain`` switches the centered form off (cheaper, same result here).

Timings are the best of ``--repeats`` runs over all frames, on the wall clock or (``--clock cpu``,
steadier on a loaded machine) the thread's CPU time; ``--no-codac`` times ours alone. Also
printed: statuses, the number of contraction passes per frame, and whether the truth stayed in the
set.
"""

from __future__ import annotations

import argparse
import collections
import math

from tileviz.config import Config, preset, with_overrides
from tileviz.core.contraction import (
    contract_box,
    lever_enclosure,
    observation_windows,
)
from tileviz.core.prediction import compass_pieces, predict_box
from tileviz.pipeline import initial_box
from tileviz.testing import codac_oracle_worker, timing
from tileviz.testing.drives import localizer_of, make_run, time_step
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Box


def run_ours(cfg: Config, run: list[dict]) -> tuple[list[tuple], dict]:
    """One pass through the run with the Localizer; returns the predicted boxes and stats."""
    loc = localizer_of(cfg)
    predicted = []
    statuses: collections.Counter[str] = collections.Counter()
    passes: collections.Counter[int] = collections.Counter()
    inside = boxes_max = 0
    for f in run:
        step = loc.step(f["odometry"], f["compass"], f["observation"], f["truth"])
        predicted.append(step.predicted.hull().as_tuple())
        statuses[step.status] += 1
        passes[step.passes] += 1
        inside += step.updated.contains(*f["truth"].as_tuple())
        boxes_max = max(boxes_max, len(step.updated))
    return predicted, {"statuses": dict(statuses), "passes": dict(sorted(passes.items())),
                       "truth_inside": inside, "frames": len(run), "max_boxes": boxes_max}


def time_core(cfg: Config, run: list[dict], repeats: int) -> float:
    """The maths alone on Box values, one box carried frame to frame (the hull of the result)."""
    L = cfg.floor.tile_size
    lever = lever_enclosure(cfg.camera.offset)
    nz = cfg.noise
    n = cfg.localizer.passes
    cap = cfg.localizer.max_boxes
    prepared = []
    for f in run:
        o = f["odometry"]
        odo = None if o is None else (o.speed - nz.speed_error, o.speed + nz.speed_error,
                                      o.yaw_rate - nz.yaw_rate_error,
                                      o.yaw_rate + nz.yaw_rate_error, o.dt)
        c = f["compass"]
        tbox = None
        if cfg.localizer.mode == "truth":
            p = f["truth"]
            ix, iy, it = cfg.localizer.truth_inflation
            tbox = Box(p.x - ix, p.x + ix, p.y - iy, p.y + iy, p.theta - it, p.theta + it)
        prepared.append((odo, c - nz.compass_error, c + nz.compass_error, f["observation"], tbox))
    best = math.inf
    for _ in range(repeats):
        box = initial_box(cfg)
        t0 = timing.clock()
        for odo, c_lo, c_hi, obs, tbox in prepared:
            if tbox is not None:
                box = tbox
            elif odo is not None:
                box = predict_box(box, *odo)
            cut = compass_pieces(box, c_lo, c_hi)
            if cut:
                box = cut[0]
            got, _, _ = contract_box(box, observation_windows(obs), L, lever, n, cap)
            if got:
                box = Box(min(b[0] for b in got), max(b[1] for b in got), min(b[2] for b in got),
                          max(b[3] for b in got), min(b[4] for b in got), max(b[5] for b in got))
        best = min(best, timing.clock() - t0)
    return best / len(run) * 1e6


def time_codac(cfg: Config, run: list[dict], predicted: list[tuple], repeats: int) -> dict:
    off = cfg.camera.offset
    boxes = []
    for f, b in zip(run, predicted, strict=True):
        w = observation_windows(f["observation"])[0]
        boxes.append([[b[0], b[1]], [b[2], b[3]], [b[4], b[5]],
                      [w[0], w[1]], [w[2], w[3]], [w[4], w[5]]])
    spec = {"task": "bench", "L": cfg.floor.tile_size, "rho": math.hypot(*off),
            "phi": math.atan2(off[1], off[0]), "boxes": boxes, "repeats": repeats}
    try:
        return codac_oracle_worker.run(spec)
    except RuntimeError as exc:
        raise SystemExit(str(exc)) from None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=7)
    timing.add_clock(ap)
    ap.add_argument("--no-codac", action="store_true", help="time ours only")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:localizer)")
    args = ap.parse_args()
    machine = Machine()
    rows: list[tuple[str, str]] = []
    timing.use_clock(args.clock)
    for name, mode in (("default", "autonomous"), ("seed", "autonomous"),
                       ("default", "truth"), ("seed", "truth")):
        cfg = with_overrides(preset(name), localizer={"mode": mode})
        run = make_run(cfg, args.frames, args.seed)
        predicted, stats = run_ours(cfg, run)
        step_us = time_step(cfg, run, args.repeats)
        core_us = time_core(cfg, run, args.repeats)
        codac = ({"us_per_box": {}} if args.no_codac
                 else time_codac(cfg, run, predicted, args.repeats))
        print(f"== {name} preset, mode {mode}: L={cfg.floor.tile_size} m, "
              f"camera offset {cfg.camera.offset} m, "
              f"{args.frames} frames, best of {args.repeats}")
        print(f"   statuses {stats['statuses']}, passes/frame {stats['passes']}, "
              f"truth inside {stats['truth_inside']}/{stats['frames']}, "
              f"max boxes {stats['max_boxes']}")
        print(f"   ours step (Localizer.step: predict+compass+contract): {step_us:7.1f} us/frame")
        print(f"   ours core (Box values: predict+compass+contract):     {core_us:7.1f} us/frame")
        for variant, us in codac["us_per_box"].items():
            print(f"   codac {variant:<28s} (contract only): {us:7.1f} us/frame   "
                  f"ours step / codac = {step_us / us:4.2f}   core / codac = {core_us / us:4.2f}")
        rows.append((f"{name}, {mode}: Localizer.step", f"{step_us:.1f} us/frame"))
        fix = {v: us for v, us in codac["us_per_box"].items() if "fixpoint" in v}
        if fix:  # what our contraction returns: codac's fixpoint, its faster variant
            best = min(fix, key=fix.__getitem__)
            rows.append((f"{name}, {mode}: codac {best} (contraction only)",
                         f"{fix[best]:.1f} us/frame"))
    if args.write_figures:
        write_block("localizer", "Localizer step against codac", rows, machine=machine,
                    note=f"{args.frames} frames, best of {args.repeats}, {args.clock} clock.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
