"""The "Camera and stages" panel's table of checks: for the frame on screen, the robust
extractor's decision path (the readings tried, every check with its value, limit and result,
the refusing check first and in bold), updated as frames are stepped through, and sent only
while that panel is shown (no browser: the panel on a viser server's GUI)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from tileviz.app import commands as C
from tileviz.app.panels import ImagePanels, checks_text
from tileviz.app.session import Session, SessionOptions
from tileviz.config import preset
from tileviz.vision.decision import number


@pytest.fixture(scope="module")
def gui():
    import viser

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield server.gui
    server.stop()


def _session(tmp_path: Path, blur: float) -> Session:
    cfg = preset("default")
    cfg = replace(cfg, camera=replace(cfg.camera, blur_sigma=blur))
    return Session(cfg, SessionOptions(out_dir=tmp_path, interactive=True))


def test_the_stages_panel_shows_why_the_frame_on_screen_was_refused(gui, tmp_path) -> None:
    """A camera blurred beyond what the extractor trusts: each frame is refused, and the
    panel's table names the check that refused the frame on screen, with the value measured
    and the limit, in bold; a sharp camera's frame shows every check passed."""
    panels = ImagePanels(gui)
    s = _session(tmp_path / "blurred", 9.0)
    try:
        s.apply(C.Step())
        entry = s.shown_entry()
        vision = entry.record.vision
        assert not vision.accepted and vision.decision is not None
        ref = vision.decision.refusal
        assert ref is not None
        panels.show(entry, display=True, stages=True)
        text = panels.checks.content
        assert panels.checks.visible and text == checks_text(vision)
        assert f"by {ref.check}" in text and f"value {number(ref.value)}" in text
        assert f"**{ref.check}" in text  # the refusing row, in bold
        assert f"{ref.relation} {number(ref.limit)}**" in text
        assert "| check | value | limit | result |" in text
        assert all(t.reading.label() in text for t in vision.decision.readings)
    finally:
        s.close()
    s = _session(tmp_path / "sharp", 0.7)
    try:
        s.apply(C.Step())
        s.apply(C.Step())
        sharp = s.shown_entry()
        assert sharp.record.vision.accepted
        panels.show(sharp, display=False, stages=True)  # stage images off: the checks still
        text = panels.checks.content
        assert text.startswith("**Checks of this frame**") and "accepted" in text
        assert "FAIL" not in text and "foreign_edge" in text and "bound.position" in text
        s.apply(C.StepBack())  # stepping back shows the earlier frame's checks
        panels.show(s.shown_entry(), display=True, stages=True)
        assert panels.checks.content == checks_text(s.shown_entry().record.vision)
    finally:
        s.close()


def test_the_checks_are_sent_only_while_the_stages_panel_is_shown(gui, tmp_path) -> None:
    panels = ImagePanels(gui)
    s = _session(tmp_path, 0.7)
    try:
        s.apply(C.Step())
        first = s.shown_entry()
        panels.show(first, display=True, stages=False)
        assert not panels.checks.visible and panels.checks.content == ""
        s.apply(C.Step())
        panels.show(s.shown_entry(), display=True, stages=True)
        assert panels.checks.visible and panels.checks.content
        shown = panels.checks.content
        panels.show(first, display=True, stages=False)  # another panel: nothing new is sent
        assert not panels.checks.visible and panels.checks.content == shown
    finally:
        s.close()


def test_the_faithful_extractor_says_it_records_no_checks(gui, tmp_path) -> None:
    cfg = preset("default")
    cfg = replace(cfg, vision=replace(cfg.vision, extractor="faithful"))
    s = Session(cfg, SessionOptions(out_dir=tmp_path, interactive=True))
    try:
        s.apply(C.Step())
        panels = ImagePanels(gui)
        panels.show(s.shown_entry(), display=True, stages=True)
        assert "records no decision path" in panels.checks.content
    finally:
        s.close()
