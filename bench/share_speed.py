"""What sharing a 60 s run costs: the page, the figure and the movie (issue 31).

    python bench/share_speed.py [--dataset DS] [--seconds 60] [--out out/share] [--only NAMES]

Records ``--seconds`` of the default simulation (``python -m tileviz record``) unless
``--dataset`` is given, then runs, one after the other:

1. ``python -m tileviz export-html DS OUT.html --quiet`` (the defaults: every frame, 200 px
   images, the ``lines`` stage): the file's MB (10^6 bytes), the command's wall time and CPU
   time (user + system; its vision runs in the command's process, so this is all of it);
2. ``python -m tileviz figure DS OUT.png --quiet`` with ``--jobs 1`` (all the CPU counted) and
   with the default jobs (the wall time a user waits; the vision workers' CPU is not counted);
3. ``python -m tileviz figure DS OUT.mp4 --quiet`` (every 2nd frame, 960 px): wall and CPU
   (with the default jobs: the CPU of the vision workers, children of a fork server the
   command does not wait for, is not counted) and the file's MB (skipped without the share
   extra);
4. ``python -m tileviz replay DS --out RUN.csv --quiet`` (the CSV, written once), then
   ``python -m tileviz figure DS OUT.png --boxes RUN.csv --quiet``: the figure without a
   replay, wall and CPU (the whole command: start-up, imports, reading, drawing).

5. In this process, the replay apart from the drawing: ``load_run`` (the replay, one job) and
   ``load_boxes`` (the CSV read), then ``save_figure`` and ``movie`` of the replayed run (the
   drawing alone), wall and CPU.

``--only`` runs the rows named (comma-separated: ``export-html``, ``figure``, ``movie``,
``boxes``, ``in-process``; default all). Prints one line per command and the machine's
1-minute load average before each.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
from pathlib import Path


def _run(args: list[str]) -> tuple[float, float]:
    """Wall and CPU (user + system) seconds of ``python -m tileviz ARGS``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "tileviz", *args], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed: {r.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dataset", default=None)
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--out", default="out/share")
    p.add_argument("--only", default="export-html,figure,movie,boxes,in-process")
    a = p.parse_args()
    only = set(a.only.split(","))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    ds = Path(a.dataset) if a.dataset else out / f"run{a.seconds:g}s"
    if not ds.exists():
        _run(["record", str(ds), "--duration", str(a.seconds), "--quiet"])
    frames = sum(1 for _ in open(ds / "frames.csv")) - 1
    print(f"dataset {ds}: {frames} frames")
    _run(["extract", "--help"])  # the imports' files read once, before the timings
    from tileviz.share.figure import share_missing

    table = out / "run.csv"
    rows = [
        ("export-html", "export-html", ["export-html", str(ds), str(out / "run.html"),
                                        "--quiet"], out / "run.html"),
        ("figure", "figure --jobs 1", ["figure", str(ds), str(out / "run.png"), "--quiet",
                                       "--jobs", "1"], out / "run.png"),
        ("figure", "figure", ["figure", str(ds), str(out / "run.png"), "--quiet"],
         out / "run.png"),
        ("movie", "movie", ["figure", str(ds), str(out / "run.mp4"), "--quiet"],
         out / "run.mp4"),
        ("boxes", "replay --out", ["replay", str(ds), "--out", str(table), "--quiet"], table),
        ("boxes", "figure --boxes", ["figure", str(ds), str(out / "boxes.png"), "--boxes",
                                     str(table), "--quiet"], out / "boxes.png"),
    ]
    for row, name, args, path in rows:
        if row not in only:
            continue
        if row == "movie" and (missing := share_missing()) is not None:
            print(f"{name:<16} skipped: {missing}")
            continue
        load = os.getloadavg()[0]
        wall, cpu = _run(args)
        print(f"{name:<16} {path.stat().st_size / 1e6:7.2f} MB  wall {wall:6.1f} s  "
              f"cpu {cpu:6.1f} s  (load {load:.1f}; python -m tileviz {' '.join(args)})")

    if "in-process" not in only:
        return
    from tileviz.share.figure import movie, save_figure
    from tileviz.share.run import Views, load_boxes, load_run

    if table.exists():
        load = os.getloadavg()[0]
        t0, c0 = time.perf_counter(), time.process_time()
        load_boxes(ds, table)
        print(f"{'load_boxes (CSV)':<20} wall {time.perf_counter() - t0:6.1f} s  "
              f"cpu {time.process_time() - c0:6.1f} s  (load {load:.1f})")
    for name, views in (("replay (load_run)", None),
                        ("replay, movie views", Views(every=2, width=480))):
        load = os.getloadavg()[0]
        t0, c0 = time.perf_counter(), time.process_time()
        run = load_run(ds, jobs=1, views=views)
        print(f"{name:<20} wall {time.perf_counter() - t0:6.1f} s  "
              f"cpu {time.process_time() - c0:6.1f} s  (load {load:.1f})")
    draws = [("figure drawing", lambda: save_figure(run, out / "alone.png"))]
    if share_missing() is None:
        draws.append(("movie drawing", lambda: movie(run, out / "alone.mp4")))
    for name, draw in draws:
        load = os.getloadavg()[0]
        t0, c0 = time.perf_counter(), time.process_time()
        draw()
        print(f"{name:<20} wall {time.perf_counter() - t0:6.1f} s  "
              f"cpu {time.process_time() - c0:6.1f} s  (load {load:.1f}; the ffmpeg encoder "
              "is a child process, not counted)")


if __name__ == "__main__":
    main()
