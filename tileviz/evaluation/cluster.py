"""Evaluation runs on a Dask distributed cluster (``tileviz evaluate --scheduler ...``).

``--scheduler tcp://host:8786`` connects to a running scheduler (started with Dask's own
``dask scheduler`` and ``dask worker`` commands, see docs/cluster.md); ``--scheduler local:N``
starts a local cluster of N worker processes (one thread each) for this campaign and closes it
after.

Each run is one task, :func:`tileviz.evaluation.simulate.run_one` on its
:class:`~tileviz.evaluation.simulate.Task`: the same function, the same seeds as ``--jobs``, so
every result but the CPU times is the same. Results are handed back in the order runs finish.
When a worker dies (killed, machine lost), the scheduler gives its runs to the other workers
(``distributed.scheduler.allowed-failures``: a run whose workers died more than
:data:`ALLOWED_FAILURES` times is given up, with an error naming it); each run's future completes
once, so each result is handed back once.

Before submitting, every worker is asked which tileviz it runs (version and a digest of the
package's source files): workers that cannot import tileviz, or run another version or other
code, are refused with one line (their results could differ). Workers that join later are not
checked. dask.distributed is an optional dependency (``pip install -e '.[cluster]'``); it is
imported only here.
"""

from __future__ import annotations

import logging
import signal
import threading
import uuid
from collections.abc import Callable, Sequence
from typing import Any

from tileviz.evaluation.simulate import RunResult, Task, run_one

__all__ = ["ALLOWED_FAILURES", "CONNECT_TIMEOUT_S", "ClusterError", "WORKER_WAIT_S",
           "parse_scheduler", "run_on_cluster", "tileviz_identity"]

CONNECT_TIMEOUT_S = 10.0
"""How long to try reaching a scheduler, seconds."""
WORKER_WAIT_S = 60.0
"""How long to wait for a first worker to join a scheduler that has none, seconds."""
ALLOWED_FAILURES = 5
"""Worker deaths a run may go through before it is given up."""


class ClusterError(ValueError):
    """A cluster problem to report in one line (unreachable scheduler, bad workers)."""


def parse_scheduler(text: str) -> tuple[str, int]:
    """``local:N`` -> ("local", N); ``tcp://host:port`` (or ``host:port``, tcp assumed) ->
    (address, 0). ClusterError naming the option otherwise."""
    t = text.strip()
    if t.startswith("local:"):
        try:
            n = int(t[len("local:"):])
        except ValueError:
            n = 0
        if n < 1:
            raise ClusterError(f"--scheduler {text}: local:N needs a worker count N >= 1")
        return "local", n
    if "://" not in t:
        t = "tcp://" + t
    rest = t.split("://", 1)[1]
    host, _, port = rest.rpartition(":")
    if not host or not port.isdigit():
        raise ClusterError(f"--scheduler {text}: expected tcp://host:port or local:N")
    return t, 0


def tileviz_identity() -> tuple[str, str] | None:
    """(version, sha256 of the package's .py and .json files) of the tileviz this process
    imports; None when it cannot import tileviz."""
    return _make_probe()()


def _make_probe() -> Callable[[], tuple[str, str] | None]:
    # a nested function: pickled by value, so a worker without tileviz can still run it
    def probe() -> tuple[str, str] | None:
        import hashlib
        import pathlib

        try:
            import tileviz
        except ImportError:
            return None
        root = pathlib.Path(tileviz.__file__).parent
        h = hashlib.sha256()
        for p in sorted([*root.rglob("*.py"), *root.rglob("*.json")]):
            h.update(p.relative_to(root).as_posix().encode())
            h.update(b"\0")
            h.update(p.read_bytes())
        return str(getattr(tileviz, "__version__", "?")), h.hexdigest()

    return probe


def _check_workers(client: Any, address: str) -> None:
    mine = tileviz_identity()
    assert mine is not None
    seen = client.run(_make_probe())
    for worker, ident in sorted(seen.items()):
        if ident is None:
            raise ClusterError(f"the Dask worker {worker} (scheduler {address}) cannot import "
                               f"tileviz: install this tileviz on every worker "
                               f"(pip install -e '.[cluster]')")
        if ident[0] != mine[0]:
            raise ClusterError(f"the Dask worker {worker} (scheduler {address}) runs tileviz "
                               f"{ident[0]}, this is {mine[0]}: install the same version on "
                               f"every worker")
        if ident[1] != mine[1]:
            raise ClusterError(f"the Dask worker {worker} (scheduler {address}) runs other "
                               f"tileviz code than this one (same version {mine[0]}, other "
                               f"files): install the same tileviz on every worker")


def _run_one_on_worker(task: Task) -> RunResult:
    """:func:`run_one` on a Dask worker, after the set-up of every tileviz entry point (OpenCV on
    :data:`tileviz.vision.OPENCV_THREADS` threads: the same observations as ``--jobs``)."""
    from tileviz.vision import set_opencv_threads

    set_opencv_threads()
    return run_one(task)


def run_on_cluster(
    tasks: Sequence[Task],
    scheduler: str,
    done: Callable[[RunResult], None],
    workers: Callable[[int], None] | None = None,
) -> None:
    """Make every task on the cluster ``scheduler`` (:func:`parse_scheduler`); call ``done``
    with each result as its run finishes (once per task) and ``workers`` with the cluster's
    worker count at the start and after each run. ClusterError (one line) when dask.distributed
    is missing, the scheduler cannot be reached, no worker joins within :data:`WORKER_WAIT_S`,
    or a worker runs other tileviz. KeyboardInterrupt cancels the runs not finished."""
    try:
        import dask
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise ClusterError("--scheduler needs dask.distributed: pip install -e '.[cluster]' "
                           "(or pip install 'dask[distributed]')") from None
    target, n = parse_scheduler(scheduler)
    # (a local cluster's workers get this configuration: no statistical profiler sampling the
    # runs' stacks)
    with dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
                          "distributed.worker.profile.enabled": False}):
        cluster = None
        client = None
        futures: list[Any] = []
        try:
            if target == "local":
                # the worker processes start with Ctrl-C ignored (inherited): the main process
                # alone handles it and closes the cluster, the workers print nothing (nor do
                # their logs of the heartbeats lost while the cluster closes)
                main = threading.current_thread() is threading.main_thread()
                old = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
                try:
                    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                           dashboard_address=":0", silence_logs=logging.CRITICAL)
                finally:
                    if main:
                        signal.signal(signal.SIGINT, old)
                address = cluster.scheduler_address
            else:
                address = target
            try:
                client = Client(address, timeout=CONNECT_TIMEOUT_S)
            except (OSError, TimeoutError) as e:
                raise ClusterError(f"cannot reach the Dask scheduler at {address}: "
                                   f"{_first_line(e)}") from None
            try:
                client.wait_for_workers(1, timeout=WORKER_WAIT_S)
            except TimeoutError:
                raise ClusterError(f"no Dask worker joined the scheduler at {address} within "
                                   f"{WORKER_WAIT_S:g} s") from None
            _check_workers(client, address)

            def count() -> int:
                return len(client.scheduler_info(n_workers=-1)["workers"])

            if workers:
                workers(count())
            token = uuid.uuid4().hex[:8]
            futures = [client.submit(_run_one_on_worker, t, pure=False,
                                     key=f"tileviz-{t.scenario}-r{t.run}-s{t.seed}-{token}")
                       for t in tasks]
            # on this client's event loop: by default as_completed follows the current Dask
            # client, and when that is another one (a caller's own client) a result lost with
            # its worker and awaited again raised "bound to a different event loop"
            for fut in as_completed(futures, loop=client.loop):
                done(fut.result())
                fut.release()
                if workers:
                    workers(count())
        except KeyboardInterrupt:
            if client is not None and futures:
                client.cancel(futures)
            raise
        finally:
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()


def _first_line(e: BaseException) -> str:
    text = str(e).strip().splitlines()
    return text[0] if text else type(e).__name__
