"""How big a recorded dataset is, and what PNG compression costs its replay (issue 35).

    python bench/dataset_size.py [--seconds 10] [--replay-seconds 60] [--repeats 3]
                                 [--csv out/dataset_size.csv] [--skip-sizes] [--skip-replay]

1. Size: ``python -m tileviz record DS --duration SECONDS --png-level L [--lens webcam]`` for the
   default camera (320x240 views) and the webcam lens (640x480 raw images), at every
   ``--png-level`` 0..9. MB are 10^6 bytes; MB a minute = the folder's bytes / its frames x the
   frames a minute of recording (60 / dt).
2. Replay: ``python -m tileviz replay DS --out O.csv --quiet`` (``--jobs 1`` and the default)
   on ``--png-level`` 0 and 1 datasets of ``--replay-seconds`` and of 2 s, for both cameras.
   The command's wall time over its frames, and the time a frame adds: (wall of the long
   dataset - wall of the 2 s one) / (their frame difference), which leaves out the start-up.
   With ``--jobs 1`` also the CPU time (user + system) a frame adds, less sensitive than the
   wall time to other work on the machine (the default's workers are children of a fork server
   that replay does not wait for, so their time is not counted: no figure there); and the
   median 1-minute load average during the runs.
   The runs are interleaved (level 0, level 1, level 0, ...) ``--repeats`` times, the median
   kept (after one untimed replay); the datasets were just written, so they are read from the
   page cache.

Prints one row per measure (and writes them to ``--csv``).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CAMERAS = {"default": [], "webcam": ["--lens", "webcam"]}
COLUMNS = ("measure", "camera", "png_level", "jobs", "frames", "mb", "mb_per_min",
           "wall_s", "ms_per_frame", "ms_per_frame_marginal", "cpu_ms_per_frame_marginal",
           "load")


def tileviz(*args: str) -> tuple[float, float]:
    """Run ``python -m tileviz ARGS``; its wall time and the CPU time (user + system) of it and
    the processes it waited for, seconds (exit on a failure)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "tileviz", *args], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        sys.exit(f"tileviz {' '.join(args)} failed: {r.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def record(folder: Path, camera: str, level: int, seconds: float) -> tuple[int, int, float]:
    """Record a dataset; (frames, bytes, frames a minute)."""
    tileviz("record", str(folder), "--duration", str(seconds), "--png-level", str(level),
            "--quiet", *CAMERAS[camera])
    frames = sum(1 for _ in open(folder / "frames.csv", encoding="utf-8")) - 1
    size = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    dt = json.loads((folder / "meta.json").read_text(encoding="utf-8"))["dt"]
    return frames, size, 60.0 / dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="recording for the sizes, s")
    ap.add_argument("--replay-seconds", type=float, default=60.0,
                    help="recording for the replay speed, s")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--csv", type=Path, default=None, help="also write the rows here")
    ap.add_argument("--skip-sizes", action="store_true")
    ap.add_argument("--skip-replay", action="store_true")
    args = ap.parse_args()
    rows: list[dict[str, object]] = []

    def emit(row: dict[str, object]) -> None:
        rows.append(row)
        print("  ".join(f"{k}={row[k]}" for k in COLUMNS if row.get(k, "") != ""), flush=True)

    with tempfile.TemporaryDirectory(prefix="tileviz-size-") as tmp:
        root = Path(tmp)
        for camera in CAMERAS if not args.skip_sizes else ():
            for level in range(10):
                folder = root / f"size-{camera}-{level}"
                frames, size, per_min = record(folder, camera, level, args.seconds)
                emit({"measure": "size", "camera": camera, "png_level": level,
                      "frames": frames, "mb": f"{size / 1e6:.1f}",
                      "mb_per_min": f"{size / frames * per_min / 1e6:.0f}"})
                shutil.rmtree(folder)  # keep the disk free
        if not args.skip_replay:
            for camera in CAMERAS:
                ds = {(level, length): root / f"replay-{camera}-{level}-{length}"
                      for level in (0, 1) for length in ("long", "short")}
                counts = {key: record(folder, camera, key[0],
                                      args.replay_seconds if key[1] == "long" else 2.0)[0]
                          for key, folder in ds.items()}
                # untimed: the first replay may compile the vision kernels (cached after)
                tileviz("replay", str(ds[(0, "short")]), "--out", str(root / "o.csv"), "--quiet")
                for jobs in (["--jobs", "1"], []):
                    walls: dict[tuple[int, str], list[float]] = {key: [] for key in ds}
                    cpus: dict[tuple[int, str], list[float]] = {key: [] for key in ds}
                    loads = []
                    for _ in range(args.repeats):
                        for key, folder in ds.items():
                            wall, cpu = tileviz("replay", str(folder), "--out",
                                                str(root / "o.csv"), "--quiet", *jobs)
                            walls[key].append(wall)
                            cpus[key].append(cpu)
                            loads.append(os.getloadavg()[0])
                    for level in (0, 1):
                        long_w = statistics.median(walls[(level, "long")])
                        short_w = statistics.median(walls[(level, "short")])
                        long_c = statistics.median(cpus[(level, "long")])
                        short_c = statistics.median(cpus[(level, "short")])
                        n, n0 = counts[(level, "long")], counts[(level, "short")]
                        emit({"measure": "replay", "camera": camera, "png_level": level,
                              "jobs": jobs[1] if jobs else "default", "frames": n,
                              "wall_s": f"{long_w:.2f}",
                              "ms_per_frame": f"{1e3 * long_w / n:.2f}",
                              "ms_per_frame_marginal":
                                  f"{1e3 * (long_w - short_w) / (n - n0):.2f}",
                              "cpu_ms_per_frame_marginal":
                                  f"{1e3 * (long_c - short_c) / (n - n0):.2f}" if jobs else "",
                              "load": f"{statistics.median(loads):.1f}"})
    if args.csv is not None:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with open(args.csv, "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=COLUMNS)
            w.writeheader()
            w.writerows(rows)
        print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
