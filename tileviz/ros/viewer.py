"""``serve --ros``: the live demo following a ROS 1 run, as a run source of the demo's loop.

:class:`RosFeed` is a rospy node (``tileviz_viewer`` by default) with the localizer node's
inputs (:class:`tileviz.ros.node.RosInputs`: the same private parameters, topics and
combination, :class:`tileviz.ros.live.LiveCombiner`), plus the true pose when one is published
(``~truth_topic``, ``/truth`` by default: ``geometry_msgs/PoseStamped`` stamped as the image of
its frame, as ``ros-sim`` publishes it). Without ``~meta`` or ``~meta_param`` it reads the
simulator's ``/tileviz_sim/meta``.

:class:`RosSource` hands the session's frame loop the combined frames: the image as it came
(the session rectifies it with the meta's ``camera_model``, showing raw and rectified), the
compass, the true pose of the same stamp, and, before each frame (:meth:`RosSource.prime`),
the motion since the previous frame and the bounds declared now, so that the page's sets are
those ``python -m tileviz ros`` publishes for the same messages. The localizer starts from the
meta's ``initial_pose`` +- ``initial_pose_error``: subscribe before the robot moves (``ros-sim
--subscribers``). Stamps: nanoseconds of ROS time.
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict, deque
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from tileviz.app.sources import SourceNote, SourceWaiting
from tileviz.types import FrameInput, Pose

if TYPE_CHECKING:
    from tileviz.datasets.camera_model import Rectifier
    from tileviz.pipeline import FrameLoop
    from tileviz.ros.live import LiveInput

__all__ = ["DEFAULT_META_PARAM", "RosFeed", "RosSource"]

DEFAULT_META_PARAM = "/tileviz_sim/meta"
"""The parameter holding the run's meta.json when neither ``~meta`` nor ``~meta_param`` is set
(the one ``ros-sim`` sets)."""
TRUTHS_KEPT = 4000
"""True poses kept by stamp, at most (the oldest go first)."""
NEXT_WAIT = 0.05
"""Seconds ``next()`` waits for a frame before raising SourceWaiting."""
TRUTH_WAIT = 0.2
"""Seconds a frame waits for its true pose once a true pose was ever received."""
IDLE_SAY = 1.0
"""Seconds without a frame before SourceWaiting says why."""


def _yaw(q: Any) -> float:
    from tileviz.datasets.bag_import import yaw_of

    return float(yaw_of(q))


class RosFeed:
    """The viewer's ROS node: init with ``remaps`` (``name:=value`` arguments: ROS remappings and
    private parameters), read the parameters (CliError naming one that is wrong), warm the
    vision kernels; :meth:`start` subscribes. Raises CliError when ROS 1 is absent or no master
    answers."""

    def __init__(self, remaps: list[str], name: str = "tileviz_viewer") -> None:
        from tileviz.ros import load_rospy, require_master
        from tileviz.ros.live import LiveCombiner
        from tileviz.ros.node import RosInputs

        rospy = load_rospy()
        require_master()
        # serve handles SIGINT/SIGTERM itself; rospy's handlers need the main thread anyway
        rospy.init_node(name, argv=["serve", *remaps], disable_signals=True)
        self.rospy = rospy
        self._lock = threading.Lock()
        self._problems: deque[str] = deque(maxlen=20)
        self.inputs = RosInputs(rospy, LiveCombiner, self._log, meta_param=DEFAULT_META_PARAM)
        self.combiner: LiveCombiner = self.inputs.live
        self.truth_topic = str(rospy.get_param("~truth_topic", "/truth"))
        self._truths: OrderedDict[int, Pose] = OrderedDict()
        self._started = False
        from tileviz.vision.warmup import warm_up

        warm_up((self.combiner.cfg.vision.extractor,), self.combiner.cfg)

    def _log(self, text: str) -> None:
        with self._lock:
            if not self._problems or self._problems[-1] != text:
                self._problems.append(text)

    def problems(self) -> list[str]:
        """The bad-input lines since the last call (the combiner's included), oldest first."""
        problem = self.combiner.last_problem
        if problem is not None:
            self.combiner.last_problem = None
            self._log(problem)
        with self._lock:
            out = list(self._problems)
            self._problems.clear()
        return out

    def start(self) -> None:
        """Subscribe (once): the camera, odometry and IMU topics, and the true pose."""
        if self._started:
            return
        from geometry_msgs.msg import PoseStamped

        self._started = True
        self.inputs.subscribe()
        if self.truth_topic:
            self.rospy.Subscriber(self.truth_topic, PoseStamped, self._on_truth, queue_size=200)

    def _on_truth(self, msg: Any) -> None:
        stamp = int(msg.header.stamp.to_nsec())
        x, y = float(msg.pose.position.x), float(msg.pose.position.y)
        theta = _yaw(msg.pose.orientation)
        if not all(math.isfinite(v) for v in (x, y, theta)):
            self._log(f"{self.truth_topic} stamped {stamp} holds a non-finite value: ignored")
            return
        with self._lock:
            self._truths[stamp] = Pose(x, y, theta)
            while len(self._truths) > TRUTHS_KEPT:
                self._truths.popitem(last=False)

    def truth_at(self, stamp: int, wait: float = TRUTH_WAIT) -> Pose | None:
        """The true pose stamped ``stamp`` (ns), waiting up to ``wait`` s for it once any true
        pose was received; None when there is none."""
        end = time.monotonic() + wait
        while True:
            with self._lock:
                pose = self._truths.get(stamp)
                any_truth = bool(self._truths)
            if pose is not None or not any_truth or time.monotonic() >= end:
                return pose
            time.sleep(0.002)

    def now(self) -> int:
        """ROS time, nanoseconds."""
        return self.inputs.now()

    def describe(self) -> str:
        i = self.inputs
        topics = [t for t in (i.image_topic, i.odom_topic, i.imu_topic) if t]
        return "ROS run on " + ", ".join(topics)

    def close(self) -> None:
        """Leave the ROS graph."""
        self.rospy.signal_shutdown("tileviz serve stopped")


class RosSource:
    """A ROS run as the session's run source (:class:`tileviz.app.sources.RunSource`): frames
    as the combiner makes them; ``next()`` raises SourceWaiting when none is ready within
    :data:`NEXT_WAIT` s. ``pose``: the true pose of the last frame handed out (Relocalize
    restarts there, the next frame's motion then follows it)."""

    simulator = False
    restart_on_settings = False
    path_closed = False
    realtime = True

    def __init__(self, feed: RosFeed) -> None:
        self.feed = feed
        self.rectifier: Rectifier | None = feed.combiner.rectifier
        self.index = 0
        self._got: LiveInput | None = None
        self._last: Pose | None = None
        self._idle_since = time.monotonic()
        self._lost_said = False

    def __iter__(self) -> RosSource:
        return self

    def __next__(self) -> FrameInput:
        self.feed.start()
        combiner = self.feed.combiner
        end = time.monotonic() + NEXT_WAIT
        while True:
            got = combiner.next_input(self.feed.now())
            if got is not None:
                break
            now = time.monotonic()
            if now >= end:
                raise SourceWaiting(self._why() if now - self._idle_since >= IDLE_SAY else "")
            time.sleep(0.002)
        self._idle_since = time.monotonic()
        self._got = got
        truth = self.feed.truth_at(got.stamp)
        self._last = truth
        self.index = got.frame.index + 1
        return replace(got.frame, truth=truth)

    def _why(self) -> str:
        i = self.feed.inputs
        if self.feed.combiner.counts["images"] == 0:
            return f"waiting for images on {i.image_topic}"
        if self.feed.combiner.pending():
            return f"images wait for odometry on {i.odom_topic}"
        return f"no image on {i.image_topic} for over {IDLE_SAY:g} s"

    def prime(self, runner: FrameLoop) -> list[SourceNote]:
        """The motion since the previous frame and the declared bounds into ``runner``; the bad
        inputs since the last frame; once a late message broke a bound a frame used, an error
        note that degrades the run."""
        got, self._got = self._got, None
        if got is not None:
            self.feed.combiner.prime(runner, got)
        notes = [SourceNote(text) for text in self.feed.problems()]
        reason = self.feed.combiner.lost_reason
        if reason is not None and not self._lost_said:
            self._lost_said = True
            notes.append(SourceNote(f"the set no longer vouches for the truth: {reason}",
                                    "error", degrades=True))
        return notes

    @property
    def pose(self) -> Pose | None:
        return self._last

    def path(self) -> list[tuple[float, float]]:
        """None known ahead: the page draws the robot's trail as it goes."""
        return []

    def describe(self) -> str:
        return self.feed.describe()
