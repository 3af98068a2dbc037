"""Export MCAP in the live demo: the last recording, written beside its folder on a background
thread, the end said in one note; refusals and failures are one line, the run goes on."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

pytest.importorskip("mcap_protobuf", reason="the [ros] extra (pip install -e '.[ros]')")

from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate  # noqa: E402
from mcap.reader import make_reader  # noqa: E402

from tileviz.app import commands as C  # noqa: E402
from tileviz.app.session import Session, SessionOptions  # noqa: E402
from tileviz.config import preset  # noqa: E402
from tileviz.pipeline.replay import replay  # noqa: E402


def _session(tmp_path: Path) -> Session:
    return Session(preset("default"), SessionOptions(out_dir=tmp_path / "out", interactive=True))


def _record(s: Session, name: str, frames: int) -> Path:
    s.apply(C.Step())
    s.apply(C.StartRecording(name))
    for _ in range(frames):
        s.apply(C.Step())
    s.apply(C.StopRecording())
    assert s.last_recording is not None
    return s.last_recording


def _finish(s: Session) -> None:
    assert s.export is not None
    s.export.join(timeout=300)
    s.poll()
    assert s.export is None


def test_export_writes_the_recording_as_the_replay_does(tmp_path: Path) -> None:
    s = _session(tmp_path)
    folder = _record(s, "run one", 6)
    s.apply(C.ExportMcap())
    assert s.notes[-1].text.startswith(f"exporting {folder} to ")
    _finish(s)
    out = folder.with_name(folder.name + ".mcap")
    assert s.notes[-1].level == "info"
    assert s.notes[-1].text == f"exported 6 frames to {out} (open it in Foxglove)"
    s.apply(C.Step())  # the run goes on
    s.close()
    topics: dict[str, list] = {}
    with open(out, "rb") as f:
        reader = make_reader(f)
        for _, channel, message in reader.iter_messages():
            topics.setdefault(channel.topic, []).append(message)
    assert {t: len(v) for t, v in topics.items()} == {
        "/camera/image": 6, "/truth": 6, "/set/prediction": 6, "/set/contraction": 6,
        "/status": 6}
    # the boxes are those `replay` computes from the recorded dataset
    table = tmp_path / "replay.csv"
    replay(folder, out=table, jobs=1)
    rows = list(csv.DictReader(table.open()))
    update = SceneUpdate()
    update.ParseFromString(topics["/set/contraction"][-1].data)
    last = update.entities[0].cubes
    assert len(last) >= 1
    x_lo = min(c.pose.position.x - c.size.x / 2 for c in last)
    x_hi = max(c.pose.position.x + c.size.x / 2 for c in last)
    assert x_lo == pytest.approx(float(rows[-1]["x_lo"]), abs=1e-9)
    assert x_hi == pytest.approx(float(rows[-1]["x_hi"]), abs=1e-9)


def test_export_refuses_in_one_line_without_a_finished_recording(tmp_path: Path) -> None:
    s = _session(tmp_path)
    with pytest.raises(ValueError, match="^nothing to export: record a run first"):
        s.apply(C.ExportMcap())
    s.apply(C.StartRecording("busy"))
    s.apply(C.Step())
    with pytest.raises(ValueError, match="^nothing to export: stop the recording first"):
        s.apply(C.ExportMcap())
    s.apply(C.StopRecording())
    assert s.export is None
    s.close()


def test_a_failed_export_is_one_error_line_and_the_run_goes_on(tmp_path: Path) -> None:
    s = _session(tmp_path)
    folder = _record(s, "broken", 3)
    (folder / "frames.csv").write_text("not,a,dataset\n")
    s.apply(C.ExportMcap())
    _finish(s)
    note = s.notes[-1]
    assert note.level == "error" and "\n" not in note.text
    assert note.text.startswith(f"MCAP export of {folder} failed: ")
    s.apply(C.Step())
    assert s.shown_entry() is not None
    s.close()
