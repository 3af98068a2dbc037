"""``python -m tileviz import-bag BAG OUT ...``: a ROS 1 bag or a ROS 2 bag (sqlite3 or MCAP
storage) into a tileviz-dataset/1 folder, read with the ``rosbags`` library (no ROS install).

One frame per image (``sensor_msgs/Image`` rgb8, bgr8 or mono8, or ``sensor_msgs/
CompressedImage``), at its header stamp (the bag's receive time when the stamp is zero); ``t`` is
counted from the first image. Row k's speed and yaw rate (``nav_msgs/Odometry``: twist
``linear.x``, ``angular.z``) and frame k's compass (the yaw of ``sensor_msgs/Imu``'s orientation)
combine the messages around the frame so that the declared bounds still hold
(``docs/dataset-format.md``, "Importing a ROS bag"):

- an odometry message holds from its stamp until the next one; row k's reading is the middle of
  the values held during [t_k, t_k+1) and the bound grows by half their range;
- the heading at an image's stamp lies on the shorter arc between the two IMU yaws around it;
  the compass is that arc's middle and its bound grows by half the arc (a frame with no IMU
  message on one side of it has no compass).

The declared ``speed_error``, ``yaw_rate_error`` and ``compass_error`` are the given ones plus
the largest growth over the frames; ``meta.json``'s ``import_widening`` keeps those growths.
Bad input is one line: a topic the bag lacks (its topics listed), an unknown message type, a bag
without images, time going backwards, a truncated bag; the frames before the problem are
written (a valid, shorter dataset) before the error is reported. A ROS 2 MCAP file cut short
(a recording that crashed: no summary, no index) is read record by record up to the cut; a
ROS 1 bag or a sqlite3 database without its index cannot be read at all (one line).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from tileviz.cliutil import CliError, Parser, nonneg_float, positive_float, read_json, run_cli
from tileviz.datasets.timeline import (
    SensorTimeline,
    combine_compass,
    combine_odometry,
    seconds_since,
)

__all__ = ["IMAGE_TYPES", "combine_compass", "combine_odometry", "decode_image_message",
           "import_bag", "main", "yaw_of"]

IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
ODOM_TYPE = "nav_msgs/msg/Odometry"
IMU_TYPE = "sensor_msgs/msg/Imu"
ENCODINGS = ("rgb8", "bgr8", "mono8")


def _rosbags() -> Any:
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise CliError("import-bag needs the rosbags package: pip install -e '.[ros]'") from None
    return AnyReader


@dataclass
class _Series:
    """Stamped samples of one topic, nanoseconds (ROS time) and values, in time order."""

    t: list[int]
    v: list[tuple[float, ...]]


def _stamp(msg: Any, bag_ns: int) -> int:
    """The header stamp, nanoseconds (kept as an integer: a float of seconds since 1970 keeps
    only a quarter of a microsecond)."""
    st = getattr(getattr(msg, "header", None), "stamp", None)
    if st is not None:
        ns = int(st.sec) * 1_000_000_000 + int(getattr(st, "nanosec", getattr(st, "nsec", 0)))
        if ns > 0:
            return ns
    return int(bag_ns)


def yaw_of(q: Any) -> float:
    """Yaw (rad, counter-clockwise about z) of a quaternion, wrapped to (-pi, pi]."""
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    return math.pi if yaw <= -math.pi else yaw


def decode_image_message(msg: Any, msgtype: str, where: str) -> np.ndarray:
    """An image message (ROS 1 or ROS 2, as rosbags or rospy give it: ``encoding``, ``height``,
    ``width``, ``step``, ``data``; or ``format``, ``data``) as HxWx3 RGB uint8; CliError naming
    the message."""
    if msgtype.endswith("CompressedImage"):
        from tileviz.datasets.images import decode_image, size_problem

        raw = bytes(msg.data)
        problem = size_problem(raw)
        if problem is not None:
            raise CliError(f"{where}: compressed image ({msg.format!r}): {problem}")
        complaints: list[str] = []
        img = decode_image(raw, complaints=complaints)
        if img is None:
            why = f" ({complaints[0]})" if complaints else ""
            raise CliError(f"{where}: compressed image ({msg.format!r}) cannot be decoded{why}")
        return img
    enc = str(msg.encoding).lower()
    if enc not in ENCODINGS:
        raise CliError(f"{where}: image encoding {msg.encoding!r} is not supported "
                       f"({', '.join(ENCODINGS)})")
    ch = 1 if enc == "mono8" else 3
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.frombuffer(bytes(msg.data), np.uint8)
    if h <= 0 or w <= 0 or step < w * ch or data.size < step * h:
        raise CliError(f"{where}: image data is {data.size} bytes, {w}x{h} {enc} with step "
                       f"{step} needs {step * h}")
    img = data[: step * h].reshape(h, step)[:, : w * ch].reshape(h, w, ch)
    if enc == "mono8":
        return cv2.cvtColor(img, cv2.COLOR_GRAY2RGB)
    return np.ascontiguousarray(img if enc == "rgb8" else img[:, :, ::-1])


@dataclass(frozen=True)
class BagImportOptions:
    """The command line of ``import-bag`` (units: metres, radians, seconds, pixels)."""

    image_topic: str
    odom_topic: str
    imu_topic: str | None
    tile_size: float
    ppm: float
    camera_offset: tuple[float, float]
    speed_error: float
    yaw_rate_error: float
    compass_error: float
    camera_model_meta: str | None = None
    start_pose: tuple[float, float, float] | None = None
    start_error: tuple[float, float, float] | None = None


def camera_model_file(path: str) -> tuple[Any, tuple[int, int] | None]:
    """The camera model of a JSON file with a ``camera_model`` block (a dataset's meta.json, or
    what ``calibrate`` prints) and the rectified view size it gives (``image_width``,
    ``image_height``), or None (then the raw size). CliError naming the file."""
    from tileviz.datasets.camera_model import CameraModel, CameraModelError

    doc = read_json(path, "--camera-model")
    if not isinstance(doc, dict) or doc.get("camera_model") is None:
        raise CliError(f"--camera-model: {path} has no camera_model block")
    try:
        model = CameraModel.from_json(doc["camera_model"], path)
    except CameraModelError as e:
        raise CliError(str(e)) from None
    w, h = doc.get("image_width"), doc.get("image_height")
    if (isinstance(w, int) and not isinstance(w, bool) and w > 0
            and isinstance(h, int) and not isinstance(h, bool) and h > 0):
        return model, (w, h)
    return model, None


@dataclass(frozen=True)
class _Connection:
    topic: str
    msgtype: str
    id: int


class _CutMcap:
    """A ROS 2 MCAP file read record by record up to where it breaks: a recording cut short
    has no summary or index, which rosbags needs. Same few calls as rosbags' AnyReader; the
    message iteration raises at the cut. Message types from the ROS 2 (Humble) definitions."""

    def __init__(self, path: Path) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.path = path
        self.typestore = get_typestore(Stores.ROS2_HUMBLE)
        schemas: dict[int, str] = {}
        conns: dict[int, _Connection] = {}
        for rec in self._records(stop_at_cut=True):
            kind = type(rec).__name__
            if kind == "Schema":
                schemas[rec.id] = rec.name
            elif kind == "Channel" and rec.message_encoding == "cdr":
                conns[rec.id] = _Connection(rec.topic, schemas.get(rec.schema_id, "?"), rec.id)
        self.connections = list(conns.values())

    def _records(self, *, stop_at_cut: bool) -> Iterator[Any]:
        from mcap.stream_reader import StreamReader

        with open(self.path, "rb") as f:
            it = iter(StreamReader(f).records)
            while True:
                try:
                    rec = next(it)
                except StopIteration:
                    return
                except Exception:
                    if stop_at_cut:
                        return
                    raise
                yield rec

    def open(self) -> None:
        pass

    def close(self) -> None:
        pass

    def messages(self, connections: list[_Connection]) -> Iterator[tuple[Any, int, bytes]]:
        by_id = {c.id: c for c in connections}
        for rec in self._records(stop_at_cut=False):
            if type(rec).__name__ == "Message" and rec.channel_id in by_id:
                yield by_id[rec.channel_id], rec.log_time, rec.data

    def deserialize(self, raw: bytes, msgtype: str) -> Any:
        return self.typestore.deserialize_cdr(raw, msgtype)


def _open_bag(path: Path, any_reader: Any) -> Any:
    """rosbags' reader of the bag, or for a ROS 2 MCAP file cut short (no footer) the records
    up to the cut."""
    try:
        reader = any_reader([path])
        reader.open()
        return reader
    except Exception as e:  # noqa: BLE001 - rosbags' errors for unreadable bags vary
        files = sorted(path.glob("*.mcap")) if path.is_dir() else [path]
        if len(files) == 1 and files[0].suffix == ".mcap":
            try:
                cut = _CutMcap(files[0])
            except Exception:  # noqa: BLE001
                cut = None
            if cut is not None and cut.connections:
                return cut
        raise CliError(f"{path}: not a readable ROS bag ({type(e).__name__}: {e})") from None


def _topics(reader: Any) -> dict[str, str]:
    return {c.topic: c.msgtype for c in reader.connections}


def _check_topic(topics: dict[str, str], topic: str, types: tuple[str, ...], bag: str,
                 option: str) -> None:
    if topic not in topics:
        have = ", ".join(f"{t} ({m})" for t, m in sorted(topics.items())) or "none"
        raise CliError(f"{bag}: no topic {topic!r} ({option}); its topics: {have}")
    if topics[topic] not in types:
        raise CliError(f"{bag}: topic {topic!r} is {topics[topic]}, {option} needs "
                       f"{' or '.join(types)}")


def _messages(reader: Any, topic: str, bag: str) -> Iterator[tuple[int, int, Any, str]]:
    """(number, stamp ns, message, type) of one topic in bag order; CliError (one line) when
    time goes backwards or the bag is truncated or damaged."""
    conns = [c for c in reader.connections if c.topic == topic]
    last = -1
    n = 0
    it = reader.messages(connections=conns)
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except Exception as e:  # noqa: BLE001 - rosbags' errors for damaged files vary
            why = f"{type(e).__name__}: {e}" if str(e) else type(e).__name__
            raise CliError(f"{bag}: truncated or damaged after {n} message(s) on {topic!r} "
                           f"({why})") from None
        conn, bag_ns, raw = item
        try:
            msg = reader.deserialize(raw, conn.msgtype)
        except Exception as e:  # noqa: BLE001
            raise CliError(f"{bag}: {topic!r} message {n}: cannot be read as {conn.msgtype} "
                           f"({type(e).__name__})") from None
        t = _stamp(msg, bag_ns)
        if t < last:
            raise CliError(f"{bag}: time goes backwards on {topic!r} at message {n} "
                           f"({(last - t) * 1e-9:.9f} s before the one before it)")
        last = t
        yield n, t, msg, conn.msgtype
        n += 1


def _series(reader: Any, topic: str, bag: str, pick: Any) -> tuple[_Series, str | None]:
    """The samples of a topic up to its first problem (and that problem's message)."""
    s = _Series([], [])
    try:
        for _, t, msg, _ in _messages(reader, topic, bag):
            s.t.append(t)
            s.v.append(pick(msg))
    except CliError as e:
        return s, str(e)
    return s, None


def import_bag(bag: str, out: str, opt: BagImportOptions) -> tuple[int, dict[str, float]]:
    """Write the dataset; returns (frames written, the widenings). CliError (one line) for bad
    input, after writing the frames before the problem."""
    from tileviz.datasets import DatasetMeta, DatasetWriter
    from tileviz.types import FrameInput, Odometry

    any_reader = _rosbags()
    path = Path(bag)
    if not path.exists():
        raise CliError(f"{bag}: no such bag file or folder")
    model = view = None
    if opt.camera_model_meta is not None:
        model, view = camera_model_file(opt.camera_model_meta)
    reader = _open_bag(path, any_reader)
    try:
        topics = _topics(reader)
        _check_topic(topics, opt.image_topic, IMAGE_TYPES, bag, "--image-topic")
        _check_topic(topics, opt.odom_topic, (ODOM_TYPE,), bag, "--odom-topic")
        if opt.imu_topic is not None:
            _check_topic(topics, opt.imu_topic, (IMU_TYPE,), bag, "--imu-topic")
        # pass 1: motion, heading and the image stamps (stopping at a topic's first problem)
        odom, odom_err = _series(reader, opt.odom_topic, bag, lambda m: (
            float(m.twist.twist.linear.x), float(m.twist.twist.angular.z)))
        imu, imu_err = (_series(reader, opt.imu_topic, bag, lambda m: (yaw_of(m.orientation),))
                        if opt.imu_topic is not None else (_Series([], []), None))
        stamps: list[int] = []
        img_err = None
        try:
            for _, t, _, _ in _messages(reader, opt.image_topic, bag):
                stamps.append(t)
        except CliError as e:
            img_err = str(e)
        if not stamps:
            raise CliError(img_err or f"{bag}: no images on {opt.image_topic!r}")
        problem = img_err or odom_err or imu_err
        if odom_err is not None or imu_err is not None:  # frames up to the last sample only
            ends = [s.t[-1] for s, e in ((odom, odom_err), (imu, imu_err)) if e is not None
                    and s.t]
            limit = min(ends) if ends else -1
            stamps = [t for t in stamps if t <= limit]
        if not stamps:
            raise CliError(problem or f"{bag}: no images")
        timeline = SensorTimeline()
        for t, (speed, yaw_rate) in zip(odom.t, odom.v, strict=True):
            timeline.add_odometry(t, speed, yaw_rate)
        for t, (yaw,) in zip(imu.t, imu.v, strict=True):
            timeline.add_imu(t, yaw)
        rows: list[tuple[int, float, float, float, float, float | None]] = []
        widen = {"speed": 0.0, "yaw_rate": 0.0, "compass": 0.0}
        for k, t in enumerate(stamps):
            speed = yaw_rate = ds = dw = 0.0
            if k + 1 < len(stamps):
                motion = timeline.motion(t, stamps[k + 1])
                if motion is None:
                    problem = problem or (f"{bag}: no odometry on {opt.odom_topic!r} before "
                                          f"image {k + 1}")
                    stamps = stamps[: k + 1]
                else:
                    speed, ds = motion.speed, motion.speed_half
                    yaw_rate, dw = motion.yaw_rate, motion.yaw_rate_half
            comp = timeline.compass(t)
            widen["speed"] = max(widen["speed"], ds)
            widen["yaw_rate"] = max(widen["yaw_rate"], dw)
            if comp is not None:
                widen["compass"] = max(widen["compass"], comp[1])
            rows.append((t, speed, ds, yaw_rate, dw, None if comp is None else comp[0]))
            if k + 1 >= len(stamps):
                break
        # pass 2: the images, written one by one
        first_raw = None
        count = 0
        writer = None
        try:
            for n, t, msg, msgtype in _messages(reader, opt.image_topic, bag):
                if n >= len(rows):
                    break
                where = f"{bag}: {opt.image_topic!r} message {n}"
                image = decode_image_message(msg, msgtype, where)
                h, w = image.shape[:2]
                if writer is None:
                    first_raw = (w, h)
                    if model is not None and (w, h) != (model.raw_width, model.raw_height):
                        raise CliError(f"{where}: image is {w}x{h}, the camera model's raw "
                                       f"size is {model.raw_width}x{model.raw_height}")
                    size = view if view is not None else (w, h)
                    dts = np.diff([r[0] for r in rows]) * 1e-9
                    start = opt.start_pose if opt.start_pose is not None else (0.0, 0.0, 0.0)
                    err = opt.start_error if opt.start_error is not None else (
                        opt.tile_size / 2, opt.tile_size / 2, math.pi)
                    meta = DatasetMeta(
                        name=f"imported from {path.name}", tile_size=opt.tile_size,
                        ppm=opt.ppm, image_width=size[0], image_height=size[1],
                        camera_offset=opt.camera_offset,
                        dt=float(np.median(dts)) if len(dts) else 0.05,
                        initial_pose=start, initial_pose_error=err,
                        speed_error=opt.speed_error + widen["speed"],
                        yaw_rate_error=opt.yaw_rate_error + widen["yaw_rate"],
                        compass_error=opt.compass_error + widen["compass"],
                        extra={"import_widening": dict(widen), "source_bag": str(path.name)},
                        camera_model=model,
                    )
                    DatasetMeta.from_json(json.loads(json.dumps(meta.to_json())))  # validate
                    writer = DatasetWriter(out, meta)
                elif (w, h) != first_raw:
                    raise CliError(f"{where}: image is {w}x{h}, the first was "
                                   f"{first_raw[0]}x{first_raw[1]}")  # type: ignore[index]
                t, speed, _, yaw_rate, _, compass = rows[n]
                t_s = seconds_since(t, rows[0][0])  # from the first image
                odo = (Odometry(speed, yaw_rate, seconds_since(rows[n + 1][0], rows[0][0]) - t_s)
                       if n + 1 < len(rows) else None)
                writer.write(FrameInput(index=n, t=t_s, image=image, odometry=odo,
                                        compass=compass, truth=None))
                count += 1
        finally:
            if writer is not None:
                writer.close()
        if problem is not None:
            raise CliError(f"{problem} (the {count} frame(s) before it were written to {out})")
        return count, widen
    finally:
        reader.close()


def _floats(text: str, n: int, option: str, *, nonneg: bool = False) -> tuple[float, ...]:
    try:
        v = tuple(float(p) for p in text.split(","))
    except ValueError:
        v = ()
    if len(v) != n or not all(math.isfinite(x) and (x >= 0 or not nonneg) for x in v):
        names = {2: "F,L", 3: "X,Y,TH" if not nonneg else "EX,EY,ETH"}[n]
        raise CliError(f"{option} must be {names} ({n} finite{' non-negative' if nonneg else ''}"
                       f" numbers), got {text!r}")
    return v


def _parser(prog: str) -> Parser:
    p = Parser(prog=prog, description="Import a ROS 1 or ROS 2 bag (sqlite3 or MCAP) into a "
               "tileviz-dataset/1 folder.")
    p.add_argument("bag", help="a ROS 1 .bag file or a ROS 2 bag folder (or .mcap/.db3 file)")
    p.add_argument("out", help="output dataset folder (must not exist or be empty)")
    p.add_argument("--image-topic", required=True, help="sensor_msgs/Image or CompressedImage")
    p.add_argument("--odom-topic", required=True, help="nav_msgs/Odometry")
    p.add_argument("--imu-topic", default=None, help="sensor_msgs/Imu (its yaw is the compass)")
    p.add_argument("--tile-size", required=True, type=positive_float("--tile-size"),
                   help="L, metres")
    p.add_argument("--ppm", required=True, type=positive_float("--ppm"),
                   help="pixels per metre of the (rectified) view")
    p.add_argument("--camera-offset", required=True, metavar="F,L",
                   help="optical centre on the floor, forward,left metres, robot frame")
    p.add_argument("--speed-error", required=True, type=nonneg_float("--speed-error"),
                   help="m/s bound")
    p.add_argument("--yaw-rate-error", required=True, type=nonneg_float("--yaw-rate-error"),
                   help="rad/s bound")
    p.add_argument("--compass-error", required=True, type=nonneg_float("--compass-error"),
                   help="rad bound")
    p.add_argument("--camera-model", default=None, metavar="JSON",
                   help="a JSON file with the camera's camera_model block (a dataset's "
                   "meta.json, whose image_width/height are the view, or calibrate's output)")
    p.add_argument("--start-pose", default=None, metavar="X,Y,TH",
                   help="known start pose (default 0,0,0: the grout crossing nearest the start)")
    p.add_argument("--start-error", default=None, metavar="EX,EY,ETH",
                   help="the start lies within --start-pose +- these (default L/2,L/2,pi)")
    return p


def main(command: str, argv: list[str]) -> int:
    """Entry point of ``python -m tileviz import-bag``."""
    prog = f"tileviz {command}"
    args = _parser(prog).parse_args(argv)

    def body() -> int:
        opt = BagImportOptions(
            image_topic=args.image_topic, odom_topic=args.odom_topic, imu_topic=args.imu_topic,
            tile_size=args.tile_size, ppm=args.ppm,
            camera_offset=_floats(args.camera_offset, 2, "--camera-offset"),  # type: ignore[arg-type]
            speed_error=args.speed_error, yaw_rate_error=args.yaw_rate_error,
            compass_error=args.compass_error, camera_model_meta=args.camera_model,
            start_pose=(_floats(args.start_pose, 3, "--start-pose")  # type: ignore[arg-type]
                        if args.start_pose else None),
            start_error=(_floats(args.start_error, 3, "--start-error",  # type: ignore[arg-type]
                                 nonneg=True) if args.start_error else None),
        )
        n, widen = import_bag(args.bag, args.out, opt)
        print(f"imported {n} frames into {args.out}; bounds widened by {widen['speed']:.4g} m/s,"
              f" {widen['yaw_rate']:.4g} rad/s, {widen['compass']:.4g} rad (asynchrony, docs)")
        return 0

    return run_cli(prog, body)
