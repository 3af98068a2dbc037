"""Views read with a wrong ``ppm``: how many the robust extractor accepts, and how many of those
lie outside their own declared bound (the calibration is a hypothesis of H4, docs/guarantees.md).

    python bench/wrong_calibration.py [--poses 60] [--factors 0.95,0.98,1.02,1.05]

Frames of the default preset (L = 1 m, 200 px/m, 320x240, camera noise on) at random poses,
rendered at the true ``ppm`` and extracted with ``ppm`` times each factor.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from tileviz.config import VisionConfig, preset
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision import extract, observation_error


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--poses", type=int, default=60)
    ap.add_argument("--factors", default="0.95,0.98,1.02,1.05")
    args = ap.parse_args(argv)
    base = preset("default")
    renderer = FloorRenderer(base.floor, base.camera)
    tile = base.floor.tile_size
    print(f"default preset: L = {tile} m, {base.camera.ppm:g} px/m, {args.poses} poses")
    for f in (float(v) for v in args.factors.split(",")):
        rng = np.random.default_rng(1)
        cam = replace(base.camera, ppm=base.camera.ppm * f)
        accepted = outside = 0
        for _ in range(args.poses):
            pose = Pose(rng.uniform(0, 5), rng.uniform(0, 5), rng.uniform(-math.pi, math.pi))
            res = extract(renderer.render(pose, rng), camera=cam, tile_size=tile,
                          vision=VisionConfig(extractor="robust"))
            if res.accepted:
                accepted += 1
                obs = res.observation
                e1, e2, e3 = observation_error(obs, pose, tile, cam.offset)
                outside += (max(abs(e1), abs(e2)) > obs.position_error
                            or abs(e3) > obs.heading_error)
        print(f"ppm declared x{f:g}: accepted {accepted}/{args.poses}, "
              f"outside their bound {outside}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
