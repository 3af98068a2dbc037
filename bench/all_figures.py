"""Regenerate every block of ``docs/figures.md``: each bench that writes one, run with
``--write-figures``, one after the other (each block records its own command, date, commit and
the machine's load).

    python bench/all_figures.py              # the quick forms (see QUICK): 10-15 minutes
    python bench/all_figures.py --full       # the forms of FULL: about 2 hours
    python -m bench.all_figures --only vision_study,evaluation --full
    python bench/all_figures.py --list       # the commands, without running them

Times are on a 2-core machine shared with other jobs (load average 5-12). The full forms'
longest are acceptance (three 10-minute runs, about half an hour), faults (about 25 minutes),
vision_study (5040 views: a few minutes idle, half an hour loaded) and evaluation (about half an
hour); the other twenty together take under half an hour. The quick forms measure the same
things on fewer frames, views and runs (their figures are noisier, and each block says which
command made it). A bench that fails is reported and the others still run; the exit status is 1
then. At the end each bench's wall time is printed. The browser benches need Debian's chromium.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import time

from tileviz.testing import REPO

FULL: dict[str, list[str]] = {
    "acceptance": ["acceptance.py", "--minutes", "10"],
    "faults": ["faults.py", "--jobs", "2"],
    "fault_defaults": ["fault_defaults.py"],
    "preset_bounds": ["preset_bounds.py", "--poses", "2000"],
    "accuracy_study": ["accuracy_study.py", "--poses", "2000", "--floors", "200"],
    "accuracy_faults": ["accuracy_study.py", "--poses", "600", "--floors", "100", "--faults"],
    "localizer": ["bench_localizer.py"],
    "mcl_default": ["bench_mcl.py", "--seconds", "30", "--clock", "thread"],
    "mcl_seed": ["bench_mcl.py", "--seconds", "30", "--clock", "thread", "--preset", "seed"],
    "vision": ["bench_vision.py", "--clock", "cpu"],
    "renderer": ["bench_camera.py", "--clock", "cpu"],
    "rectify_640x480": ["bench_rectify.py", "--variant", "all"],
    "rectify_320x240": ["bench_rectify.py", "--variant", "all", "--width", "320", "--height",
                        "240"],
    "png_levels": ["png_levels.py"],
    "server": ["bench_server.py", "--seconds", "20", "--browser"],
    "page": ["bench_page.py"],
    "page_bare": ["bench_page.py", "--bare", "--box", "noenv", "--moving"],
    "page_parts": ["bench_page_parts.py", "full", "show-floor", "bare"],
    "vision_study": ["vision_study.py", "--split", "fresh8", "--views-per-family", "500",
                     "--corrupted-per-family", "60", "--jobs", "2"],
    "cable_along": ["cable_along.py", "--views-per-family", "60", "--jobs", "2"],
    "motion_blur": ["cable_along.py", "--motion", "--views-per-family", "80", "--jobs", "2"],
    "cable_crossing": ["cable_along.py", "--crossing", "--views-per-family", "100", "--jobs",
                       "2"],
    "checker_bands_one": ["checker_bands.py", "--floors", "30", "--views", "20",
                          "--survey-views", "30", "--jobs", "2"],
    "checker_bands_both": ["checker_bands.py", "--floors", "30", "--views", "20",
                           "--survey-views", "30", "--jobs", "2", "--families", "both"],
    "evaluation": ["evaluation.py", "--runs", "4", "--duration", "120", "--scenarios", "all",
                   "--jobs", "2", "--out", "docs/eval"],
    "mcl_calibration": ["mcl_calibration.py", "--runs", "2", "--seconds", "60"],
    "cluster": ["cluster_throughput.py", "--runs", "2", "--duration", "10", "--scenarios",
                "clean,seed", "--repeat", "2"],
}
"""Each block's bench and the options of the figures the docs quote."""

QUICK: dict[str, list[str]] = {
    "acceptance": ["acceptance.py", "--minutes", "0.5", "--cases", "default"],
    "faults": ["faults.py", "--seeds", "1", "--seed-preset-seeds", "0", "--out", ""],
    "fault_defaults": ["fault_defaults.py", "--frames", "500", "--repeats", "2"],
    "preset_bounds": ["preset_bounds.py", "--poses", "150"],
    "accuracy_study": ["accuracy_study.py", "--poses", "150", "--floors", "30"],
    "accuracy_faults": ["accuracy_study.py", "--poses", "150", "--floors", "30", "--faults"],
    "localizer": ["bench_localizer.py", "--frames", "500", "--repeats", "2"],
    "mcl_default": ["bench_mcl.py", "--seconds", "10", "--clock", "thread", "--repeat", "2"],
    "mcl_seed": ["bench_mcl.py", "--seconds", "10", "--clock", "thread", "--repeat", "2",
                 "--preset", "seed"],
    "vision": ["bench_vision.py", "--clock", "cpu", "--frames", "30"],
    "renderer": ["bench_camera.py", "--clock", "cpu", "--frames", "30"],
    "rectify_640x480": ["bench_rectify.py", "--variant", "all", "--frames", "20", "--passes",
                        "2"],
    "rectify_320x240": ["bench_rectify.py", "--variant", "all", "--frames", "20", "--passes",
                        "2", "--width", "320", "--height", "240"],
    "png_levels": ["png_levels.py", "--frames", "30"],
    "server": ["bench_server.py", "--seconds", "6", "--browser"],
    "page": ["bench_page.py", "--seconds", "5", "--warmup", "5"],
    "page_bare": ["bench_page.py", "--bare", "--box", "noenv", "--moving", "--seconds", "5",
                  "--warmup", "5"],
    "page_parts": ["bench_page_parts.py", "full", "bare", "--window", "3", "--repeat", "1"],
    "vision_study": ["vision_study.py", "--split", "fresh8", "--views-per-family", "20",
                     "--corrupted-per-family", "5", "--jobs", "2"],
    "cable_along": ["cable_along.py", "--views-per-family", "10", "--jobs", "2"],
    "motion_blur": ["cable_along.py", "--motion", "--views-per-family", "10", "--jobs", "2"],
    "cable_crossing": ["cable_along.py", "--crossing", "--views-per-family", "10", "--jobs",
                       "2"],
    "checker_bands_one": ["checker_bands.py", "--floors", "8", "--views", "10",
                          "--survey-views", "30", "--jobs", "2"],
    "checker_bands_both": ["checker_bands.py", "--floors", "8", "--views", "10",
                           "--survey-views", "30", "--jobs", "2", "--families", "both"],
    "evaluation": ["evaluation.py", "--runs", "1", "--duration", "20", "--scenarios",
                   "clean,seed,slip,kidnap", "--jobs", "2", "--out", "out/eval-quick"],
    "mcl_calibration": ["mcl_calibration.py", "--runs", "1", "--seconds", "15"],
    "cluster": ["cluster_throughput.py", "--runs", "1", "--duration", "5", "--scenarios",
                "clean"],
}
"""The same benches on less work."""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--full", action="store_true", help="the forms the docs quote (hours)")
    ap.add_argument("--only", default="", help=f"comma-separated, of: {', '.join(FULL)}")
    ap.add_argument("--list", action="store_true", help="print the commands only")
    args = ap.parse_args(argv)
    forms = FULL if args.full else QUICK
    names = [n for n in args.only.split(",") if n] or list(forms)
    unknown = [n for n in names if n not in forms]
    if unknown:
        ap.error(f"unknown bench block(s): {', '.join(unknown)}")
    failed: list[str] = []
    spent: dict[str, float] = {}
    for name in names:
        script, *opts = forms[name]
        cmd = [sys.executable, str(REPO / "bench" / script), *opts, "--write-figures"]
        shown = shlex.join(["python", f"bench/{script}", *opts, "--write-figures"])
        print(f"== {name}: {shown}", flush=True)
        if args.list:
            continue
        t0 = time.perf_counter()
        r = subprocess.run(cmd, cwd=REPO)
        spent[name] = time.perf_counter() - t0
        if r.returncode != 0:
            failed.append(name)
            print(f"== {name} FAILED (exit status {r.returncode})", flush=True)
    if spent:
        print("\n== wall time per bench: " + ", ".join(f"{n} {t / 60:.1f} min"
                                                      for n, t in spent.items()))
        print(f"== all: {sum(spent.values()) / 60:.1f} min"
              + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
