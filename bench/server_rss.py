"""Memory of the live server over a long run: RSS at start and end.

    python bench/server_rss.py --minutes 10

Starts ``serve.py`` at real-time speed with every stage image streamed, samples its resident
set size (from /proc) every 30 s, prints the samples and the growth after the history is full.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

from tileviz.testing import REPO


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--port", type=int, default=8093)
    args = ap.parse_args()
    proc = subprocess.Popen([sys.executable, str(REPO / "serve.py"), "--port", str(args.port),
                             "--out-dir", "/tmp/tileviz-rss"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        t0 = time.monotonic()
        samples = []
        while time.monotonic() - t0 < args.minutes * 60:
            time.sleep(30)
            samples.append((time.monotonic() - t0, rss_mb(proc.pid)))
            print(f"t={samples[-1][0]:6.0f} s  RSS {samples[-1][1]:7.1f} MB", flush=True)
        # 2000 frames of history fill in 100 s at real time; growth after that is a leak
        after = [s for s in samples if s[0] >= 120]
        if len(after) >= 2:
            print(f"RSS at {after[0][0]:.0f} s: {after[0][1]:.1f} MB; at the end: "
                  f"{after[-1][1]:.1f} MB; growth {after[-1][1] - after[0][1]:+.1f} MB")
    finally:
        proc.terminate()
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
