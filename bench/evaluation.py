"""The evaluation's headline figures: one ``python -m tileviz evaluate`` campaign, then its
``results.csv`` summed up in ``docs/figures.md`` (``figures:evaluation``).

    python bench/evaluation.py [evaluate options...] [--write-figures]
    python -m bench.evaluation --runs 1 --duration 20 --scenarios clean,seed --write-figures
    python bench/evaluation.py --runs 4 --duration 120 --scenarios all --jobs 1 --out docs/eval

Every option but ``--write-figures`` goes to ``evaluate`` as it is (``--out`` default
``out/eval``; ``--out docs/eval`` writes the full tables and plots of ``docs/eval/`` in place).
The figures kept: per scenario, the interval localizer (autonomous, its fault model on) and the
calibrated and untuned MCL: containment over the vouched frames, false vouches, the median set
width and the CPU per frame (``docs/evaluation.md`` says what each means).
"""

from __future__ import annotations

import csv
import subprocess
import sys
import time
from pathlib import Path

from tileviz.testing.figures import Machine, command_line, write_block

METHODS = {"interval": "interval (autonomous)", "mcl": "MCL, calibrated",
           "mcl-untuned": "MCL, untuned"}
"""The methods of ``results.csv`` kept in the figures, as the table names them."""


def rows_of(results: Path) -> list[tuple[str, ...]]:
    """The figure rows of an evaluation's ``results.csv``."""
    out = []
    with open(results, newline="", encoding="utf-8") as f:
        for r in csv.DictReader(f):
            if r["method"] not in METHODS:
                continue
            wx = 100 * float(r["width_x_median_m"])
            wy = 100 * float(r["width_y_median_m"])
            out.append((r["scenario"], METHODS[r["method"]], f"{float(r['containment_pct']):.2f}",
                        r["false_vouches"] if r["method"] == "interval" else "-",
                        f"{wx:.2f} / {wy:.2f}", f"{float(r['width_theta_median_deg']):.2f}",
                        f"{float(r['cpu_us_per_frame']):.0f}"))
    return out


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    write = "--write-figures" in args
    args = [a for a in args if a != "--write-figures"]
    if "-h" in args or "--help" in args:
        print(__doc__)
        return 0
    out = Path("out/eval")
    for flag in ("--out", "--resume"):
        if flag in args[:-1]:
            out = Path(args[args.index(flag) + 1])
    if "--out" not in args and "--resume" not in args:
        args += ["--out", str(out)]
    machine = Machine()
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "tileviz", "evaluate", *args])
    if r.returncode != 0:
        return r.returncode
    minutes = (time.perf_counter() - t0) / 60
    if write:
        write_block("evaluation", "Evaluation against odometry and MCL", rows_of(
            out / "results.csv"), machine=machine, command=command_line(argv),
            header=("scenario", "method", "containment %", "false vouches",
                    "box width x / y median (cm)", "heading width (deg)", "CPU µs/frame"),
            note=f"{minutes:.1f} min. Every method, the fault scenarios and the calibration: "
            f"`{out}/results.md`.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
