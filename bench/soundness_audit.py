"""The long adversarial soundness run: >= 1e5 frames of runs that respect every declared
bound at its nastiest, the truth in exact arithmetic, every frame's predicted set, updated set and
written hull checked (``tileviz/testing/adversary.py`` describes the adversary; the test suite
runs a few hundred frames of it, ``tests/test_soundness_adversarial.py``).

    nice -n 10 python bench/soundness_audit.py                 # 1e5 frames, 20 per run
    python bench/soundness_audit.py --frames 2000 --seed 7     # a quick look

Prints frames, runs (cases), membership checks, violations (each with its class, seed and frame)
and the time taken; exit status 1 when any violation was found.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter

from tileviz.testing.adversary import KINDS, RandomChooser, run, scenario


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100_000, help="at least this many frames")
    ap.add_argument("--per-run", type=int, default=20, help="frames per run")
    ap.add_argument("--seed", type=int, default=0, help="first seed")
    args = ap.parse_args()
    t0 = time.perf_counter()
    frames = checks = runs = 0
    statuses: Counter[str] = Counter()
    per_kind: Counter[str] = Counter()
    violations: list[str] = []
    seed = args.seed
    while frames < args.frames:
        for kind in KINDS:
            rep = run(scenario(RandomChooser(seed), kind, args.per_run))
            runs += 1
            frames += rep.frames
            checks += rep.checks
            statuses.update(rep.statuses)
            per_kind[kind] += rep.frames
            violations += [f"seed {seed}: {v}" for v in rep.violations]
            seed += 1
        if runs % 400 == 0:
            print(f"  {frames} frames, {len(violations)} violations, "
                  f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)
    dt = time.perf_counter() - t0
    print(f"soundness audit: {frames} frames in {runs} runs ({args.per_run} frames each, seeds "
          f"{args.seed}..{seed - 1}), {checks} membership checks (predicted, updated, hull), "
          f"{len(violations)} violations, {dt:.0f} s ({dt / max(frames, 1) * 1e3:.1f} ms/frame)")
    print("frames per class: " + ", ".join(f"{k} {per_kind[k]}" for k in KINDS))
    print("statuses: " + ", ".join(f"{k} {v}" for k, v in statuses.most_common()))
    for v in violations[:20]:
        print("  " + v)
    return 1 if violations else 0


if __name__ == "__main__":
    raise SystemExit(main())
