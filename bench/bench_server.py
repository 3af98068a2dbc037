"""Throughput of the live server: loop frames/s with every stage image streamed, and the
scene updates a client receives per second.

    python bench/bench_server.py                          # websocket client, 20 s
    python bench/bench_server.py --seconds 20 --browser   # also a real chromium page
    python -m bench.bench_server --seconds 10 --write-figures

``serve.py`` runs in its own process (default preset, 320x240, display on: every frame's camera
view and stage images JPEG-encoded and kept in the history, the shown frame's streamed), pushing
at most ``--push-rate`` scene updates and ``--image-rate`` image updates a second. First at
``--max-speed`` (as fast as it can): a client speaking viser's websocket protocol measures, from
what it receives, the loop rate (the timeline's end advances one position per frame made), the
robot pose updates (one per push), the camera and the stage image updates; the server's CPU time
per frame is read from /proc. Then, with ``--browser``, a second server runs at
``--browser-speed`` (default 2x real time, 40 new frames a second: the loop at full speed would
take the CPU the software-rendered page needs on a small machine) and a headless Debian chromium
loads the page; the websocket messages it receives are decoded and counted the same way.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import subprocess
import tempfile
import time
from collections import Counter
from typing import Any

from tileviz.testing.browser import ARGS, CHROMIUM, cpu_seconds
from tileviz.testing.figures import Machine, write_block
from tileviz.testing.wsclient import ViserClient, decode_window, start_serve


def image_uuids(messages: list[dict[str, Any]]) -> dict[str, str]:
    """uuid -> "camera", "inset" or "stage" for the GUI images among ``messages``."""
    def kind(label: str) -> str:
        if label == "camera view":
            return "camera"
        return "inset" if label.startswith("the set around") else "stage"

    return {m["uuid"]: kind(str(m["props"].get("label") or ""))
            for m in messages if m.get("type") == "GuiImageMessage"}


def timeline_uuid(messages: list[dict[str, Any]]) -> str:
    return next(m["uuid"] for m in messages
                if m.get("type") == "GuiSliderMessage" and m["props"].get("label") == "Timeline")


def count(messages: list[dict[str, Any]], kinds: dict[str, str], timeline: str) -> Counter:
    """Robot pose updates, camera and stage image updates, and the timeline's largest end."""
    c: Counter = Counter()
    for m in messages:
        t = m.get("type")
        if t == "SetPositionMessage" and m.get("name") == "/robot":
            c["robot"] += 1
        elif t == "GuiUpdateMessage":
            u = m.get("updates", {})
            if "_data" in u:
                c[kinds.get(m.get("uuid"), "other")] += 1
            if m.get("uuid") == timeline and "max" in u:
                c["timeline_max"] = max(c["timeline_max"], int(u["max"]))
    return c


def last_timeline_max(messages: list[dict[str, Any]], timeline: str) -> int:
    best = 0
    for m in messages:
        if m.get("type") == "GuiUpdateMessage" and m.get("uuid") == timeline:
            best = max(best, int(m.get("updates", {}).get("max", 0)))
        if m.get("type") == "GuiSliderMessage" and m.get("uuid") == timeline:
            best = max(best, int(m["props"]["max"]))
    return best


async def ws_run(url: str, seconds: float) -> tuple[Counter, int, float, int]:
    async with ViserClient(url) as c:
        await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage")
        # the left panel sends the stages only when it shows them
        await c.send({"type": "GuiUpdateMessage", "uuid": c.gui_uuid("Below"),
                      "updates": {"value": "Camera and stages"}})
        await asyncio.sleep(3.0)  # warm up
        timeline = timeline_uuid(c.messages)
        kinds = image_uuids(c.messages)
        n0, t0 = len(c.messages), time.perf_counter()
        start = last_timeline_max(c.messages, timeline)
        await asyncio.sleep(seconds)
        n1, t1 = len(c.messages), time.perf_counter()
        got = count(c.messages[n0:n1], kinds, timeline)
        stages = sum(1 for v in kinds.values() if v == "stage")
        return got, got["timeline_max"] - start, t1 - t0, stages


PAGE_COUNTERS = """
(() => {
  // animation frames the page renders, counted inside the page (viser's websocket lives in a
  // web worker, so its messages are counted through devtools instead)
  const c = {frames: 0};
  window.__tileviz = c;
  const tick = () => { c.frames += 1; requestAnimationFrame(tick); };
  requestAnimationFrame(tick);
})();
"""
"""A counter the page keeps itself."""


def browser_run(url: str, seconds: float, viewport: tuple[int, int] = (1400, 900),
                ) -> tuple[Counter, float, int, dict[str, float]]:
    """What the page's own websocket receives while ``seconds`` pass, decoded and counted, and
    the animation frames the page rendered a second."""
    from playwright.sync_api import sync_playwright

    frames: list[tuple[bool, bytes]] = []
    recording = {"on": False}

    def on_ws(ws: Any) -> None:
        def on_frame(payload: object) -> None:
            if isinstance(payload, bytes):
                frames.append((recording["on"], payload))
        ws.on("framereceived", on_frame)

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})
        page.add_init_script(PAGE_COUNTERS)
        page.on("websocket", on_ws)
        page.goto(url)
        page.wait_for_selector("canvas", timeout=60_000)
        page.wait_for_timeout(3000)
        read = "() => ({...window.__tileviz, now: performance.now()})"
        c0 = page.evaluate(read)
        recording["on"] = True
        t0 = time.perf_counter()
        page.wait_for_timeout(seconds * 1000)
        recording["on"] = False
        span = time.perf_counter() - t0
        c1 = page.evaluate(read)
        browser.close()
    secs = (c1["now"] - c0["now"]) / 1e3
    inpage = {"frames": (c1["frames"] - c0["frames"]) / secs}
    before = [m for on, f in frames if not on for m in decode_window(f)]
    during = [m for on, f in frames if on for m in decode_window(f)]
    got = count(during, image_uuids(before), timeline_uuid(before))
    return got, span, sum(1 for on, _ in frames if on), inpage


def start_server(tmp: str, args: argparse.Namespace, speed: str) -> tuple[Any, str]:
    """``serve.py`` in its own process at ``speed`` (``max`` or a multiple of real time)."""
    cmd = ["--port", "0", "--out-dir", tmp, "--push-rate", str(args.push_rate),
           "--image-rate", str(args.image_rate), "--display" if args.display else "--no-display"]
    cmd += ["--max-speed"] if speed == "max" else ["--speed", speed]
    try:
        return start_serve(cmd, stderr=subprocess.DEVNULL)
    except RuntimeError as e:
        raise SystemExit(str(e)) from None


def stop_server(proc: Any) -> None:
    proc.terminate()
    proc.wait(timeout=30)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--push-rate", type=float, default=40.0)
    ap.add_argument("--image-rate", type=float, default=20.0)
    ap.add_argument("--browser", action="store_true", help="also measure a real chromium page")
    ap.add_argument("--browser-speed", default="2",
                    help="the server's speed while the browser is measured: x real time "
                    "(default 2: 40 new frames/s at dt = 0.05 s) or 'max'")
    ap.add_argument("--viewport", default="1400x900", help="browser page size, WxH pixels")
    ap.add_argument("--display", action=argparse.BooleanOptionalAction, default=True,
                    help="stream the stage images (default on)")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:server)")
    args = ap.parse_args()
    machine = Machine()
    with tempfile.TemporaryDirectory() as tmp:
        proc, url = start_server(tmp, args, "max")
        try:
            cpu0 = cpu_seconds([proc.pid])
            got, frames, span, stages = asyncio.run(ws_run(url, args.seconds))
            cpu = cpu_seconds([proc.pid]) - cpu0  # includes the 3 s warm-up
        finally:
            stop_server(proc)
        print(f"320x240, display {'on' if args.display else 'off'} ({stages} stage image "
              f"panels), push rate cap {args.push_rate:g}/s, image rate cap "
              f"{args.image_rate:g}/s, {span:.1f} s measured, "
              f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        print(f"loop at max speed: {frames / span:.1f} frames/s (simulate, render, vision "
              f"keeping its stages, localizer, JPEG-encode camera + stages, history)")
        per = cpu / (frames * (span + 3.0) / span)
        print(f"server CPU: {1e3 * per:.1f} ms a frame, all threads (loop, JPEG encoder, "
              f"viser sender), pushes included: {1.0 / per:.0f} frames/s on one free core")
        print(f"websocket client (server at max speed): {got['robot'] / span:.1f} robot pose "
              f"updates/s, {got['camera'] / span:.1f} camera images/s, "
              f"{got['stage'] / span:.1f} stage images/s")
        rows = [("loop at max speed, every stage image kept", f"{frames / span:.0f} frames/s"),
                ("server CPU a frame, all threads", f"{1e3 * per:.1f} ms"),
                ("a websocket client receives: robot poses / camera / stage images",
                 f"{got['robot'] / span:.0f} / {got['camera'] / span:.0f} / "
                 f"{got['stage'] / span:.0f} a second")]
        if args.browser:
            proc, url = start_server(tmp, args, args.browser_speed)
            try:
                vw, vh = (int(v) for v in args.viewport.lower().split("x"))
                bgot, bspan, nframes, inpage = browser_run(url, args.seconds, (vw, vh))
            finally:
                stop_server(proc)
            print(f"chromium page ({vw}x{vh}, software WebGL; server at speed "
                  f"{args.browser_speed}): {bgot['robot'] / bspan:.1f} robot pose updates/s, "
                  f"{bgot['camera'] / bspan:.1f} camera images/s, "
                  f"{bgot['stage'] / bspan:.1f} stage images/s "
                  f"({nframes / bspan:.1f} websocket messages/s; load average "
                  f"{os.getloadavg()[0]:.1f})")
            print(f"  the page rendered {inpage['frames']:.1f} animation frames/s")
            rows += [(f"headless chromium receives (server at {args.browser_speed}x): robot "
                      "poses / camera / stage images",
                      f"{bgot['robot'] / bspan:.0f} / {bgot['camera'] / bspan:.0f} / "
                      f"{bgot['stage'] / bspan:.0f} a second"),
                     ("the page paints (software WebGL)", f"{inpage['frames']:.1f} frames/s")]
    if args.write_figures:
        write_block("server", "The live server's throughput", rows, machine=machine,
                    note=f"{args.seconds:g} s measured; push rate cap {args.push_rate:g}/s, "
                    f"image rate cap {args.image_rate:g}/s.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
