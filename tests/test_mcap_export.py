"""replay --mcap: an MCAP file with Foxglove's schemas, read back with the mcap reader."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

pytest.importorskip("mcap_protobuf", reason="the [ros] extra (pip install -e '.[ros]')")

from mcap.reader import make_reader  # noqa: E402
from mcap_protobuf.decoder import DecoderFactory  # noqa: E402

from tileviz.__main__ import main as tileviz_main  # noqa: E402
from tileviz.datasets.mcap_export import CONTRACTION_RGB, PREDICTION_RGB  # noqa: E402

FRAMES = 41


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    d = tmp_path_factory.mktemp("mcap")
    ds = d / "ds"
    assert tileviz_main(["record", str(ds), "--duration", "2", "--quiet", "--seed", "5"]) == 0
    out, mcap = d / "r.csv", d / "run.mcap"
    assert tileviz_main(["replay", str(ds), "--out", str(out), "--mcap", str(mcap),
                         "--quiet"]) == 0
    return ds, out, mcap


def _messages(path: Path) -> dict[str, list]:
    out: dict[str, list] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None  # the file was finished (index and summary written)
        for schema, channel, message in reader.iter_messages():
            out.setdefault(channel.topic, []).append((schema, channel, message))
    return out


def test_topics_counts_and_schemas(exported: tuple[Path, Path, Path]) -> None:
    _, _, mcap = exported
    msgs = _messages(mcap)
    assert set(msgs) == {"/camera/image", "/truth", "/set/prediction", "/set/contraction",
                         "/status"}
    assert all(len(v) == FRAMES for v in msgs.values())
    names = {t: v[0][0].name for t, v in msgs.items()}
    assert names == {"/camera/image": "foxglove.CompressedImage",
                     "/truth": "foxglove.PoseInFrame",
                     "/set/prediction": "foxglove.SceneUpdate",
                     "/set/contraction": "foxglove.SceneUpdate",
                     "/status": "tileviz.Status"}
    times = [m.log_time for _, _, m in msgs["/status"]]
    assert times == sorted(times) and times[1] - times[0] == 50_000_000


def test_one_box_and_the_status_match_the_replay_csv(exported: tuple[Path, Path, Path]) -> None:
    ds, out, mcap = exported
    with open(out, newline="") as f:
        rows = list(csv.DictReader(f))
    k = 25
    row = rows[k]
    assert int(row["boxes"]) == 1
    with open(mcap, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        got = {}
        for _, channel, message, decoded in reader.iter_decoded_messages(
                topics=["/set/contraction", "/set/prediction", "/camera/image", "/truth"]):
            if message.sequence == k:
                got[channel.topic] = decoded
    with open(mcap, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=["/status"]):
            if message.sequence == k:
                got[channel.topic] = message.data
    cube = got["/set/contraction"].entities[0].cubes[0]
    x_lo, x_hi = float(row["x_lo"]), float(row["x_hi"])
    t_lo, t_hi = float(row["theta_lo"]), float(row["theta_hi"])
    assert cube.pose.position.x == pytest.approx(0.5 * (x_lo + x_hi), abs=1e-12)
    assert cube.size.x == pytest.approx(x_hi - x_lo, abs=1e-12)
    assert cube.size.y == pytest.approx(float(row["y_hi"]) - float(row["y_lo"]), abs=1e-12)
    assert cube.size.z == pytest.approx(t_hi - t_lo, abs=1e-12)
    z_lo = cube.pose.position.z - 0.5 * cube.size.z
    assert -math.pi <= z_lo < math.pi
    assert math.remainder(z_lo - t_lo, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    assert (round(cube.color.r * 255), round(cube.color.g * 255),
            round(cube.color.b * 255)) == CONTRACTION_RGB
    pred = got["/set/prediction"].entities[0].cubes[0]
    assert (round(pred.color.g * 255)) == PREDICTION_RGB[1]
    status = json.loads(got["/status"])
    assert status["status"] == row["status"] and status["boxes"] == 1
    assert status["x_width"] == pytest.approx(x_hi - x_lo)
    assert got["/camera/image"].format == "png"
    assert bytes(got["/camera/image"].data) == (ds / "images" / f"{k:06d}.png").read_bytes()
    with open(ds / "frames.csv", newline="") as f:
        truth = list(csv.DictReader(f))[k]
    assert got["/truth"].pose.position.x == float(truth["x"])


def test_the_demo_colours() -> None:
    pytest.importorskip("viser")
    from tileviz.app.scene import COLOURS

    assert PREDICTION_RGB == COLOURS["prediction"] and CONTRACTION_RGB == COLOURS["boxes"]
