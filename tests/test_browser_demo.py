"""The demo as a newcomer meets it, in a real browser (Debian chromium driven by Playwright):
a reset while paused leaves nothing of the old run on screen, the default port's page is the
server's own, the inset shows the boxes, the buttons stay put when notes arrive, and recording
while paused says what happened. Waits are for conditions (generous, for a loaded machine),
never for a time."""

from __future__ import annotations

import re
import socket
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from tileviz.app.server import App
from tileviz.app.session import SessionOptions
from tileviz.config import preset
from tileviz.testing.browser import ARGS, CHROMIUM

pytestmark = [pytest.mark.browser, pytest.mark.slow]

WAIT = 300_000
"""Milliseconds a condition may take to come true on a loaded machine (a hang guard only)."""


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Debian chromium is needed at {CHROMIUM} (apt-get install chromium; "
                    ".ci/run does it)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


@pytest.fixture()
def app(tmp_path: Path) -> Iterator[App]:
    a = App(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True), port=0)
    a.start()
    yield a
    a.stop()


def open_page(browser: object, url: str) -> object:
    from playwright.sync_api import expect

    page = browser.new_page(viewport={"width": 1400, "height": 900})  # type: ignore[attr-defined]
    page.set_default_timeout(WAIT)  # clicks too may wait long on a loaded machine
    page.goto(url)
    page.wait_for_selector("canvas", timeout=WAIT)
    expect(page.get_by_text("frame 0,")).to_be_visible(timeout=WAIT)
    return page


def button(page: object, name: str) -> object:
    return page.get_by_role("button", name=name, exact=True)  # type: ignore[attr-defined]


def status(page: object) -> str:
    return page.locator(".tileviz-status").inner_text()  # type: ignore[attr-defined]


def notes(page: object) -> str:
    return page.locator(".tileviz-notes").inner_text()  # type: ignore[attr-defined]


def test_reset_while_paused_clears_the_old_run_at_once(browser, app):
    from playwright.sync_api import expect

    page = open_page(browser, app.url)
    for k in range(1, 6):
        button(page, "Step").click()
        expect(page.get_by_text(f"frame {k},")).to_be_visible(timeout=WAIT)
    button(page, "Kidnap (teleport the robot)").click()
    expect(page.locator(".tileviz-notes")).to_contain_text("kidnapped", timeout=WAIT)
    expect(page.locator(".tileviz-status")).to_contain_text("of the last 6 frames",
                                                           timeout=WAIT)
    button(page, "Reset the run").click()
    # at once, still paused: frame 0 of the new run, its counts, its timeline; no old note
    expect(page.locator(".tileviz-notes")).to_contain_text("Reset: a new run from frame 0",
                                                          timeout=WAIT)
    text = status(page)
    assert re.search(r"frame 0, t = [0-9.]+ s, paused", text), text
    assert "of the last 1 frames" in text and "history 1/" in text
    assert "kidnapped" not in notes(page)
    assert app.session.shown == 0 and len(app.session.history) == 1
    page.close()


def test_the_default_port_serves_its_own_page_when_taken(browser, tmp_path):
    from playwright.sync_api import expect

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        a = App(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True),
                port=port)
        a.start()
        try:
            assert a.port != port and a.url.endswith(f":{a.port}/")
            page = open_page(browser, a.url)
            button(page, "Step").click()
            expect(page.get_by_text("frame 1,")).to_be_visible(timeout=WAIT)
            assert a.session.shown == 1  # the page is this server's
            page.close()
        finally:
            a.stop()


INSET_IMG = "img[src^='blob:']"
"""The inset: the first image the server sent (viser's own logo is an inline SVG image)."""


def _inset_pixels(page: object) -> np.ndarray:
    img = page.locator(INSET_IMG).first  # type: ignore[attr-defined]
    png = img.screenshot()
    return cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR),
                        cv2.COLOR_BGR2RGB)


def test_the_inset_shows_the_boxes_and_follows_each_step(browser, app):
    """The inset (the first image the server sends; viser's logo is an inline SVG): a few
    frames in, the centimetre-wide set fills a good part of it, with the prediction and the
    truth; every step sends a new picture."""
    from playwright.sync_api import expect

    page = open_page(browser, app.url)
    expect(page.get_by_text("the set around the truth, magnified")).to_be_visible(timeout=WAIT)
    for k in range(1, 6):
        button(page, "Step").click()
        expect(page.get_by_text(f"frame {k},")).to_be_visible(timeout=WAIT)
    src0 = page.locator(INSET_IMG).first.get_attribute("src")
    shot = _inset_pixels(page)
    assert min(shot.shape[:2]) >= 300  # the inset itself, not an icon
    r, g, b = (shot[..., i].astype(int) for i in range(3))
    blue = (b > r + 40) & (b > g + 15)
    green = (g > r + 25) & (g > b + 25)
    pink = (r > 200) & (b > 100) & (g < 140)
    assert blue.mean() > 0.05 and green.any() and pink.any()
    button(page, "Step").click()
    expect(page.get_by_text("frame 6,")).to_be_visible(timeout=WAIT)
    page.wait_for_function(f"(src) => document.querySelector(\"{INSET_IMG}\").src !== src",
                           arg=src0, timeout=WAIT)
    page.close()


def place(page: object, name: str) -> tuple[float, float, float, float]:
    """Where button ``name`` is in the control panel: its box relative to the panel's top (the
    status block's), so that scrolling the panel (a click scrolls its button into view) does not
    count as moving."""
    top = page.locator(".tileviz-status").bounding_box()  # type: ignore[attr-defined]
    b = button(page, name).bounding_box()  # type: ignore[attr-defined]
    return (b["x"] - top["x"], b["y"] - top["y"], b["width"], b["height"])


def settled_place(page: object, name: str) -> tuple[float, float, float, float]:
    """:func:`place` once the panel's layout has settled (two readings 0.5 s apart agree; a new
    page can still be laying out its panel), bounded by the hang guard."""
    last = place(page, name)
    for _ in range(int(WAIT / 500)):
        page.wait_for_timeout(500)  # type: ignore[attr-defined]
        now = place(page, name)
        if now == last:
            return now
        last = now
    raise AssertionError(f"the control panel never settled: {name!r} kept moving")


def test_a_button_stays_put_after_kidnap_and_reset(browser, app):
    from playwright.sync_api import expect

    page = open_page(browser, app.url)
    button(page, "Step").click()  # one round trip of updates after the first layout
    expect(page.get_by_text("frame 1,")).to_be_visible(timeout=WAIT)
    play, step = settled_place(page, "Play"), place(page, "Step")
    status = page.locator(".tileviz-status").bounding_box()
    button(page, "Kidnap (teleport the robot)").click()
    expect(page.locator(".tileviz-notes")).to_contain_text("kidnapped", timeout=WAIT)
    button(page, "Step").click()
    expect(page.get_by_text("frame 2,")).to_be_visible(timeout=WAIT)
    assert place(page, "Play") == play
    button(page, "Reset the run").click()
    expect(page.locator(".tileviz-notes")).to_contain_text("Reset: a new run", timeout=WAIT)
    assert place(page, "Play") == play and place(page, "Step") == step
    # the status block itself keeps its size
    after = page.locator(".tileviz-status").bounding_box()
    assert (after["width"], after["height"]) == (status["width"], status["height"])
    page.close()


def test_recording_while_paused_says_what_happened(browser, app):
    from playwright.sync_api import expect

    page = open_page(browser, app.url)
    button(page, "Start recording").click()
    expect(page.locator(".tileviz-notes")).to_contain_text("press Play or Step", timeout=WAIT)
    button(page, "Stop recording").click()
    expect(page.locator(".tileviz-notes")).to_contain_text("nothing recorded", timeout=WAIT)
    # with a Step in between, the frame is written and the note says how many
    button(page, "Start recording").click()
    expect(button(page, "Stop recording")).to_be_visible(timeout=WAIT)
    button(page, "Step").click()
    expect(page.get_by_text("frame 1,")).to_be_visible(timeout=WAIT)
    button(page, "Stop recording").click()
    expect(page.locator(".tileviz-notes")).to_contain_text("recorded 1 frames (", timeout=WAIT)
    page.close()


def test_a_laptop_sized_page_reads_whole_and_a_late_tab_shows_the_frame(browser, app):
    """At 1280 x 720: the left tab's label is whole, viser's software-WebGL notice does not
    cover the scene, the scene keeps about half the width; a tab opened after 25 steps shows
    that frame in its timeline box and status."""
    from playwright.sync_api import expect

    from tileviz.app import commands as C

    page = browser.new_page(viewport={"width": 1280, "height": 720})
    page.set_default_timeout(WAIT)
    page.goto(app.url)
    page.wait_for_selector("canvas", timeout=WAIT)
    expect(page.get_by_text("frame 0,")).to_be_visible(timeout=WAIT)
    expect(page.get_by_text("Set, camera, plots", exact=True)).to_be_visible()
    assert page.locator("#webgl-software-rendering:visible").count() == 0
    box = page.locator("canvas").first.bounding_box()
    assert box is not None and box["width"] >= 600
    for _ in range(25):
        app.submit(C.Step())
    expect(page.get_by_text("frame 25,")).to_be_visible(timeout=WAIT)
    late = browser.new_page(viewport={"width": 1280, "height": 720})
    late.set_default_timeout(WAIT)
    late.goto(app.url)
    expect(late.get_by_text("frame 25,")).to_be_visible(timeout=WAIT)
    values = [late.locator("input").nth(i).input_value()
              for i in range(late.locator("input").count())]
    assert "25" in values  # the timeline's box
    late.close()
    page.close()
