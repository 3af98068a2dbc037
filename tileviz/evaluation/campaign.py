"""Many evaluation runs, in this process or in a pool of worker processes (:func:`evaluate`)."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed

from tileviz.evaluation.scenarios import SCENARIOS
from tileviz.evaluation.simulate import RunResult, Task, run_one

__all__ = ["evaluate"]


def evaluate(
    scenarios: Sequence[str],
    *,
    runs: int,
    duration: float,
    jobs: int = 1,
    seed: int = 0,
    particles: int = 1000,
    mcl_inject: float = 0.0,
    mcl_sigma_scale: float = 0.5,
    progress: bool = True,
    on_result: Callable[[RunResult], None] | None = None,
) -> list[RunResult]:
    """Make every (scenario, run) in ``jobs`` processes (1 = in this process); results sorted by
    scenario (in the given order) then run. Run r uses simulator seed ``seed + r``."""
    for s in scenarios:
        if s not in SCENARIOS:
            raise ValueError(f"unknown scenario {s!r} (choose from {', '.join(SCENARIOS)})")
    if int(runs) != runs or runs < 1:
        raise ValueError(f"runs must be an integer >= 1, got {runs!r}")
    if int(jobs) != jobs or jobs < 1:
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    if not math.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration must be a finite number > 0, got {duration!r}")
    tasks = [Task(s, r, seed + r, duration, particles, mcl_inject, mcl_sigma_scale)
             for s in scenarios for r in range(runs)]
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), desc="evaluate", unit="run", disable=not progress,
               file=sys.stderr, dynamic_ncols=True)
    results: list[RunResult] = []
    try:
        if jobs <= 1:
            for task in tasks:
                results.append(run_one(task))
                if on_result:
                    on_result(results[-1])
                bar.update(1)
        else:
            import multiprocessing

            ctx = multiprocessing.get_context("spawn")
            # (OpenCV runs on one thread in each worker: importing tileviz.vision sets it)
            with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
                futures = [pool.submit(run_one, t) for t in tasks]
                for fut in as_completed(futures):
                    results.append(fut.result())
                    if on_result:
                        on_result(results[-1])
                    bar.update(1)
    finally:
        bar.close()
    rank = {s: i for i, s in enumerate(scenarios)}
    results.sort(key=lambda r: (rank[r.scenario], r.run))
    return results
