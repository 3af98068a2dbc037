"""What the soak found (issue 33, ``bench/soak.py``).

- viser's push can race its own event loop thread once in a long while ("deque mutated during
  iteration": it sets an asyncio.Event from the caller's thread while a client connects or
  leaves). Such a push is made again at the next push, without an error for the user; a push that
  keeps failing is said.
- Over an hour of clients coming and going, the heaps' free parts fragment and the resident set
  crept up while the memory in use did not: the server hands the free pages back."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tileviz.app import commands as C
from tileviz.app.server import App
from tileviz.app.session import SessionOptions
from tileviz.config import preset

HANG_S = 300.0
"""A hang guard only (a loaded machine may be slow)."""


@contextmanager
def _paused_server(tmp_path: Path) -> Iterator[App]:
    """The demo server, started paused (Step advances), stopped at the end of the block."""
    server = App(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True), port=0)
    server.start()
    try:
        yield server
    finally:
        server.stop()


def _until(cond: object) -> None:
    end = time.monotonic() + HANG_S
    while not cond():  # type: ignore[operator]
        assert time.monotonic() < end, "the loop did not get there"
        time.sleep(0.02)


def _failing(app: App, times: int) -> list[int]:
    """Make the next ``times`` pushes raise as viser's race does; returns the failures made."""
    real = app._push_inner
    failed: list[int] = []

    def push(plots: bool) -> None:
        if len(failed) < times:
            failed.append(1)
            raise RuntimeError("deque mutated during iteration")
        real(plots)

    app._push_inner = push  # type: ignore[method-assign]
    return failed


def test_a_push_that_fails_once_is_made_again_without_an_error(tmp_path: Path) -> None:
    with _paused_server(tmp_path) as app:
        failed = _failing(app, 1)
        app.submit(C.Step())
        _until(lambda: failed and "<b>frame 1</b>," in app.controls.status.content)
        assert not [n.text for n in app.session.notes if n.text.startswith("display:")]


def test_a_push_that_keeps_failing_is_said(tmp_path: Path) -> None:
    with _paused_server(tmp_path) as app:
        _keeps_failing(app)


def _keeps_failing(app: App) -> None:
    failed = _failing(app, 2)
    app.submit(C.Step())
    _until(lambda: len(failed) == 2 and any(n.text.startswith("display:")
                                            for n in app.session.notes))
    app.submit(C.Step())  # the loop goes on; the next frame shows, with the note
    _until(lambda: "<b>frame 2</b>," in app.controls.status.content)
    assert [n.text for n in app.session.notes if n.text.startswith("display:")] == [
        "display: deque mutated during iteration"]
    assert "deque mutated during iteration" in app.controls.status.content


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def test_the_server_hands_freed_heap_pages_back(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """160 MB of small blocks freed but for one in 50 (which keeps the heap from shrinking by
    itself): the server's process gives the free pages back."""
    import numpy as np

    import tileviz.app.server as server_module

    monkeypatch.setattr(server_module, "HEAP_TRIM_PERIOD", 0.2, raising=False)
    with _paused_server(tmp_path):
        blocks = [np.ones(500) for _ in range(40_000)]  # 4 kB each, from the heap
        kept = blocks[::50]
        held = _rss_mb()  # read before the free: the server may trim at any moment after it
        del blocks
        end = time.monotonic() + HANG_S
        while _rss_mb() > held - 80.0:
            assert time.monotonic() < end, f"RSS stays at {_rss_mb():.0f} MB ({held:.0f} held)"
            time.sleep(0.05)
        assert len(kept) == 800
