"""A run served live to Foxglove (or Lichtblick) with Foxglove's SDK (``foxglove-sdk``), on
127.0.0.1: the topics and schemas of ``replay --mcap`` (:data:`tileviz.datasets.mcap_export.
TOPICS`: camera, truth, the sets as cubes, status), each frame as it is processed.

Used by ``serve.py --foxglove [PORT]`` and ``python -m tileviz ros --foxglove [PORT]``. Imports
neither rospy nor viser.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from tileviz.cliutil import CliError

__all__ = ["DEFAULT_PORT", "FOXGLOVE_INSTALL", "FoxgloveLive"]

DEFAULT_PORT = 8765
"""Foxglove's usual WebSocket port."""
FOXGLOVE_INSTALL = "pip install -e '.[ros]'"


class FoxgloveLive:
    """A Foxglove WebSocket server on ``host``:``port`` (0: any free port, :attr:`port` says
    which); :meth:`publish` sends one frame's messages, :meth:`close` stops the server."""

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1",
                 name: str = "tileviz") -> None:
        try:
            import foxglove
        except ImportError:
            raise CliError(f"--foxglove needs the foxglove-sdk package: {FOXGLOVE_INSTALL}"
                           ) from None
        from tileviz.datasets.mcap_export import TOPICS, FrameEncoder

        self._enc = FrameEncoder()
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(name=name, host=host, port=port,
                                                 context=self._context)
        except Exception as e:  # noqa: BLE001 - the SDK's errors for a busy port vary
            raise CliError(f"--foxglove: cannot serve on {host}:{port} ({e})") from None
        self.port = int(self._server.port)
        self.host = host
        self._channels: dict[str, Any] = {}
        for key, (sname, encoding, data) in self._enc.schemas().items():
            schema = foxglove.Schema(name=sname, encoding=encoding, data=data)
            self._channels[key] = foxglove.Channel(
                TOPICS[key], schema=schema,
                message_encoding="json" if key == "status" else "protobuf",
                context=self._context)

    def publish(self, rec: Any, ns: int, image: np.ndarray | None = None,
                status: str | None = None) -> None:
        """One frame (a :class:`tileviz.pipeline.FrameRecord`) stamped ``ns`` (nanoseconds);
        ``image``: the camera image (HxWx3 RGB or HxW gray uint8, sent as PNG), default the
        record's; ``status`` overrides the record's."""
        img = rec.image if image is None else image
        data = None
        if img is not None and img.size:
            bgr = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
            ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
            if ok:
                data = (buf.tobytes(), "png")
        for key, payload in self._enc.messages(rec, ns, data, status):
            self._channels[key].log(payload, log_time=ns)

    def close(self) -> None:
        self._server.stop()
