"""The page export-html writes, opened from file:// in headless chromium (Debian's, driven by
Playwright as in test_browser.py): it draws the scene, the boxes and the camera view, and its
player moves the robot while it plays and not while it is paused. The ``--site`` folder, served
over HTTP (python's http.server), draws the same scene from its recording file."""

from __future__ import annotations

import functools
import subprocess
import sys
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
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


def _chromium() -> None:
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Debian chromium is needed at {CHROMIUM} (apt-get install chromium; "
                    ".ci/run does it)")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tileviz.cli import record

    ds = tmp_path_factory.mktemp("browser_share") / "run"
    assert record([str(ds), "--duration", "6", "--quiet"]) == 0
    return ds


def _export(*args: str) -> None:
    r = subprocess.run([sys.executable, "-m", "tileviz", "export-html", *args, "--quiet"],
                       capture_output=True, text=True, timeout=HANG_S)
    assert r.returncode == 0, r.stderr


def _draws_the_scene(page, ds: Path) -> np.ndarray:
    """Wait until the page shows the floor grid and, in the panel column (left of the room),
    the magnified set's blue and green boxes and the camera view's floor colours (the software
    renderer draws when it gets the CPU; the images arrive after the grid); the last shot."""
    frame0 = cv2.imread(str(sorted((ds / "images").iterdir())[0]))
    camera_mean = tuple(int(v) for v in frame0.reshape(-1, 3).mean(axis=0)[::-1])  # RGB
    page.wait_for_selector("canvas")
    grout = grid_colour(preset("default").floor)

    def missing(shot: np.ndarray) -> list[str]:
        left = shot[:, : W // 3]
        return [what for what, ok in (
            ("no floor grid drawn", _near(shot, grout, 40).sum() > 3000),
            ("no contracted box drawn", _near(left, COLOURS["boxes"], 50).sum() > 100),
            ("no predicted box drawn", _near(left, COLOURS["prediction"], 50).sum() > 100),
            ("no camera view drawn", _near(left, camera_mean, 30).sum() > 2000)) if not ok]

    for _ in range(HANG_S):
        shot = _shot(page)
        if not missing(shot):
            break
        page.wait_for_timeout(1000)
    assert not missing(shot), missing(shot)
    return shot


def test_the_exported_page_plays_offline(dataset, tmp_path) -> None:
    _chromium()
    from playwright.sync_api import sync_playwright

    ds = dataset
    out = tmp_path / "run.html"
    _export(str(ds), str(out))
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": W, "height": H})
        page.set_default_timeout(HANG_S * 1000)
        requests: list[str] = []
        page.on("request", lambda q: requests.append(q.url))
        page.goto(out.as_uri())
        slider = page.locator("[role=slider]")
        _draws_the_scene(page, ds)
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


class _QuietHandler(SimpleHTTPRequestHandler):
    """python -m http.server's handler without its log lines."""

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002
        return


def test_the_site_folder_served_over_http_draws_the_scene(dataset, tmp_path) -> None:
    _chromium()
    from playwright.sync_api import sync_playwright

    site = tmp_path / "site"
    _export(str(dataset), "--site", str(site))
    server = ThreadingHTTPServer(("127.0.0.1", 0),
                                 functools.partial(_QuietHandler, directory=str(site)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    base = f"http://127.0.0.1:{server.server_address[1]}/"
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": W, "height": H})
            page.set_default_timeout(HANG_S * 1000)
            served: list[tuple[str, int]] = []
            page.on("response", lambda r: served.append((r.url, r.status)))
            page.goto(base)
            shot = _draws_the_scene(page, dataset)
            browser.close()
    finally:
        server.shutdown()
        server.server_close()
    (tmp_path / "site.png").write_bytes(cv2.imencode(".png", shot)[1].tobytes())
    # the scene came from the recording beside the page, read over HTTP
    assert (base + "run.viser", 200) in served, served
    assert {u.split("/", 3)[2] for u, _ in served if u.startswith("http")} == \
        {base.split("/")[2]}, served
