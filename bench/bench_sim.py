"""Cost of one simulation frame (pymunk world + controller + sensors), rendering excluded.

It runs SimSource with a blank camera (so only the simulation is timed) for each preset and
setpoint, and prints milliseconds per frame (median of ``--repeats`` runs). When the floor renderer
(``tileviz.sim.camera``) exists it also prints the cost of a whole SimSource frame with it.

    python bench/bench_sim.py                 # 2000 frames x 3 repeats
    python bench/bench_sim.py --frames 500
"""

from __future__ import annotations

import argparse
import importlib.util
import itertools
import statistics
import time
from dataclasses import replace

from tileviz.config import Config, preset
from tileviz.sim.source import BlankRenderer, SimSource


def ms_per_frame(cfg: Config, frames: int, repeats: int, blank: bool) -> float:
    times = []
    for _ in range(repeats):
        renderer = BlankRenderer(cfg.camera.width, cfg.camera.height) if blank else None
        src = SimSource(cfg, renderer=renderer)
        t0 = time.perf_counter()
        for _frame in itertools.islice(src, frames):
            pass
        times.append((time.perf_counter() - t0) / frames * 1e3)
    return statistics.median(times)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=2000)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    print(f"simulation step, rendering excluded ({args.frames} frames, median of "
          f"{args.repeats}):")
    for name in ("default", "seed"):
        base = preset(name)
        for sp in ("lissajous", "waypoints", "manual"):
            cfg = replace(base, sim=replace(base.sim, setpoint=sp))
            ms = ms_per_frame(cfg, args.frames, args.repeats, blank=True)
            print(f"  {name:8s} {sp:10s} {ms:7.4f} ms/frame")
        walls = replace(base, sim=replace(base.sim, walls=True,
                                          obstacles=((1.0, 1.0, 0.3), (-2.0, 0.5, 0.5))))
        ms = ms_per_frame(walls, args.frames, args.repeats, blank=True)
        print(f"  {name:8s} {'walls+obst':10s} {ms:7.4f} ms/frame")
    if importlib.util.find_spec("tileviz.sim.camera") is not None:
        n = max(args.frames // 10, 50)
        for name in ("default", "seed"):
            ms = ms_per_frame(preset(name), n, 1, blank=False)
            print(f"  {name:8s} with the floor renderer: {ms:7.3f} ms/frame ({n} frames)")
    else:
        print("  (tileviz.sim.camera not present: rendering not measured)")


if __name__ == "__main__":
    main()
