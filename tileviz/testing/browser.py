"""Headless chromium for the browser tests and the page benches: Debian's ``/usr/bin/chromium``
driven by Playwright (never ``playwright install``), software WebGL (SwiftShader, no GPU), and the
CPU time its processes use (Linux ``/proc``).
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["ARGS", "CHROMIUM", "COUNT_FRAMES", "chromium_pids", "cpu_seconds", "descendants"]

CHROMIUM = "/usr/bin/chromium"
"""Debian's chromium (``apt-get install chromium``; ``.ci/run`` installs it)."""
ARGS = ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--disable-component-update", "--no-first-run"]
"""chromium's options: headless, software WebGL, no background traffic."""

COUNT_FRAMES = """(ms) => new Promise((done) => {
    let n = 0; const t0 = performance.now();
    function tick(t) { n += 1; if (t - t0 < ms) requestAnimationFrame(tick);
                       else done([n, (performance.now() - t0) / 1000]); }
    requestAnimationFrame(tick);
})"""
"""Page script (``page.evaluate(COUNT_FRAMES, ms)``): the ``requestAnimationFrame`` callbacks over
``ms`` milliseconds, one per painted frame, and the seconds they spanned."""


def descendants(root: int) -> list[int]:
    """Pids of the processes below ``root``."""
    parent: dict[int, int] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                parent[int(d.name)] = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
    out, todo = [], [root]
    while todo:
        p = todo.pop()
        kids = [c for c, pp in parent.items() if pp == p]
        out += kids
        todo += kids
    return out


def chromium_pids() -> list[int]:
    """Pids of the chromium processes this process started."""
    return [q for q in descendants(os.getpid())
            if b"chrom" in Path(f"/proc/{q}/cmdline").read_bytes()[:200]]


def cpu_seconds(pids: list[int]) -> float:
    """User + system CPU seconds of ``pids`` so far (processes gone since count nothing)."""
    total = 0.0
    for pid in pids:
        try:
            f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
    return total
