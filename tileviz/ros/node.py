"""``python -m tileviz ros``: the live localizer as a ROS 1 node (rospy).

Subscribes (topic names are private parameters, defaults in brackets):

- ``~image_topic`` [``/camera/image``]: ``sensor_msgs/Image`` (rgb8, bgr8, mono8) or
  ``sensor_msgs/CompressedImage``, whichever the publisher sends;
- ``~odom_topic`` [``/odom``]: ``nav_msgs/Odometry`` (twist ``linear.x`` m/s, ``angular.z``
  rad/s);
- ``~imu_topic`` [``/imu``, ``""`` for none]: ``sensor_msgs/Imu`` (the orientation's yaw is the
  compass).

Parameters: the floor, camera, bounds and start with the names and units of a dataset's
meta.json (``docs/dataset-format.md``: ``tile_size``, ``ppm``, ``image_width``,
``image_height``, ``camera_offset``, ``dt``, ``initial_pose``, ``initial_pose_error``,
``speed_error``, ``yaw_rate_error``, ``compass_error``, ``camera_model``, ...), from ``~meta``
(a meta.json file), from ``~meta_param`` (the name of a parameter holding meta.json's text,
waited for up to ``~wait`` seconds: the simulator sets ``/tileviz_sim/meta``), then from private
parameters of those names, each overriding the ones before. ``~widening`` (three numbers: m/s,
rad/s, rad) is added to the declared bounds for the messages' asynchrony
(:mod:`tileviz.ros.live`); ``~max_delay`` (s) how long an image waits for the messages after
it; ``~max_pending`` [4] how many images may wait (the oldest are dropped beyond);
``~frame_id`` [``world``] the frame of the published poses.

Publishes, one message each per frame (stamped with the image's stamp):

- ``~set`` (``visualization_msgs/MarkerArray``): one cube per box of the set after this frame
  (namespace ``contraction``, blue) and after the prediction (``prediction``, green), x and y in
  metres, the heading drawn as height (1 rad a metre), as ``replay --mcap`` draws them;
- ``~hull`` (``geometry_msgs/PoseWithCovarianceStamped``): the hull of the set. It is a BOX, not
  a covariance: the position and yaw are the hull's centre, and the diagonal entries (x, y, yaw)
  of the "covariance" hold the SQUARES OF THE HALF-WIDTHS, so their square roots are the
  guaranteed half-widths (m, m, rad); nothing there is a variance;
- ``~status`` (``std_msgs/String``, JSON): status, code, box count, the hull's widths (the
  fields of ``replay --mcap``'s ``/status``), the boxes themselves (``set``: [x_lo, x_hi, y_lo,
  y_hi, t_lo, t_hi] each), ``vision_ms`` and ``localizer_ms``, the message counters
  (:data:`tileviz.ros.live.COUNTERS`), the reason a frame's view was refused, and
  ``lost_reason``;
- ``~observation`` (``std_msgs/String``, JSON): the tile observation (y1, y2 m, y3 rad and their
  bounds) or null, and the refusal reason;
- ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``): OK contracted, WARN predicted or
  rejected, ERROR lost.

Without frames for a second (no image, or no odometry to combine it with), the node publishes
the status ``predicted`` (``stale``: true, and why), never ``contracted``. Bad input is one line
on the node's log; the node keeps running. ``--foxglove [PORT]`` also serves the run live to
Foxglove (:mod:`tileviz.ros.foxglove_live`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from tileviz.cliutil import CliError, Parser, read_json, run_cli

__all__ = ["hull_covariance", "main", "meta_from_params"]

META_KEYS = ("name", "tile_size", "ppm", "image_width", "image_height", "camera_offset", "dt",
             "initial_pose", "initial_pose_error", "speed_error", "yaw_rate_error",
             "compass_error", "camera_model")
"""meta.json's keys that a private parameter of the same name overrides."""


def meta_from_params(get: Any, has: Any, wait: float = 10.0) -> Any:
    """The DatasetMeta the parameters describe (``get(name)``/``has(name)``: rospy's
    ``get_param``/``has_param``); CliError naming the parameter or the key."""
    from tileviz.datasets import DatasetError, DatasetMeta

    doc: dict[str, Any] = {}
    if has("~meta"):
        path = str(get("~meta"))
        if not Path(path).is_file():
            raise CliError(f"~meta: {path}: no such file")
        d = read_json(path, "~meta")
        if not isinstance(d, dict):
            raise CliError(f"~meta: {path} is not a JSON object")
        doc.update(d)
    if has("~meta_param"):
        name = str(get("~meta_param"))
        end = time.monotonic() + wait
        while not has(name) and time.monotonic() < end:
            time.sleep(0.1)
        if not has(name):
            raise CliError(f"~meta_param: no parameter {name!r} after {wait:g} s")
        try:
            d = json.loads(str(get(name)))
        except json.JSONDecodeError as e:
            raise CliError(f"~meta_param: {name} is not JSON ({e.msg})") from None
        if not isinstance(d, dict):
            raise CliError(f"~meta_param: {name} is not a JSON object")
        doc.update(d)
    for key in META_KEYS:
        if has(f"~{key}"):
            doc[key] = get(f"~{key}")
    doc.setdefault("format", "tileviz-dataset/1")
    doc.setdefault("name", "live ROS run")
    try:
        return DatasetMeta.from_json(doc, where="parameters")
    except DatasetError as e:
        raise CliError(f"{e} (set it as ~NAME, or in ~meta / ~meta_param)") from None


def hull_covariance(half: tuple[float, float, float]) -> list[float]:
    """The 6x6 row-major "covariance" of ``~hull``: the squares of the hull's half-widths in x,
    y (m) and yaw (rad) on the diagonal (a box, not a covariance), zeros elsewhere."""
    cov = [0.0] * 36
    cov[0], cov[7], cov[35] = half[0] ** 2, half[1] ** 2, half[2] ** 2
    return cov


def _floats(value: Any, n: int, name: str) -> tuple[float, ...]:
    if isinstance(value, str):
        value = value.replace(",", " ").split()
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        v = ()
    if len(v) != n or not all(math.isfinite(x) and x >= 0 for x in v):
        raise CliError(f"{name} must be {n} finite numbers >= 0, got {value!r}")
    return v


class _Node:
    """The rospy side: subscribers feed :class:`tileviz.ros.live.LiveLocalizer`, the main
    loop steps it and publishes."""

    def __init__(self, rospy: Any, foxglove: int | None) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import Imu
        from std_msgs.msg import String
        from visualization_msgs.msg import MarkerArray

        from tileviz.ros.live import LiveLocalizer

        self.rospy = rospy
        p = rospy.get_param
        meta = meta_from_params(p, rospy.has_param, float(p("~wait", 30.0)))
        imu_topic = str(p("~imu_topic", "/imu"))
        widening = _floats(p("~widening", [0.0, 0.0, 0.0]), 3, "~widening")
        max_delay = float(p("~max_delay", 0.5))
        if not (math.isfinite(max_delay) and max_delay >= 0):
            raise CliError(f"~max_delay must be a number of seconds >= 0, got {max_delay!r}")
        self.frame_id = str(p("~frame_id", "world"))
        self.image_topic = str(p("~image_topic", "/camera/image"))
        self.odom_topic = str(p("~odom_topic", "/odom"))
        max_pending = p("~max_pending", 4)
        if not isinstance(max_pending, int) or max_pending < 1:
            raise CliError(f"~max_pending must be an integer >= 1, got {max_pending!r}")
        self.live = LiveLocalizer(meta, has_imu=bool(imu_topic), widening=widening,  # type: ignore[arg-type]
                                  max_delay=int(max_delay * 1e9), max_pending=max_pending)
        self.pub_set = rospy.Publisher("~set", MarkerArray, queue_size=5)
        self.pub_hull = rospy.Publisher("~hull", PoseWithCovarianceStamped, queue_size=5)
        self.pub_status = rospy.Publisher("~status", String, queue_size=20)
        self.pub_obs = rospy.Publisher("~observation", String, queue_size=20)
        self.pub_diag = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=5)
        self.fox = None
        if foxglove is not None:
            from tileviz.ros.foxglove_live import FoxgloveLive

            self.fox = FoxgloveLive(foxglove)
            rospy.loginfo(f"tileviz: Foxglove live on ws://127.0.0.1:{self.fox.port}")
        from tileviz.vision.warmup import warm_up

        warm_up((self.live.cfg.vision.extractor,), self.live.cfg)  # before the first image
        self._logged: str | None = None
        self._last_frame = time.monotonic()
        self._last_status: str = "predicted"
        rospy.loginfo("tileviz: ready")
        rospy.Subscriber(self.image_topic, rospy.AnyMsg, self._on_image, queue_size=4,
                         buff_size=2 ** 24)
        rospy.Subscriber(self.odom_topic, Odometry, self._on_odom, queue_size=200)
        if imu_topic:
            rospy.Subscriber(imu_topic, Imu, self._on_imu, queue_size=200)
        self.imu_topic = imu_topic

    # ---------------------------------------------------------------- callbacks
    def _now(self) -> int:
        return int(self.rospy.get_rostime().to_nsec())

    @staticmethod
    def _stamp(header: Any, fallback: int) -> int:
        ns = int(header.stamp.to_nsec())
        return ns if ns > 0 else fallback

    def _on_image(self, raw: Any) -> None:
        from sensor_msgs.msg import CompressedImage, Image

        from tileviz.datasets.bag_import import decode_image_message

        now = self._now()
        kind = raw._connection_header.get("type", "?")
        cls = {"sensor_msgs/Image": Image, "sensor_msgs/CompressedImage": CompressedImage}.get(
            kind)
        if cls is None:
            self._log(f"{self.image_topic} is {kind}: needs sensor_msgs/Image or "
                      "CompressedImage")
            return
        try:
            msg = cls().deserialize(raw._buff)
        except Exception as e:  # noqa: BLE001 - genpy's errors for bad bytes vary
            self.live.add_image(now, None, now, error=f"{self.image_topic}: unreadable message "
                                f"({type(e).__name__})")
            return
        stamp = self._stamp(msg.header, now)
        try:
            image = decode_image_message(msg, kind, f"{self.image_topic} stamped {stamp}")
        except CliError as e:
            self.live.add_image(stamp, None, now, error=str(e), seq=msg.header.seq)
            return
        self.live.add_image(stamp, image, now, seq=msg.header.seq)

    def _on_odom(self, msg: Any) -> None:
        stamp = self._stamp(msg.header, self._now())
        self.live.add_odometry(stamp, float(msg.twist.twist.linear.x),
                               float(msg.twist.twist.angular.z), seq=msg.header.seq)

    def _on_imu(self, msg: Any) -> None:
        from tileviz.datasets.bag_import import yaw_of

        stamp = self._stamp(msg.header, self._now())
        self.live.add_imu(stamp, yaw_of(msg.orientation), seq=msg.header.seq)

    # ---------------------------------------------------------------- publishing
    def _log(self, text: str) -> None:
        if text != self._logged:
            self.rospy.logwarn(f"tileviz: {text}")
            self._logged = text

    def _header(self, stamp: int) -> Any:
        from std_msgs.msg import Header

        h = Header()
        h.stamp = self.rospy.Time(*divmod(stamp, 1_000_000_000))
        h.frame_id = self.frame_id
        return h

    def _markers(self, frame: Any) -> Any:
        from visualization_msgs.msg import Marker, MarkerArray

        from tileviz.datasets.mcap_export import CONTRACTION_RGB, PREDICTION_RGB

        arr = MarkerArray()
        clear = Marker()
        clear.action = Marker.DELETEALL
        arr.markers.append(clear)
        header = self._header(frame.stamp)
        for ns, boxes, rgb in (("prediction", frame.record.predicted, PREDICTION_RGB),
                               ("contraction", frame.record.updated, CONTRACTION_RGB)):
            for i, box in enumerate(boxes.boxes):
                m = Marker()
                m.header = header
                m.ns, m.id, m.type, m.action = ns, i, Marker.CUBE, Marker.ADD
                lo = box.t_lo - 2 * math.pi * math.floor((box.t_lo + math.pi) / (2 * math.pi))
                wx, wy, wt = box.widths
                m.pose.position.x, m.pose.position.y = box.centre[:2]
                m.pose.position.z = lo + 0.5 * wt
                m.pose.orientation.w = 1.0
                m.scale.x, m.scale.y, m.scale.z = max(wx, 1e-6), max(wy, 1e-6), max(wt, 1e-6)
                m.color.r, m.color.g, m.color.b = (c / 255.0 for c in rgb)
                m.color.a = 0.35
                arr.markers.append(m)
        return arr

    def _diagnostic(self, status: str, message: str) -> Any:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

        level = {"contracted": DiagnosticStatus.OK, "lost": DiagnosticStatus.ERROR}.get(
            status, DiagnosticStatus.WARN)
        arr = DiagnosticArray()
        arr.header.stamp = self.rospy.get_rostime()
        st = DiagnosticStatus(level=level, name="tileviz: localization",
                              message=f"{status}: {message}", hardware_id="tileviz")
        st.values = [KeyValue(key=k, value=str(v)) for k, v in self.live.counts.items()]
        arr.status = [st]
        return arr

    def publish(self, frame: Any) -> None:
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from std_msgs.msg import String

        from tileviz.datasets.mcap_export import status_fields

        rec = frame.record
        doc = status_fields(rec, frame.status)
        doc.update(index=rec.index, stamp=frame.stamp, reason=frame.reason,
                   set=[list(b.as_tuple()) for b in rec.updated.boxes],
                   counts=dict(self.live.counts), lost_reason=self.live.lost_reason,
                   stale=False, vision_ms=rec.timings.get("vision_ms"),
                   localizer_ms=rec.timings.get("localizer_ms"))
        self.pub_status.publish(String(data=json.dumps(doc)))
        obs = rec.vision.observation
        self.pub_obs.publish(String(data=json.dumps({
            "index": rec.index, "stamp": frame.stamp, "reason": frame.reason,
            "observation": None if obs is None else {
                "y1": obs.y1, "y2": obs.y2, "y3": obs.y3,
                "position_error": obs.position_error, "heading_error": obs.heading_error}})))
        self.pub_set.publish(self._markers(frame))
        hull = rec.updated.hull()
        if hull is not None:
            msg = PoseWithCovarianceStamped()
            msg.header = self._header(frame.stamp)
            cx, cy, ct = hull.centre
            msg.pose.pose.position.x, msg.pose.pose.position.y = cx, cy
            msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = (math.sin(ct / 2),
                                                                        math.cos(ct / 2))
            wx, wy, wt = hull.widths
            msg.pose.covariance = hull_covariance((wx / 2, wy / 2, wt / 2))
            self.pub_hull.publish(msg)
        self.pub_diag.publish(self._diagnostic(frame.status, frame.reason))
        if self.fox is not None:
            self.fox.publish(rec, frame.stamp, status=frame.status)
        self._last_status = frame.status

    def stale(self) -> None:
        """No frame for ``idle`` seconds: say predicted (or lost), and why."""
        from std_msgs.msg import String

        if self.live.counts["images"] == 0:
            why = f"no image on {self.image_topic} yet"
        elif self.live.pending():
            why = f"images wait for odometry on {self.odom_topic}"
        else:
            why = f"no image on {self.image_topic} for over 1 s"
        status = "lost" if self._last_status == "lost" or self.live.lost_reason else "predicted"
        self._log(why)
        self.pub_status.publish(String(data=json.dumps({
            "status": status, "code": {"lost": 3}.get(status, 1), "stale": True, "reason": why,
            "counts": dict(self.live.counts), "lost_reason": self.live.lost_reason})))
        self.pub_diag.publish(self._diagnostic(status, why))

    def spin(self) -> int:
        rospy = self.rospy
        next_stale = time.monotonic() + 1.0
        while not rospy.is_shutdown():
            try:
                frame = self.live.step(self._now())
            except ValueError as e:  # a bad number in a message: that frame fails, not the node
                self._log(str(e))
                continue
            if self.live.last_problem is not None:
                self._log(self.live.last_problem)
                self.live.last_problem = None
            if frame is None:
                now = time.monotonic()
                if now - self._last_frame >= 1.0 and now >= next_stale:
                    self.stale()
                    next_stale = now + 1.0
                time.sleep(0.002)
                continue
            self._last_frame = time.monotonic()
            self.publish(frame)
        if self.fox is not None:
            self.fox.close()
        return 0


def _parser(prog: str) -> Parser:
    p = Parser(prog=prog, description="The live localizer as a ROS 1 node: parameters as "
               "private ROS parameters (~meta, ~image_topic, ...: see docs/ros.md).")
    p.add_argument("--foxglove", nargs="?", const=8765, default=None, type=int, metavar="PORT",
                   help="also serve the run live to Foxglove on 127.0.0.1:PORT (default 8765)")
    p.add_argument("--name", default="tileviz", help="node name (default tileviz)")
    return p


def main(command: str, argv: list[str]) -> int:
    """Entry point of ``python -m tileviz ros``."""
    prog = f"tileviz {command}"

    def body() -> int:
        from tileviz.ros import load_rospy, require_master

        rospy = load_rospy()
        args = _parser(prog).parse_args(rospy.myargv(argv=[prog, *argv])[1:])
        require_master()
        rospy.init_node(args.name, disable_rostime=False)
        node = _Node(rospy, args.foxglove)
        return node.spin()

    try:
        return run_cli(prog, body)
    except argparse.ArgumentError as e:  # pragma: no cover - Parser exits on its own
        sys.stderr.write(f"{prog}: {e}\n")
        return 2
