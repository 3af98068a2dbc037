"""The live loop's frame rate with and without 20 websocket clients churning.

    python bench/server_load.py                    # 8 s unloaded, then 60 s of churn
    python bench/server_load.py --seconds 30 --clients 20

The server runs in this process at real time (20 frames/s nominal, the default preset); the
clients run in another process (as browsers would), each connecting, waiting for the whole scene
(ReplayDoneMessage) and leaving, again and again. Prints the loop's frames per second before and
during the churn, their ratio, and the connections served. ``tests/test_server_load.py`` checks
the behaviour (frames keep coming, none lost or repeated, every client served); the rates are
here because they depend on what else the machine is doing.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from tileviz.app.server import App
from tileviz.app.session import SessionOptions
from tileviz.config import preset
from tileviz.testing import churn


def rate(app: App, seconds: float) -> float:
    """Frames per second the loop made over ``seconds`` of wall time."""
    f0, t0 = app.session.history.last, time.monotonic()
    time.sleep(seconds)
    return (app.session.history.last - f0) / (time.monotonic() - t0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clients", type=int, default=20)
    ap.add_argument("--seconds", type=float, default=60.0, help="churn duration")
    ap.add_argument("--unloaded", type=float, default=8.0, help="unloaded measurement, s")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        app = App(preset("default"), SessionOptions(out_dir=Path(tmp), speed=1.0), port=0)
        app.start()
        try:
            time.sleep(2.0)
            unloaded = rate(app, args.unloaded)
            load = churn.start(app.url, args.clients, args.seconds, 1)
            time.sleep(3.0)  # clients connecting
            loaded = rate(app, max(1.0, args.seconds - 6.0))
            out, err = load.communicate()
            if load.returncode != 0:
                raise SystemExit(f"the clients failed: {err.strip()[-500:]}")
            connections = sum(int(c) for c in out.split())
            errors = app.session.errors
        finally:
            app.stop()
    print(f"loop: {unloaded:.1f} frames/s unloaded, {loaded:.1f} frames/s with {args.clients} "
          f"clients churning ({loaded / unloaded:.2f} of unloaded; nominal 20); "
          f"{connections} connections served; {errors} loop errors")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
