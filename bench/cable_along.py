"""A cable laid along a grout line: how often the robust extractor accepts such a view, and how
often outside its own declared bound (a false accept).

    python bench/cable_along.py [--views-per-family 100] [--first-seed 0] [--jobs 1]
                                [--csv out.csv] [--motion | --crossing] [--write-figures]
    python -m bench.cable_along --motion --views-per-family 80

Floors and cameras as in ``bench/vision_study.py`` (``tileviz/testing/floorgen.py``, every
family; the views are :func:`tileviz.testing.views.cable_view` and
:func:`~tileviz.testing.views.motion_view`); on each view, a straight cable (2..10 px wide, dark
or light) runs parallel to the grout line of one family nearest the view's centre, its centre
``delta`` px from the line's (uniform in [-25, 25] px: lying on the grout, touching it, or a few
px beside it). The random study's cables lie at any angle, so few run along a line; this one
asks for the hardest case. The table groups the views by the gap between the cable's and the
grout's edges (negative: they overlap).

``--motion``: no cable; instead a short motion blur (2..15 px, shorter than the study's
15..40 px, at any angle) that smears the grout lines of one family more than the other's into
ramps, rather than wiping them out. The table groups the views by the blur's length.

``--crossing``: a cable of the grout's shade crossing that grout line at a small angle
(:func:`~tileviz.testing.views.crossing_cable_view`, 0.02..0.08 rad): over the view it lies on
the line, then beside it, and one line read as the grout and the cable turns off the lattice.
The table groups the views by the angle.
"""

from __future__ import annotations

import argparse
import collections
import csv
import math
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
from typing import NamedTuple

from tileviz.testing import floorgen
from tileviz.testing.figures import Machine, write_block
from tileviz.testing.views import cable_view, crossing_cable_view, motion_view

GAPS = ((-math.inf, 0.0), (0.0, 3.0), (3.0, 6.0), (6.0, 10.0), (10.0, math.inf))
"""Buckets of the gap between the cable's and the grout's edges (px)."""
LENGTHS = ((2.0, 4.0), (4.0, 7.0), (7.0, 10.0), (10.0, 15.0))
"""Buckets of the motion blur's length (px) with ``--motion``."""
ANGLES = ((0.02, 0.04), (0.04, 0.06), (0.06, 0.08))
"""Buckets of the cable's angle to the grout line (rad, either way) with ``--crossing``."""
WORST = "largest error / bound (position or heading)"
"""The last column: over the accepted views, the larger of error / bound for the position and
the heading (a view is outside its bound when either passes 1)."""


def _task(args: tuple[int, str]) -> dict:
    return cable_view(*args)


def _motion_task(args: tuple[int, str]) -> dict:
    return motion_view(*args)


def _crossing_task(args: tuple[int, str]) -> dict:
    row = crossing_cable_view(*args)
    row["abs_angle"] = abs(row["angle"])
    return row


class Mode(NamedTuple):
    """One kind of view: its task, the row's key that buckets it, the buckets, their name and
    unit, the figures block and its title, and how a view outside its bound is described."""

    task: Callable[[tuple[int, str]], dict]
    key: str
    buckets: tuple[tuple[float, float], ...]
    what: str
    unit: str
    block: str
    title: str
    describe: Callable[[dict], str]


MODES = {
    "cable": Mode(_task, "gap", GAPS, "gap between cable and grout", "px", "cable_along",
                  "A cable along a grout line",
                  lambda r: f"cable {r['width']:.1f} px, shade {r['shade']:.0f}, "
                  f"{r['delta']:+.1f} px off a {r['grout_px']:.1f} px grout line"),
    "motion": Mode(_motion_task, "length", LENGTHS, "motion blur length", "px", "motion_blur",
                   "A short motion blur",
                   lambda r: f"motion blur {r['length']:.1f} px at {r['angle']:.2f} rad"),
    "crossing": Mode(_crossing_task, "abs_angle", ANGLES, "angle of the cable to the grout",
                     "rad", "cable_crossing", "A cable crossing a grout line",
                     lambda r: f"cable {r['width']:.1f} px crossing a {r['grout_px']:.1f} px "
                     f"grout line at {r['angle']:+.3f} rad"),
}
"""The kinds of view, by the option that chooses them (none: ``cable``)."""


def report(rows: list[dict], mode: str = "cable") -> str:
    """Markdown: per bucket of ``mode``'s key (:data:`MODES`) and per family, views, accepted,
    accepted outside the bound."""
    m = MODES[mode]
    out = [f"| {m.what} ({m.unit}) | views | accepted | outside own bound | "
           f"{WORST} |", "|---|---|---|---|---|"]
    for lo, hi in m.buckets:
        sel = [r for r in rows if lo <= r[m.key] < hi]
        out.append(_row(f"{lo:g} .. {hi:g}", sel))
    out += ["", f"| family | views | accepted | outside own bound | {WORST} |",
            "|---|---|---|---|---|"]
    for fam in floorgen.ALL_FAMILIES:
        out.append(_row(fam, [r for r in rows if r["family"] == fam]))
    out.append(_row("all", rows))
    bad = [r for r in rows if r["accepted"] and not r["inside"]]
    if bad:
        out += ["", "Accepted outside their bound:"]
        out += [f"- seed {r['seed']} {r['family']}: {m.describe(r)}; error {r['err_px']:.2f} px, "
                f"{r['err_rad']:.4f} rad; bound {r['bound_px']:.2f} px, {r['bound_rad']:.4f} rad"
                for r in bad]
    return "\n".join(out)


def _row(name: str, sel: list[dict]) -> str:
    return "| " + " | ".join(_cells(name, sel)) + " |"


def _cells(name: str, sel: list[dict]) -> tuple[str, str, str, str, str]:
    """(name, views, accepted, accepted outside their bound, largest error / bound: the worse
    of the position's and the heading's)."""
    acc = [r for r in sel if r["accepted"]]
    bad = [r for r in acc if not r["inside"]]
    worst = max((max(r["err_px"] / r["bound_px"], r["err_rad"] / r["bound_rad"]) for r in acc),
                default=math.nan)
    return name, str(len(sel)), str(len(acc)), str(len(bad)), floorgen.cell(worst, ".2f")


def figure_rows(rows: list[dict], mode: str) -> list[tuple[str, ...]]:
    """The figures: per bucket of ``mode``'s key (:data:`MODES`), then all views."""
    m = MODES[mode]
    return [*(_cells(f"{lo:g} .. {hi:g} {m.unit}", [r for r in rows if lo <= r[m.key] < hi])
              for lo, hi in m.buckets), _cells("all", rows)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--views-per-family", type=int, default=100)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--csv", default="")
    kind = ap.add_mutually_exclusive_group()
    kind.add_argument("--motion", action="store_true",
                      help="a short motion blur instead of a cable along the grout")
    kind.add_argument("--crossing", action="store_true",
                      help="a cable crossing a grout line at a small angle")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:cable_along, "
                    "figures:motion_blur with --motion, figures:cable_crossing with --crossing)")
    args = ap.parse_args(argv)
    mode = "motion" if args.motion else "crossing" if args.crossing else "cable"
    m = MODES[mode]
    machine = Machine()
    tasks = [(args.first_seed + i, fam) for i in range(args.views_per_family)
             for fam in floorgen.ALL_FAMILIES]
    try:
        with ProcessPoolExecutor(args.jobs) if args.jobs > 1 else nullcontext() as pool:
            rows = list(pool.map(m.task, tasks, chunksize=8) if pool else map(m.task, tasks))
    except ImportError as exc:
        print(f"cable_along.py: {exc}")
        return 2
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=list(rows[0]))
            wr.writeheader()
            wr.writerows(rows)
    print(report(rows, mode))
    reasons = collections.Counter(r["reason"] for r in rows if not r["accepted"])
    print("\nrefusals: " + ", ".join(f"{k} {v}" for k, v in reasons.most_common()))
    if args.write_figures:
        write_block(m.block, m.title, figure_rows(rows, mode), machine=machine,
                    header=(m.what, "views", "accepted", "accepted outside own bound", WORST),
                    note=f"Seeds {args.first_seed}..{args.first_seed + args.views_per_family - 1}"
                    " of every family.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
