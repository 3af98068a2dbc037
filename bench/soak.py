"""The demo server for a long time under clients that come and go (issue 33): memory, loop rate,
errors.

    python bench/soak.py --minutes 60
    python bench/soak.py --minutes 5 --clients 4 --no-browser

The server (:class:`tileviz.app.server.App`, the default preset at real time: 20 frames/s nominal,
every stage image streamed) runs in this process. In another process ``--clients`` websocket clients
(``tileviz.testing.wsclient``) each connect, wait for the whole scene, press buttons at random
(Play/Pause, Step, Step back, Go live, Reset the run, Kidnap, Start/Stop recording, Export MCAP,
Relocalize) and disconnect, again and again. In a third, one real headless chromium (Playwright,
``/usr/bin/chromium``) keeps the page open, clicks Step, Play/Pause and Go live and reloads the page
now and then. The bench itself presses Play when the run has stayed paused for 20 s (a client's
Pause otherwise stops the loop for the rest of the soak) and deletes recordings older than 3 minutes
(the disk would fill).

Every 10 s it samples the process's resident set size (VmRSS), the frames the loop advanced while
playing and the seconds it played (to 0.1 s), the loop thread's CPU time and what went wrong;
every minute it prints a line. At the end: RSS after
minute 5 and at the end (growth; also the least-squares slope over that span), the loop rate
(frames per second while playing, and loop CPU milliseconds per frame) over minutes 5-10 and the
last 5 minutes (the history, 2000 frames, has filled by minute 5; for runs under 15 minutes the
second fifth and the last fifth of the run), and the errors:
frames that failed, loop exceptions, failed recordings or exports, tracebacks printed by any
thread, commands dropped, client and browser failures. Refusals of a button pressed at the wrong
moment (Export MCAP with nothing recorded) are counted apart: they are the answer a user gets.
``--json FILE`` writes the samples and the summary. ``--tracemalloc``: Python's allocations are
traced from the end of the settling span (minute 5) on; the summary then lists the source lines
whose live allocations grew most from half a span later (minute 7.5) to the end (a leak in Python
code shows there; a resident set that grows while they do not is the C heaps'). Tracing slows the
loop: its rate is then no figure.
"""

from __future__ import annotations

import argparse
import asyncio
import ctypes
import gc
import io
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import tracemalloc
from pathlib import Path
from typing import Any

from tileviz.testing.browser import ARGS as CHROMIUM_ARGS
from tileviz.testing.browser import CHROMIUM

BUTTONS = {  # label -> weight of a random press
    "Play|Pause": 6, "Step": 4, "Step back": 2, "Go live": 2, "Reset the run": 1,
    "Kidnap (teleport the robot)": 2, "Start recording|Stop recording": 2, "Export MCAP": 1,
    "Relocalize (tell the true pose)": 1,
}
REFUSALS = ("nothing to export", "already running", "already recording", "nothing recorded",
            "is not recorded", "cannot be used")
"""Words of the notes that answer a button pressed at the wrong moment (not errors)."""


# --------------------------------------------------------------------------- the clients' process
async def _client(url: str, until: float, rng: random.Random, stats: dict[str, Any]) -> None:
    from tileviz.testing.wsclient import ViserClient

    while time.monotonic() < until:
        try:
            async with ViserClient(url) as c:
                await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage", timeout=300)
                stats["connects"] += 1
                uuids: dict[str, str] = {}
                for key in BUTTONS:
                    for label in key.split("|"):
                        try:
                            uuids[key] = c.gui_uuid(label, "GuiButtonMessage")
                            break
                        except KeyError:
                            continue
                keys = [k for k in BUTTONS if k in uuids]
                for _ in range(rng.randint(1, 10)):
                    key = rng.choices(keys, [BUTTONS[k] for k in keys])[0]
                    await c.send({"type": "GuiUpdateMessage", "uuid": uuids[key],
                                  "updates": {"value": True}})
                    stats["presses"] += 1
                    await asyncio.sleep(rng.uniform(0.1, 3.0))
        except Exception as e:  # noqa: BLE001 - counted and reported
            stats["failures"] += 1
            stats["last_failure"] = f"{type(e).__name__}: {e}"[:200]
        await asyncio.sleep(rng.uniform(0.0, 2.0))


async def _clients(url: str, n: int, seconds: float, seed: int) -> None:
    until = time.monotonic() + seconds
    stats: dict[str, Any] = {"connects": 0, "presses": 0, "failures": 0, "last_failure": ""}

    async def report() -> None:
        while True:
            print(json.dumps(stats), flush=True)
            await asyncio.sleep(10)

    reporter = asyncio.create_task(report())
    await asyncio.gather(*(_client(url, until, random.Random(seed + i), stats)
                           for i in range(n)))
    reporter.cancel()
    print(json.dumps(stats), flush=True)


# --------------------------------------------------------------------------- the browser's process
def _browser(url: str, seconds: float, seed: int) -> None:
    from playwright.sync_api import sync_playwright

    rng = random.Random(seed)
    stats: dict[str, Any] = {"loads": 0, "clicks": 0, "page_errors": 0, "failures": 0,
                             "last_failure": ""}
    until = time.monotonic() + seconds
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.set_default_timeout(300_000)

        def page_error(err: object) -> None:
            stats["page_errors"] += 1
            stats["last_failure"] = f"page error: {err}"[:200]

        page.on("pageerror", page_error)
        last = 0.0
        while time.monotonic() < until:
            try:
                if stats["loads"] == 0 or rng.random() < 0.15:
                    page.goto(url)
                    page.get_by_text("frame ").first.wait_for(timeout=300_000)
                    stats["loads"] += 1
                else:
                    name = rng.choice(["Step", "Play", "Pause", "Go live"])
                    button = page.get_by_role("button", name=name, exact=True)
                    if button.count():
                        button.click()
                        stats["clicks"] += 1
            except Exception as e:  # noqa: BLE001 - counted and reported
                stats["failures"] += 1
                stats["last_failure"] = f"{type(e).__name__}: {e}"[:200]
            time.sleep(rng.uniform(2.0, 15.0))
            if time.monotonic() - last >= 10:
                print(json.dumps(stats), flush=True)
                last = time.monotonic()
        browser.close()
    print(json.dumps(stats), flush=True)


# --------------------------------------------------------------------------- the server's process
class _Tee(io.TextIOBase):
    """stderr that counts tracebacks (any thread's) and keeps the last one's first lines."""

    def __init__(self, real: Any) -> None:
        self.real = real
        self.tracebacks = 0
        self.last: list[str] = []
        self._lock = threading.Lock()

    def write(self, text: str) -> int:
        with self._lock:
            if "Traceback (most recent call last)" in text:
                self.tracebacks += 1
                self.last = []
            if len(self.last) < 40:
                self.last.append(text)
        return self.real.write(text)

    def flush(self) -> None:
        self.real.flush()


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
        "fordblks", "keepcost")]


def _heap_mb() -> tuple[float, float]:
    """(bytes in use, bytes free but kept) of glibc's allocator over all arenas, MB; NaN where
    there is no mallinfo2 (not glibc, or older than 2.33)."""
    try:
        fn = ctypes.CDLL(None).mallinfo2
    except (OSError, AttributeError):
        return float("nan"), float("nan")
    fn.restype = _Mallinfo2
    m = fn()
    return (m.uordblks + m.hblkhd) / 2**20, m.fordblks / 2**20


def _viser_messages(app: Any) -> int:
    """Messages viser keeps to replay to a new client (its scene and GUI state)."""
    ws = getattr(app.server, "_websock_server", None)
    buf = getattr(ws, "_broadcast_buffer", None)
    return len(getattr(buf, "message_from_id", {}))


def _thread_cpu_s(tid: int) -> float:
    fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class _Lines:
    """The last JSON line a child process printed (read on a thread)."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.proc = proc
        self.last: dict[str, Any] = {}
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            try:
                self.last = json.loads(line)
            except ValueError:
                continue


def _window_rates(samples: list[dict[str, Any]], t0: float, t1: float) -> tuple[float, float]:
    """(frames per second of playing time, loop CPU ms per frame) between the first sample at
    or after ``t0`` and the last at or before ``t1``."""
    inside = [x for x in samples if t0 <= x["t"] <= t1]
    if len(inside) < 2:
        return float("nan"), float("nan")
    a, b = inside[0], inside[-1]
    frames = b["advanced"] - a["advanced"]
    playing = b["playing_s"] - a["playing_s"]
    if frames <= 0 or playing <= 0:
        return float("nan"), float("nan")
    return frames / playing, 1e3 * (b["loop_cpu_s"] - a["loop_cpu_s"]) / frames


def _slope_mb_per_h(points: list[tuple[float, float]]) -> float:
    if len(points) < 2:
        return float("nan")
    n = len(points)
    mx = sum(t for t, _ in points) / n
    my = sum(v for _, v in points) / n
    var = sum((t - mx) ** 2 for t, _ in points)
    return 3600.0 * sum((t - mx) * (v - my) for t, v in points) / var if var else float("nan")


def _clean_recordings(out_dir: Path, keep: set[Path], older_than: float) -> None:
    now = time.time()
    for p in out_dir.iterdir():
        base = p.with_suffix("") if p.suffix == ".mcap" else p
        if base in keep or p in keep:
            continue
        try:
            if now - p.stat().st_mtime > older_than:
                shutil.rmtree(p) if p.is_dir() else p.unlink()
        except OSError:
            continue


def _traced_growth(before: tracemalloc.Snapshot, after: tracemalloc.Snapshot,
                   top: int = 12) -> list[str]:
    """The source lines whose live traced allocations grew most between the two snapshots."""
    keep = [tracemalloc.Filter(False, tracemalloc.__file__)]
    diff = after.filter_traces(keep).compare_to(before.filter_traces(keep), "lineno")
    total = sum(d.size_diff for d in diff)
    lines = [f"traced Python allocations: {total / 2**20:+.2f} MB from the first snapshot to "
             f"the end over {len(diff)} source lines; the largest changes:"]
    for d in sorted(diff, key=lambda d: -abs(d.size_diff))[:top]:
        frame = d.traceback[0]
        lines.append(f"  {d.size_diff / 2**10:+9.1f} kB {d.count_diff:+7d} blocks "
                     f"(now {d.size / 2**10:9.1f} kB) {frame.filename}:{frame.lineno}")
    return lines


def soak(minutes: float, clients: int, browser: bool, seed: int, json_out: str | None,
         trace: bool = False) -> int:
    from tileviz.app import commands as C
    from tileviz.app.server import App
    from tileviz.app.session import Session, SessionOptions
    from tileviz.config import preset

    tee = _Tee(sys.stderr)
    sys.stderr = tee
    advanced = [0]
    real_advance = Session.advance

    def advance(self: Session) -> bool:
        playing = self.playing  # the loop's frames, not a Step's
        ok = real_advance(self)
        advanced[0] += bool(ok and playing)
        return ok

    Session.advance = advance  # type: ignore[method-assign]
    seen_notes: dict[str, int] = {}
    real_note = Session.note

    def note(self: Session, text: str, level: str = "info") -> None:
        if level == "error":
            key = text[:120]
            seen_notes[key] = seen_notes.get(key, 0) + 1
        real_note(self, text, level)

    Session.note = note  # type: ignore[method-assign]
    seconds = minutes * 60.0
    tmp = Path(tempfile.mkdtemp(prefix="tileviz-soak-"))
    out_dir = tmp / "runs"
    app = App(preset("default"), SessionOptions(out_dir=out_dir), port=0)
    app.start()
    s = app.session
    assert s is not None and app._thread is not None
    tid = app._thread.native_id
    assert tid is not None
    me = str(Path(__file__).resolve())
    procs = [_Lines(subprocess.Popen(
        [sys.executable, me, "--role", "clients", "--url", app.url, "--seconds", str(seconds),
         "--clients", str(clients), "--seed", str(seed)],
        stdout=subprocess.PIPE, text=True))]
    if browser:
        procs.append(_Lines(subprocess.Popen(
            [sys.executable, me, "--role", "browser", "--url", app.url, "--seconds",
             str(seconds), "--seed", str(seed + 1000)],
            stdout=subprocess.PIPE, text=True)))
    samples: list[dict[str, Any]] = []
    start = time.monotonic()
    playing_s = [0.0]
    done = threading.Event()

    def clock() -> None:  # seconds of playing, to 0.1 s
        last = time.monotonic()
        while not done.wait(0.1):
            now = time.monotonic()
            if s.playing:
                playing_s[0] += now - last
            last = now

    threading.Thread(target=clock, daemon=True).start()
    paused_since: float | None = None
    next_print = 60.0
    objects = len(gc.get_objects())
    settle = 300.0 if seconds >= 900 else seconds / 5
    snapshot: tracemalloc.Snapshot | None = None
    traced: list[str] = []
    try:
        while (now := time.monotonic() - start) < seconds:
            time.sleep(10.0)
            now = time.monotonic() - start
            if not s.playing:
                paused_since = paused_since if paused_since is not None else now
                if now - paused_since >= 20.0:
                    app.submit(C.Play())
                    paused_since = None
            else:
                paused_since = None
            rec = s.recorder
            keep = {p for p in (rec.path, rec.last, rec.pending,
                                rec.export.dataset if rec.export else None) if p is not None}
            if out_dir.is_dir():
                _clean_recordings(out_dir, keep, 180.0)
            refusals = sum(n for k, n in seen_notes.items() if any(r in k for r in REFUSALS))
            if len(samples) % 6 == 0:  # once a minute: the objects Python holds
                objects = len(gc.get_objects())
            in_use, kept = _heap_mb()
            if trace and not tracemalloc.is_tracing() and snapshot is None and now >= settle:
                tracemalloc.start(1)
            if trace and snapshot is None and now >= settle + settle / 2:
                # what lives from here on (what tracing saw allocated and still held is in it)
                snapshot = tracemalloc.take_snapshot()
            sample: dict[str, Any] = {
                "t": now, "rss_mb": _rss_mb(), "advanced": advanced[0],
                "playing_s": playing_s[0],
                "loop_cpu_s": _thread_cpu_s(tid), "frames_failed": s.errors,
                "error_notes": sum(seen_notes.values()) - refusals, "refusals": refusals,
                "tracebacks": tee.tracebacks, "dropped": app.dropped,
                "loop_alive": app.running, "heap_in_use_mb": in_use, "heap_free_mb": kept,
                "python_objects": objects, "viser_messages": _viser_messages(app),
                "threads": threading.active_count(),
                "traced_mb": (tracemalloc.get_traced_memory()[0] / 2**20
                              if tracemalloc.is_tracing() else None),
                "clients": procs[0].last, "browser": procs[1].last if browser else {},
            }
            samples.append(sample)
            if now >= next_print or now >= seconds:
                next_print += 60.0
                c = sample["clients"]
                b = sample["browser"]
                print(f"{now / 60:5.1f} min  RSS {sample['rss_mb']:7.1f} MB (heap in use "
                      f"{in_use:6.1f}, free {kept:6.1f}; {objects} objects, "
                      f"{sample['viser_messages']} viser messages, {sample['threads']} threads)"
                      f"  frames "
                      f"{sample['advanced']:7d}  loop CPU {sample['loop_cpu_s']:7.1f} s  "
                      f"errors {sample['frames_failed'] + sample['error_notes']}"
                      f"+{sample['tracebacks']} tb  refusals {refusals}  clients "
                      f"{c.get('connects', 0)} conn {c.get('presses', 0)} presses "
                      f"{c.get('failures', 0)} failed  browser {b.get('loads', 0)} loads "
                      f"{b.get('clicks', 0)} clicks {b.get('failures', 0)} failed "
                      f"{b.get('page_errors', 0)} page errors", flush=True)
            if not app.running:
                print("the loop thread stopped", flush=True)
                break
        if snapshot is not None:
            traced = _traced_growth(snapshot, tracemalloc.take_snapshot())
            tracemalloc.stop()
    finally:
        done.set()
        for p in procs:
            p.proc.wait(timeout=600)
        app.stop()
        sys.stderr = tee.real
        shutil.rmtree(tmp, ignore_errors=True)
    return _summary(samples, seconds, seen_notes, tee, procs, json_out, traced)


def _summary(samples: list[dict[str, Any]], seconds: float, seen_notes: dict[str, int],
             tee: _Tee, procs: list[_Lines], json_out: str | None,
             traced: list[str]) -> int:
    if not samples:
        print("no samples")
        return 1
    end = samples[-1]["t"]
    window = 300.0 if seconds >= 900 else seconds / 5
    settle = 300.0 if seconds >= 900 else seconds / 5  # the history fills first
    first = _window_rates(samples, settle, settle + window)
    last = _window_rates(samples, end - window, end)
    after5 = [x for x in samples if x["t"] >= min(300.0, seconds / 3)]
    growth = after5[-1]["rss_mb"] - after5[0]["rss_mb"] if after5 else float("nan")
    slope = _slope_mb_per_h([(x["t"], x["rss_mb"]) for x in after5])
    fin = samples[-1]
    lines = [
        f"soak: {end / 60:.1f} min, {fin['advanced']} frames advanced",
        f"RSS: {samples[0]['rss_mb']:.1f} MB at {samples[0]['t']:.0f} s, "
        f"{after5[0]['rss_mb']:.1f} MB at {after5[0]['t'] / 60:.1f} min, "
        f"{fin['rss_mb']:.1f} MB at the end, max {max(x['rss_mb'] for x in samples):.1f} MB; "
        f"growth after {after5[0]['t'] / 60:.1f} min {growth:+.1f} MB "
        f"(least-squares slope {slope:+.1f} MB/h)",
        f"heap in use (glibc, all arenas): {after5[0]['heap_in_use_mb']:.1f} MB at "
        f"{after5[0]['t'] / 60:.1f} min, {fin['heap_in_use_mb']:.1f} MB at the end (free but "
        f"kept: {after5[0]['heap_free_mb']:.1f} -> {fin['heap_free_mb']:.1f} MB); Python "
        f"objects {after5[0]['python_objects']} -> {fin['python_objects']}; viser messages "
        f"kept {after5[0]['viser_messages']} -> {fin['viser_messages']}; threads "
        f"{after5[0]['threads']} -> {fin['threads']}",
        f"loop rate while playing: {first[0]:.2f} frames/s ({first[1]:.1f} ms loop CPU/frame) "
        f"over minutes {settle / 60:.1f}-{(settle + window) / 60:.1f}, {last[0]:.2f} frames/s "
        f"({last[1]:.1f} ms) over the last {window / 60:.1f}; end/start "
        f"{last[0] / first[0]:.3f}",
        f"errors: {fin['frames_failed']} frames failed, {fin['error_notes']} error notes, "
        f"{fin['tracebacks']} tracebacks, {fin['dropped']} commands dropped, loop "
        f"{'alive' if fin['loop_alive'] else 'STOPPED'}; refusals (answers to a press at the "
        f"wrong moment): {fin['refusals']}",
        f"clients: {json.dumps(procs[0].last)}",
    ]
    if len(procs) > 1:
        lines.append(f"browser: {json.dumps(procs[1].last)}")
    for text, n in sorted(seen_notes.items(), key=lambda kv: -kv[1])[:12]:
        lines.append(f"  note x{n}: {text}")
    lines += traced
    if tee.tracebacks:
        lines.append("last traceback: " + "".join(tee.last)[:2000])
    print("\n".join(lines), flush=True)
    if json_out:
        Path(json_out).write_text(json.dumps({"samples": samples, "summary": lines}, indent=1))
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--clients", type=int, default=4, help="websocket clients (default 4)")
    ap.add_argument("--no-browser", action="store_true", help="no chromium")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None, help="write the samples and the summary here")
    ap.add_argument("--tracemalloc", action="store_true",
                    help="trace Python's allocations after the settling span and list the "
                    "source lines that grew (slows the loop)")
    ap.add_argument("--role", choices=("server", "clients", "browser"), default="server",
                    help=argparse.SUPPRESS)
    ap.add_argument("--url", help=argparse.SUPPRESS)
    ap.add_argument("--seconds", type=float, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.role == "clients":
        asyncio.run(_clients(args.url, args.clients, args.seconds, args.seed))
        return 0
    if args.role == "browser":
        _browser(args.url, args.seconds, args.seed)
        return 0
    if not args.no_browser and not Path(CHROMIUM).exists():
        print(f"soak: no chromium at {CHROMIUM} (apt-get install chromium, or --no-browser)")
        return 2
    return soak(args.minutes, args.clients, not args.no_browser, args.seed, args.json,
                args.tracemalloc)


if __name__ == "__main__":
    raise SystemExit(main())
