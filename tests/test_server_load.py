"""The server under load (issue 7): 20 websocket clients connect and disconnect again and again
for 60 s while the loop runs; the loop goes on making frames, nothing fails, a new client is
served. (No rate is asserted: the machine is shared; ``bench/bench_server.py`` measures it.)"""

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

# The clients run in their own process, as browsers would: they must not share the server's GIL.
LOAD = """
import asyncio, sys, time
from tests.wsclient import ViserClient

async def churn(url, until):
    n = 0
    while time.monotonic() < until:
        async with ViserClient(url) as c:
            await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage", timeout=60)
        n += 1
    return n

async def main(url, clients, seconds):
    until = time.monotonic() + seconds
    counts = await asyncio.gather(*(churn(url, until) for _ in range(clients)))
    print(sum(counts))

asyncio.run(main(sys.argv[1], int(sys.argv[2]), float(sys.argv[3])))
"""


def _frames(app: App, seconds: float) -> int:
    """Frames the loop made over ``seconds`` of wall time."""
    f0 = app.session.frames_computed
    time.sleep(seconds)
    return app.session.frames_computed - f0


@pytest.mark.slow
def test_twenty_clients_churning_for_a_minute(tmp_path: Path) -> None:
    # real time (20 frames/s): the pace a user sees; the loop must keep it under load
    app = App(preset("default"), SessionOptions(out_dir=tmp_path, speed=1.0), port=0)
    app.start()
    try:
        assert _frames(app, 2.0) > 0  # the loop runs
        env = dict(os.environ, PYTHONPATH=str(REPO))
        load = subprocess.Popen(
            [sys.executable, "-c", LOAD, app.url, str(CLIENTS), str(LOAD_SECONDS)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        )
        time.sleep(3.0)  # clients connecting
        loaded = _frames(app, LOAD_SECONDS - 6.0)
        out, err = load.communicate(timeout=LOAD_SECONDS + 120)
        assert load.returncode == 0, err[-2000:]
        connections = int(out.strip().splitlines()[-1])
        assert connections >= CLIENTS * 2  # each client came and went more than once
        assert loaded > 0  # the loop went on while the clients came and went
        assert app.session.errors == 0, list(app.session.notes)

        async def new_client() -> bool:
            async with ViserClient(app.url) as c:
                await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage", timeout=60)
                return any(m.get("type") == "GuiUpdateMessage" for m in c.messages) or bool(
                    c.messages)

        assert asyncio.run(new_client())
    finally:
        app.stop()
