"""Checkerboards with a grout band along their tile edges nearly as dark as the dark tiles.

    python bench/checker_bands.py [--floors 12] [--views 20] [--survey-views 30]
                                  [--families one|both] [--seed 0] [--jobs 1] [--csv out.csv]
                                  [--write-figures]

Each floor is a checkerboard (``floorgen.banded_checker``: dark squares 50-110, light 160-220
gray levels) with a grout band 4-9 px wide centred on the edges between its tiles, along one
family of lines (``--families one``) or both, 2-16 levels darker than the dark squares (1-32 %
of the step between the two shades, mostly under 15 %), so the band's far side (grout to dark
tile) is a faint edge. The lattice's lines are the bands' centres. A camera
that does not see the band sees an edge where the light tile meets the band, half the band's
width off the line: on such a floor the edges a camera sees depart from the lattice by that
much, which is what ``lattice_tolerance`` declares (docs/vision.md, "Colour").

Per floor, ``--survey-views`` views with their true poses are surveyed twice
(:func:`tileviz.vision.survey.survey`): the kind left to recognise, and declared ``checker``;
the tolerance each recommends is shown beside half the band's width. Then ``--views`` other
views are extracted three ways: nothing declared (a perfect lattice), the first survey's
tolerance declared (the kind left to recognise), and ``kind: checker`` with the second's. For
each: views accepted, and accepted views whose truth lies outside their declared bound (the
ideal lattice), with the worst error over bound.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tileviz.config import CameraConfig, FloorModel, VisionConfig  # noqa: E402
from tileviz.testing import floorgen  # noqa: E402
from tileviz.testing.figures import Machine, write_block  # noqa: E402
from tileviz.types import Pose  # noqa: E402
from tileviz.vision import extract, observation_error  # noqa: E402
from tileviz.vision.survey import survey  # noqa: E402

WAYS = ("none", "tolerance", "checker")
"""What the extractor is told of the floor: nothing, the survey's tolerance, the kind too."""


def band_width(spec: floorgen.FloorSpec) -> float:
    """The band's width, px."""
    return spec.second[0] if spec.second is not None else spec.grout_px


def _view(spec: floorgen.FloorSpec, rng: np.random.Generator) -> tuple[np.ndarray, Pose]:
    cx, cy, th = floorgen.draw_view(rng)
    return floorgen.render(spec, cx, cy, th, rng), Pose(cx, cy, th)


def run_floor(args: tuple[int, str, int, int]) -> list[dict[str, Any]]:
    """The survey and the views of one floor: one row per view and way."""
    seed, families, n_survey, n_views = args
    spec = floorgen.banded_checker(seed, families)
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    vision = VisionConfig(extractor="robust")
    tols = {}
    for kind in ("grout", "checker"):
        rng = np.random.default_rng([seed, 7103, 1])
        try:
            tols[kind] = survey((_view(spec, rng) for _ in range(n_survey)), camera=cam,
                                tile_size=spec.tile_size, vision=vision, kind=kind).tolerance
        except ValueError:
            tols[kind] = math.nan
    rng = np.random.default_rng([seed, 7103, 2])
    rows = []
    for k in range(n_views):
        img, truth = _view(spec, rng)
        for way in WAYS:
            tol = tols["checker" if way == "checker" else "grout"]
            if way != "none" and not math.isfinite(tol):
                continue
            floor = (FloorModel() if way == "none" else
                     FloorModel("checker" if way == "checker" else "grout", tol))
            res = extract(img, camera=cam, tile_size=spec.tile_size, vision=vision,
                          floor=floor)
            row: dict[str, Any] = {
                "floor": seed, "view": k, "way": way, "band_px": band_width(spec),
                "depth": spec.grout_shade - (spec.band_shade or 0.0),
                "step": spec.tile_shade - spec.grout_shade,
                "survey_tol_px": tols["grout"] * spec.ppm,
                "survey_checker_tol_px": tols["checker"] * spec.ppm, "accepted": res.accepted,
                "reason": res.reason, "err_px": math.nan, "bound_px": math.nan,
                "err_rad": math.nan, "bound_rad": math.nan, "inside": True}
            if res.accepted and res.observation is not None:
                obs = res.observation
                e1, e2, e3 = observation_error(obs, truth, spec.tile_size, (0.0, 0.0))
                ep = max(abs(e1), abs(e2))
                row.update(err_px=ep * spec.ppm, bound_px=obs.position_error * spec.ppm,
                           err_rad=abs(e3), bound_rad=obs.heading_error,
                           inside=ep <= obs.position_error and abs(e3) <= obs.heading_error)
            rows.append(row)
    return rows


def report(rows: list[dict[str, Any]]) -> str:
    """The table: per way, views, accepted, outside, worst error over bound."""
    floors = sorted({r["floor"] for r in rows})
    out = ["| floor | band px | depth | survey tolerance px: kind recognised / checker | "
           "nothing declared: accepted / outside | tolerance: accepted / outside | "
           "checker + tolerance: accepted / outside |", "|---|---|---|---|---|---|---|"]
    total = {w: [0, 0, 0] for w in WAYS}
    for f in floors:
        mine = [r for r in rows if r["floor"] == f]
        cells = []
        for w in WAYS:
            rw = [r for r in mine if r["way"] == w]
            acc = sum(r["accepted"] for r in rw)
            bad = sum(not r["inside"] for r in rw)
            total[w][0] += len(rw)
            total[w][1] += acc
            total[w][2] += bad
            cells.append(f"{acc}/{len(rw)} / {bad}" if rw else "—")
        r0 = mine[0]
        out.append(f"| {f} | {r0['band_px']:.1f} | {r0['depth']:.0f} of {r0['step']:.0f} | "
                   f"{r0['survey_tol_px']:.2f} / {r0['survey_checker_tol_px']:.2f} (half band "
                   f"{0.5 * r0['band_px']:.2f}) | "
                   + " | ".join(cells) + " |")
    out.append("| all | | | | " + " | ".join(f"{a}/{n} / {b}" for n, a, b in
                                             (total[w] for w in WAYS)) + " |")
    worst = [r["err_px"] / r["bound_px"] for r in rows if not r["inside"]]
    if worst:
        out.append(f"\nworst error / bound outside: {max(worst):.2f}")
    return "\n".join(out)


WAY_NAMES = {"none": "nothing declared", "tolerance": "the surveyed tolerance, kind recognised",
             "checker": "kind checker and its surveyed tolerance"}


def figure_rows(rows: list[dict[str, Any]]) -> list[tuple[str, ...]]:
    """Per way: views, accepted, accepted outside their bound, largest error over bound."""
    out: list[tuple[str, ...]] = []
    for w in WAYS:
        rw = [r for r in rows if r["way"] == w]
        acc = [r for r in rw if r["accepted"]]
        ratio = [max(r["err_px"] / r["bound_px"], r["err_rad"] / r["bound_rad"]) for r in acc]
        out.append((WAY_NAMES[w], str(len(rw)), str(len(acc)),
                    str(sum(not r["inside"] for r in rw)),
                    f"{max(ratio):.2f}" if ratio else "-"))
    return out


def survey_note(rows: list[dict[str, Any]], families: str) -> str:
    """What the surveys (with the true poses) recommended: with bands along one family, how
    many floors' tolerance covers half the band (the edges' departure); along both, the
    median tolerance (a grout darker than both shades, read at its centre)."""
    floors = {r["floor"]: r for r in rows}
    parts = []
    for key, what in (("survey_tol_px", "kind recognised"), ("survey_checker_tol_px",
                                                             "kind checker")):
        ok = [r for r in floors.values() if math.isfinite(r[key])]
        if families == "one":
            cover = sum(r[key] >= 0.5 * r["band_px"] - 1e-9 for r in ok)
            said = f"{cover} recommending at least half the band"
        else:
            said = ("median tolerance " + (f"{float(np.median([r[key] for r in ok])):.2f} px"
                                           if ok else "-"))
        parts.append(f"{what}: {len(ok)} of {len(floors)} floors surveyed (5 views or more "
                     f"accepted), {said}")
    return "Surveys with the true poses: " + "; ".join(parts) + "."


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--floors", type=int, default=12)
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--survey-views", type=int, default=30)
    ap.add_argument("--families", choices=("one", "both"), default="one")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--csv")
    ap.add_argument("--write-figures", action="store_true",
                    help="write the summary into docs/figures.md (block checker_bands_FAMILIES)")
    args = ap.parse_args(argv)
    machine = Machine()
    tasks = [(args.seed + f, args.families, args.survey_views, args.views)
             for f in range(args.floors)]
    with ProcessPoolExecutor(args.jobs) if args.jobs > 1 else nullcontext() as ex:
        parts = list(ex.map(run_floor, tasks) if ex is not None else map(run_floor, tasks))
    rows = [r for p in parts for r in p]
    if args.csv:
        with open(args.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    print(report(rows))
    print(survey_note(rows, args.families))
    if args.write_figures:
        write_block(f"checker_bands_{args.families}",
                    "Checkerboards with a faint grout band along "
                    + ("one family of edges" if args.families == "one" else "both families"),
                    figure_rows(rows), machine=machine,
                    header=("declared", "views", "accepted", "accepted outside own bound",
                            "largest error / bound"),
                    note=survey_note(rows, args.families))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
