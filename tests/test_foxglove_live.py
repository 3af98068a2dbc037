"""The live Foxglove server (foxglove-sdk): a client speaking Foxglove's WebSocket protocol
(subprotocol foxglove.sdk.v1) sees the topics of ``replay --mcap``, subscribes and receives every
topic's messages of a frame, decodable with their schemas."""

from __future__ import annotations

import asyncio
import json
import struct

import pytest

pytest.importorskip("foxglove", reason="the [ros] extra (pip install -e '.[ros]')")
websockets = pytest.importorskip("websockets")

from tileviz.config import Config  # noqa: E402
from tileviz.datasets.mcap_export import TOPICS  # noqa: E402
from tileviz.pipeline.frame_loop import FrameLoop  # noqa: E402
from tileviz.ros.foxglove_live import FoxgloveLive  # noqa: E402
from tileviz.sim.source import SimSource  # noqa: E402


async def _client(port: int, publish: object) -> dict[str, bytes]:
    got: dict[str, bytes] = {}
    async with websockets.connect(f"ws://127.0.0.1:{port}",
                                  subprotocols=["foxglove.sdk.v1"]) as ws:
        channels: dict[int, str] = {}
        subs: dict[int, str] = {}
        while len(channels) < len(TOPICS):
            msg = json.loads(await asyncio.wait_for(ws.recv(), 30))
            if msg.get("op") == "advertise":
                for ch in msg["channels"]:
                    channels[ch["id"]] = ch["topic"]
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": c} for i, c in enumerate(channels)]}))
        subs = {i: channels[c] for i, c in enumerate(channels)}
        await asyncio.sleep(0.5)
        publish()  # type: ignore[operator]
        while len(got) < len(TOPICS):
            data = await asyncio.wait_for(ws.recv(), 30)
            if isinstance(data, bytes) and data[0] == 1:  # opcode 1: message data
                sub_id = struct.unpack_from("<I", data, 1)[0]
                got[subs[sub_id]] = data[1 + 4 + 8:]
    return got


def test_a_client_receives_every_topic_of_a_frame() -> None:
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    cfg = Config()
    frame = next(iter(SimSource(cfg)))
    rec = FrameLoop(cfg).process(frame)
    server = FoxgloveLive(port=0)
    try:
        got = asyncio.run(_client(server.port, lambda: server.publish(rec, 1_000_000_000)))
    finally:
        server.close()
    assert set(got) == set(TOPICS.values())
    status = json.loads(got["/status"])
    assert status["status"] == rec.status and status["boxes"] == len(rec.updated)
    cubes = SceneUpdate.FromString(got["/set/contraction"]).entities[0].cubes
    assert len(cubes) == len(rec.updated)
    assert got["/camera/image"]  # a PNG of the view
