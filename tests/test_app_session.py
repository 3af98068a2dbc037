"""The live server's run logic without a browser: stepping, the history, commands, files."""

from __future__ import annotations

import csv
import math
from dataclasses import replace

import numpy as np
import pytest

from tileviz.app import commands as C
from tileviz.app.history import Entry, History
from tileviz.app.outputs import output_path, sanitize_name
from tileviz.app.session import Session, SessionOptions
from tileviz.config import preset
from tileviz.datasets import DatasetSource, dataset_mb, read_meta


@pytest.fixture(scope="module")
def cfg():
    return preset("default")


def make(cfg, tmp_path, **kw) -> Session:
    kw.setdefault("interactive", True)
    return Session(cfg, SessionOptions(out_dir=tmp_path / "out", **kw))


def test_step_advances_exactly_one_frame_and_step_back_shows_the_stored_frame(cfg, tmp_path):
    s = make(cfg, tmp_path)
    s.apply(C.Step())
    assert (s.history.last, s.shown) == (0, 0)
    for _ in range(3):
        s.apply(C.Step())
    assert (s.history.last, s.shown) == (3, 3)
    live = s.shown_entry()
    assert live is not None and len(live.images) > 2  # camera + stages
    s.apply(C.StepBack())
    s.apply(C.StepBack())
    assert s.shown == 1 and s.history.last == 3  # nothing computed
    s.apply(C.Step())  # forward through the history: the stored frame 2, not a new one
    assert s.shown == 2 and s.history.last == 3
    s.apply(C.Seek(3))
    again = s.shown_entry()
    assert again is live  # the very same record and the same image bytes
    assert again.record.index == 3
    s.apply(C.Seek(-50))
    assert s.shown == 0
    s.apply(C.Seek(10**6))
    assert s.shown == 3
    s.close()


def test_play_replays_the_history_before_computing_new_frames(cfg, tmp_path):
    s = make(cfg, tmp_path)
    for _ in range(4):
        s.apply(C.Step())
    s.apply(C.Seek(1))
    s.apply(C.Play())
    assert s.playing
    s.advance()
    s.advance()
    assert (s.shown, s.history.last) == (3, 3)
    s.advance()
    assert (s.shown, s.history.last) == (4, 4)
    s.close()


def test_the_history_is_bounded_and_keeps_the_newest_frames(cfg, tmp_path):
    assert SessionOptions().history >= 2000
    s = make(cfg, tmp_path, history=5)
    for _ in range(8):
        s.apply(C.Step())
    assert (s.history.first, s.history.last, len(s.history)) == (3, 7, 5)
    with pytest.raises(KeyError):
        s.history.get(2)
    s.apply(C.StepBack())
    s.apply(C.Seek(0))
    assert s.shown == 3  # the oldest kept
    s.close()


def test_history_entries_drop_the_raw_arrays_but_keep_jpeg_copies(cfg, tmp_path):
    s = make(cfg, tmp_path)
    s.apply(C.Step())
    e = s.shown_entry()
    assert e.record.image.size == 0 and e.record.vision.stages == {}
    names = [n for n, _ in e.images]
    assert names[0] == "camera" and len(names) >= 5
    for _, data in e.images:
        assert data[:2] == b"\xff\xd8"  # JPEG
    assert sum(len(d) for _, d in e.images) < 400_000
    s.apply(C.SetDisplay(False))
    s.apply(C.Step())
    assert [n for n, _ in s.shown_entry().images] == ["camera"]
    s.close()


def test_history_positions_survive_gaps_but_refuse_frames_out_of_order(cfg, tmp_path):
    s = make(cfg, tmp_path)
    s.apply(C.Step())
    s.apply(C.Step())
    h = History(10)
    first = s.history.get(0)
    assert h.append(first) == 0
    later = Entry(replace(s.history.get(1).record, index=5), ())
    assert h.append(later) == 1 and h.get(1).index == 5  # a gap in frame indices is fine
    with pytest.raises(ValueError, match="does not follow"):
        h.append(first)
    s.close()


def test_bad_values_are_refused_with_a_message_naming_them():
    with pytest.raises(ValueError, match="tile size"):
        C.Restart(0.0, 200.0)
    with pytest.raises(ValueError, match="ppm"):
        C.Restart(1.0, math.inf)
    with pytest.raises(ValueError, match="speed error bound"):
        C.SetNoise(math.nan, 0.01, 0.02)
    with pytest.raises(ValueError, match="mode"):
        C.SetMode("telepathy")
    with pytest.raises(ValueError, match="waypoint 1"):
        C.parse_waypoints("1, 2; 3")
    with pytest.raises(ValueError, match="target x"):
        C.SetManualTarget(float("nan"), 0.0)
    with pytest.raises(ValueError, match="frame index must be an integer"):
        C.Seek(1.5)
    assert C.parse_waypoints("1, 2; -3 4\n5,6") == ((1.0, 2.0), (-3.0, 4.0), (5.0, 6.0))


def test_a_failing_frame_is_logged_and_the_run_goes_on(cfg, tmp_path, capsys):
    class FlakyRenderer:
        """Frame 1: the camera raises (nothing moved); frame 2: a wrong-size image (the vision
        refuses it after the simulator moved on)."""

        def __init__(self):
            self.calls = 0

        def render(self, pose, rng=None, faults=None):
            self.calls += 1
            if self.calls == 2:
                raise RuntimeError("camera unplugged")
            h = cfg.camera.height if self.calls != 4 else cfg.camera.height // 2
            img = np.full((h, cfg.camera.width, 3), 128, np.uint8)
            img[:, ::40] = 40  # something to look at
            return img

    s = make(cfg, tmp_path, renderer=FlakyRenderer())
    s.apply(C.Step())
    s.apply(C.Step())  # the camera raises: logged, the same frame is tried again
    assert s.errors == 1 and not s.degraded and len(s.history) == 1
    s.apply(C.Step())  # frame 1
    s.apply(C.Step())  # frame 2: the runner raises, the simulator has moved on
    s.apply(C.Step())  # frame 3
    assert s.errors == 2 and s.degraded
    assert [s.history.get(p).record.index for p in range(len(s.history))] == [0, 1, 3]
    assert "image is" in s.notes[-1].text and s.notes[-1].level == "error"
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2
    assert err[0].startswith("tileviz serve: frame 1: simulator: camera unplugged")
    assert err[1].startswith("tileviz serve: frame 2: ")
    s.apply(C.Relocalize())
    assert not s.degraded
    s.close()


def test_commands_change_the_run(cfg, tmp_path):
    s = make(cfg, tmp_path)
    s.apply(C.Step())
    s.apply(C.SetMode("odometry"))
    s.apply(C.Step())
    assert s.shown_entry().record.status == "predicted"
    s.apply(C.SetMode("autonomous"))
    s.apply(C.SetExtractor("faithful"))
    s.apply(C.Step())
    assert s.shown_entry().record.vision.extractor == "faithful"
    s.apply(C.SetNoise(0.05, 0.02, 0.03, 0.5))
    assert s.runner.bounds.speed_error == 0.05 and s.source.cfg.noise.fraction == 0.5
    s.apply(C.SetManualTarget(2.0, -1.0))
    assert s.setpoint_kind == "manual" and s.cfg.sim.manual_target == (2.0, -1.0)
    s.apply(C.Step())
    assert s.shown_entry().record.setpoint == (2.0, -1.0)
    s.apply(C.SetWaypoints(((1.0, 1.0), (2.0, 2.0))))
    assert s.setpoint_kind == "waypoints"
    s.apply(C.Restart(0.5, 150.0, "light_grout"))
    # the new run's frame 0 is shown at once, paused: nothing of the old run stays
    assert s.cfg.floor.tile_size == 0.5 and s.cfg.camera.ppm == 150.0 and not s.playing
    assert len(s.history) == 1 and s.shown_entry().record.index == 0
    assert [n.text for n in s.notes] == [
        "new run: tile size 0.5 m, 150 px/m, floor style light_grout"]
    s.apply(C.Step())
    assert s.shown_entry().record.index == 1
    s.close()


def test_reset_while_paused_shows_the_new_run_at_once(cfg, tmp_path):
    s = make(cfg, tmp_path)
    s.apply(C.Step())
    first = s.shown_entry().record.truth
    for _ in range(4):
        s.apply(C.Step())
    s.apply(C.Kidnap((1.0, 1.0, 0.0)))
    s.apply(C.Step())
    assert s.tally.frames == 6 and any("kidnapped" in n.text for n in s.notes)
    s.apply(C.Reset())
    assert not s.playing and len(s.history) == 1 and s.shown == 0
    rec = s.shown_entry().record
    assert rec.index == 0 and rec.truth == first
    # the old run's notes and counts are gone; one note says what happened
    assert len(s.notes) == 1 and s.notes[0].text.startswith("Reset: a new run from frame 0")
    assert s.tally.frames == 1
    s.close()


def test_recording_while_paused_says_what_happened(cfg, tmp_path):
    s = make(cfg, tmp_path)
    s.apply(C.StartRecording("nothing"))
    assert "press Play or Step" in s.notes[-1].text
    s.apply(C.StopRecording())
    assert s.notes[-1].text.startswith("nothing recorded: no new frame")
    assert not (tmp_path / "out" / "nothing").exists() and not s.recording_active
    s.apply(C.StartRecording("two"))
    s.apply(C.Step())
    s.apply(C.Step())
    s.apply(C.StopRecording())
    # the note gives the dataset's size, as record does
    mb = dataset_mb(tmp_path / "out" / "two")
    assert mb > 0.1  # two images of the default camera
    assert s.notes[-1].text.startswith(f"recorded 2 frames ({mb:.1f} MB) to")
    assert len((tmp_path / "out" / "two" / "frames.csv").read_text().splitlines()) == 3
    s.close()


def test_kidnap_is_noticed_and_relocalize_recovers(cfg, tmp_path):
    s = make(cfg, tmp_path)
    for _ in range(3):
        s.apply(C.Step())
    s.apply(C.Kidnap((2.3, -1.7, 0.4)))
    s.apply(C.Step())
    rec = s.shown_entry().record
    assert math.isclose(rec.truth.x, 2.3) and math.isclose(rec.truth.y, -1.7)
    # the localizer was not told: the view contradicts its set, which it must say
    assert rec.status in ("rejected", "lost") and not rec.truth_inside()
    s.apply(C.Relocalize())
    s.apply(C.Step())
    rec = s.shown_entry().record
    assert rec.status == "contracted" and rec.truth_inside()
    s.close()


def test_recording_writes_a_dataset_under_the_output_folder_that_replays(cfg, tmp_path):
    s = make(cfg, tmp_path)
    for _ in range(3):
        s.apply(C.Step())
    s.apply(C.StartRecording("../../etc/my run!"))
    for _ in range(4):
        s.apply(C.Step())
    s.apply(C.StopRecording())
    folders = list((tmp_path / "out").iterdir())
    assert [f.name for f in folders] == ["my_run"]
    src = DatasetSource(folders[0])
    frames = list(src)
    assert len(frames) == 4
    first = s.history.get(3).record
    assert frames[0].truth == first.truth
    meta = read_meta(folders[0])
    assert meta.initial_pose == first.truth.as_tuple()  # the recording starts mid-run
    s.close()


def test_output_file_holds_the_six_residuals_per_frame(cfg, tmp_path):
    s = make(cfg, tmp_path, output_file="../../residuals.csv")
    for _ in range(5):
        s.apply(C.Step())
    s.close()
    path = tmp_path / "out" / "residuals.csv"
    assert s.csv_path == path
    rows = list(csv.reader(path.open()))
    assert rows[0] == ["index", "t", "r1", "r2", "r3", "r4", "r5", "r6"]
    assert [int(r[0]) for r in rows[1:]] == [0, 1, 2, 3, 4]
    for r, p in zip(rows[1:], range(5), strict=True):
        want = s.history.get(p).record.residuals
        assert want is not None and [float(v) for v in r[2:]] == list(want)


def test_names_are_sanitized_and_never_overwrite(tmp_path):
    assert sanitize_name("../../etc/passwd") == "passwd"
    assert sanitize_name("a b/c\\..\\d") == "d"
    assert sanitize_name("...") == "run"
    assert sanitize_name("ok-name_1.csv") == "ok-name_1.csv"
    p1 = output_path(tmp_path, "x.csv", suffix=".csv")
    p1.write_text("1")
    p2 = output_path(tmp_path, "x", suffix=".csv")
    assert p1.name == "x.csv" and p2.name == "x-1.csv" and p2.parent == tmp_path


def test_the_mcl_baseline_runs_beside_and_its_particles_are_kept_per_frame(cfg, tmp_path):
    from tileviz.baselines.mcl import calibrated_config

    s = make(cfg, tmp_path, mcl=True, mcl_particles=300)
    # the demo's MCL is the calibrated filter, as `tileviz evaluate` runs it (measured view
    # likelihood, KLD-sampling between 100 and 300 particles)
    assert s.mcl.mcl.config == calibrated_config(particles=300, seed=cfg.sim.seed)
    for _ in range(5):
        s.apply(C.Step())
    e = s.shown_entry()
    assert e.mcl is not None and e.mcl.particles.shape[1] == 3
    assert 100 <= len(e.mcl.particles) <= 300
    truth = e.record.truth
    assert math.hypot(truth.x - e.mcl.mean[0], truth.y - e.mcl.mean[1]) < 0.1
    row = s.history.window(s.shown, 1)[0]
    from tileviz.app.history import METRIC_NAMES

    col = dict(zip(METRIC_NAMES, row, strict=True))
    assert col["mcl_error_xy"] == pytest.approx(math.hypot(truth.x - e.mcl.mean[0],
                                                           truth.y - e.mcl.mean[1]))
    s.apply(C.StepBack())
    assert s.shown_entry().mcl is s.history.get(3).mcl  # the stored cloud, not a new one
    s.apply(C.SetMcl(False))
    s.apply(C.Seek(10))
    s.apply(C.Step())
    assert s.shown_entry().mcl is None
    s.apply(C.SetMcl(True))  # switched on mid-run: starts from the interval set
    s.apply(C.Step())
    assert s.shown_entry().mcl is not None
    s.close()


def test_the_floor_is_its_tile_grid_and_the_texture_a_layer_to_switch_on(tmp_path):
    for name in ("seed", "default"):
        s = make(preset(name), tmp_path)
        assert s.layers["grid"] and not s.layers["floor"]
        s.apply(C.SetLayer("floor", True))
        assert s.layers["floor"]
        s.close()


def test_a_lost_localizer_stays_lost_when_the_settings_change(cfg, tmp_path):
    s = make(cfg, tmp_path)
    s.apply(C.Step())
    s.apply(C.Kidnap((2.3, -1.7, 0.4)))
    for _ in range(cfg.localizer.max_rejections + 2):
        s.apply(C.Step())
    assert s.shown_entry().record.status == "lost"
    s.apply(C.SetNoise(0.03, 0.02, 0.03))  # new bounds must not make its set vouch again
    s.apply(C.SetInflation(0.2, 0.1))
    s.apply(C.Step())
    assert s.shown_entry().record.status == "lost" and s.runner.bounds.speed_error == 0.03
    s.apply(C.SetMode("truth"))  # needs no prior: takes effect at once
    s.apply(C.Step())
    assert s.shown_entry().record.status == "contracted" and s.shown_entry().record.truth_inside()
    s.apply(C.SetMode("autonomous"))
    s.apply(C.Step())
    assert s.shown_entry().record.status == "contracted" and s.shown_entry().record.truth_inside()
    s.close()


def test_the_fault_model_is_set_from_the_gui_and_the_page_says_when_it_is_used(cfg, tmp_path):
    """The settings' fault model (SetFaultModel) reaches the localizer; the status readout says
    when the fault set is followed (frame k of it) and counts the views that fit neither set
    before ``lost`` (a kidnap)."""
    from tileviz.app.status import fault_line

    with pytest.raises(ValueError, match="fault model speed"):
        C.SetFaultModel(-0.1, 0.1)
    s = make(cfg, tmp_path)
    assert (s.cfg.localizer.fault_speed, s.cfg.localizer.fault_yaw_rate) == (0.2, 0.1)
    s.apply(C.SetFaultModel(0.3, 0.1, on=False))
    assert (s.cfg.localizer.fault_speed, s.cfg.localizer.fault_yaw_rate) == (0.0, 0.0)
    s.apply(C.SetFaultModel(0.3, 0.15))
    assert (s.cfg.localizer.fault_speed, s.cfg.localizer.fault_yaw_rate) == (0.3, 0.15)
    for _ in range(10):
        s.apply(C.Step())
    s.apply(C.Inject("slip", frames=40))
    lines = []
    for _ in range(50):
        s.apply(C.Step())
        rec = s.shown_entry().record
        lines.append(fault_line(rec.step, s.cfg.localizer))
        assert rec.status != "lost"
    followed = [ln for ln in lines if ln.startswith("tracking through a fault: frame ")]
    assert followed and "frame 1 of the fault set" in followed[0]
    s.apply(C.Kidnap((2.3, -1.7, 0.4)))
    said = []
    for _ in range(8):
        s.apply(C.Step())
        rec = s.shown_entry().record
        said.append((rec.status, fault_line(rec.step, s.cfg.localizer)))
    assert any("fit neither set (5 make it lost)" in ln for _, ln in said)
    assert said[-1] == ("lost", "")
    s.close()


def test_relocalize_in_a_region_from_the_gui_and_after_lost(cfg, tmp_path):
    """The GUI's "Re-localize in the region" (RelocalizeRegion) restarts a lost localizer with
    candidates that hold the truth; with ``relocalize_region`` (``serve --relocalize-region``)
    that happens by itself at the frame after ``lost``."""
    from tileviz.app.status import fault_line

    assert C.parse_region("-1, -2, 3 4") == (-1.0, -2.0, 3.0, 4.0)
    with pytest.raises(ValueError, match="region"):
        C.parse_region("1, 2, 3")
    with pytest.raises(ValueError, match="x0 <= x1"):
        C.RelocalizeRegion((1.0, 0.0, 0.0, 1.0))
    for auto in (False, True):
        region = (1.3, -2.5, 3.1, -1.0)  # holds the kidnap's pose (2.3, -1.7)
        s = make(cfg, tmp_path / str(auto), relocalize_region=region if auto else None)
        for _ in range(3):
            s.apply(C.Step())
        s.apply(C.Kidnap((2.3, -1.7, 0.4)))
        for _ in range(8):
            s.apply(C.Step())
        statuses = [s.history.get(i).record.status for i in range(s.history.first, s.shown + 1)]
        assert "lost" in statuses
        if not auto:
            assert s.shown_entry().record.status == "lost"
            s.apply(C.RelocalizeRegion(region))
        s.apply(C.Step())
        rec = s.shown_entry().record
        assert rec.status == "contracted" and rec.truth_inside() and len(rec.updated) > 1
        assert fault_line(rec.step, s.cfg.localizer).startswith(
            f"re-localizing: {len(rec.updated)} candidates")
        s.close()


class _FakeImage:
    def __init__(self, label: str = "", visible: bool = True) -> None:
        self.label, self.visible, self.image = label, visible, None


class _FakeMarkdown:
    def __init__(self, visible: bool = True) -> None:
        self.content, self.visible = "", visible


class _FakeGui:
    def add_image(self, blank, *, label="", format="jpeg", jpeg_quality=90, visible=True):
        return _FakeImage(label, visible)

    def add_markdown(self, text, *, visible=True):
        return _FakeMarkdown(visible)


def test_a_stage_that_found_nothing_is_captioned_none_found(cfg, tmp_path):
    """The stages panel on a clean default view: the foreign-lines stage is black (nothing
    foreign) and its label says "none found"; a stage that drew something does not."""
    from tileviz.app.panels import ImagePanels

    s = make(cfg, tmp_path, display=True)
    s.apply(C.Step())
    panels = ImagePanels(_FakeGui())
    panels.show(s.shown_entry(), True, True)
    labels = {slot.handle.label for slot in panels.stages if slot.handle.visible}
    assert "foreign lines: none found" in labels
    assert "gray" in labels  # a stage with something drawn keeps its plain title
    s.close()


def test_the_view_plot_shows_each_view_within_its_bound_at_or_below_one(cfg, tmp_path):
    """The plot "Is the view within its bound of the true pose?": per coordinate, each accepted
    view's error over its declared bound; on the robust extractor's views of the default run
    every value is at most 1 (the view agrees), and frames without a view have no value."""
    from tileviz.app.history import METRIC_NAMES, metrics_of

    s = make(cfg, tmp_path)
    cols = [METRIC_NAMES.index(n) for n in ("view_x", "view_y", "view_heading")]
    seen = 0
    for _ in range(20):
        s.apply(C.Step())
        rec = s.shown_entry().record
        row = metrics_of(rec)[cols]
        if rec.vision.observation is None:
            assert np.isnan(row).all()
        else:
            seen += 1
            assert np.isfinite(row).all() and (row <= 1.0).all() and (row >= 0.0).all()
    assert seen >= 15
    s.close()
