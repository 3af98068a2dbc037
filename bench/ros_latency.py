"""Latency of the live ROS node: from an image's stamp to the publication of its set.

A real roscore (``tileviz.testing.ros``), ``ros-sim`` in real time (20 Hz camera, 50 Hz
odometry) and ``python -m tileviz ros``; a subscriber takes each ``/tileviz/status`` message's
arrival (ROS time) minus its frame's stamp. The simulator stamps frame k ``start + k dt`` and
publishes it then, so the figure holds the transport both ways and the node's wait for the
messages after the image. Prints the median and p99 (ms), vision's own median and p99, and the
frames dropped.

    python bench/ros_latency.py [--frames 400]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from tileviz.ros import load_rospy
from tileviz.testing.ros import ros_missing, roscore


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=400)
    args = ap.parse_args()
    why = ros_missing()
    if why is not None:
        raise SystemExit(f"ros_latency: {why}")
    with tempfile.TemporaryDirectory() as tmp, roscore(Path(tmp)) as graph:
        import os

        os.environ.update(graph.env)
        rospy = load_rospy()
        from std_msgs.msg import String

        sim = graph.start("sim", "ros-sim", "--frames", str(args.frames), "--rate", "1",
                          "--odom-rate", "50", "--subscribers", "2", "--linger", "2")
        graph.start("node", "ros", "_meta_param:=/tileviz_sim/meta")
        rospy.init_node("latency_probe", anonymous=True, disable_signals=True)
        lat: list[float] = []
        vis: list[float] = []
        last: dict = {}

        def on_status(m: String) -> None:
            now = rospy.get_rostime().to_nsec()
            d = json.loads(m.data)
            if d.get("stale"):
                return
            lat.append((now - d["stamp"]) * 1e-6)
            vis.append(d["vision_ms"])
            last.update(d)

        rospy.Subscriber("/tileviz/status", String, on_status, queue_size=1000)
        sim.wait()
        time.sleep(2)
        rospy.signal_shutdown("done")
    a, v = np.array(lat), np.array(vis)
    print(f"frames {len(a)} of {args.frames}; dropped behind "
          f"{last.get('counts', {}).get('dropped_behind')}")
    print(f"stamp -> set published: median {np.median(a):.1f} ms, p99 "
          f"{np.percentile(a, 99):.1f} ms (frame period 50 ms)")
    print(f"vision: median {np.median(v):.1f} ms, p99 {np.percentile(v, 99):.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
