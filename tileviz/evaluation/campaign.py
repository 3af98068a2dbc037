"""Many evaluation runs, in this process, in a pool of worker processes or on a Dask cluster
(:func:`evaluate`)."""

from __future__ import annotations

import math
import signal
import sys
from collections.abc import Callable, Collection, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed

from tileviz.evaluation.scenarios import SCENARIOS
from tileviz.evaluation.simulate import RunResult, Task, run_one

__all__ = ["evaluate"]


def _worker_init(threads: int) -> None:
    """A pool worker: Ctrl-C is left to the main process (which stops the campaign); OpenCV runs
    on the caller's thread count (:func:`tileviz.vision.set_opencv_threads`)."""
    from tileviz.vision import set_opencv_threads

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    set_opencv_threads(threads)


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
    fault_model: tuple[float, float] | None = None,
    progress: bool = True,
    on_result: Callable[[RunResult], object] | None = None,
    scheduler: str | None = None,
    skip: Collection[tuple[str, int, int]] = (),
) -> list[RunResult]:
    """Make every (scenario, run) but those in ``skip`` ((scenario, run, seed) keys) in this
    process (``jobs`` 1), a pool of ``jobs`` processes, or on the Dask cluster ``scheduler``
    (:mod:`tileviz.evaluation.cluster`; ``jobs`` is then unused); ``on_result`` gets each result
    as its run finishes. Returns the results made, sorted by scenario (in the given order) then
    run. Run r uses simulator seed ``seed + r``. ``fault_model``: the autonomous localizer's
    fault model (m/s, rad/s; None: the configuration's default; :class:`Task`). Ctrl-C
    (KeyboardInterrupt) stops the runs not finished and propagates; ``on_result`` has seen every
    finished one."""
    for s in scenarios:
        if s not in SCENARIOS:
            raise ValueError(f"unknown scenario {s!r} (choose from {', '.join(SCENARIOS)})")
    if int(runs) != runs or runs < 1:
        raise ValueError(f"runs must be an integer >= 1, got {runs!r}")
    if int(jobs) != jobs or jobs < 1:
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    if not math.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration must be a finite number > 0, got {duration!r}")
    skipped = set(skip)
    tasks = [Task(s, r, seed + r, duration, particles, mcl_inject, mcl_sigma_scale, fault_model)
             for s in scenarios for r in range(runs) if (s, r, seed + r) not in skipped]
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), desc="evaluate", unit="run", disable=not progress,
               file=sys.stderr, dynamic_ncols=True)
    results: list[RunResult] = []

    def done(res: RunResult) -> None:
        results.append(res)
        if on_result:
            on_result(res)
        bar.update(1)

    try:
        if not tasks:
            pass
        elif scheduler is not None:
            from tileviz.evaluation.cluster import run_on_cluster

            def workers(n: int) -> None:
                bar.set_postfix(workers=n, refresh=False)

            run_on_cluster(tasks, scheduler, done, workers)
        elif jobs <= 1:
            for task in tasks:
                done(run_one(task))
        else:
            import multiprocessing

            import cv2

            ctx = multiprocessing.get_context("spawn")
            # each worker runs OpenCV on this process's thread count (one, as the entry point set
            # it): the same observations whatever --jobs
            pool = ProcessPoolExecutor(max_workers=jobs, mp_context=ctx,
                                       initializer=_worker_init,
                                       initargs=(cv2.getNumThreads(),))
            bar.set_postfix(workers=jobs, refresh=False)
            interrupted = False
            try:
                futures = [pool.submit(run_one, t) for t in tasks]
                for fut in as_completed(futures):
                    done(fut.result())
            except KeyboardInterrupt:
                interrupted = True
                raise
            finally:
                # the runs in progress when interrupted are not waited for
                procs = list((getattr(pool, "_processes", None) or {}).values()) \
                    if interrupted else []
                pool.shutdown(wait=not interrupted, cancel_futures=True)
                for proc in procs:
                    proc.terminate()
    finally:
        bar.close()
    rank = {s: i for i, s in enumerate(scenarios)}
    results.sort(key=lambda r: (rank[r.scenario], r.run))
    return results
