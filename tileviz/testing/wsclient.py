"""A minimal viser websocket client for the server tests and ``bench/bench_server.py`` (it needs
the test extra's msgpack, zstandard and websockets, and this checkout's ``serve.py``).

viser's wire format (``viser/infra/_infra.py``, version 1.1): the client asks for the subprotocol
``viser-v<version>``. Each server->client websocket message is one *window* of messages:

    [8 bytes]  length of the msgpack payload once decompressed (little-endian uint64)
    [8 bytes]  length of the zstd-compressed msgpack payload (little-endian uint64)
    [N bytes]  zstd-compressed msgpack {"messages": [...], "timestampSec": ...,
               "binaryBufferLengths": [...]}
    padding to 8-byte alignment, then the binary buffers (numpy arrays), each 8-byte aligned;
    a message refers to buffer i by a placeholder {"__binary_index": i, "dtype": "<f4"}.

Client->server messages are plain msgpack dicts with a ``type`` (the message class name). The
server treats a client as connected after its first ``ViewerCameraMessage``; GUI callbacks only
run for connected clients.
"""

from __future__ import annotations

import asyncio
import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

from tileviz.testing import REPO, missing

try:
    import msgpack
    import zstandard
except ImportError as exc:
    raise ImportError(missing(exc.name or "msgpack", "tileviz.testing.wsclient")) from exc

__all__ = ["ViserClient", "decode_window", "serving", "start_serve", "stop_serve",
           "subprotocol"]


def subprotocol() -> str:
    """The websocket subprotocol of the installed viser version."""
    import viser

    return f"viser-v{viser.__version__}"


def _resolve(obj: Any, buffers: list[memoryview]) -> Any:
    if isinstance(obj, dict):
        if "__binary_index" in obj and "dtype" in obj:
            return np.frombuffer(buffers[obj["__binary_index"]], dtype=np.dtype(obj["dtype"]))
        return {k: _resolve(v, buffers) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_resolve(v, buffers) for v in obj]
    return obj


def start_serve(args: Sequence[str], *, cwd: str | os.PathLike[str] | None = None,
                stderr: int | None = subprocess.PIPE) -> tuple[subprocess.Popen[str], str]:
    """Start ``serve.py`` of this checkout with ``args`` in its own process and return it with
    the URL it prints once it serves (e.g. ``http://127.0.0.1:PORT/``). If it exits before
    printing one, raises RuntimeError with its stderr. The caller stops the process."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, str(REPO / "serve.py"), *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=stderr, text=True)
    for line in proc.stdout:  # type: ignore[union-attr]
        m = re.search(r"open (http://\S+)", line)
        if m:
            return proc, m.group(1)
    proc.kill()
    err = proc.stderr.read() if proc.stderr is not None else ""
    raise RuntimeError(f"serve.py did not start: {err.strip()}")


@contextmanager
def serving(args: Sequence[str], *, cwd: str | os.PathLike[str] | None = None,
            ) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """:func:`start_serve` as a context: ``(process, url)``, the process killed on leaving if it
    is still running (a failed test leaves no server behind)."""
    proc, url = start_serve(args, cwd=cwd)
    try:
        yield proc, url
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def stop_serve(proc: subprocess.Popen[str], timeout: float = 60.0) -> tuple[str, str]:
    """Stop ``serve.py`` as Ctrl-C does (SIGINT) and return its (stdout, stderr) once it has
    exited (``timeout`` seconds at most, else subprocess.TimeoutExpired)."""
    proc.send_signal(signal.SIGINT)
    return proc.communicate(timeout=timeout)


def decode_window(payload: bytes) -> list[dict[str, Any]]:
    """The messages of one server->client websocket message (see the module docstring); numpy
    placeholders become 1-D numpy arrays (flat, of the given dtype)."""
    if len(payload) < 16:
        raise ValueError(f"viser window too short: {len(payload)} bytes")
    inner_len = int.from_bytes(payload[0:8], "little")
    comp_len = int.from_bytes(payload[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(payload[16:16 + comp_len],
                                                    max_output_size=inner_len)
    body = msgpack.unpackb(inner, raw=False, strict_map_key=False)
    offset = 16 + comp_len
    view = memoryview(payload)
    buffers: list[memoryview] = []
    for n in body.get("binaryBufferLengths", ()):
        offset += (8 - offset % 8) % 8
        buffers.append(view[offset:offset + n])
        offset += n
    return [_resolve(m, buffers) for m in body["messages"]]


class ViserClient:
    """An asyncio websocket client of a viser server that keeps every message it receives.

    Use ``async with ViserClient(url) as c: ...``; :meth:`wait_for` waits for a message matching a
    predicate; :meth:`send` sends a message dict."""

    def __init__(self, url: str) -> None:
        self.url = url.replace("http://", "ws://").replace("https://", "wss://")
        self.messages: list[dict[str, Any]] = []
        self.windows = 0
        self._ws: Any = None
        self._reader: asyncio.Task[None] | None = None
        self._event = asyncio.Event()

    async def __aenter__(self) -> ViserClient:
        import websockets
        from websockets.typing import Subprotocol

        self._ws = await websockets.connect(self.url, subprotocols=[Subprotocol(subprotocol())],
                                            max_size=None, compression=None)
        self._reader = asyncio.create_task(self._read())
        await self.send({
            "type": "ViewerCameraMessage", "wxyz": (1.0, 0.0, 0.0, 0.0),
            "position": (0.0, -5.0, 5.0), "fov": 1.0, "near": 0.01, "far": 1000.0,
            "image_height": 600, "image_width": 800, "look_at": (0.0, 0.0, 0.0),
            "up_direction": (0.0, 0.0, 1.0),
        })
        return self

    async def __aexit__(self, *exc: object) -> None:
        if self._reader is not None:
            self._reader.cancel()
        if self._ws is not None:
            await self._ws.close()

    async def _read(self) -> None:
        import websockets

        try:
            async for raw in self._ws:
                if isinstance(raw, bytes):
                    self.messages.extend(decode_window(raw))
                    self.windows += 1
                    self._event.set()
        except websockets.exceptions.ConnectionClosed:
            pass

    async def send(self, message: dict[str, Any]) -> None:
        await self._ws.send(msgpack.packb(message, use_bin_type=True))

    async def wait_for(self, predicate: Any, timeout: float = 30.0,
                       start: int = 0) -> dict[str, Any]:
        """The first message from position ``start`` on with ``predicate(message)`` true; waits
        up to ``timeout`` seconds (TimeoutError)."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        i = start
        while True:
            while i < len(self.messages):
                if predicate(self.messages[i]):
                    return self.messages[i]
                i += 1
            left = deadline - loop.time()
            if left <= 0:
                raise TimeoutError("no matching viser message arrived")
            self._event.clear()
            try:
                await asyncio.wait_for(self._event.wait(), left)
            except TimeoutError:
                pass

    def of_type(self, name: str) -> Iterator[dict[str, Any]]:
        """Received messages of one type (e.g. ``GuiButtonMessage``)."""
        return (m for m in self.messages if m.get("type") == name)

    def gui_uuid(self, label: str, kind: str | None = None) -> str:
        """The uuid of the GUI element with that label (and message type ``kind``, if given)."""
        for m in self.messages:
            props = m.get("props")
            if isinstance(props, dict) and props.get("label") == label and "uuid" in m:
                if kind is None or m.get("type") == kind:
                    return str(m["uuid"])
        raise KeyError(f"no GUI element labelled {label!r}")

    async def click(self, label: str) -> None:
        """Press the button with that label."""
        uuid = self.gui_uuid(label, "GuiButtonMessage")
        await self.send({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": True}})
