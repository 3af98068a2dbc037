"""The live server replaying a recorded dataset (``serve --dataset``): the boxes it shows are the
ones ``python -m tileviz replay`` writes, it pauses at the end or at a bad row with a note, steps
back through what it showed, and refuses the simulator's commands with a note."""

from __future__ import annotations

import asyncio
import csv
import re
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from tileviz.app import commands as C
from tileviz.app.commands import SIMULATOR_ONLY
from tileviz.app.scene import SceneView, ribbon_centreline
from tileviz.app.session import Session, SessionOptions
from tileviz.cli import main as cli
from tileviz.datasets import DatasetSource, read_meta, replay_config
from tileviz.pipeline import FrameLoop
from tileviz.pipeline.outputs import replay_row
from tileviz.testing.wsclient import ViserClient, serving, stop_serve
from tileviz.types import Box, BoxSet

DURATION = 1.5
"""Seconds recorded: 31 frames at the default 20 Hz."""


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("rec") / "demo"
    assert cli("record", [str(folder), "--duration", str(DURATION), "--quiet"]) == 0
    return folder


@pytest.fixture(scope="module")
def frames(dataset: Path) -> int:
    return sum(1 for _ in open(dataset / "frames.csv")) - 1


def cli_replay(folder: Path, out: Path, *args: str) -> list[list[str]]:
    """The rows (header first) ``python -m tileviz replay`` writes for ``folder``."""
    assert cli("replay", [str(folder), "--out", str(out), "--quiet", *args]) in (0, 2)
    with open(out, newline="") as f:
        return list(csv.reader(f))


def session(folder: Path, tmp_path: Path, *, mode: str | None = None,
            extractor: str | None = None, **kw: object) -> Session:
    cfg = replay_config(read_meta(folder), mode=mode, extractor=extractor)
    return Session(cfg, SessionOptions(out_dir=tmp_path / "out", interactive=True,
                                       dataset=folder, **kw))  # type: ignore[arg-type]


def play_to_end(s: Session, limit: int = 10_000) -> None:
    s.apply(C.Play())
    for _ in range(limit):
        if not s.playing:
            return
        s.advance()
    raise AssertionError("the replay did not stop")


def shown_rows(s: Session) -> list[list[str]]:
    """The replay rows of every frame in the session's history, as ``replay`` writes them."""
    rows = []
    for p in range(s.history.first, s.history.last + 1):
        rows.append([str(v) for v in replay_row(s.history.get(p).record)])
    return rows


def test_the_replay_shows_the_boxes_the_command_line_replay_writes(dataset, frames, tmp_path):
    s = session(dataset, tmp_path, mcl=True, mcl_particles=200)
    play_to_end(s)
    assert len(s.history) == frames and s.history.get(s.history.last).record.index == frames - 1
    want = cli_replay(dataset, tmp_path / "r.csv")
    assert shown_rows(s) == want[1:]
    # not only the hull: the very same contracted boxes, frame by frame
    runner = FrameLoop(replay_config(read_meta(dataset)))
    for p, rec in enumerate(runner.run(DatasetSource(dataset))):
        assert s.history.get(p).record.updated == rec.updated
        assert s.history.get(p).record.truth == rec.truth  # the robot stands at the true pose
    assert s.history.get(5).mcl is not None  # the MCL baseline ran beside, and changed nothing
    assert s.errors == 0 and not s.degraded
    s.close()


@pytest.mark.parametrize(("command", "args"), [
    (C.SetMode("odometry"), ["--mode", "odometry"]),
    (C.SetExtractor("faithful"), ["--extractor", "faithful"]),
])
def test_a_mode_or_extractor_change_replays_from_frame_0_as_the_command_line(
        command, args, dataset, frames, tmp_path):
    s = session(dataset, tmp_path)
    for _ in range(6):
        s.apply(C.Step())
    s.apply(command)
    assert len(s.history) == 1 and s.shown_entry().record.index == 0  # frame 0, at once
    assert "from frame 0" in s.notes[-1].text
    play_to_end(s)
    assert shown_rows(s) == cli_replay(dataset, tmp_path / "r.csv", *args)[1:]
    s.close()


def test_start_frame_opens_the_recorded_run_paused_at_that_frame(dataset, frames, tmp_path):
    s = session(dataset, tmp_path)
    k = frames // 2
    s.skip_to(k)
    entry = s.shown_entry()
    assert not s.playing and entry.index == k and s.history.last == s.shown
    assert len(dict(entry.images)) > 2  # the frame shown has its stage images
    # the sets are those of a replay from frame 0
    assert shown_rows(s)[-1] == cli_replay(dataset, tmp_path / "r.csv")[k + 1]
    s.apply(C.Step())
    assert s.shown_entry().index == k + 1
    s.close()


def test_the_end_of_the_dataset_pauses_and_the_stored_frames_stay(dataset, frames, tmp_path):
    s = session(dataset, tmp_path)
    s.apply(C.Play())
    play_to_end(s)
    last = frames - 1
    assert not s.playing and (s.shown, s.history.last) == (last, last)
    assert s.notes[-1].text.startswith(f"end of dataset, {frames} frames")
    assert s.ended == f"end of dataset, {frames} frames"
    notes = len(s.notes)
    computed = s.frames_computed
    s.apply(C.Step())  # nothing more: no new frame, no repeated note
    assert (s.shown, s.history.last, len(s.notes)) == (last, last, notes)
    s.apply(C.StepBack())
    back = s.shown_entry()
    assert s.shown == last - 1 and back is s.history.get(last - 1)  # the stored frame itself
    assert back.record.index == last - 1 and back.images[0][1][:2] == b"\xff\xd8"
    s.apply(C.Seek(3))
    assert s.shown_entry().record.index == 3
    play_to_end(s)  # forward through the stored frames, not the dataset again
    assert s.shown == last and s.frames_computed == computed
    s.apply(C.Reset())
    assert s.shown_entry().record.index == 0 and len(s.history) == 1 and s.ended is None
    s.apply(C.Step())
    assert s.shown_entry().record.index == 1
    s.close()


def test_the_readout_keeps_saying_the_dataset_ended(dataset, frames, tmp_path):
    from tileviz.app.status import StatusState, render_status

    s = session(dataset, tmp_path)  # no server: the readout alone
    play_to_end(s)
    text = render_status(StatusState.of(s, s.shown_entry(), None, live=True))
    assert text.count(f"end of dataset, {frames} frames") == 1
    for _ in range(3):
        s.apply(C.Kidnap())  # newer notes push the end's note out of view
    text = render_status(StatusState.of(s, s.shown_entry(), None, live=True))
    assert f"end of dataset, {frames} frames" in text and f"frame {frames - 1}" in text
    s.close()


def _damage_speed(cells: list[str], folder: Path) -> None:
    cells[3] = "banana"


def _remove_image(cells: list[str], folder: Path) -> None:
    (folder / cells[2]).unlink()


@pytest.mark.parametrize("damage", [_damage_speed, _remove_image])
def test_a_bad_row_keeps_the_frames_before_it_and_names_file_and_row(damage, dataset, tmp_path,
                                                                     capsys):
    folder = tmp_path / "ds"
    shutil.copytree(dataset, folder)
    lines = (folder / "frames.csv").read_text().splitlines()
    bad = 7  # frame 7: line 9 of frames.csv
    cells = lines[bad + 1].split(",")
    damage(cells, folder)
    lines[bad + 1] = ",".join(cells)
    (folder / "frames.csv").write_text("\n".join(lines) + "\n")
    s = session(folder, tmp_path)
    play_to_end(s)
    assert [s.history.get(p).record.index for p in range(len(s.history))] == list(range(bad))
    note = s.notes[-1]
    assert note.level == "error" and f"frames.csv line {bad + 2} (frame {bad})" in note.text
    assert not s.playing and s.ended is not None
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"frames.csv line {bad + 2} (frame {bad})" in err[0]
    # the frames before it are those of the undamaged dataset
    assert shown_rows(s) == cli_replay(dataset, tmp_path / "r.csv")[1: bad + 1]
    s.apply(C.StepBack())
    assert s.shown_entry().record.index == bad - 2
    s.close()


def test_simulator_commands_leave_a_note_and_change_nothing(dataset, tmp_path):
    s = session(dataset, tmp_path)
    for _ in range(3):
        s.apply(C.Step())
    cfg, shown, version = s.cfg, s.shown, s.world_version
    commands = [C.SetSetpoint("manual"), C.SetManualTarget(1.0, 2.0),
                C.SetWaypoints(((1.0, 1.0),)), C.Kidnap(), C.Kidnap((1.0, 1.0, 0.0)),
                C.SetNoise(0.05, 0.05, 0.05, 2.0), C.Inject("slip"), C.Restart(0.5, 150.0),
                C.StartRecording("x"), C.StopRecording()]
    assert {type(c) for c in commands} == set(SIMULATOR_ONLY)
    for cmd in commands:
        s.apply(cmd)
        assert C.label(cmd) in s.notes[-1].text and "nothing changed" in s.notes[-1].text
    assert (s.cfg, s.shown, s.world_version, len(s.history)) == (cfg, shown, version, 3)
    assert s.setpoint_kind == "dataset" and not s.recording_active
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    s.apply(C.Step())
    want = cli_replay(dataset, tmp_path / "r.csv")
    assert shown_rows(s) == want[1:5]  # the replay went on as if nothing was asked
    s.close()


def test_relocalize_uses_the_next_true_pose_and_without_truth_says_so(dataset, tmp_path):
    s = session(dataset, tmp_path)
    for _ in range(3):
        s.apply(C.Step())
    s.apply(C.Relocalize())
    s.apply(C.Step())
    rec = s.shown_entry().record
    assert rec.index == 3 and rec.truth_inside()  # the peeked frame is the one delivered next
    s.close()

    # the same dataset without the truth columns
    folder = tmp_path / "notruth"
    shutil.copytree(dataset, folder)
    rows = list(csv.reader(open(folder / "frames.csv", newline="")))
    with open(folder / "frames.csv", "w", newline="") as f:
        csv.writer(f).writerows(r[:6] for r in rows)
    s = session(folder, tmp_path)
    s.apply(C.Step())
    s.apply(C.Relocalize())
    assert "not known" in s.notes[-1].text and s.shown_entry().record.truth is None
    assert s.source.path() == []
    s.apply(C.Step())
    assert s.shown_entry().record.index == 1
    s.close()


def test_a_dataset_frame_draws_no_setpoint_and_the_robot_at_the_estimate_without_truth():
    import viser

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = SceneView(server.scene, pool=2)
        cfg = replay_config(read_meta_default())
        view.set_world(cfg, path=[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], waypoints=[(1.0, 1.0)],
                       setpoint_kind="dataset", closed=False)
        view.apply_layers({"path": True, "setpoint": True, "truth": True, "robot": True},
                          force=True)
        seg = ribbon_centreline(view.path.vertices)
        drawn = {(tuple(np.round(a[:2], 6)), tuple(np.round(b[:2], 6)))
                 for a, b in seg if not np.allclose(a, b)}
        assert drawn == {((0.0, 0.0), (1.0, 0.0)), ((1.0, 0.0), (1.0, 1.0))}  # not a loop
        assert view.path.visible
        box = Box(2.0, 2.2, 3.0, 3.2, 0.4, 0.6)
        rec = SimpleNamespace(truth=None, setpoint=None, updated=BoxSet((box,)),
                              predicted=BoxSet((box,)))
        trail = np.zeros((2, 2))
        view.show(rec, trail, trail)
        assert tuple(view.robot.position[:2]) == pytest.approx((2.1, 3.1))
        assert not view.setpoint.visible and not view.truth.visible
        view.apply_layers({"path": True, "setpoint": True, "truth": False, "robot": True})
        view.apply_layers({"path": True, "setpoint": True, "truth": True, "robot": True})
        assert not view.truth.visible  # switching the layer on does not show an unknown pose
    finally:
        server.stop()


def read_meta_default():
    from tileviz.config import preset
    from tileviz.datasets import DatasetMeta

    return DatasetMeta.from_config(preset("default"))


def visible(c: ViserClient, label: str) -> bool:
    """Whether the browser shows the GUI element labelled ``label`` (its creation, then its
    updates)."""
    uuid = c.gui_uuid(label)
    shown = True
    for m in c.messages:
        if m.get("uuid") != uuid:
            continue
        if isinstance(m.get("props"), dict) and "visible" in m["props"]:
            shown = bool(m["props"]["visible"])
        if m.get("type") == "GuiUpdateMessage" and "visible" in m.get("updates", {}):
            shown = bool(m["updates"]["visible"])
    return shown


def test_serve_dataset_replays_in_the_browser_to_the_end(dataset, frames, tmp_path):
    with serving(["--port", "0", "--dataset", str(dataset), "--max-speed", "--mode",
                  "autonomous", "--out-dir", str(tmp_path)], cwd=tmp_path) as (proc, url):
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/", url), url

        def status(m: dict, pattern: str) -> bool:
            return (m.get("type") in ("GuiUpdateMessage", "GuiHtmlMessage")
                    and re.search(pattern, str(m.get("updates", m.get("props", {})))) is not None)

        async def scenario() -> None:
            async with ViserClient(url) as c:
                await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage")
                # the frames advance to the dataset's end, which the readout says
                await c.wait_for(lambda m: status(m, rf"end of dataset, {frames} frames"),
                                 timeout=600)
                shown = [int(x) for m in c.messages
                         for x in re.findall(r"<b>frame (\d+)</b>", str(m.get("updates", "")))]
                assert max(shown) == frames - 1 and len(set(shown)) >= 2
                # the simulator's controls are not shown
                for label in ("Kidnap (teleport the robot)", "Setpoint", "Faults", "Record",
                              "Floor and camera"):
                    assert not visible(c, label), label
                assert visible(c, "Step back") and visible(c, "Mode")
                mark = len(c.messages)
                await c.click("Step back")
                await c.wait_for(lambda m: status(m, rf"<b>frame {frames - 2}</b>"),
                                 start=mark)

        asyncio.run(scenario())
        out, err = stop_serve(proc)
    assert proc.returncode == 0, err
    assert "Traceback" not in err
