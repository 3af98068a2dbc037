"""The robust extractor's CPU time per floor family, side by side for several revisions of this
repository, in one run on the same views.

    python bench/compare_versions.py --rev c459d09 --rev HEAD [--views 60] [--rounds 3]
                                     [--families plain,photo]

Each revision is checked out (``git worktree add --detach``) into a temporary folder; the views
(``tileviz/testing/floorgen.py`` of the working tree, clean, seeds 0..) are rendered once and
saved; then, round after round, each revision times ``tileviz.vision.extract`` on every view in a
process of its own (``PYTHONPATH`` = its checkout; OpenCV on one thread; this thread's CPU time,
``time.thread_time``, after one warm-up pass that also loads the compiled kernels). The figure
per family and revision is the median over its views of the per-view median over rounds; the
ratio is to the first ``--rev``. The revisions' order alternates between rounds, so that a load
changing during the run weighs on every revision alike.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

TIMER = r"""
import json, sys, time
import numpy as np
from tileviz.config import CameraConfig, VisionConfig
from tileviz.vision import extract, set_opencv_threads
set_opencv_threads(1)
data = np.load(sys.argv[1], allow_pickle=False)
meta = json.loads(open(sys.argv[2]).read())
vision = VisionConfig(extractor="robust")
out = []
for warm in (True, False):
    for k, m in enumerate(meta):
        img = data[f"v{k}"]
        cam = CameraConfig(ppm=m["ppm"], width=img.shape[1], height=img.shape[0],
                           offset=(0.0, 0.0))
        t0 = time.thread_time()
        extract(img, camera=cam, tile_size=m["tile"], vision=vision)
        if not warm:
            out.append((time.thread_time() - t0) * 1e3)
print(json.dumps(out))
"""


def views(families: list[str], n: int) -> tuple[dict[str, np.ndarray], list[dict]]:
    """``n`` clean views of each family (images, and per view its family, ppm and tile size)."""
    from tileviz.testing import floorgen
    from tileviz.testing.views import FAMILY_SALT

    imgs: dict[str, np.ndarray] = {}
    meta: list[dict] = []
    for fam in families:
        for seed in range(n):
            rng = np.random.default_rng([seed, FAMILY_SALT[fam], 0])
            spec = floorgen.draw_floor(fam, rng)
            cx, cy, th = floorgen.draw_view(rng)
            imgs[f"v{len(meta)}"] = floorgen.render(spec, cx, cy, th, rng)
            meta.append({"family": fam, "ppm": spec.ppm, "tile": spec.tile_size})
    return imgs, meta


def main(argv: list[str] | None = None) -> int:
    from tileviz.testing import floorgen

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rev", action="append", required=True, help="a git revision (repeat)")
    ap.add_argument("--views", type=int, default=60, help="views per family")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--families", default=",".join(floorgen.FAMILIES))
    args = ap.parse_args(argv)
    families = args.families.split(",")
    with tempfile.TemporaryDirectory(prefix="tileviz-versions-") as tmp:
        t = Path(tmp)
        imgs, meta = views(families, args.views)
        np.savez(t / "views.npz", **imgs)  # type: ignore[arg-type]
        (t / "views.json").write_text(json.dumps(meta))
        trees = []
        for i, rev in enumerate(args.rev):
            tree = t / f"rev{i}"
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach",
                            str(tree), rev], check=True)
            trees.append(tree)
        times: list[list[list[float]]] = [[] for _ in args.rev]
        try:
            for r in range(args.rounds):
                order = list(range(len(args.rev)))
                if r % 2:
                    order.reverse()
                for i in order:
                    env = {**os.environ, "PYTHONPATH": str(trees[i])}
                    res = subprocess.run([sys.executable, "-c", TIMER, str(t / "views.npz"),
                                          str(t / "views.json")], env=env, check=True,
                                         capture_output=True, text=True)
                    times[i].append(json.loads(res.stdout.strip().splitlines()[-1]))
        finally:
            for tree in trees:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                                str(tree)], check=False)
    print(f"robust extractor, CPU ms per view (median over {args.views} clean views of each "
          f"family of the median of {args.rounds} rounds), ratio to {args.rev[0]}")
    print("| family | " + " | ".join(args.rev) + " |")
    print("|---|" + "---|" * len(args.rev))
    per_view = [[statistics.median(vals) for vals in zip(*runs, strict=True)] for runs in times]
    for fam in [*families, "all"]:
        idx = [k for k, m in enumerate(meta) if fam in ("all", m["family"])]
        meds = [statistics.median(pv[k] for k in idx) for pv in per_view]
        cells = [f"{m:.2f}" + ("" if i == 0 else f" ({m / meds[0]:.2f}x)")
                 for i, m in enumerate(meds)]
        print(f"| {fam} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
