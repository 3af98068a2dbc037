"""Websocket clients that connect to a viser server, wait for the whole scene and leave, again
and again, in a process of their own (as browsers would: they must not share the server's GIL).

    python -m tileviz.testing.churn URL CLIENTS SECONDS CYCLES

Each of CLIENTS clients connects, waits until the server has sent it the whole scene
(``ReplayDoneMessage``) and leaves, at least CYCLES times and until SECONDS have passed. Prints
the number of connections each client made, on one line. :func:`start` starts it.
"""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys
import time

from tileviz.testing import REPO

__all__ = ["churn", "main", "start"]


async def churn(url: str, until: float, cycles: int) -> int:
    """One client's connections (at least ``cycles``, until ``time.monotonic() >= until``)."""
    from tileviz.testing.wsclient import ViserClient

    n = 0
    while n < cycles or time.monotonic() < until:
        async with ViserClient(url) as c:
            await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage", timeout=600)
        n += 1
    return n


async def _all(url: str, clients: int, seconds: float, cycles: int) -> list[int]:
    until = time.monotonic() + seconds
    return list(await asyncio.gather(*(churn(url, until, cycles) for _ in range(clients))))


def start(url: str, clients: int, seconds: float, cycles: int) -> subprocess.Popen[str]:
    """This module's clients in their own process (stdout and stderr piped, text)."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.Popen(
        [sys.executable, "-m", "tileviz.testing.churn", url, str(clients), str(seconds),
         str(cycles)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def main(argv: list[str] | None = None) -> int:
    """The command line of the module docstring."""
    url, clients, seconds, cycles = argv if argv is not None else sys.argv[1:]
    counts = asyncio.run(_all(url, int(clients), float(seconds), int(cycles)))
    print(" ".join(map(str, counts)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
