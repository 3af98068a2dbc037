"""How many frames a second headless Chromium paints the live page, with software WebGL
(SwiftShader, no GPU), at the server's default settings.

    python bench/bench_page.py [--seconds 10] [--warmup 8]
                               [--bare [--box env|noenv] [--moving]] [-- serve options...]

``serve.py`` runs in its own process (default preset, playing in real time, default options or
the ones after ``--``); Debian's chromium (1400x900) opens the page, waits ``--warmup`` seconds,
then counts ``requestAnimationFrame`` callbacks over ``--seconds`` (the browser calls one per
frame it paints; a page busy decoding messages or rendering paints fewer). ``--bare``: the same
count on an empty viser page (a grid only; ``--box``: one lit box, with or without viser's
environment map; ``--moving``: the box moves 20 times a second, as the live page's scene does),
for comparison. viser draws on demand: a page whose scene does not change draws nothing and the
browser paints its idle frames cheaply, while every scene update makes it draw for the next
quarter second, so a scene updated 20 times a second is drawn continuously and the rate is what
one drawing of the scene costs. Also the CPU time all chromium
processes used per painted frame (a figure less sensitive to other load than the rate). The
rate depends on the machine and its load: run it on an idle machine, read it as a rough number.
"""

from __future__ import annotations

import argparse
import math
import threading
import time

from tileviz.testing.browser import ARGS, CHROMIUM, COUNT_FRAMES, chromium_pids, cpu_seconds
from tileviz.testing.figures import Machine, write_block
from tileviz.testing.wsclient import start_serve, stop_serve


def paint_rate(url: str, seconds: float, warmup: float) -> tuple[float, float]:
    """Frames painted a second, and the browser's CPU seconds (every chromium process) per
    painted frame, over ``seconds`` after ``warmup``."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.goto(url)
        page.wait_for_selector("canvas", timeout=120_000)
        page.wait_for_timeout(warmup * 1000)
        pids = chromium_pids()
        c0 = cpu_seconds(pids)
        n, span = page.evaluate(COUNT_FRAMES, seconds * 1000)
        cpu = cpu_seconds(pids) - c0
        browser.close()
    return n / span, cpu / max(n, 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--warmup", type=float, default=8.0)
    ap.add_argument("--bare", action="store_true", help="an empty viser page instead")
    ap.add_argument("--box", choices=("env", "noenv"), default=None,
                    help="with --bare: one lit box instead of the grid, with viser's default "
                    "environment map (image-based lighting) or without it")
    ap.add_argument("--moving", action="store_true",
                    help="with --bare --box: the box moves 20 times a second")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figure into docs/figures.md (figures:page, "
                    "figures:page_bare with --bare)")
    ap.add_argument("serve", nargs="*", help="serve.py options (after --)")
    args = ap.parse_args()
    machine = Machine()
    if args.bare:
        import viser

        server = viser.ViserServer(port=0, verbose=False)
        if args.box is None:
            server.scene.add_grid("/grid")
        else:
            server.scene.configure_default_lights(enabled=True, cast_shadow=False)
            if args.box == "noenv":
                server.scene.configure_environment_map(None)
            box = server.scene.add_box("/box", color=(200, 100, 100),
                                       dimensions=(0.5, 0.3, 0.1))
        stop = threading.Event()

        def move() -> None:
            k = 0
            while not stop.wait(0.05):
                k += 1
                box.position = (0.5 * math.sin(k / 20.0), 0.0, 0.0)

        if args.moving and args.box is not None:
            threading.Thread(target=move, daemon=True).start()
        try:
            rate, cpu = paint_rate(f"http://127.0.0.1:{server.get_port()}/", args.seconds,
                                   args.warmup)
        finally:
            stop.set()
            server.stop()
        what = "a grid" if args.box is None else (
            f"one box, {args.box}{', moving 20 times a second' if args.moving else ''}")
        print(f"bare viser page ({what}): {rate:.1f} frames painted a second, browser CPU "
              f"{1e3 * cpu:.0f} ms a painted frame")
        if args.write_figures:
            write_block("page_bare", "Headless chromium painting a bare viser page",
                        [(f"bare viser page, {what}", f"{rate:.1f} frames/s, "
                          f"{1e3 * cpu:.0f} ms browser CPU a frame")], machine=machine)
        return
    proc, url = start_serve(["--port", "0", *args.serve])
    try:
        t0 = time.perf_counter()
        rate, cpu = paint_rate(url, args.seconds, args.warmup)
        wall = time.perf_counter() - t0
    finally:
        stop_serve(proc)
    print(f"tileviz page ({' '.join(args.serve) or 'default options'}): {rate:.1f} frames "
          f"painted a second, browser CPU {1e3 * cpu:.0f} ms a painted frame (over "
          f"{args.seconds:g} s after {args.warmup:g} s; {wall:.0f} s in all)")
    if args.write_figures:
        write_block("page", "Headless chromium painting the live page", [
            (f"live page, {' '.join(args.serve) or 'default options'}",
             f"{rate:.1f} frames/s, {1e3 * cpu:.0f} ms browser CPU a frame")],
            machine=machine, note="1400x900, software WebGL (SwiftShader), playing in real time.")


if __name__ == "__main__":
    main()
