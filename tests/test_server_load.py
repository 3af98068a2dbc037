"""The server under load (issue 7): 20 websocket clients connect and disconnect again and again
for 60 s while the loop runs. What a user would notice, whatever else the machine is doing: the
loop keeps making frames, no frame is lost or repeated, nothing fails, every client is served
every time it connects, and a new client is served afterwards.

How fast the loop stays under this churn is a figure, not a test: ``bench/server_load.py``."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import pytest

from tileviz.app.server import App
from tileviz.app.session import SessionOptions
from tileviz.config import preset
from tileviz.testing import churn
from tileviz.testing.wsclient import ViserClient

REPO = Path(__file__).resolve().parents[1]
CLIENTS = 20
LOAD_SECONDS = 60.0
CYCLES = 2
"""Each client connects, is served and leaves at least this many times (however long it takes)."""
HANG_S = 1800.0
"""Guards against a hang only (the churn takes LOAD_SECONDS plus a few cycles on a busy machine)."""

def _check_history(app: App) -> tuple[int, int]:
    """Every frame kept is there once, in order, none skipped: the frame indices of positions
    first..last are consecutive and each metrics row belongs to its frame. Returns (first, last)
    frame index."""
    h = app.session.history
    first, last = h.first, h.last
    entries = [h.get(p) for p in range(first, last + 1)]
    indices = [e.index for e in entries]
    assert indices == list(range(indices[0], indices[0] + len(indices))), indices
    rows = h.window(last, last - first + 1)
    assert [r[0] for r in rows] == [e.record.t for e in entries]
    return indices[0], indices[-1]


@pytest.mark.slow
def test_twenty_clients_churning_for_a_minute(tmp_path: Path) -> None:
    # real time (20 frames/s): the pace a user sees
    app = App(preset("default"), SessionOptions(out_dir=tmp_path, speed=1.0), port=0)
    app.start()
    try:
        # the clients run in their own process, as browsers would (tileviz.testing.churn)
        load = churn.start(app.url, CLIENTS, LOAD_SECONDS, CYCLES)
        made = []  # the newest frame, sampled while the clients come and go
        while load.poll() is None:
            made.append(app.session.history.last)
            time.sleep(1.0)
        out, err = load.communicate(timeout=HANG_S)
        assert load.returncode == 0, err[-2000:]
        counts = [int(c) for c in out.split()]
        assert len(counts) == CLIENTS and min(counts) >= CYCLES  # every client served each time
        # the loop kept making frames through the churn, and kept them all, once each, in order
        assert made[-1] > made[0]
        assert made == sorted(made)
        _check_history(app)
        assert app.session.errors == 0, list(app.session.notes)
        before = app.session.history.last

        async def new_client() -> list[dict]:
            async with ViserClient(app.url) as c:
                await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage", timeout=600)
                return c.messages

        messages = asyncio.run(new_client())
        types = {m.get("type") for m in messages}
        # the newcomer got the controls, the camera image and the set's boxes, not a handshake
        assert {"GuiButtonMessage", "GuiImageMessage", "BoxMessage"} <= types
        while app.session.history.last <= before:  # and the loop still runs after the load
            time.sleep(0.2)
        _check_history(app)
        assert app.session.errors == 0, list(app.session.notes)
    finally:
        app.stop()
