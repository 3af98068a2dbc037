"""Regenerate ``static/screenshot.png`` (the README's picture of the live demo).

    python static/make_screenshot.py [--seconds 40] [--out static/screenshot.png]

Runs the default preset at 4x real time for ``--seconds`` of wall time (trails build up), then
photographs the page with Debian's chromium (``/usr/bin/chromium``) through Playwright.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from tileviz.app.commands import Pause
from tileviz.app.server import App
from tileviz.app.session import SessionOptions
from tileviz.config import preset
from tileviz.testing.browser import ARGS, CHROMIUM


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=40.0)
    p.add_argument("--out", default=str(Path(__file__).with_name("screenshot.png")))
    args = p.parse_args()
    from playwright.sync_api import sync_playwright

    cfg = preset("default")
    with tempfile.TemporaryDirectory() as tmp:
        app = App(cfg, SessionOptions(out_dir=Path(tmp), speed=4.0), port=0)
        app.start()
        try:
            time.sleep(args.seconds)
            app.submit(Pause())
            time.sleep(1.0)
            entry = app.session.shown_entry()
            x, y = entry.record.truth.x, entry.record.truth.y
            app.server.initial_camera.position = (x + 1.0, y - 3.2, 3.4)
            app.server.initial_camera.look_at = (x, y + 0.4, 0.0)
            with sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
                page = browser.new_page(viewport={"width": 1600, "height": 1000})
                page.goto(app.url)
                page.wait_for_selector("canvas", timeout=60_000)
                page.wait_for_timeout(4000)
                notes = page.locator(".mantine-Notification-closeButton")
                for i in range(notes.count()):
                    notes.nth(i).click()
                page.wait_for_timeout(2500)
                page.screenshot(path=args.out)
                browser.close()
        finally:
            app.stop()
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
