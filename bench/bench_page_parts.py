"""What each part of the live page costs headless Chromium with software WebGL: one server, one
browser, configurations measured in turn and interleaved (so the machine's load drifts over all of
them alike).

    python bench/bench_page_parts.py [--window 4] [--repeat 2] CONFIG [CONFIG ...]

A CONFIG is ``full``, ``bare`` (not the live page: a bare viser page whose one lit box moves 20
times a second, as ``bench/bench_page.py --bare --box noenv --moving`` measures it, loaded in the
same browser tab in turn with the live page: the reference to read the live page's rate against
under the same load) or ``+``-joined parts to leave out or change:
``hide-LAYER`` (a scene layer: floor, grid, robot, footprint, truth, prediction, boxes, wedge,
setpoint, path, trails, particles), ``show-LAYER`` (a layer that is off by default, e.g.
``show-floor``: the floor texture), ``no-images`` (camera and stage panels), ``no-inset``,
``no-status`` (the readouts and controls the loop refreshes), ``no-follow`` (the view does not
follow the robot), ``tex-N`` (with ``show-floor``: a floor texture of N pixels a side instead of
:data:`tileviz.app.scene.TEXTURE_PIXELS`). Example::

    python bench/bench_page_parts.py full bare show-floor hide-grid no-images+no-inset+no-status

For each configuration: frames painted a second and the CPU time of Chromium's GPU process (where
software WebGL draws) and of all its processes per painted frame, one figure per repeat. The
server plays the default preset in real time, as ``python serve.py`` does. Read the figures side
by side; on a loaded machine the rates of all configurations drop together.
"""

from __future__ import annotations

import argparse
import math
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tileviz.testing.browser import ARGS, CHROMIUM, COUNT_FRAMES, chromium_pids, cpu_seconds
from tileviz.testing.figures import Machine, fmt_range, write_block


def _kind(pid: int) -> str:
    """Chromium's process type of ``pid`` (``browser`` for the main process)."""
    try:
        m = re.search(rb"--type=([a-z-]+)", Path(f"/proc/{pid}/cmdline").read_bytes())
    except OSError:
        return "gone"
    return m.group(1).decode() if m else "browser"


class Parts:
    """Switches parts of a running :class:`tileviz.app.server.App` on and off."""

    def __init__(self, app: Any) -> None:
        self.app = app
        self.texture: int | None = None
        self.saved: dict[str, tuple[object, str, Callable[..., Any]]] = {
            "no-images": (app.panels, "show", app.panels.show),
            "no-inset": (app.inset, "show", app.inset.show),
            "no-status": (app.controls, "refresh", app.controls.refresh),
            "no-follow": (app, "_follow", app._follow),
        }

    def apply(self, config: str) -> None:
        from tileviz.app.scene import TEXTURE_PIXELS, floor_texture

        parts = set() if config == "full" else set(config.split("+"))
        unknown = {p for p in parts
                   if p not in self.saved and not p.startswith(("hide-", "show-", "tex-"))}
        if unknown:
            raise SystemExit(f"unknown part(s) {sorted(unknown)} in {config!r}")
        app = self.app
        for part, (obj, attr, fn) in self.saved.items():
            setattr(obj, attr, (lambda *a, **k: None) if part in parts else fn)
        hidden = {p[5:] for p in parts if p.startswith("hide-")}
        shown = {p[5:] for p in parts if p.startswith("show-")}
        tex = next((int(p[4:]) for p in parts if p.startswith("tex-")), TEXTURE_PIXELS)
        scene = app.scene
        with app.server.atomic():
            if tex != (self.texture or TEXTURE_PIXELS):
                half = app.cfg.sim.room_half_size
                scene.floor = app.server.scene.add_image(
                    "/floor", floor_texture(app.cfg.floor, half, tex), 2 * half, 2 * half,
                    format="jpeg", jpeg_quality=90, cast_shadow=False)
                scene._nodes["floor"] = [scene.floor]
                self.texture = tex
            for name, nodes in scene._nodes.items():
                for h in nodes:
                    h.visible = name not in hidden and (name in shown
                                                        or scene.layers.get(name, True))
            for name, (_, outline) in scene.sets.items():
                outline.visible = name not in hidden
            for name in ("trails", "path"):
                if name in hidden:
                    for h in ([scene.trail_truth, scene.trail_est, scene.head_truth,
                               scene.head_est] if name == "trails" else [scene.path]):
                        if h is not None:
                            h.visible = False


class BarePage:
    """A bare viser page: one lit box (no environment map) moving 20 times a second."""

    def __init__(self) -> None:
        import threading

        import viser

        self.server = viser.ViserServer(port=0, verbose=False)
        self.server.scene.configure_default_lights(enabled=True, cast_shadow=False)
        self.server.scene.configure_environment_map(None)
        box = self.server.scene.add_box("/box", color=(200, 100, 100), dimensions=(0.5, 0.3, 0.1))
        self._stop = threading.Event()

        def move() -> None:
            k = 0
            while not self._stop.wait(0.05):
                k += 1
                box.position = (0.5 * math.sin(k / 20.0), 0.0, 0.0)

        threading.Thread(target=move, daemon=True).start()
        self.url = f"http://127.0.0.1:{self.server.get_port()}/"

    def stop(self) -> None:
        self._stop.set()
        self.server.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("configs", nargs="+")
    ap.add_argument("--window", type=float, default=4.0, help="seconds counted per measurement")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--warmup", type=float, default=6.0)
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:page_parts)")
    args = ap.parse_args()
    machine = Machine()
    figures: list[tuple[str, str]] = []

    import cv2
    from playwright.sync_api import sync_playwright

    from tileviz.app.server import App
    from tileviz.app.session import SessionOptions
    from tileviz.config import preset

    cv2.setNumThreads(1)
    app = App(preset("default"), SessionOptions(), port=0)
    app.start()
    bare = BarePage() if "bare" in args.configs else None
    parts = Parts(app)
    results: dict[str, list[tuple[float, float, float]]] = {c: [] for c in args.configs}
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(app.url)
            page.wait_for_selector("canvas", timeout=120_000)
            page.wait_for_timeout(args.warmup * 1000)
            pids = chromium_pids()
            gpu = [q for q in pids if _kind(q) == "gpu-process"]
            for _ in range(args.repeat):
                for config in args.configs:
                    if config == "bare":
                        page.goto(bare.url)
                        page.wait_for_selector("canvas", timeout=120_000)
                        page.wait_for_timeout(args.warmup * 1000)
                    else:
                        parts.apply(config)
                        page.wait_for_timeout(1500)
                    g0, a0 = cpu_seconds(gpu), cpu_seconds(pids)
                    n, span = page.evaluate(COUNT_FRAMES, args.window * 1000)
                    n = max(int(n), 1)
                    results[config].append((n / span, 1e3 * (cpu_seconds(gpu) - g0) / n,
                                            1e3 * (cpu_seconds(pids) - a0) / n))
                    if config == "bare":
                        page.goto(app.url)
                        page.wait_for_selector("canvas", timeout=120_000)
                        page.wait_for_timeout(args.warmup * 1000)
            browser.close()
    finally:
        app.stop()
        if bare is not None:
            bare.stop()
    width = max(len(c) for c in args.configs)
    for config, rows in results.items():
        print(f"{config:{width}s}  frames/s " + " ".join(f"{r[0]:5.1f}" for r in rows)
              + "  | GPU process ms/frame " + " ".join(f"{r[1]:4.0f}" for r in rows)
              + "  | all ms/frame " + " ".join(f"{r[2]:4.0f}" for r in rows))
        figures.append((config, fmt_range([r[0] for r in rows], ".1f", "frames/s") + ", "
                        + fmt_range([r[2] for r in rows], ".0f", "ms") + " browser CPU a frame"))
    if "bare" in results:
        ref = sum(r[0] for r in results["bare"]) / len(results["bare"])
        for config, rows in results.items():
            if config != "bare":
                mean = sum(r[0] for r in rows) / len(rows)
                print(f"{config:{width}s}  {mean:5.1f} frames/s = {mean / ref:.2f} x the bare "
                      f"page's {ref:.1f}")
                figures.append((f"{config} / bare page", f"{mean / ref:.2f}x"))
    print(f"load average {os.getloadavg()[0]:.1f}")
    if args.write_figures:
        write_block("page_parts", "What each part of the live page costs headless chromium",
                    figures, machine=machine, note=f"{args.repeat} repeats of {args.window:g} "
                    "s each, configurations in turn in one browser tab.")


if __name__ == "__main__":
    main()
