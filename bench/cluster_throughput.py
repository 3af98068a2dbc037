"""Runs per minute of one evaluation campaign: a local Dask cluster against the process pool.

    python bench/cluster_throughput.py [--runs 4] [--duration 20] [--scenarios clean,seed]
                                       [--workers 2] [--repeat 1]

Runs ``python -m tileviz evaluate`` on the same campaign with ``--jobs N`` and with
``--scheduler local:N`` (N = ``--workers``), alternately ``--repeat`` times, and prints each one's
wall-clock time (the whole command: start-up, the runs, the report) and runs per minute, and
whether the two gave the same tables (CPU column aside). Each mode's fixed cost (start-up, workers,
report) is measured first on a campaign of one 1-frame run and also taken out.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tileviz.testing.figures import Machine, fmt_range, write_block


def table(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r.pop("cpu_us_per_frame", None)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--scenarios", default="clean,seed")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:cluster)")
    args = ap.parse_args()
    machine = Machine()
    rates: dict[str, list[float]] = {name: [] for name in ("--jobs", "--scheduler")}
    n = args.runs * len(args.scenarios.split(","))
    base = [sys.executable, "-m", "tileviz", "evaluate", "--runs", str(args.runs),
            "--duration", f"{args.duration:g}", "--scenarios", args.scenarios, "--quiet"]
    modes = {"--jobs": ["--jobs", str(args.workers)],
             "--scheduler": ["--scheduler", f"local:{args.workers}"]}
    print(f"campaign: {n} runs ({args.runs} x {args.scenarios}) of {args.duration:g} s, "
          f"{args.workers} workers")
    with tempfile.TemporaryDirectory() as tmp:
        # the fixed cost of each mode: start-up and report of a campaign of one 1-frame run
        fixed = {}
        for name, extra in modes.items():
            t0 = time.perf_counter()
            subprocess.run([*base[:4], "--runs", "1", "--duration", "0.05", "--scenarios",
                            "clean", "--quiet", *extra, "--out", str(Path(tmp) / "fixed")],
                           check=True, stdout=subprocess.DEVNULL)
            fixed[name] = time.perf_counter() - t0
            print(f"{' '.join(extra):22s} fixed cost (one 1-frame run) {fixed[name]:6.1f} s",
                  flush=True)
        outs = {}
        for rep in range(args.repeat):
            for name, extra in modes.items():
                out = Path(tmp) / f"{name.strip('-')}{rep}"
                t0 = time.perf_counter()
                subprocess.run([*base, *extra, "--out", str(out)], check=True,
                               stdout=subprocess.DEVNULL)
                wall = time.perf_counter() - t0
                net = max(wall - fixed[name], 1e-9)
                print(f"{' '.join(extra):22s} {wall:7.1f} s wall, {60.0 * n / wall:6.2f} runs/min;"
                      f" without the fixed cost {60.0 * n / net:6.2f} runs/min", flush=True)
                outs[name] = out
                rates[name].append(60.0 * n / wall)
        same = all(table(outs["--jobs"] / f) == table(outs["--scheduler"] / f)
                   for f in ("results.csv", "runs.csv", "calibration.csv"))
        print(f"same tables (CPU aside): {same}")
    if args.write_figures:
        rows = [(f"{' '.join(modes[name])}: whole command", fmt_range(rates[name], ".2f",
                                                                      "runs/min"))
                for name in modes]
        rows += [(f"{' '.join(modes[name])}: fixed cost (a 1-frame campaign)",
                  f"{fixed[name]:.1f} s") for name in modes]
        rows.append(("same tables (CPU column aside)", "yes" if same else "NO"))
        write_block("cluster", "A campaign on one machine: processes against a local Dask "
                    "cluster", rows, machine=machine,
                    note=f"{n} runs of {args.duration:g} s, {args.workers} workers.")


if __name__ == "__main__":
    main()
