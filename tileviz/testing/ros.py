"""A real ROS 1 master for tests and benches: :func:`roscore` starts ``roscore`` on a free port
(its own ``ROS_HOME``), yields the environment that points nodes at it, and stops it and every
process :func:`start` started (SIGINT, then SIGKILL after a grace period) at exit."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["RosGraph", "free_port", "roscore", "ros_missing"]


def ros_missing() -> str | None:
    """Why ROS 1 cannot run here (no roscore, no rospy), or None."""
    from tileviz.ros import rospy_missing

    if shutil.which("roscore") is None:
        return "no roscore on PATH (apt-get install ros-core, docs/ros.md)"
    return rospy_missing()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class RosGraph:
    """Processes of one test's ROS graph, each in its own process group."""

    def __init__(self, env: dict[str, str], logs: Path) -> None:
        self.env = env
        self.logs = logs
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(self, name: str, *argv: str, python: bool = True) -> subprocess.Popen[bytes]:
        """Start ``python -m tileviz ARGV`` (or ``ARGV`` when not ``python``), its output in
        ``logs/NAME.log``."""
        cmd = [sys.executable, "-m", "tileviz", *argv] if python else list(argv)
        log = open(self.logs / f"{name}.log", "wb")  # noqa: SIM115 - closed with the process
        p = subprocess.Popen(cmd, env=self.env, stdout=log, stderr=subprocess.STDOUT,
                             start_new_session=True)
        self.procs.append(p)
        return p

    def log(self, name: str) -> str:
        return (self.logs / f"{name}.log").read_text(errors="replace")

    @staticmethod
    def stop(p: subprocess.Popen[bytes], grace: float = 20.0) -> int:
        """SIGINT to the process group, SIGKILL after ``grace`` seconds; the exit status."""
        if p.poll() is None:
            try:
                os.killpg(p.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
            try:
                p.wait(grace)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        return int(p.returncode)

    @staticmethod
    def group_alive(p: subprocess.Popen[bytes]) -> bool:
        """Whether any process of ``p``'s group is still running."""
        try:
            os.killpg(p.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True


@contextmanager
def roscore(tmp: Path) -> Iterator[RosGraph]:
    """A roscore on a free port for the ``with`` block; its graph's processes stop after it."""
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}",
               ROS_HOME=str(tmp / "ros_home"), ROS_IP="127.0.0.1", PYTHONUNBUFFERED="1")
    env.pop("ROS_HOSTNAME", None)
    graph = RosGraph(env, tmp)
    core = graph.start("roscore", "roscore", "-p", str(port), python=False)
    try:
        end = time.monotonic() + 60
        while True:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            if core.poll() is not None or time.monotonic() > end:
                raise RuntimeError(f"roscore did not start: {graph.log('roscore')[-500:]}")
            time.sleep(0.2)
        time.sleep(1.0)  # rosout comes up after the master
        yield graph
    finally:
        for p in reversed(graph.procs):
            graph.stop(p)
