"""CPU time per frame of the interval localizer and of Monte Carlo Localization, vision excluded.

Both methods get the same inputs: a simulated run (default preset unless ``--preset``) is made once
and vision is run once per frame; the odometry, compass and observations are kept. Then each method
is run over the whole sequence ``--repeat`` times and its CPU time (``--clock``, by default
``time.process_time``) around the ``step`` calls alone is divided by the frame count; the best
repeat is kept (the least disturbed by other processes on a shared machine). MCL is timed with
several particle counts.

``--after-vision`` runs vision (untimed) right before every timed step, as the frame loop and
``tileviz evaluate`` do: the step then starts with caches full of image buffers and costs more
(several times for the interval localizer); that is why ``evaluate``'s CPU column is higher
than the isolated figure. Two things make it so, and the script prints both:

- a floor: an empty function timed the same way. With ``--clock process`` (``evaluate``'s clock)
  it counts every thread of the process, and OpenCV's worker threads are still busy for a while
  after ``extract`` returns; ``--clock thread`` (``time.thread_time``) counts the calling thread
  only (both methods run on it: MCL's numpy calls here are single-threaded). The floor is paid
  by every method alike, so it weighs most on the cheapest.
- cold caches: vision evicts the interpreter's code and the method's bytecode, so the first step
  after it runs several times slower than a step in a tight loop; the more distinct code a step
  runs, the more it pays. ``--after-sweep MB`` shows it without vision: it writes once over an
  MB-sized array (untimed) before every step (an array the size of the last-level cache costs
  the step about what vision does; OpenCV's thread count does not matter). ``--inputs odometry``
  (prediction only) shows how much of that cost is not the contraction's.

    python bench/bench_mcl.py                       # 60 s of default preset, 1000 particles
    python bench/bench_mcl.py --seconds 30 --preset seed --particles 100 1000 10000
    python bench/bench_mcl.py --seconds 30 --after-vision --clock thread
    python bench/bench_mcl.py --seconds 30 --after-sweep 32 --clock thread
    python bench/bench_mcl.py --seconds 30 --after-sweep 32 --clock thread --inputs odometry
    python -m bench.bench_mcl --seconds 30 --clock thread --write-figures   # figures:mcl_default
"""

from __future__ import annotations

import argparse
import itertools
import math
import time

import numpy as np

from tileviz.baselines.mcl import MCL, MclConfig
from tileviz.config import preset
from tileviz.core.localizer import Localizer
from tileviz.pipeline import initial_box
from tileviz.sim.source import SimSource
from tileviz.testing.figures import Machine, write_block
from tileviz.types import SensorBounds
from tileviz.vision import extract, set_opencv_threads

set_opencv_threads()  # as every tileviz entry point (workers re-run this on import)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds")
    ap.add_argument("--preset", default="default", choices=("default", "seed"))
    ap.add_argument("--particles", type=int, nargs="+", default=[1000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--after-vision", action="store_true",
                    help="run vision (untimed) before every timed step, as the frame loop does")
    ap.add_argument("--after-sweep", type=float, default=0.0, metavar="MB",
                    help="write over an array of MB megabytes (untimed) before every timed step")
    ap.add_argument("--inputs", choices=("odometry", "compass", "all"), default="all",
                    help="what each step gets: odometry only (prediction), odometry and compass, "
                    "or also the view (the frame loop)")
    ap.add_argument("--clock", choices=("process", "thread"), default="process",
                    help="CPU clock: process (all threads, as tileviz evaluate) or thread "
                    "(the calling thread only)")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:mcl_PRESET)")
    args = ap.parse_args()
    machine = Machine()
    rows: list[tuple[str, str]] = []
    clock = time.process_time if args.clock == "process" else time.thread_time

    cfg = preset(args.preset)
    n = int(round(args.seconds / cfg.sim.dt))
    L, off = cfg.floor.tile_size, cfg.camera.offset
    bounds = SensorBounds(cfg.noise.speed_error, cfg.noise.yaw_rate_error,
                          cfg.noise.compass_error)
    inputs = []
    pending = None
    vis = 0.0
    for frame in itertools.islice(SimSource(cfg), n):
        c0 = time.process_time()
        v = extract(frame.image, camera=cfg.camera, tile_size=L, vision=cfg.vision)
        vis += time.process_time() - c0
        inputs.append((pending, frame.compass, v.observation, frame.image))
        pending = frame.odometry
    used = sum(o is not None for _, _, o, _ in inputs)

    sweep = np.zeros(int(args.after_sweep * 2**20), np.uint8)

    def timed(step) -> float:
        total = 0.0
        for odo, comp, obs, image in inputs:
            if args.after_vision:
                extract(image, camera=cfg.camera, tile_size=L, vision=cfg.vision)
            if sweep.size:
                np.add(sweep, 1, out=sweep)
            if args.inputs != "all":
                obs = None
                comp = comp if args.inputs == "compass" else None
            c0 = clock()
            step(odo, comp, obs)
            total += clock() - c0
        return total / n

    print(f"preset {args.preset}: {n} frames, {used} with an observation; "
          f"vision {1e3 * vis / n:.2f} ms CPU/frame (not counted below); clock {args.clock}")

    def empty(odo: object, comp: object, obs: object) -> None:
        """Nothing: what the timing itself costs."""

    where = (" (each step right after vision)" if args.after_vision else "") + (
        f" (each step after a {args.after_sweep:g} MB sweep)" if sweep.size else "")
    t_floor = min(timed(empty) for _ in range(args.repeat))
    print(f"floor (an empty function, same timing): {1e6 * t_floor:8.1f} us CPU/frame{where}")

    def time_interval() -> float:
        loc = Localizer(tile_size=L, camera_offset=off, bounds=bounds, config=cfg.localizer,
                        initial=initial_box(cfg))
        return timed(loc.step)

    def time_mcl(particles: int) -> float:
        mcl = MCL(tile_size=L, camera_offset=off, bounds=bounds, initial=initial_box(cfg),
                  config=MclConfig(particles=particles, seed=1))
        return timed(mcl.step)

    t_int = min(time_interval() for _ in range(args.repeat))
    print(f"interval localizer (autonomous): {1e6 * t_int:8.1f} us CPU/frame{where}")
    rows.append(("interval localizer, CPU per frame", f"{1e6 * t_int:.1f} us"))
    for p in args.particles:
        t_mcl = min(time_mcl(p) for _ in range(args.repeat))
        ratio = t_mcl / t_int if t_int > 0 else math.inf
        net = (t_mcl - t_floor) / (t_int - t_floor) if t_int > t_floor else math.inf
        print(f"MCL, {p:6d} particles:          {1e6 * t_mcl:8.1f} us CPU/frame "
              f"= {ratio:5.1f}x the interval localizer ({net:.1f}x without the floor)")
        rows.append((f"MCL, {p} particles, CPU per frame", f"{1e6 * t_mcl:.1f} us "
                     f"({ratio:.1f}x the interval localizer)"))
    if args.write_figures:
        rows.insert(0, ("clock; steps", f"{args.clock}{where or ''}; {args.inputs} inputs"))
        write_block(f"mcl_{args.preset}", f"CPU per frame, MCL against the interval localizer "
                    f"({args.preset} preset)", rows, machine=machine)


if __name__ == "__main__":
    main()
