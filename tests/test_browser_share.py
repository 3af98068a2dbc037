"""The page export-html writes, opened from file:// in headless chromium (Debian's, driven by
Playwright as in test_browser.py): it draws the scene, the boxes and the camera view, and its
player moves the robot while it plays and not while it is paused."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from tileviz.app.scene import COLOURS, grid_colour
from tileviz.config import preset
from tileviz.testing.browser import ARGS, CHROMIUM

pytestmark = [pytest.mark.browser, pytest.mark.slow]

HANG_S = 300
"""Seconds any wait may take before the test calls it a hang."""
W, H = 1400, 900


def _near(shot: np.ndarray, rgb: tuple[int, ...], tol: int) -> np.ndarray:
    return np.abs(shot.astype(int) - np.array(rgb[::-1])).max(axis=2) < tol


def _shot(page) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(page.screenshot(), np.uint8), cv2.IMREAD_COLOR)


def test_the_exported_page_plays_offline(tmp_path) -> None:
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Debian chromium is needed at {CHROMIUM} (apt-get install chromium; "
                    ".ci/run does it)")
    from playwright.sync_api import sync_playwright

    from tileviz.cli import record

    ds = tmp_path / "run"
    assert record([str(ds), "--duration", "6", "--quiet"]) == 0
    out = tmp_path / "run.html"
    r = subprocess.run([sys.executable, "-m", "tileviz", "export-html", str(ds), str(out),
                        "--quiet"], capture_output=True, text=True, timeout=HANG_S)
    assert r.returncode == 0, r.stderr
    frame0 = cv2.imread(str(sorted((ds / "images").iterdir())[0]))
    camera_mean = tuple(int(v) for v in frame0.reshape(-1, 3).mean(axis=0)[::-1])  # RGB
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": W, "height": H})
        page.set_default_timeout(HANG_S * 1000)
        requests: list[str] = []
        page.on("request", lambda q: requests.append(q.url))
        page.goto(out.as_uri())
        page.wait_for_selector("canvas")
        slider = page.locator("[role=slider]")
        grout = grid_colour(preset("default").floor)
        for _ in range(HANG_S):  # the software renderer draws when it gets the CPU
            shot = _shot(page)
            if _near(shot, grout, 40).sum() > 3000:
                break
            page.wait_for_timeout(1000)
        # the panel column (left of the room): the magnified set's blue and green boxes and
        # the camera view's floor colours
        left = shot[:, : W // 3]
        assert _near(shot, grout, 40).sum() > 3000, "no floor grid drawn"
        assert _near(left, COLOURS["boxes"], 50).sum() > 100, "no contracted box drawn"
        assert _near(left, COLOURS["prediction"], 50).sum() > 100, "no predicted box drawn"
        assert _near(left, camera_mean, 30).sum() > 2000, "no camera view drawn"
        # pause: nothing moves; play: the robot (and its trail, sets) moves over the room
        play = page.locator("button.mantine-ActionIcon-root").first
        play.click()  # the page starts playing: this pauses it
        page.wait_for_timeout(1500)
        t0 = float(slider.get_attribute("aria-valuenow", timeout=HANG_S * 1000) or "nan")
        a = _shot(page)
        page.wait_for_timeout(2500)
        b = _shot(page)
        t1 = float(slider.get_attribute("aria-valuenow") or "nan")
        play.click()
        page.wait_for_timeout(2500)
        c = _shot(page)
        t2 = float(slider.get_attribute("aria-valuenow") or "nan")
        browser.close()
    room = (slice(H // 6, H - 80), slice(W // 3, W))
    (tmp_path / "page.png").write_bytes(cv2.imencode(".png", c)[1].tobytes())
    assert t1 == t0 and t2 != t1, (t0, t1, t2)  # (the player loops at the end)
    assert np.array_equal(a[room], b[room]), "the scene moved while paused"
    assert (np.abs(c[room].astype(int) - b[room]).max(axis=2) > 40).sum() > 50, \
        "the robot did not move while playing"
    assert {u.split(":", 1)[0] for u in requests} <= {"file", "data", "blob"}, requests
