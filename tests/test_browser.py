"""The live page in a real browser: Debian's chromium driven by Playwright (never
``playwright install``: ``.ci/run`` installs ``chromium`` with apt)."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import urlparse

import cv2
import numpy as np
import pytest

from tileviz.app.scene import grid_colour
from tileviz.app.server import App
from tileviz.app.session import SessionOptions
from tileviz.config import preset
from tileviz.testing.browser import ARGS, CHROMIUM

pytestmark = [pytest.mark.browser, pytest.mark.slow]

CONTROLS = ("Play", "Step", "Step back", "Go live", "Click the floor to set the target",
            "Drive the waypoints", "Kidnap (teleport the robot)",
            "Relocalize (tell the true pose)", "Reset the run", "Start recording")


HANG_S = 300
"""Seconds any wait may take before the test calls it a hang (a loaded machine is slow, not
wrong)."""


def _floor_drawn(shot: np.ndarray) -> bool:
    """Not blank: the floor's tile grid (grout-coloured lines) crosses the middle of the page,
    with the robot and the other shapes in many shades."""
    h, w = shot.shape[:2]
    middle = shot[h // 4: 3 * h // 4, 400: w - 400]
    grout = np.array(grid_colour(preset("default").floor)[::-1])  # BGR
    lines = (np.abs(middle.astype(int) - grout).max(axis=2) < 40).sum()
    # a blank or half-drawn canvas holds a few flat colours; the scene's anti-aliased lines,
    # the robot and its footprint some hundreds
    return (middle.std() > 8 and len(np.unique(middle.reshape(-1, 3), axis=0)) > 200
            and lines > 500)


def test_page_shows_the_scene_steps_and_has_the_controls(tmp_path):
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Debian chromium is needed at {CHROMIUM} (apt-get install chromium; "
                    ".ci/run does it)")
    from playwright.sync_api import expect, sync_playwright

    expect.set_options(timeout=HANG_S * 1000)  # every expect: visible eventually, not in 5 s

    app = App(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True), port=0)
    app.start()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.set_default_timeout(HANG_S * 1000)  # clicks too (Playwright's default: 30 s)
            requests: list[str] = []
            page.on("request", lambda r: requests.append(r.url))
            page.goto(app.url)
            page.wait_for_selector("canvas", timeout=HANG_S * 1000)
            expect(page.get_by_text("frame 0,")).to_be_visible(timeout=HANG_S * 1000)
            for name in CONTROLS:
                expect(page.get_by_role("button", name=name, exact=True)).to_be_visible()
            for label in ("Timeline", "Setpoint", "Mode", "Extractor", "Speed bound (m/s)"):
                expect(page.get_by_text(label, exact=True).first).to_be_visible()
            expect(page.get_by_text("camera view", exact=True)).to_be_visible()

            page.get_by_role("button", name="Step", exact=True).click()
            expect(page.get_by_text("frame 1,")).to_be_visible(timeout=HANG_S * 1000)
            assert (app.session.history.last, app.session.shown) == (1, 1)

            # the software renderer draws the frame when it gets the CPU: wait for the floor's
            # grid (however long a loaded machine takes; the timeout only guards a hang)
            for _ in range(HANG_S):
                png = page.screenshot()
                shot = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
                if _floor_drawn(shot):
                    break
                page.wait_for_timeout(1000)
            # the stages panel shows the checks of the frame on screen
            page.get_by_role("button", name="Camera and stages", exact=True).click()
            expect(page.get_by_text("Checks of this frame").first).to_be_visible()
            browser.close()
    finally:
        app.stop()
    (tmp_path / "page.png").write_bytes(png)
    assert shot.shape[:2] == (900, 1400)
    assert _floor_drawn(shot)
    # nothing was fetched from anywhere but the server itself
    hosts = {urlparse(u).hostname for u in requests if not u.startswith(("blob:", "data:"))}
    assert hosts == {"127.0.0.1"}, hosts
