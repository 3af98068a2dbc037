"""``python -m tileviz ros-sim`` (the simulator as a ROS 1 robot) and ``python -m tileviz
ros-controller`` (the demo's PD controller as a node).

ros-sim publishes, for frame k, stamped ``start + k dt`` (ROS time at start, ``dt`` the
simulator's frame period, exact in nanoseconds):

- ``/odom`` (``nav_msgs/Odometry``): frame k's measured speed and yaw rate (bounded errors,
  ``docs/guarantees.md``), the motion from pose k to pose k+1, stamped ``t_k`` and, with
  ``--odom-rate``, again every 1/rate s until ``t_{k+1}`` (the same reading: the simulator
  measures one per frame);
- ``/imu`` (``sensor_msgs/Imu``): the compass at pose k as the orientation's yaw;
- ``/truth`` (``geometry_msgs/PoseStamped``): the true pose k;
- ``/camera/image`` (``sensor_msgs/Image`` rgb8, or ``CompressedImage`` PNG on
  ``/camera/image/compressed`` with ``--compressed``): the view rendered at pose k;
- the parameter ``~meta`` (``/tileviz_sim/meta``): the run's meta.json as text (floor, camera,
  bounds, start), which the localizer node reads through its ``~meta_param``.

It drives with its own setpoint (``--drive setpoint``, the default: ``--setpoint`` lissajous,
manual or waypoints; ``/setpoint`` ``geometry_msgs/PointStamped`` drives to a point) or with
``geometry_msgs/Twist`` on ``/cmd_vel`` (``--drive cmd_vel``: forward m/s and yaw rate rad/s,
held until the next, zero when none came for 0.5 s). ``~inject`` (``std_msgs/String``, JSON:
``{"kind": "kidnap", "x": .., "y": .., "theta": ..}`` or any fault of
``SimSource.inject``, e.g. ``{"kind": "dropout", "frames": 40}``) starts a fault. Commands
received on topics are applied between frames by the simulation loop.

ros-controller subscribes ``/truth`` and ``/setpoint``, runs the demo's PD controller
(:class:`tileviz.sim.controller.Controller`) toward its setpoint (``--setpoint``) and publishes
``/cmd_vel``.
"""

from __future__ import annotations

import json
import math
import queue
import time
from dataclasses import replace
from typing import Any

from tileviz.cliutil import CliError, Parser, config_from_args, nonneg_float, run_cli
from tileviz.types import Pose

__all__ = ["TwistDrive", "main", "sim_meta", "twist_of_wheels", "wheels_of_twist"]


def wheels_of_twist(v: float, w: float, wheel_base: float) -> tuple[float, float]:
    """(left, right) wheel speeds (m/s) of a forward speed ``v`` (m/s) and yaw rate ``w``
    (rad/s) for a differential drive of ``wheel_base`` (m)."""
    half = 0.5 * w * wheel_base
    return v - half, v + half


def twist_of_wheels(left: float, right: float, wheel_base: float) -> tuple[float, float]:
    """(forward speed m/s, yaw rate rad/s) of wheel speeds (m/s)."""
    return 0.5 * (left + right), (right - left) / wheel_base


class TwistDrive:
    """Stands in for the simulator's controller: the wheel speeds of the last ``/cmd_vel``
    (zero once ``timeout`` seconds of wall time passed without one)."""

    def __init__(self, wheel_base: float, timeout: float = 0.5) -> None:
        self.wheel_base = wheel_base
        self.timeout = timeout
        self.twist = (0.0, 0.0)
        self.when = -math.inf

    def set(self, v: float, w: float) -> None:
        if math.isfinite(v) and math.isfinite(w):
            self.twist = (v, w)
            self.when = time.monotonic()

    def reset(self) -> None:
        pass

    def command(self, pose: Pose, target: Any, dt: float) -> tuple[float, float]:
        if time.monotonic() - self.when > self.timeout:
            return (0.0, 0.0)
        return wheels_of_twist(*self.twist, self.wheel_base)


def sim_meta(cfg: Any) -> dict[str, Any]:
    """The meta.json (as a dict) of a simulated run: floor, camera, bounds and start, without
    the stored simulator configuration (what the localizer needs, as ``import-bag`` writes)."""
    from tileviz.datasets import DatasetMeta

    meta = replace(DatasetMeta.from_config(cfg, name="tileviz ros-sim"), extra={})
    return meta.to_json()


def _quat(theta: float) -> tuple[float, float]:
    return math.sin(theta / 2), math.cos(theta / 2)


def _sim(rospy: Any, args: Any) -> int:
    from geometry_msgs.msg import PointStamped, PoseStamped, Twist
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import CompressedImage, Image, Imu
    from std_msgs.msg import String

    from tileviz.sim.source import SimSource

    cfg = config_from_args(args)
    source = SimSource(cfg)
    drive = None
    if args.drive == "cmd_vel":
        drive = TwistDrive(cfg.sim.wheel_base)
        source.controller = drive  # type: ignore[assignment]
    rospy.set_param("~meta", json.dumps(sim_meta(cfg)))
    pub_odom = rospy.Publisher("/odom", Odometry, queue_size=100)
    pub_imu = rospy.Publisher("/imu", Imu, queue_size=100)
    pub_truth = rospy.Publisher("/truth", PoseStamped, queue_size=100)
    if args.compressed:
        pub_img = rospy.Publisher("/camera/image/compressed", CompressedImage, queue_size=10)
    else:
        pub_img = rospy.Publisher("/camera/image", Image, queue_size=10)
    commands: queue.Queue[tuple[str, Any]] = queue.Queue()
    rospy.Subscriber("/setpoint", PointStamped,
                     lambda m: commands.put(("setpoint", (m.point.x, m.point.y))))
    rospy.Subscriber("~inject", String, lambda m: commands.put(("inject", m.data)))
    if drive is not None:
        rospy.Subscriber("/cmd_vel", Twist, lambda m: drive.set(m.linear.x, m.angular.z))
    import cv2

    dt_ns = round(cfg.sim.dt * 1e9)
    odom_ns = round(1e9 / args.odom_rate) if args.odom_rate > 0 else dt_ns
    end = time.monotonic() + args.wait  # subscribers connect before the first frame
    while (pub_img.get_num_connections() < args.subscribers and time.monotonic() < end
           and not rospy.is_shutdown()):
        time.sleep(0.05)
    if pub_img.get_num_connections() < args.subscribers:
        rospy.logwarn(f"tileviz ros-sim: {pub_img.get_num_connections()} of "
                      f"{args.subscribers} camera subscribers after {args.wait:g} s; starting")
    time.sleep(0.5 if args.subscribers else 0.0)  # the other topics' connections too
    start = rospy.get_rostime().to_nsec()
    wall0 = time.monotonic()
    seq = 0
    k = 0
    scheduled: dict[int, list[str]] = {}
    for spec in args.inject:
        at, _, text = spec.partition(":")
        if not at.isdigit() or not text:
            raise CliError(f"--inject must be FRAME:JSON, got {spec!r}")
        scheduled.setdefault(int(at), []).append(text)
    while not rospy.is_shutdown() and (args.frames is None or k < args.frames):
        for text in scheduled.pop(k, []):
            commands.put(("inject", text))
        while not commands.empty():
            kind, arg = commands.get()
            try:
                if kind == "setpoint":
                    source.set_manual_target(*arg)
                else:
                    spec = json.loads(arg)
                    if not isinstance(spec, dict) or "kind" not in spec:
                        raise ValueError("~inject needs a JSON object with a kind")
                    fault = spec.pop("kind")
                    source.inject(str(fault), **spec)
            except (ValueError, TypeError) as e:
                rospy.logwarn(f"tileviz ros-sim: {kind}: {e}")
        frame = next(source)
        t = start + k * dt_ns
        stamp = rospy.Time(*divmod(t, 1_000_000_000))
        odo = frame.odometry
        assert odo is not None and frame.truth is not None
        om = Odometry()
        om.header.stamp, om.header.frame_id, om.child_frame_id = stamp, "world", "base_link"
        om.header.seq = seq
        om.twist.twist.linear.x, om.twist.twist.angular.z = odo.speed, odo.yaw_rate
        pub_odom.publish(om)
        if frame.compass is not None:
            im = Imu()
            im.header.stamp, im.header.frame_id = stamp, "base_link"
            im.orientation.z, im.orientation.w = _quat(frame.compass)
            pub_imu.publish(im)
        ps = PoseStamped()
        ps.header.stamp, ps.header.frame_id = stamp, "world"
        ps.pose.position.x, ps.pose.position.y = frame.truth.x, frame.truth.y
        ps.pose.orientation.z, ps.pose.orientation.w = _quat(frame.truth.theta)
        pub_truth.publish(ps)
        if args.compressed:
            cm = CompressedImage()
            cm.header.stamp, cm.header.frame_id = stamp, "camera"
            cm.format = "png"
            cm.data = cv2.imencode(".png", cv2.cvtColor(frame.image, cv2.COLOR_RGB2BGR))[1
                                                                                      ].tobytes()
            pub_img.publish(cm)
        else:
            img = Image()
            img.header.stamp, img.header.frame_id = stamp, "camera"
            img.height, img.width = frame.image.shape[:2]
            img.encoding, img.step = "rgb8", frame.image.shape[1] * 3
            img.data = frame.image.tobytes()
            pub_img.publish(img)
        seq += 1
        # the same reading again at the odometry rate until the next frame
        j = 1
        while j * odom_ns < dt_ns and not rospy.is_shutdown():
            due = wall0 + (k * dt_ns + j * odom_ns) * 1e-9 / args.rate if args.rate > 0 else 0
            time.sleep(max(0.0, due - time.monotonic()))
            om.header.stamp = rospy.Time(*divmod(t + j * odom_ns, 1_000_000_000))
            om.header.seq = seq
            pub_odom.publish(om)
            seq += 1
            j += 1
        k += 1
        if args.rate > 0:
            time.sleep(max(0.0, wall0 + k * dt_ns * 1e-9 / args.rate - time.monotonic()))
    time.sleep(args.linger)  # the last messages reach the subscribers
    return 0


def _controller(rospy: Any, args: Any) -> int:
    from geometry_msgs.msg import PointStamped, PoseStamped, Twist

    from tileviz.sim.controller import Controller
    from tileviz.sim.setpoints import Lissajous, ManualTarget, Waypoints

    cfg = config_from_args(args)
    s = cfg.sim
    ctrl = Controller(s.wheel_base, s.max_wheel_speed)
    state: dict[str, Any] = {"setpoint": {
        "lissajous": lambda: Lissajous(s.lissajous_amplitude, s.lissajous_omega),
        "manual": lambda: ManualTarget(*s.manual_target),
        "waypoints": lambda: Waypoints(tuple((p[0], p[1]) for p in s.waypoints)),
    }[s.setpoint](), "t0": None, "prev": None}
    pub = rospy.Publisher("/cmd_vel", Twist, queue_size=10)

    def on_setpoint(m: Any) -> None:
        state["setpoint"] = ManualTarget(m.point.x, m.point.y)
        ctrl.reset()

    def on_truth(m: Any) -> None:
        t = m.header.stamp.to_sec()
        if state["t0"] is None:
            state["t0"] = t
        q = m.pose.orientation
        pose = Pose(m.pose.position.x, m.pose.position.y, 2 * math.atan2(q.z, q.w))
        dt = s.dt if state["prev"] is None else max(t - state["prev"], 1e-6)
        state["prev"] = t
        target = state["setpoint"].target(t - state["t0"], pose)
        v, w = twist_of_wheels(*ctrl.command(pose, target, dt), s.wheel_base)
        tw = Twist()
        tw.linear.x, tw.angular.z = v, w
        pub.publish(tw)

    rospy.Subscriber("/setpoint", PointStamped, on_setpoint)
    rospy.Subscriber("/truth", PoseStamped, on_truth, queue_size=1)
    rospy.spin()
    return 0


def _parser(prog: str, sim: bool) -> Parser:
    p = Parser(prog=prog, description="The simulator as a ROS 1 robot." if sim else
               "The demo's PD controller as a ROS 1 node (/truth, /setpoint -> /cmd_vel).")
    p.add_argument("--seed", type=int, default=None, help="the simulator's seed")
    p.add_argument("--setpoint", choices=("lissajous", "manual", "waypoints"), default=None,
                   help="what the robot drives to (default lissajous)")
    if sim:
        p.add_argument("--drive", choices=("setpoint", "cmd_vel"), default="setpoint",
                       help="its own setpoint and controller, or /cmd_vel")
        p.add_argument("--rate", type=nonneg_float("--rate"), default=1.0,
                       help="speed against real time (1: real time; 0: as fast as it can)")
        p.add_argument("--odom-rate", type=nonneg_float("--odom-rate"), default=50.0,
                       help="odometry messages a second (default 50; 0: one a frame)")
        p.add_argument("--frames", type=int, default=None, help="stop after this many frames")
        p.add_argument("--inject", action="append", default=[], metavar="FRAME:JSON",
                       help='start a fault at a frame, as ~inject does: 50:\'{"kind": '
                       '"kidnap", "x": 1, "y": 0, "theta": 0}\' (repeatable)')
        p.add_argument("--compressed", action="store_true",
                       help="publish sensor_msgs/CompressedImage (PNG) on "
                       "/camera/image/compressed")
        p.add_argument("--subscribers", type=int, default=0,
                       help="wait for this many camera subscribers before the first frame")
        p.add_argument("--wait", type=nonneg_float("--wait"), default=60.0,
                       help="at most this many seconds (default 60) for --subscribers")
        p.add_argument("--linger", type=nonneg_float("--linger"), default=1.0,
                       help="seconds to stay up after the last frame (with --frames)")
    return p


def main(command: str, argv: list[str]) -> int:
    """Entry point of ``python -m tileviz ros-sim`` and ``ros-controller``."""
    prog = f"tileviz {command}"
    sim = command == "ros-sim"

    def body() -> int:
        from tileviz.ros import load_rospy, require_master

        rospy = load_rospy()
        args = _parser(prog, sim).parse_args(rospy.myargv(argv=[prog, *argv])[1:])
        if sim and args.frames is not None and args.frames < 1:
            raise CliError(f"--frames must be an integer >= 1, got {args.frames}")
        require_master()
        rospy.init_node("tileviz_sim" if sim else "tileviz_controller")
        return _sim(rospy, args) if sim else _controller(rospy, args)

    return run_cli(prog, body)
