"""A replayed run as an MCAP file that Foxglove opens (``replay DATASET --mcap OUT.mcap``).

Topics (log time = the frame's ``t`` in nanoseconds; Foxglove's published protobuf schemas,
``foxglove-schemas-protobuf``, unless said otherwise):

- ``/camera/image`` (``foxglove.CompressedImage``): each frame's stored image file as it is
  (PNG or JPEG bytes: nothing decoded or encoded again; the raw camera image when the dataset
  has a camera model).
- ``/truth`` (``foxglove.PoseInFrame``, frame ``world``): the true pose, when the dataset has it.
- ``/set/prediction`` and ``/set/contraction`` (``foxglove.SceneUpdate``): the robot-pose set
  after the prediction and after this frame's update, one cube per box in (x, y, theta) space:
  x and y in metres, the heading drawn as height (1 rad a metre, the box's theta interval shifted
  by whole turns so that its lower end is in [-pi, pi)); in the demo's colours, translucent.
- ``/status`` (JSON, schema ``tileviz.Status``): ``status`` (text), ``code`` (0 contracted,
  1 predicted, 2 rejected, 3 lost), ``boxes``, and the widths ``x_width``, ``y_width`` (m) and
  ``theta_width`` (rad) of the set's hull: plottable series.

Frames: world metres (x east, y north), heading counter-clockwise from +x (``docs/
dataset-format.md``). Needs the ``[ros]`` extra (``mcap``, ``mcap-protobuf-support``,
``foxglove-schemas-protobuf``).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from tileviz.cliutil import CliError
from tileviz.types import BoxSet

if TYPE_CHECKING:
    from tileviz.pipeline import FrameRecord

__all__ = ["CONTRACTION_RGB", "PREDICTION_RGB", "STATUS_CODES", "TOPICS", "FrameEncoder",
           "McapExport", "status_fields"]

PREDICTION_RGB = (40, 190, 70)
"""The demo's colour of the predicted set (green, ``tileviz.app.scene.COLOURS``)."""
CONTRACTION_RGB = (30, 100, 240)
"""The demo's colour of the updated set's boxes (blue)."""
ALPHA = 0.35
STATUS_CODES = {"contracted": 0, "predicted": 1, "rejected": 2, "lost": 3}
STATUS_SCHEMA = {
    "type": "object",
    "properties": {
        "status": {"type": "string"}, "code": {"type": "integer"},
        "boxes": {"type": "integer"}, "x_width": {"type": "number"},
        "y_width": {"type": "number"}, "theta_width": {"type": "number"},
    },
}


MCAP_INSTALL = "pip install -e '.[ros]'"
"""The install line that brings the MCAP writer's packages (the ``ros`` extra)."""


def mcap_missing() -> str | None:
    """None when the MCAP export can run here, else one line saying what to install."""
    from importlib.util import find_spec

    for module in ("mcap", "mcap_protobuf", "foxglove_schemas_protobuf"):
        if find_spec(module) is None:
            return f"MCAP export needs the mcap and foxglove packages: {MCAP_INSTALL}"
    return None


def _modules() -> tuple[Any, ...]:
    try:
        from foxglove_schemas_protobuf.Color_pb2 import Color
        from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
        from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
        from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
        from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
        from mcap.writer import Writer
        from mcap_protobuf.schema import register_schema
    except ImportError:
        raise CliError(f"MCAP export needs the mcap and foxglove packages: {MCAP_INSTALL}"
                       ) from None
    return Writer, register_schema, CompressedImage, PoseInFrame, SceneUpdate, CubePrimitive, Color


TOPICS = {"image": "/camera/image", "truth": "/truth", "prediction": "/set/prediction",
          "contraction": "/set/contraction", "status": "/status"}
"""The topics of a run (key -> topic), in the MCAP file and on the live Foxglove server."""


class FrameEncoder:
    """A frame's messages as (key of :data:`TOPICS`, serialized bytes), with Foxglove's
    protobuf schemas (``/status``: JSON); :meth:`schemas` gives each key's schema
    (name, encoding, data) as an MCAP file or a live server registers it."""

    def __init__(self) -> None:
        (self.writer_cls, _, self._image, self._pose, self._scene, self._cube,
         self._color) = _modules()

    def schemas(self) -> dict[str, tuple[str, str, bytes]]:
        """key -> (schema name, schema encoding, schema data); the message encoding is
        ``protobuf`` for every key but ``status`` (``json``)."""
        from mcap_protobuf.schema import build_file_descriptor_set

        def proto(cls: Any) -> tuple[str, str, bytes]:
            return (cls.DESCRIPTOR.full_name, "protobuf",
                    build_file_descriptor_set(message_class=cls).SerializeToString())

        return {"image": proto(self._image), "truth": proto(self._pose),
                "prediction": proto(self._scene), "contraction": proto(self._scene),
                "status": ("tileviz.Status", "jsonschema", json.dumps(STATUS_SCHEMA).encode())}

    @staticmethod
    def _stamp(msg: Any, ns: int) -> None:
        msg.timestamp.seconds, msg.timestamp.nanos = divmod(ns, 1_000_000_000)

    def _set(self, boxes: BoxSet, rgb: tuple[int, int, int], name: str, ns: int) -> bytes:
        update = self._scene()
        ent = update.entities.add()
        self._stamp(ent, ns)
        ent.frame_id = "world"
        ent.id = name
        for box in boxes.boxes:
            lo = box.t_lo - 2 * math.pi * math.floor((box.t_lo + math.pi) / (2 * math.pi))
            wx, wy, wt = box.widths
            cube = ent.cubes.add()
            cube.pose.position.x, cube.pose.position.y = box.centre[:2]
            cube.pose.position.z = lo + 0.5 * wt
            cube.pose.orientation.w = 1.0
            cube.size.x, cube.size.y, cube.size.z = wx, wy, wt
            cube.color.r, cube.color.g, cube.color.b = (c / 255.0 for c in rgb)
            cube.color.a = ALPHA
        return update.SerializeToString()

    def messages(self, rec: FrameRecord, ns: int, image: tuple[bytes, str] | None,
                 status: str | None = None) -> list[tuple[str, bytes]]:
        """The messages of one frame stamped ``ns`` (nanoseconds): ``image`` (PNG or JPEG
        bytes, ``png``/``jpeg``) when given, the truth when known, both sets and the status
        (``status`` overrides the record's)."""
        out: list[tuple[str, bytes]] = []
        if image is not None:
            img = self._image()
            self._stamp(img, ns)
            img.frame_id = "camera"
            img.data, img.format = image
            out.append(("image", img.SerializeToString()))
        if rec.truth is not None:
            pose = self._pose()
            self._stamp(pose, ns)
            pose.frame_id = "world"
            pose.pose.position.x, pose.pose.position.y = rec.truth.x, rec.truth.y
            pose.pose.orientation.w = math.cos(rec.truth.theta / 2)
            pose.pose.orientation.z = math.sin(rec.truth.theta / 2)
            out.append(("truth", pose.SerializeToString()))
        out.append(("prediction", self._set(rec.predicted, PREDICTION_RGB, "prediction", ns)))
        out.append(("contraction", self._set(rec.updated, CONTRACTION_RGB, "contraction", ns)))
        out.append(("status", json.dumps(status_fields(rec, status)).encode()))
        return out


def status_fields(rec: FrameRecord, status: str | None = None) -> dict[str, Any]:
    """The ``/status`` message of a frame: status, code, box count, the hull's widths."""
    st = status if status is not None else rec.status
    hull = rec.updated.hull()
    widths = list(hull.widths) if hull is not None else [None, None, None]
    return {"status": st, "code": STATUS_CODES.get(st, -1), "boxes": len(rec.updated),
            "x_width": widths[0], "y_width": widths[1], "theta_width": widths[2]}


class McapExport:
    """Writes one frame's messages at a time (:meth:`write`), each frame in the file as a whole
    chunk when :meth:`write` returns; :meth:`close` finishes the file (its summary and index: a
    file not closed, e.g. a replay killed, is readable by a streaming reader up to its last
    frame)."""

    def __init__(self, path: str | os.PathLike[str], dataset: str | os.PathLike[str]) -> None:
        self._enc = FrameEncoder()
        p = Path(path)
        if not p.parent.is_dir():
            raise OSError(f"{p.parent}: output directory does not exist")
        self.dataset = Path(dataset)
        self._file: IO[bytes] = open(p, "wb")  # noqa: SIM115 - closed in close()
        # each frame's messages end their chunk (Writer.flush), so a replay killed before close()
        # leaves a file a streaming reader reads up to its last frame; a writer without flush()
        # (mcap < 1.6) writes the messages unchunked
        self._chunked = hasattr(self._enc.writer_cls, "flush")
        self._w = self._enc.writer_cls(self._file, **({} if self._chunked else
                                                       {"use_chunking": False}))
        self._w.start(profile="", library="tileviz")
        self._ch: dict[str, int] = {}
        ids: dict[str, int] = {}
        for key, (name, encoding, data) in self._enc.schemas().items():
            if name not in ids:
                ids[name] = self._w.register_schema(name=name, encoding=encoding, data=data)
            self._ch[key] = self._w.register_channel(
                topic=TOPICS[key], message_encoding="json" if key == "status" else "protobuf",
                schema_id=ids[name])
        self.count = 0

    def write(self, rec: FrameRecord, image_name: str | None) -> None:
        """The messages of one replayed frame (``image_name``: its stored image file, relative
        to the dataset folder, or None)."""
        ns = round(rec.t * 1e9)
        image = None
        if image_name:
            fmt = "jpeg" if Path(image_name).suffix.lower() in (".jpg", ".jpeg") else "png"
            image = ((self.dataset / image_name).read_bytes(), fmt)
        for key, data in self._enc.messages(rec, ns, image):
            self._w.add_message(channel_id=self._ch[key], log_time=ns, publish_time=ns,
                                data=data, sequence=self.count)
        self.count += 1
        if self._chunked:
            self._w.flush()
        else:
            self._file.flush()

    def close(self) -> None:
        if not self._file.closed:
            self._w.finish()
            self._file.close()
