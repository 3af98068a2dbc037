"""Cost of one simulation frame (pymunk world + controller + sensors), rendering excluded.

It runs SimSource with a blank camera (so only the simulation is timed) for each preset and
setpoint, and prints milliseconds per frame (median of ``--repeats`` runs). When the floor renderer
(``tileviz.sim.camera``) exists it also prints the cost of a whole SimSource frame with it. It
also prints how closely the robot follows the Lissajous setpoint of each preset.

    python bench/bench_sim.py                 # 2000 frames x 3 repeats
    python bench/bench_sim.py --frames 500
"""

from __future__ import annotations

import argparse
import importlib.util
import itertools
import math
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


def tracking(cfg: Config) -> tuple[float, float, float]:
    """Distance (m) from the robot to the Lissajous setpoint over one lap after 20 s of settling:
    median, max; and the largest wheel speed reached (m/s)."""
    src = SimSource(cfg, renderer=BlankRenderer(cfg.camera.width, cfg.camera.height))
    settle = int(20 / cfg.sim.dt)
    lap = int(2 * math.pi / cfg.sim.lissajous_omega / cfg.sim.dt)
    errors, wheel = [], 0.0
    for f in itertools.islice(src, settle + lap):
        if f.index >= settle:
            errors.append(math.dist(f.truth.as_tuple()[:2], f.setpoint))
        wheel = max(wheel, *map(abs, src.world.wheels))
    return statistics.median(errors), max(errors), wheel


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
    for name in ("default", "seed"):
        med, worst, wheel = tracking(preset(name))
        print(f"  {name:8s} Lissajous tracking over one lap: median {med * 100:.2f} cm, "
              f"max {worst * 100:.2f} cm, fastest wheel {wheel:.3f} m/s")
    if importlib.util.find_spec("tileviz.sim.camera") is not None:
        n = max(args.frames // 10, 50)
        for name in ("default", "seed"):
            ms = ms_per_frame(preset(name), n, 1, blank=False)
            print(f"  {name:8s} with the floor renderer: {ms:7.3f} ms/frame ({n} frames)")
    else:
        print("  (tileviz.sim.camera not present: rendering not measured)")


if __name__ == "__main__":
    main()
