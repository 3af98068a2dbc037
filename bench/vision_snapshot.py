"""Snapshot the robust extractor's outputs on a fixed set of views, or compare against one.

    python bench/vision_snapshot.py save FILE [--per-family 40]
    python bench/vision_snapshot.py compare FILE

``save`` renders the views (the simulator's frames on the default and seed presets and on every
floor style, and ``tileviz/testing/floorgen.py`` views of every family, clean and corrupted),
extracts each with the robust extractor and writes the images and every output field to FILE (a
pickle). ``compare`` extracts the same images again and reports every view whose outputs differ in
any field (``--decisions``: in the decision only, with the views newly accepted and refused)
(observation, reason, segments, angles, bags, disambiguation, offsets, median, details, and the
stage images of every tenth view), bit for bit. A refactor or a speed change that should not change
decisions must report ``0 differ``.
"""

from __future__ import annotations

import argparse
import math
import pickle
from dataclasses import replace
from pathlib import Path

import numpy as np

from tileviz.config import (
    FLOOR_STYLES,
    CameraConfig,
    VisionConfig,
    floor_style,
    preset,
)
from tileviz.sim.camera import FloorRenderer
from tileviz.testing import floorgen
from tileviz.types import Pose
from tileviz.vision import extract, set_opencv_threads

FIELDS = ("accepted", "reason", "observation", "segments", "angles", "bags", "disambiguation",
          "offsets", "median", "details")


def views(per_family: int) -> list[dict]:
    """The views: dicts with the image, camera, tile size and vision config."""
    out: list[dict] = []
    rng = np.random.default_rng(11)
    for name in ("default", "seed"):
        cfg = preset(name)
        vis = replace(cfg.vision, extractor="robust")
        for style in (None, *FLOOR_STYLES):
            floor = cfg.floor if style is None else floor_style(cfg.floor, style)
            r = FloorRenderer(floor, cfg.camera)
            for _ in range(per_family // 2):
                img = r.render(Pose(rng.uniform(-5, 5), rng.uniform(-5, 5),
                                    rng.uniform(-4, 4)), rng)
                out.append({"name": f"sim-{name}-{style or 'floor'}", "image": img,
                            "camera": cfg.camera, "tile_size": floor.tile_size,
                            "vision": vis})
    vis = VisionConfig(extractor="robust")
    for fam in floorgen.FAMILIES:
        for i in range(per_family):
            corr = None if i % 4 else floorgen.CORRUPTIONS[(i // 4) % len(floorgen.CORRUPTIONS)]
            g = np.random.default_rng([i, 4242, len(fam)])
            spec = floorgen.draw_floor(fam, g)
            img = floorgen.render(spec, *floorgen.draw_view(g), g, corr)
            cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height,
                               offset=(0.0, 0.0))
            out.append({"name": f"{fam}-{corr or 'clean'}", "image": img, "camera": cam,
                        "tile_size": spec.tile_size, "vision": vis})
    return out


def outputs(v: dict, stages: bool) -> dict:
    res = extract(v["image"], camera=v["camera"], tile_size=v["tile_size"],
                  vision=v["vision"], keep_stages=stages)
    out = {f: getattr(res, f) for f in FIELDS}
    if stages:
        out["stages"] = res.stages
    return out


def same(a: object, b: object) -> bool:
    """Bit-identical (NaN equals NaN, -0.0 differs from 0.0)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float):
        return a.hex() == b.hex() or (math.isnan(a) and math.isnan(b))
    if hasattr(a, "__dataclass_fields__") and type(a) is type(b):
        return all(same(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
    return a == b


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("save", "compare"))
    ap.add_argument("file", type=Path)
    ap.add_argument("--per-family", type=int, default=40)
    ap.add_argument("--decisions", action="store_true",
                    help="compare: only the decision (accepted, reason, observation), and count "
                    "the views newly accepted and newly refused")
    args = ap.parse_args(argv)
    set_opencv_threads(1)
    if args.mode == "save":
        vs = views(args.per_family)
        for i, v in enumerate(vs):
            v["out"] = outputs(v, i % 10 == 0)
        args.file.write_bytes(pickle.dumps(vs))
        acc = sum(v["out"]["accepted"] for v in vs)
        print(f"saved {len(vs)} views ({acc} accepted) to {args.file}")
        return 0
    vs = pickle.loads(args.file.read_bytes())
    bad = gained = lost = 0
    for i, v in enumerate(vs):
        now = outputs(v, not args.decisions and i % 10 == 0)
        keys = ("accepted", "reason", "observation") if args.decisions else v["out"]
        diff = [k for k in keys if not same(v["out"][k], now[k])]
        gained += bool(now["accepted"] and not v["out"]["accepted"])
        lost += bool(v["out"]["accepted"] and not now["accepted"])
        if diff:
            bad += 1
            if bad <= 20:
                print(f"view {i} ({v['name']}): differs in {', '.join(diff)}"
                      f" (was {v['out']['reason']}, now {now['reason']})")
    print(f"{len(vs)} views, {bad} differ" + (f" ({gained} newly accepted, {lost} newly "
                                               "refused)" if args.decisions else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
