"""A client of Foxglove's live WebSocket protocol (subprotocol ``foxglove.sdk.v1``) for tests:
:func:`receive_topics` waits for the server to advertise ``topics``, subscribes to them all and
returns the first message of each (its payload bytes)."""

from __future__ import annotations

import asyncio
import json
import struct
from collections.abc import Callable, Collection

__all__ = ["receive_topics"]


async def receive_topics(port: int, topics: Collection[str],
                         publish: Callable[[], object] | None = None,
                         timeout: float = 30.0) -> dict[str, bytes]:
    """Connect to ws://127.0.0.1:``port``, subscribe to every advertised channel once all of
    ``topics`` are advertised, call ``publish`` (when given) and return, by topic, the payload of
    the first message received on each of ``topics``. ``timeout``: seconds per message, at most
    (asyncio.TimeoutError beyond)."""
    import websockets

    want = set(topics)
    got: dict[str, bytes] = {}
    async with websockets.connect(f"ws://127.0.0.1:{port}",
                                  subprotocols=["foxglove.sdk.v1"]) as ws:  # type: ignore[list-item]
        channels: dict[int, str] = {}
        while not want <= set(channels.values()):
            msg = json.loads(await asyncio.wait_for(ws.recv(), timeout))
            if msg.get("op") == "advertise":
                for ch in msg["channels"]:
                    channels[ch["id"]] = ch["topic"]
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": c} for i, c in enumerate(channels)]}))
        subs = {i: channels[c] for i, c in enumerate(channels)}
        await asyncio.sleep(0.5)
        if publish is not None:
            publish()
        while not want <= set(got):
            data = await asyncio.wait_for(ws.recv(), timeout)
            if isinstance(data, bytes) and data[0] == 1:  # opcode 1: message data
                sub_id = struct.unpack_from("<I", data, 1)[0]
                got.setdefault(subs[sub_id], data[1 + 4 + 8:])
    return got
