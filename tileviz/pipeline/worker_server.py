"""Where the replay's vision workers come from (:mod:`tileviz.pipeline.workers`), in a module
that imports nothing heavy, so that the replay command can start their fork server first thing.

The workers are forked from a fork server that loads the vision code and the robust extractor's
compiled kernels once (:mod:`tileviz.pipeline.worker_start`); until it has, no worker can
start. :func:`start_worker_server` launches that server without waiting for
it; called before this process imports the vision, dataset and localizer code (the replay
command does), the server's loading runs on the other core while this process loads its own, and
the workers are forked as soon as both are done. What the workers compute is the same whenever
the server was started.

No viser, no pymunk, no numpy here.
"""

from __future__ import annotations

import multiprocessing
import os
from multiprocessing.context import BaseContext

__all__ = ["SERVER_PRELOAD", "default_jobs", "start_worker_server", "worker_context"]

SERVER_PRELOAD = "tileviz.pipeline.worker_start"
"""The module the fork server imports before it forks any worker."""


def default_jobs() -> int:
    """The default worker count: the cores this process may run on, at most 4 (beyond that the
    in-order localizer and the workers' start-up gain little)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(4, cores))


def worker_context() -> BaseContext:
    """The multiprocessing context of the vision workers: ``forkserver`` with
    :data:`SERVER_PRELOAD` loaded in the server before it forks (a fresh, single-threaded
    process: no fork of a process that runs OpenCV's or anyone's threads), else ``spawn``."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        # (takes effect when the server starts: at start_worker_server or the first pool)
        ctx.set_forkserver_preload([SERVER_PRELOAD])
        return ctx
    return multiprocessing.get_context("spawn")


def start_worker_server() -> bool:
    """Launch the workers' fork server of this process now, unless it runs already, and return
    at once (it loads :data:`SERVER_PRELOAD` in its own process meanwhile); True when this
    process has a fork server running after the call. The first replay with workers uses it
    (it would start it otherwise). Where there is no fork server (``spawn``), or when it cannot
    be launched, nothing happens: the replay starts its workers as it would have."""
    ctx = worker_context()
    if ctx.get_start_method() != "forkserver":
        return False
    from multiprocessing import forkserver

    try:
        forkserver.ensure_running()
    except OSError:  # an optimisation only: the replay's pool reports a real failure itself
        return False
    return True
