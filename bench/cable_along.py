"""A cable laid along a grout line: how often the robust extractor accepts such a view, and how
often outside its own declared bound (a false accept).

    python bench/cable_along.py [--views-per-family 100] [--first-seed 0] [--jobs 1]
                                [--csv out.csv] [--motion]

Floors and cameras as in ``bench/vision_study.py`` (``bench/floorgen.py``, every family); on each
view, a straight cable (2..10 px wide, dark or light) runs parallel to the grout line of one
family nearest the view's centre, its centre ``delta`` px from the line's (uniform in
[-25, 25] px: lying on the grout, touching it, or a few px beside it). The random study's
cables lie at any angle, so few run along a line; this one asks for the hardest case. The
table groups the views by the gap between the cable's and the grout's edges (negative: they
overlap).

``--motion``: no cable; instead a short motion blur (2..15 px, shorter than the study's
15..40 px, at any angle) that smears the grout lines of one family more than the other's into
ramps, rather than wiping them out. The table groups the views by the blur's length.
"""

from __future__ import annotations

import argparse
import collections
import csv
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import floorgen  # noqa: E402
from vision_study import FAMILY_SALT  # noqa: E402

from tileviz.config import CameraConfig, VisionConfig  # noqa: E402
from tileviz.types import Pose  # noqa: E402
from tileviz.vision import extract, observation_error  # noqa: E402

GAPS = ((-math.inf, 0.0), (0.0, 3.0), (3.0, 6.0), (6.0, 10.0), (10.0, math.inf))
"""Buckets of the gap between the cable's and the grout's edges (px)."""
LENGTHS = ((2.0, 4.0), (4.0, 7.0), (7.0, 10.0), (10.0, 15.0))
"""Buckets of the motion blur's length (px) with ``--motion``."""


def run_view(seed: int, family: str) -> dict:
    """One view of ``family`` from ``seed`` with a cable along a grout line; the outcome."""
    rng = np.random.default_rng([seed, FAMILY_SALT[family], 2])
    spec = floorgen.draw_floor(family, rng)
    cx, cy, th = floorgen.draw_view(rng)
    k = int(rng.integers(2))
    delta = float(rng.uniform(-25.0, 25.0))
    width = float(rng.uniform(2.0, 10.0))
    shade = float(rng.uniform(10, 60) if rng.uniform() < 0.7 else rng.uniform(200, 250))
    normal, s = floorgen.line_offset(spec, cx, cy, th, k)
    img = floorgen.render(spec, cx, cy, th, rng,
                          overlay=floorgen.band(spec, normal, s + delta, width, shade))
    out = {"seed": seed, "family": family, "delta": delta, "width": width, "shade": shade,
           "grout_px": spec.grout_px, "gap": abs(delta) - 0.5 * (width + spec.grout_px),
           "line_s": s}
    return _outcome(out, img, spec, Pose(cx, cy, th))


def run_motion(seed: int, family: str) -> dict:
    """One view of ``family`` from ``seed`` under a short motion blur; the outcome."""
    rng = np.random.default_rng([seed, FAMILY_SALT[family], 3])
    spec = floorgen.draw_floor(family, rng)
    cx, cy, th = floorgen.draw_view(rng)
    length = float(rng.uniform(2.0, 15.0))
    ang = float(rng.uniform(0.0, math.pi))
    img = floorgen.render(spec, cx, cy, th, rng, motion=(length, ang))
    out = {"seed": seed, "family": family, "length": length, "angle": ang,
           "grout_px": spec.grout_px}
    return _outcome(out, img, spec, Pose(cx, cy, th))


def _outcome(out: dict, img: np.ndarray, spec: floorgen.FloorSpec, pose: Pose) -> dict:
    """``out`` with the robust extractor's outcome on ``img`` (camera at ``pose``): accepted,
    reason, the error and declared bound in px, and whether the truth is inside the bound."""
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    res = extract(img, camera=cam, tile_size=spec.tile_size,
                  vision=VisionConfig(extractor="robust"))
    out.update(accepted=res.accepted, reason=res.reason, err_px=math.nan, bound_px=math.nan,
               inside=True)
    if res.accepted:
        obs = res.observation
        e1, e2, e3 = observation_error(obs, pose, spec.tile_size, (0.0, 0.0))
        ep = max(abs(e1), abs(e2))
        out.update(err_px=ep * spec.ppm, bound_px=obs.position_error * spec.ppm,
                   inside=ep <= obs.position_error and abs(e3) <= obs.heading_error)
    return out


def _task(args: tuple[int, str]) -> dict:
    return run_view(*args)


def _motion_task(args: tuple[int, str]) -> dict:
    return run_motion(*args)


def report(rows: list[dict], motion: bool = False) -> str:
    """Markdown: per gap (``motion``: blur length) bucket and per family, views, accepted,
    accepted outside the bound."""
    head = "motion blur length (px)" if motion else "gap between cable and grout (px)"
    key, buckets = ("length", LENGTHS) if motion else ("gap", GAPS)
    out = [f"| {head} | views | accepted | outside own bound | "
           "largest error / bound |", "|---|---|---|---|---|"]
    for lo, hi in buckets:
        sel = [r for r in rows if lo <= r[key] < hi]
        out.append(_row(f"{lo:g} .. {hi:g}", sel))
    out += ["", "| family | views | accepted | outside own bound | largest error / bound |",
            "|---|---|---|---|---|"]
    for fam in floorgen.FAMILIES:
        out.append(_row(fam, [r for r in rows if r["family"] == fam]))
    out.append(_row("all", rows))
    bad = [r for r in rows if r["accepted"] and not r["inside"]]
    if bad:
        out += ["", "Accepted outside their bound:"]
        out += [f"- seed {r['seed']} {r['family']}: " + (
                f"motion blur {r['length']:.1f} px at {r['angle']:.2f} rad" if motion else
                f"cable {r['width']:.1f} px, shade {r['shade']:.0f}, {r['delta']:+.1f} px off "
                f"a {r['grout_px']:.1f} px grout line") +
                f"; error {r['err_px']:.2f} px, bound {r['bound_px']:.2f} px" for r in bad]
    return "\n".join(out)


def _row(name: str, sel: list[dict]) -> str:
    acc = [r for r in sel if r["accepted"]]
    bad = [r for r in acc if not r["inside"]]
    worst = max((r["err_px"] / r["bound_px"] for r in acc), default=math.nan)
    return f"| {name} | {len(sel)} | {len(acc)} | {len(bad)} | {floorgen.cell(worst, '.2f')} |"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--views-per-family", type=int, default=100)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--csv", default="")
    ap.add_argument("--motion", action="store_true",
                    help="a short motion blur instead of a cable along the grout")
    args = ap.parse_args(argv)
    tasks = [(args.first_seed + i, fam) for i in range(args.views_per_family)
             for fam in floorgen.FAMILIES]
    task = _motion_task if args.motion else _task
    try:
        with ProcessPoolExecutor(args.jobs) if args.jobs > 1 else nullcontext() as pool:
            rows = list(pool.map(task, tasks, chunksize=8) if pool else map(task, tasks))
    except ImportError as exc:
        print(f"cable_along.py: {exc}")
        return 2
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)
    print(report(rows, args.motion))
    reasons = collections.Counter(r["reason"] for r in rows if not r["accepted"])
    print("\nrefusals: " + ", ".join(f"{k} {v}" for k, v in reasons.most_common()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
