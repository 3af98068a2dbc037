"""Accuracy study of the two extractors over random floors, cameras and poses.

    python bench/accuracy_study.py [--poses 2000] [--floors 200] [--seed 0] [--faults]
                                   [--write-figures]
    python -m bench.accuracy_study --poses 600 --floors 100 --faults

Floors and cameras come from ``tileviz.sim.camera.random_floor`` / ``random_camera``: tile size
0.166..1 m, grout 3..15 mm, tile and grout colours, per-tile brightness jitter, texture and
stains; 100..700 px/m, 320x240 or 256x384, noise 0..8 gray levels, blur 0..1.5 px, vignetting
0..0.3, JPEG (quality 40..95) one time in three.
Every pose is uniform over a 40 m square and all headings. The error of an accepted observation
is measured modulo the floor's symmetries (``tileviz.vision.observation_error``): position in
pixels and metres (the worse of y1, y2), heading in radians.

With ``--faults`` every frame also gets one camera fault (cable, box, shadow, glare, heavy motion
blur) and the table shows how often each extractor refuses it and how often what it accepts is
outside the declared bound.

Prints one table per extractor: acceptance rate, error percentiles, the share of accepted
observations outside their own declared bound (the robust extractor's per-view bound,
docs/vision.md; the faithful extractor declares ``VisionConfig.position_error_px`` px and
``VisionConfig.heading_error`` rad), and the refusal reasons.
"""

from __future__ import annotations

import argparse
import collections
import math
import time
from dataclasses import replace

import numpy as np

from tileviz.config import VisionConfig
from tileviz.sim.camera import FloorRenderer, random_camera, random_floor
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Pose
from tileviz.vision import extract, observation_error, set_opencv_threads

set_opencv_threads()  # as every tileviz entry point (workers re-run this on import)

FAULTS = ("cable", "box", "shadow", "glare", "motion_blur")


def percentiles(values: list[float]) -> str:
    if not values:
        return "      -        -        -        -        -"
    v = np.asarray(values)
    qs = np.percentile(v, [50, 90, 99, 99.9])
    return " ".join(f"{q:8.4f}" for q in qs) + f" {v.max():8.4f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--floors", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--faults", action="store_true", help="add one camera fault to every frame")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:accuracy_study, "
                    "figures:accuracy_faults with --faults)")
    args = ap.parse_args(argv)
    machine = Machine()
    rows: list[tuple[str, str]] = []
    vision = VisionConfig()
    extractors = ("faithful", "robust")
    rng = np.random.default_rng(args.seed)
    per_floor = max(1, math.ceil(args.poses / args.floors))
    stats: dict[str, dict[str, list]] = {
        e: collections.defaultdict(list) for e in extractors
    }
    reasons: dict[str, collections.Counter] = {e: collections.Counter() for e in extractors}
    fault_out: dict[str, collections.Counter] = {e: collections.Counter() for e in extractors}
    # acceptance by tile periods across the view's smaller side (few periods: often no line
    # or only one family in view, which no extractor can read)
    bins = ((0.0, 1.0), (1.0, 2.0), (2.0, 4.0), (4.0, math.inf))
    by_bin: dict[str, collections.Counter] = {e: collections.Counter() for e in extractors}
    t0 = time.perf_counter()
    done = 0
    while done < args.poses:
        floor = random_floor(rng)
        cam = random_camera(rng)
        renderer = FloorRenderer(floor, cam)
        for _ in range(min(per_floor, args.poses - done)):
            pose = Pose(float(rng.uniform(-20, 20)), float(rng.uniform(-20, 20)),
                        float(rng.uniform(-math.pi, math.pi)))
            faults = None
            kind = "none"
            if args.faults:
                kind = FAULTS[int(rng.integers(0, len(FAULTS)))]
                faults = [(kind, {})]
            img = renderer.render(pose, rng, faults=faults)
            for ext in extractors:
                res = extract(img, camera=cam, tile_size=floor.tile_size,
                              vision=replace(vision, extractor=ext))
                reasons[ext][res.reason] += 1
                periods = min(cam.width, cam.height) / (floor.tile_size * cam.ppm)
                b = next(i for i, (lo, hi) in enumerate(bins) if lo <= periods < hi)
                by_bin[ext][(b, "n")] += 1
                by_bin[ext][(b, "ok")] += int(res.accepted)
                s = stats[ext]
                s["accepted"].append(res.accepted)
                if res.accepted:
                    e1, e2, e3 = observation_error(res.observation, pose, floor.tile_size,
                                                   cam.offset)
                    pos_m = max(abs(e1), abs(e2))
                    s["pos_px"].append(pos_m * cam.ppm)
                    s["pos_m"].append(pos_m)
                    s["head"].append(abs(e3))
                    # against the view's own declared bound (the robust extractor's per-view
                    # bound; the faithful one declares the configured bound)
                    obs = res.observation
                    outside = pos_m > obs.position_error or abs(e3) > obs.heading_error
                    s["bound_px"].append(obs.position_error * cam.ppm)
                    s["outside"].append(outside)
                    if args.faults:
                        fault_out[ext][(kind, "accepted")] += 1
                        fault_out[ext][(kind, "outside")] += int(outside)
                if args.faults:
                    fault_out[ext][(kind, "frames")] += 1
            done += 1
    elapsed = time.perf_counter() - t0
    print(f"accuracy study: {done} poses over {math.ceil(done / per_floor)} random floors and "
          f"cameras (seed {args.seed}{', one camera fault per frame' if args.faults else ''}); "
          f"{elapsed:.1f} s")
    print(f"limits: position {vision.position_error_px} px, heading {vision.heading_error} "
          f"rad (VisionConfig defaults; each view is checked against its own declared bound)")
    for ext in extractors:
        s = stats[ext]
        n = len(s["accepted"])
        acc = int(np.sum(s["accepted"]))
        out = int(np.sum(s["outside"])) if s["outside"] else 0
        print()
        print(f"== {ext}: accepted {acc}/{n} ({100.0 * acc / max(n, 1):.1f} %), "
              f"outside the declared bound: {out} ({100.0 * out / max(acc, 1):.2f} % of "
              f"accepted)")
        views = "faulty views" if args.faults else "views"
        rows += [(f"{ext}: {views} accepted", f"{acc} of {n}"),
                 (f"{ext}: accepted outside their own bound", f"{out}")]
        if s["pos_px"] and not args.faults:
            rows.append((f"{ext}: median / p99 position error of accepted views",
                         f"{np.median(s['pos_px']):.3f} / "
                         f"{np.percentile(s['pos_px'], 99):.3f} px"))
        print(f"  {'error of accepted':<22} {'p50':>8} {'p90':>8} {'p99':>8} {'p99.9':>8} "
              f"{'max':>8}")
        print(f"  {'position, px':<22} {percentiles(s['pos_px'])}")
        print(f"  {'position, mm':<22} {percentiles([1e3 * v for v in s['pos_m']])}")
        print(f"  {'heading, mrad':<22} {percentiles([1e3 * v for v in s['head']])}")
        print(f"  {'declared bound, px':<22} {percentiles(s['bound_px'])}")
        print("  reasons: " + ", ".join(f"{r} {c}" for r, c in reasons[ext].most_common()))
        print("  acceptance by tile periods across the smaller image side: " + ", ".join(
            f"{lo:g}-{hi:g}: {by_bin[ext][(i, 'ok')]}/{by_bin[ext][(i, 'n')]}"
            for i, (lo, hi) in enumerate(bins)))
        if args.faults:
            print(f"  {'fault':<12} {'frames':>7} {'accepted':>9} {'outside bound':>14}")
            for kind in FAULTS:
                fo = fault_out[ext]
                print(f"  {kind:<12} {fo[(kind, 'frames')]:>7} {fo[(kind, 'accepted')]:>9} "
                      f"{fo[(kind, 'outside')]:>14}")
    if args.write_figures:
        name = "accuracy_faults" if args.faults else "accuracy_study"
        title = ("tileviz's random floors with a camera fault on every frame" if args.faults
                 else "tileviz's random floors and cameras")
        write_block(name, title, rows, machine=machine,
                    note=f"{done} poses over {math.ceil(done / per_floor)} random floors and "
                    f"cameras, {elapsed:.0f} s.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
