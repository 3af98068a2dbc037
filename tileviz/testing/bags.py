"""A tileviz dataset written as a ROS 1 or ROS 2 bag with rosbags' writers (the ros extra)
(sensor_msgs/Image or CompressedImage, nav_msgs/Odometry, sensor_msgs/Imu)."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

T0_NS = 1_700_000_000_000_000_000
"""The bag's first image stamp (ROS time, ns)."""


def write_bag(dataset: Path, out: Path, *, ros1: bool = False, storage: str = "sqlite3",
              compressed: bool = False, odom_rate: int = 1, imu_rate: int = 1,
              imu_offset: float = 0.0, stamp_shift: dict[int, float] | None = None,
              image_limit: int | None = None) -> Path:
    """Write ``dataset`` as a bag: one image per frame at ``T0 + t``; the odometry row k held
    over the frame, published ``odom_rate`` times a frame from its start; the compass readings
    as the IMU's yaw, ``imu_rate`` times a frame, shifted by ``imu_offset`` of a frame
    (interpolated along the shorter arc between frames). ``stamp_shift``: image index -> seconds
    added to that image's header stamp (not to its time in the bag). ``image_limit``: write only
    this many images (the topic is there even with none). Returns the bag's path."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    ty = ts.types
    with open(dataset / "frames.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    times = [float(r["t"]) for r in rows]

    def header(t: float, frame: str) -> Any:
        ns = T0_NS + round(t * 1e9)
        stamp = ty["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000,
                                                  nanosec=ns % 1_000_000_000)
        if ros1:
            return ty["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return ty["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    vec = ty["geometry_msgs/msg/Vector3"]
    quat = ty["geometry_msgs/msg/Quaternion"]
    cov36 = np.zeros(36)
    cov9 = np.zeros(9)
    msgs: list[tuple[float, str, str, Any]] = []
    m: Any
    for k, (r, t) in enumerate(zip(rows, times, strict=True)):
        if image_limit is not None and k >= image_limit:
            break
        stamp = t + (stamp_shift or {}).get(k, 0.0)
        img = cv2.imread(str(dataset / r["image"]), cv2.IMREAD_COLOR)
        assert img is not None, r["image"]
        if compressed:
            ok, buf = cv2.imencode(".png", img)
            assert ok
            m = ty["sensor_msgs/msg/CompressedImage"](header=header(stamp, "cam"), format="png",
                                                      data=np.frombuffer(buf, np.uint8))
            msgs.append((t, "/camera/image", "sensor_msgs/msg/CompressedImage", m))
        else:
            h, w = img.shape[:2]
            m = ty["sensor_msgs/msg/Image"](header=header(stamp, "cam"), height=h, width=w,
                                            encoding="bgr8", is_bigendian=0, step=3 * w,
                                            data=img.reshape(-1))
            msgs.append((t, "/camera/image", "sensor_msgs/msg/Image", m))
    for k, r in enumerate(rows):
        dt = times[k + 1] - times[k] if k + 1 < len(rows) else times[k] - times[k - 1]
        for j in range(odom_rate):
            t = times[k] + dt * j / odom_rate
            twist = ty["geometry_msgs/msg/Twist"](
                linear=vec(x=float(r["speed"]), y=0.0, z=0.0),
                angular=vec(x=0.0, y=0.0, z=float(r["yaw_rate"])))
            pose = ty["geometry_msgs/msg/Pose"](position=ty["geometry_msgs/msg/Point"](
                x=0.0, y=0.0, z=0.0), orientation=quat(x=0.0, y=0.0, z=0.0, w=1.0))
            m = ty["nav_msgs/msg/Odometry"](
                header=header(t, "odom"), child_frame_id="base_link",
                pose=ty["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov36),
                twist=ty["geometry_msgs/msg/TwistWithCovariance"](twist=twist,
                                                                   covariance=cov36))
            msgs.append((t, "/odom", "nav_msgs/msg/Odometry", m))
    comp = [float(r["compass"]) for r in rows]

    def imu(t: float, yaw: float) -> Any:
        return ty["sensor_msgs/msg/Imu"](
            header=header(t, "imu"),
            orientation=quat(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
            orientation_covariance=cov9, angular_velocity=vec(x=0.0, y=0.0, z=0.0),
            angular_velocity_covariance=cov9, linear_acceleration=vec(x=0.0, y=0.0, z=0.0),
            linear_acceleration_covariance=cov9)

    for k in range(len(rows) - 1):
        for j in range(imu_rate):
            a = (j + imu_offset) / imu_rate
            t = times[k] + a * (times[k + 1] - times[k])
            yaw = comp[k] + a * math.remainder(comp[k + 1] - comp[k], 2 * math.pi)
            m = imu(t, yaw)
            msgs.append((t, "/imu", "sensor_msgs/msg/Imu", m))
    if imu_offset == 0:  # the last frame's reading too
        msgs.append((times[-1], "/imu", "sensor_msgs/msg/Imu", imu(times[-1], comp[-1])))
    msgs.sort(key=lambda x: x[0])
    types = {"/camera/image": "sensor_msgs/msg/CompressedImage" if compressed
             else "sensor_msgs/msg/Image", "/odom": "nav_msgs/msg/Odometry",
             "/imu": "sensor_msgs/msg/Imu"}
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        path = out.with_suffix(".bag")
        with Writer1(path) as w1:
            conns = {tp: w1.add_connection(tp, mt, typestore=ts) for tp, mt in types.items()}
            for t, topic, mt, m in msgs:
                w1.write(conns[topic], T0_NS + round(t * 1e9), ts.serialize_ros1(m, mt))
        return path
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer2(out, version=9, storage_plugin=plugin) as w2:
        conns = {tp: w2.add_connection(tp, mt, typestore=ts) for tp, mt in types.items()}
        for t, topic, mt, m in msgs:
            w2.write(conns[topic], T0_NS + round(t * 1e9), ts.serialize_cdr(m, mt))
    return out
