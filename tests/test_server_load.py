"""The server under load (issue 7): 20 websocket clients connect and disconnect again and again
for 60 s while the loop runs. What a user would notice, whatever else the machine is doing: the
loop keeps making frames, no frame is lost or repeated, nothing fails, every client is served
every time it connects, and a new client is served afterwards.

How fast the loop stays under this churn is a figure, not a test: ``bench/server_load.py``."""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.wsclient import ViserClient
from tileviz.app.server import App
from tileviz.app.session import SessionOptions
from tileviz.config import preset

REPO = Path(__file__).resolve().parents[1]
CLIENTS = 20
LOAD_SECONDS = 60.0
CYCLES = 2
"""Each client connects, is served and leaves at least this many times (however long it takes)."""
HANG_S = 1800.0
"""Guards against a hang only (the churn takes LOAD_SECONDS plus a few cycles on a busy machine)."""

# The clients run in their own process, as browsers would: they must not share the server's GIL.
# Each connection waits until the server has sent it the whole scene (ReplayDoneMessage).
LOAD = """
import asyncio, sys, time
from tests.wsclient import ViserClient

async def churn(url, until, cycles):
    n = 0
    while n < cycles or time.monotonic() < until:
        async with ViserClient(url) as c:
            await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage", timeout=600)
        n += 1
    return n

async def main(url, clients, seconds, cycles):
    until = time.monotonic() + seconds
    counts = await asyncio.gather(*(churn(url, until, cycles) for _ in range(clients)))
    print(" ".join(map(str, counts)))

asyncio.run(main(sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])))
"""


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
        env = dict(os.environ, PYTHONPATH=str(REPO))
        load = subprocess.Popen(
            [sys.executable, "-c", LOAD, app.url, str(CLIENTS), str(LOAD_SECONDS), str(CYCLES)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        )
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
