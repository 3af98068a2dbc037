"""The live page's readout (``tileviz.app.status.render_status``) from a snapshot of a session's
state, without a server: what a user reads beside the scene."""

from __future__ import annotations

from dataclasses import replace

from tileviz.app import commands as C
from tileviz.app.session import Note, Session, SessionOptions
from tileviz.app.status import StatusState, render_status
from tileviz.config import preset
from tileviz.types import Pose


def test_the_readout_says_the_frame_its_status_and_whether_the_set_holds_the_truth(tmp_path):
    s = Session(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True))
    try:
        for _ in range(3):
            s.apply(C.Step())
        entry = s.shown_entry()
        assert entry is not None and entry.record.status == "contracted"
        live = render_status(StatusState.of(s, entry, {"contained": 1.0, "frames": 3.0},
                                            live=True))
        assert "<b>frame 2</b>" in live and "paused" in live
        assert "status <b>contracted</b>: the camera&#x27;s view shrank the set, 1 box" in live
        assert "camera view used" in live and "truth inside" in live
        assert "truth inside the set in 100.0 % of the last 3 frames it vouched for" in live
        assert "(from the history)" not in live and "mode autonomous, extractor robust" in live

        old = s.history.get(0)
        assert "(from the history)" in render_status(StatusState.of(s, old, None, live=False))

        r = entry.record
        assert r.truth is not None
        away = replace(entry, record=replace(r, truth=Pose(r.truth.x + 3.0, r.truth.y,
                                                              r.truth.theta)))
        assert "truth <b>OUTSIDE</b>" in render_status(StatusState.of(s, away, None, live=True))
    finally:
        s.close()


def test_the_notes_show_the_newest_first_errors_marked_and_a_replay_end_kept(tmp_path):
    s = Session(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True))
    try:
        base = StatusState.of(s, None, None, live=True)
    finally:
        s.close()
    assert "<b>no frame yet</b> (paused)" in render_status(base)
    notes = (Note("end of dataset, 9 frames"), Note("one"), Note("bad <row>", "error"))
    text = render_status(replace(base, notes=notes, replaying="runs/demo (9 frames)",
                                 ended="end of dataset, 9 frames"))
    shown = text.split('class="tileviz-notes"')[1]
    assert shown.index("<b>error:</b> bad &lt;row&gt;") < shown.index("one")
    assert shown.count("end of dataset, 9 frames") == 1  # its note is still in view
    text = render_status(replace(base, notes=notes[1:], replaying="runs/demo (9 frames)",
                                 ended="end of dataset, 9 frames"))
    assert "replaying <code>runs/demo (9 frames)</code>: <b>end of dataset, 9 frames</b>" in text
    text = render_status(replace(base, recording=("runs/rec", 42), degraded=True))
    assert "recording to <code>runs/rec</code> (42 frames)" in text
    assert "a frame failed: the set may miss the truth" in text


def test_with_the_faithful_extractor_the_readout_says_its_views_can_break_their_bounds(tmp_path):
    from tileviz.summary import FAITHFUL_NOTE

    cfg = preset("default")
    faithful = replace(cfg, vision=replace(cfg.vision, extractor="faithful"))
    for c, said in ((faithful, True), (cfg, False)):
        s = Session(c, SessionOptions(out_dir=tmp_path, interactive=True))
        try:
            s.apply(C.Step())
            text = render_status(StatusState.of(s, s.shown_entry(),
                                                {"contained": 0.6, "frames": 1.0}, live=True))
            assert (FAITHFUL_NOTE.replace("'", "&#x27;") in text) is said
        finally:
            s.close()
