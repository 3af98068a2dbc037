"""Reading back a page that ``export-html`` wrote: the recording viser's client plays, and the
sets it draws frame after frame (for the tests)."""

from __future__ import annotations

import base64
import math
import re
from typing import Any

__all__ = ["page_recording", "recorded_hulls"]


def page_recording(html: str) -> dict[str, Any]:
    """The recording inside a self-contained viser page: ``durationSeconds`` and ``messages``
    ((time s, message dict) pairs) as viser's ``StateSerializer.serialize`` wrote them (an
    8-byte size, zstd, then an 8-byte msgpack length and the msgpack payload)."""
    import msgpack
    import zstandard

    m = re.search(r'__VISER_EMBED_DATA__="([^"]+)"', html)
    if m is None:
        raise ValueError("not a viser page: no embedded recording")
    raw = base64.b64decode(m.group(1))
    inner = zstandard.ZstdDecompressor().decompress(
        raw[8:], max_output_size=int.from_bytes(raw[:8], "little"))
    n = int.from_bytes(inner[:8], "little")
    return dict(msgpack.unpackb(inner[8: 8 + n], strict_map_key=False))


def recorded_hulls(recording: dict[str, Any], name: str = "boxes"
                   ) -> list[tuple[float, float, float, float] | None]:
    """The (x_lo, x_hi, y_lo, y_hi) hull, metres, of the visible boxes of the scene's set
    ``name`` (``boxes``: contracted, ``prediction``) at each recorded time (one per frame
    shown), or None when none is visible."""
    prefix = f"/intervals/{name}/"
    state: dict[str, dict[str, Any]] = {}
    out: list[tuple[float, float, float, float] | None] = []
    times = sorted({t for t, _ in recording["messages"]})
    msgs = sorted(recording["messages"], key=lambda tm: tm[0])
    i = 0
    for t in times:
        while i < len(msgs) and msgs[i][0] <= t:
            m = msgs[i][1]
            i += 1
            node = str(m.get("name", ""))
            if not node.startswith(prefix):
                continue
            s = state.setdefault(node, {"visible": True})
            kind = m["type"]
            if kind == "BoxMessage":
                s["dimensions"] = m["props"]["dimensions"]
            elif kind == "SceneNodeUpdateMessage" and "dimensions" in m["updates"]:
                s["dimensions"] = m["updates"]["dimensions"]
            elif kind == "SetPositionMessage":
                s["position"] = m["position"]
            elif kind == "SetSceneNodeVisibilityMessage":
                s["visible"] = m["visible"]
        lo_x = lo_y = math.inf
        hi_x = hi_y = -math.inf
        for s in state.values():
            if s.get("visible") and "position" in s and "dimensions" in s:
                (x, y, _), (w, h, _) = s["position"], s["dimensions"]
                lo_x, hi_x = min(lo_x, x - w / 2), max(hi_x, x + w / 2)
                lo_y, hi_y = min(lo_y, y - h / 2), max(hi_y, y + h / 2)
        out.append(None if lo_x == math.inf else (lo_x, hi_x, lo_y, hi_y))
    return out
