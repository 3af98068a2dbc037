"""The benches' clock and the options they share.

Every bench reads its figures from :func:`clock` (``--clock``): ``wall`` is
``time.perf_counter``; ``cpu`` is this thread's CPU time (``time.thread_time``), which other jobs on
a shared machine do not inflate, and which holds all of OpenCV's work when OpenCV runs on one
thread (:func:`tileviz.vision.set_opencv_threads`, what every tileviz entry point does). Seconds.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

__all__ = ["CLOCKS", "add_clock", "clock", "parser", "use_clock"]

CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.thread_time}
"""The clocks ``--clock`` chooses from."""

_clock: Callable[[], float] = time.perf_counter


def clock() -> float:
    """The time on the chosen clock, seconds (``wall`` unless :func:`use_clock` said otherwise)."""
    return _clock()


def use_clock(name: str) -> None:
    """Read every later :func:`clock` from the clock ``name`` (a key of :data:`CLOCKS`)."""
    global _clock
    _clock = CLOCKS[name]


def add_clock(ap: argparse.ArgumentParser) -> None:
    """Add ``--clock wall|cpu`` to ``ap`` (apply it with :func:`use_clock`)."""
    ap.add_argument("--clock", choices=tuple(CLOCKS), default="wall",
                    help="wall: time.perf_counter; cpu: this thread's CPU time "
                    "(time.thread_time) with OpenCV on one thread, which a busy shared machine "
                    "does not inflate")


def parser(doc: str, frames: int = 200) -> argparse.ArgumentParser:
    """A parser described by ``doc``'s first paragraph with ``--frames`` (default ``frames``)
    and ``--clock``."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--frames", type=int, default=frames)
    add_clock(ap)
    return ap
