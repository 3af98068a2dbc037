"""``python -m tileviz sample-data DIR``: files to try ``calibrate`` and ``import-bag`` on without a
robot: checkerboard images seen through the simulator's ``webcam`` lens
(:func:`tileviz.sim.lens.webcam_model`) and a short ROS 1 bag of a simulated run through the same
camera (``rosbags``, the ``ros`` extra).

The drawing of a checkerboard through a camera model (:func:`board_image`,
:func:`floor_board_image`, :func:`held_board_image`) and the writing of a dataset as a bag
(:func:`write_bag`) are also what the tests use.

Frames: robot frame (forward, left), metres; raw pixels (column, row); a board's own coordinates
(bx, by) in metres with its first inner corner at (0, 0), bx along a row of COLS corners.
"""

from __future__ import annotations

import csv
import math
import shlex
import sys
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from tileviz.datasets.camera_model import CameraModel

__all__ = ["IMAGE_TOPIC", "IMU_TOPIC", "ODOM_TOPIC", "SAMPLE", "T0_NS", "board_image",
           "floor_board_image", "held_board_image", "main", "write_bag", "write_sample"]

IMAGE_TOPIC = "/camera/image"
ODOM_TOPIC = "/odom"
IMU_TOPIC = "/imu"
T0_NS = 1_700_000_000_000_000_000
"""A written bag's first image stamp (ROS time, ns)."""


# ------------------------------------------------------------------------- checkerboards


def board_image(model: CameraModel, board_of_ray: np.ndarray, cols: int, rows: int,
                square: float, *, ss: int = 2) -> np.ndarray:
    """The raw image (gray, uint8, raw_height x raw_width) of a checkerboard of ``cols`` x
    ``rows`` inner corners and squares of ``square`` metres, seen by ``model``'s lens:
    ``board_of_ray`` (3x3) maps a normalised undistorted ray (x, y, 1) to board coordinates
    (bx, by, 1) up to scale. The board has one white square's margin and a gray background;
    ``ss`` x ``ss`` samples a pixel."""
    w, h = model.raw_width, model.raw_height
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    acc = np.zeros(h * w)
    for dy in (np.arange(ss) + 0.5) / ss - 0.5:
        for dx in (np.arange(ss) + 0.5) / ss - 0.5:
            pts = np.c_[(u + dx).ravel(), (v + dy).ravel()].reshape(-1, 1, 2)
            norm = cv2.undistortPoints(pts, model.k, model.dist).reshape(-1, 2)
            q = np.c_[norm, np.ones(len(norm))] @ board_of_ray.T
            b = q[:, :2] / q[:, 2:3]
            i, j = np.floor(b[:, 0] / square), np.floor(b[:, 1] / square)
            board = (i >= -1) & (i <= cols - 1) & (j >= -1) & (j <= rows - 1)
            margin = (i >= -2) & (i <= cols) & (j >= -2) & (j <= rows) & ~board
            acc += np.where(board, np.where((i + j) % 2 == 0, 25.0, 230.0),
                            np.where(margin, 235.0, 140.0))
    return np.clip(acc / ss**2, 0, 255).astype(np.uint8).reshape(h, w)


def floor_board_image(model: CameraModel, cols: int, rows: int, square: float,
                      pose: tuple[float, float, float]) -> np.ndarray:
    """The board lying on the floor with its centre (the centre of its inner corners) at
    ``pose[:2]`` (forward, left; metres, robot frame) and its COLS direction at ``pose[2]`` rad
    from forward (``calibrate --board-pose``), seen by ``model``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    centre = np.array([(cols - 1) / 2 * square, (rows - 1) / 2 * square])
    # floor (f, l, 1) -> board (bx, by, 1): b = R(-yaw) (p - centre_floor) + centre
    a = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]]) @ np.array(
        [[1, 0, -pose[0]], [0, 1, -pose[1]], [0, 0, 1.0]])
    a = np.array([[1, 0, centre[0]], [0, 1, centre[1]], [0, 0, 1.0]]) @ a
    return board_image(model, a @ model.h @ model.k, cols, rows, square)


def held_board_image(model: CameraModel, cols: int, rows: int, square: float,
                     rvec: tuple[float, float, float],
                     t: tuple[float, float, float]) -> np.ndarray:
    """The board held in front of the camera: rotation ``rvec`` (Rodrigues, camera frame) and
    its first inner corner at ``t`` (metres, camera frame: x image right, y image down, z along
    the optical axis), seen by ``model``."""
    r, _ = cv2.Rodrigues(np.array(rvec, np.float64))
    return board_image(model, np.linalg.inv(np.column_stack([r[:, 0], r[:, 1], np.array(t)])),
                       cols, rows, square)


# ------------------------------------------------------------------------- ROS bags


def write_bag(dataset: Path, out: Path, *, ros1: bool = False, storage: str = "sqlite3",
              compressed: bool = False, odom_rate: int = 1, imu_rate: int = 1,
              imu_offset: float = 0.0, stamp_shift: dict[int, float] | None = None,
              image_limit: int | None = None) -> Path:
    """Write the tileviz dataset folder ``dataset`` as a bag (ROS 1 ``out.bag`` with ``ros1``,
    else a ROS 2 bag folder ``out`` with ``storage`` sqlite3 or mcap): on :data:`IMAGE_TOPIC`
    one image per frame at ``T0_NS + t`` (``sensor_msgs/Image`` bgr8, or ``CompressedImage``
    PNG with ``compressed``); on :data:`ODOM_TOPIC` the odometry row k held over the frame,
    published ``odom_rate`` times a frame from its start; on :data:`IMU_TOPIC` the compass
    readings as the IMU's yaw, ``imu_rate`` times a frame, shifted by ``imu_offset`` of a
    frame (interpolated along the shorter arc between frames). ``stamp_shift``: image index ->
    seconds added to that image's header stamp (not to its time in the bag). ``image_limit``:
    write only this many images (the topic is there even with none). Returns the bag's path.
    Needs ``rosbags`` (ImportError without it)."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    ty = ts.types
    with open(dataset / "frames.csv", newline="", encoding="utf-8") as f:
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
    msgs: list[tuple[float, str, str, object]] = []
    for k, (r, t) in enumerate(zip(rows, times, strict=True)):
        if image_limit is not None and k >= image_limit:
            break
        stamp = t + (stamp_shift or {}).get(k, 0.0)
        img = cv2.imread(str(dataset / r["image"]), cv2.IMREAD_COLOR)
        if img is None:
            raise OSError(f"cannot read {dataset / r['image']}")
        if compressed:
            ok, buf = cv2.imencode(".png", img)
            if not ok:
                raise OSError(f"cannot encode {dataset / r['image']} as PNG")
            m = ty["sensor_msgs/msg/CompressedImage"](header=header(stamp, "cam"), format="png",
                                                      data=np.frombuffer(buf, np.uint8))
            msgs.append((t, IMAGE_TOPIC, "sensor_msgs/msg/CompressedImage", m))
        else:
            h, w = img.shape[:2]
            m = ty["sensor_msgs/msg/Image"](header=header(stamp, "cam"), height=h, width=w,
                                            encoding="bgr8", is_bigendian=0, step=3 * w,
                                            data=img.reshape(-1))
            msgs.append((t, IMAGE_TOPIC, "sensor_msgs/msg/Image", m))
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
            msgs.append((t, ODOM_TOPIC, "nav_msgs/msg/Odometry", m))
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
            msgs.append((t, IMU_TOPIC, "sensor_msgs/msg/Imu", imu(t, yaw)))
    if imu_offset == 0:  # the last frame's reading too
        msgs.append((times[-1], IMU_TOPIC, "sensor_msgs/msg/Imu", imu(times[-1], comp[-1])))
    msgs.sort(key=lambda x: x[0])
    types = {IMAGE_TOPIC: "sensor_msgs/msg/CompressedImage" if compressed
             else "sensor_msgs/msg/Image", ODOM_TOPIC: "nav_msgs/msg/Odometry",
             IMU_TOPIC: "sensor_msgs/msg/Imu"}
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        path = out.with_suffix(".bag")
        with Writer1(path) as w1:
            conns = {tp: w1.add_connection(tp, mt, typestore=ts) for tp, mt in types.items()}
            for t, topic, mt, msg in msgs:
                w1.write(conns[topic], T0_NS + round(t * 1e9), ts.serialize_ros1(msg, mt))
        return path
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer2(out, version=9, storage_plugin=plugin) as w2:
        conns = {tp: w2.add_connection(tp, mt, typestore=ts) for tp, mt in types.items()}
        for t, topic, mt, msg in msgs:
            w2.write(conns[topic], T0_NS + round(t * 1e9), ts.serialize_cdr(msg, mt))
    return out


# ------------------------------------------------------------------------- the sample


@dataclass(frozen=True)
class Sample:
    """What ``sample-data`` makes: the simulated robot and its camera, the board."""

    tile_size: float = 0.3
    """L, metres."""
    ppm: float = 800.0
    """Pixels per metre of the view the bag's camera sees (``import-bag --ppm``)."""
    view: tuple[int, int] = (640, 480)
    """The view's size, pixels: the webcam's raw size, the view ``import-bag`` makes from a
    camera file with the ``camera_model`` block alone."""
    camera_offset: tuple[float, float] = (0.35, 0.0)
    """The view's centre on the floor (forward, left), metres, robot frame."""
    dt: float = 0.1
    """Frame period, s."""
    duration: float = 4.0
    """Simulated seconds in the bag."""
    seed: int = 7
    board: tuple[int, int] = (9, 6)
    """Inner corners (COLS, ROWS)."""
    square: float = 0.04
    """Side of a board square, metres."""
    board_pose: tuple[float, float, float] = (0.35, 0.0, 0.0)
    """The first image's board on the floor (``calibrate --board-pose``)."""
    held: tuple[tuple[tuple[float, float, float], tuple[float, float, float]], ...] = (
        ((0.3, 0.1, 0.05), (-0.17, -0.1, 0.55)), ((-0.25, 0.3, -0.1), (-0.2, -0.06, 0.6)),
        ((0.1, -0.35, 0.2), (-0.12, -0.13, 0.5)), ((0.4, 0.4, 0.0), (-0.2, -0.12, 0.65)),
        ((-0.35, -0.2, -0.15), (-0.15, -0.08, 0.58)))
    """The other images' boards held in front of the camera: (rvec, first corner), camera
    frame (:func:`held_board_image`)."""


SAMPLE = Sample()


def _config(s: Sample) -> Any:
    from tileviz.config import preset

    cfg = preset("default")
    return replace(cfg, floor=cfg.floor.with_tile_size(s.tile_size),
                   camera=replace(cfg.camera, ppm=s.ppm, width=s.view[0], height=s.view[1],
                                  offset=s.camera_offset),
                   sim=replace(cfg.sim, dt=s.dt, seed=s.seed))


def _num(v: float) -> str:
    return f"{v:g}"


@dataclass(frozen=True)
class SampleFiles:
    """The files :func:`write_sample` wrote and the commands that use them."""

    boards: list[Path]
    bag: Path | None
    """None without the ``rosbags`` package."""
    truth: Path | None
    """``truth.csv`` (index, t, x, y, theta: the simulated true poses of the bag's images)."""
    commands: list[str]


def write_sample(folder: Path, s: Sample = SAMPLE) -> SampleFiles:
    """Write the board images (``folder/board/board0.png``: on the floor at ``s.board_pose``;
    the others held in front of the camera) and, with ``rosbags``, ``folder/run.bag`` (ROS 1:
    :data:`IMAGE_TOPIC` the webcam's raw images as PNG, :data:`ODOM_TOPIC`, :data:`IMU_TOPIC`)
    with ``folder/truth.csv``; returns them and the ``calibrate``, ``import-bag`` and ``replay``
    commands that work on them (paths as ``folder`` is written)."""
    from tileviz.sim.lens import webcam_model

    cfg = _config(s)
    model = webcam_model(cfg.camera)
    board_dir = folder / "board"
    board_dir.mkdir(parents=True, exist_ok=True)
    cols, rows = s.board
    images = [floor_board_image(model, cols, rows, s.square, s.board_pose)]
    images += [held_board_image(model, cols, rows, s.square, rvec, t) for rvec, t in s.held]
    boards = []
    for n, img in enumerate(images):
        path = board_dir / f"board{n}.png"
        if not cv2.imwrite(str(path), img):
            raise OSError(f"cannot write {path}")
        boards.append(path)
    camera = folder / "camera.json"
    d = shlex.quote(str(folder))
    cam = shlex.quote(str(camera))
    commands = [
        f"python -m tileviz calibrate {d}/board/*.png --board {cols}x{rows} --square "
        f"{_num(s.square)} --board-pose {','.join(_num(v) for v in s.board_pose)} --meta {cam}"]
    try:
        import rosbags.rosbag1  # noqa: F401 - the ros extra
    except ImportError:
        return SampleFiles(boards, None, None, commands)
    bag, truth = _write_run(folder, cfg, model, s)
    robot = shlex.quote(str(folder / "robot"))
    commands += [
        f"python -m tileviz import-bag {shlex.quote(str(bag))} {robot} --image-topic "
        f"{IMAGE_TOPIC} --odom-topic {ODOM_TOPIC} --imu-topic {IMU_TOPIC} --tile-size "
        f"{_num(s.tile_size)} --ppm {_num(s.ppm)} --camera-offset "
        f"{','.join(_num(v) for v in s.camera_offset)} --speed-error "
        f"{_num(cfg.noise.speed_error)} --yaw-rate-error {_num(cfg.noise.yaw_rate_error)} "
        f"--compass-error {_num(cfg.noise.compass_error)} --camera-model {cam}",
        f"python -m tileviz replay {robot}"]
    return SampleFiles(boards, bag, truth, commands)


def _write_run(folder: Path, cfg: Any, model: CameraModel, s: Sample) -> tuple[Path, Path]:
    """Simulate ``s.duration`` seconds through the webcam and write them as ``folder/run.bag``
    and their true poses as ``folder/truth.csv``."""
    from tileviz.datasets.format import DatasetMeta
    from tileviz.datasets.writer import DatasetWriter
    from tileviz.sim.lens import LensRenderer
    from tileviz.sim.source import SimSource

    frames = int(math.floor(s.duration / s.dt + 1e-9)) + 1
    renderer = LensRenderer(cfg.floor, cfg.camera, model)
    meta = replace(DatasetMeta.from_config(cfg, name="tileviz sample"), camera_model=model)
    truth = folder / "truth.csv"
    with tempfile.TemporaryDirectory(prefix="tileviz-sample-") as tmp:
        ds = Path(tmp) / "run"
        with DatasetWriter(ds, meta, png_level=1) as writer:
            for i, frame in enumerate(SimSource(cfg, renderer=renderer)):
                if i >= frames:
                    break
                writer.write(frame)
        (folder / "run.bag").unlink(missing_ok=True)  # a sample written before
        bag = write_bag(ds, folder / "run", ros1=True, compressed=True)
        with open(ds / "frames.csv", newline="", encoding="utf-8") as f, \
                open(truth, "w", newline="", encoding="utf-8") as g:
            out = csv.writer(g)
            out.writerow(("index", "t", "x", "y", "theta"))
            for r in csv.DictReader(f):
                out.writerow((r["index"], r["t"], r["x"], r["y"], r["theta"]))
    return bag, truth


def main(command: str, argv: list[str]) -> int:
    """Entry point of ``python -m tileviz sample-data``."""
    from tileviz.cliutil import CliError, Parser, run_cli

    prog = f"tileviz {command}"
    p = Parser(prog=prog, description="Write sample checkerboard images and a small ROS 1 bag of "
               "a simulated robot (the ros extra) to try calibrate and import-bag on; prints the "
               "commands.")
    p.add_argument("dir", help="output folder (created; its board/, run.bag, truth.csv are "
                   "replaced)")
    args = p.parse_args(argv)

    def body() -> int:
        folder = Path(args.dir)
        if folder.exists() and not folder.is_dir():
            raise CliError(f"{folder}: exists and is not a folder")
        try:
            files = write_sample(folder)
        except OSError as e:
            raise CliError(f"cannot write the sample into {folder}: {e.strerror or e}") from None
        print(f"wrote {len(files.boards)} checkerboard images to {folder / 'board'}", end="")
        if files.bag is None or files.truth is None:
            print()
            print("the sample bag needs the rosbags package: pip install -e '.[ros]'")
        else:
            with open(files.truth, encoding="utf-8") as f:
                frames = sum(1 for _ in f) - 1
            print(f", a {frames}-frame ROS 1 bag {files.bag} (true poses in {files.truth})")
        print("next:")
        for c in files.commands:
            print(f"  {c}")
        sys.stdout.flush()
        return 0

    return run_cli(prog, body)
