"""tileviz on ROS 1: the live localizer node (``python -m tileviz ros``), the simulator as a
ROS robot (``python -m tileviz ros-sim``), the controller node (``python -m tileviz
ros-controller``) and a live Foxglove server (:mod:`tileviz.ros.foxglove_live`).

rospy comes from the system's ROS 1 (Debian/Ubuntu ``apt-get install ros-core python3-rospy
...``, docs/ros.md), not from PyPI: :func:`load_rospy` finds it in the system's
``dist-packages`` when the venv does not see it. :mod:`tileviz.ros.live` (the localizer without
ROS) imports no rospy.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from types import ModuleType

from tileviz.cliutil import CliError

__all__ = ["ROS_APT", "SYSTEM_DIST_PACKAGES", "load_rospy", "require_master", "rospy_missing"]

ROS_APT = ("apt-get install -y ros-core python3-rospy python3-rosbag python3-sensor-msgs "
           "python3-nav-msgs python3-geometry-msgs python3-visualization-msgs "
           "python3-diagnostic-msgs python3-std-msgs")
"""The Debian/Ubuntu packages of ROS 1 that the nodes need (docs/ros.md)."""

SYSTEM_DIST_PACKAGES = Path("/usr/lib/python3/dist-packages")
"""Where Debian's python3-rospy and the message packages live."""


def load_rospy() -> ModuleType:
    """rospy, importable here or from :data:`SYSTEM_DIST_PACKAGES` (appended to ``sys.path``
    after the venv's own packages, so those win); CliError with the install line when ROS 1 is
    absent."""
    try:
        return importlib.import_module("rospy")
    except ImportError:
        pass
    if (SYSTEM_DIST_PACKAGES / "rospy").is_dir() and str(SYSTEM_DIST_PACKAGES) not in sys.path:
        sys.path.append(str(SYSTEM_DIST_PACKAGES))
        try:
            return importlib.import_module("rospy")
        except ImportError:
            pass
    raise CliError(f"ROS 1 (rospy) is not installed: {ROS_APT} (docs/ros.md)")


def rospy_missing() -> str | None:
    """None when rospy can be loaded, else the one line saying how to install it."""
    try:
        load_rospy()
    except CliError as e:
        return str(e)
    return None


def require_master(timeout: float = 5.0) -> None:
    """CliError naming ``ROS_MASTER_URI`` when no ROS master answers within ``timeout`` s."""
    import os
    import time

    load_rospy()
    import rosgraph

    uri = os.environ.get("ROS_MASTER_URI", "http://localhost:11311")
    end = time.monotonic() + timeout
    while not rosgraph.is_master_online():
        if time.monotonic() >= end:
            raise CliError(f"no ROS master at {uri} (start roscore, or set ROS_MASTER_URI)")
        time.sleep(0.2)
