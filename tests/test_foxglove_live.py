"""The live Foxglove server (foxglove-sdk): a client speaking Foxglove's WebSocket protocol
(subprotocol foxglove.sdk.v1) sees the topics of ``replay --mcap``, subscribes and receives every
topic's messages of a frame, decodable with their schemas."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

import pytest

pytest.importorskip("foxglove", reason="the [ros] extra (pip install -e '.[ros]')")
websockets = pytest.importorskip("websockets")

from tileviz.config import Config  # noqa: E402
from tileviz.datasets.mcap_export import TOPICS  # noqa: E402
from tileviz.pipeline.frame_loop import FrameLoop  # noqa: E402
from tileviz.ros.foxglove_live import FoxgloveLive  # noqa: E402
from tileviz.sim.source import SimSource  # noqa: E402
from tileviz.testing.foxglove import receive_topics  # noqa: E402


def test_a_client_receives_every_topic_of_a_frame() -> None:
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    cfg = Config()
    frame = next(iter(SimSource(cfg)))
    rec = FrameLoop(cfg).process(frame)
    server = FoxgloveLive(port=0)
    try:
        got = asyncio.run(receive_topics(server.port, TOPICS.values(),
                                         lambda: server.publish(rec, 1_000_000_000)))
    finally:
        server.close()
    assert set(got) == set(TOPICS.values())
    status = json.loads(got["/status"])
    assert status["status"] == rec.status and status["boxes"] == len(rec.updated)
    cubes = SceneUpdate.FromString(got["/set/contraction"]).entities[0].cubes
    assert len(cubes) == len(rec.updated)
    assert got["/camera/image"]  # a PNG of the view


def test_the_demo_serves_each_new_frame_to_a_foxglove_client(tmp_path: Path) -> None:
    """``serve --foxglove``: the session publishes every frame it makes (here the simulator's)
    on every topic of ``replay --mcap``, the status and the boxes those of the frame shown."""
    from tileviz.app.session import Session, SessionOptions

    s = Session(Config(), SessionOptions(foxglove=0, display=False, out_dir=tmp_path))
    try:
        got = asyncio.run(receive_topics(s.foxglove.port, TOPICS.values(), s.compute))
        rec = s.history.get(s.history.last).record
    finally:
        s.close()
    assert s.foxglove is None  # closed with the session
    status = json.loads(got["/status"])
    assert status["status"] == rec.status and status["boxes"] == len(rec.updated)
    assert got["/camera/image"] and got["/truth"]
