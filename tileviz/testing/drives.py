"""Synthetic drives: a robot on exact arcs, its sensors read within their declared bounds.

Two forms. :class:`Drive` moves a robot one frame at a time and feeds a
:class:`~tileviz.core.localizer.Localizer` (faults added by the caller: odometry beyond its bound,
a jump, no view). :func:`make_run` makes a whole drive of a preset as a list of frames (the
odometry of the previous step, the compass, the observation, the truth), for timing
(:func:`time_step`). Units and frames as in ``docs/dataset-format.md``: metres, radians, seconds.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tileviz.config import Config, LocalizerConfig
from tileviz.core.intervals import TWO_PI
from tileviz.core.localizer import Localizer, LocalizerStep
from tileviz.core.tiles import observe
from tileviz.pipeline import initial_box
from tileviz.testing import timing
from tileviz.types import Box, Observation, Odometry, Pose, SensorBounds

__all__ = ["BOUNDS", "DT", "E_HEAD", "E_POS", "Drive", "arc", "localizer_of", "make_run",
           "noisy_compass", "noisy_view", "time_step"]

BOUNDS = SensorBounds(speed_error=0.02, yaw_rate_error=0.01, compass_error=0.02)
"""The odometry and compass bounds of :class:`Drive` (m/s, rad/s, rad)."""
E_POS, E_HEAD = 0.01, 0.02
"""The declared view bounds of :class:`Drive` (m, rad)."""
DT = 0.05
"""The frame period of :class:`Drive`, s."""


def arc(p: Pose, v: float, w: float, h: float) -> Pose:
    """Exact unicycle motion: speed v, yaw rate w (non-zero) for h seconds."""
    t1 = p.theta + w * h
    r = v / w
    return Pose(p.x + r * (math.sin(t1) - math.sin(p.theta)),
                p.y - r * (math.cos(t1) - math.cos(p.theta)), t1)


def noisy_view(p: Pose, L: float, offset: tuple[float, float], u: np.ndarray) -> Observation:
    """The observation of ``p`` off by less than its declared bounds (u in [-1, 1]^3)."""
    y1, y2, y3 = observe(p, L, offset)
    return Observation(y1 + 0.9 * u[0] * E_POS, y2 + 0.9 * u[1] * E_POS, y3 + 0.9 * u[2] * E_HEAD,
                       E_POS, E_HEAD)


def noisy_compass(theta: float, u: float) -> float:
    """The compass reading of heading ``theta`` off by ``0.9 u`` of its bound (u in [-1, 1])."""
    return math.remainder(theta + 0.9 * u * BOUNDS.compass_error, 2 * math.pi)


class Drive:
    """A robot driving arcs, its sensors within their bounds unless told otherwise, and a
    localizer fed frame by frame (L m tiles, the camera ``offset`` (forward, left) m)."""

    def __init__(self, config: LocalizerConfig, *, L: float = 1.0,
                 offset: tuple[float, float] = (0.3, 0.0), seed: int = 0) -> None:
        self.L, self.offset = L, offset
        self.rng = np.random.default_rng(seed)
        self.truth = Pose(0.2, 0.1, 0.3)
        t = self.truth
        self.loc = Localizer(tile_size=L, camera_offset=offset, bounds=BOUNDS, config=config,
                             initial=Box(t.x - 0.02, t.x + 0.02, t.y - 0.02, t.y + 0.02,
                                         t.theta - 0.01, t.theta + 0.01))
        self.first = True

    def step(self, *, v: float = 0.5, w: float = 0.2, excess: tuple[float, float] = (0.0, 0.0),
             jump: tuple[float, float, float] | None = None,
             view: bool = True) -> LocalizerStep:
        """One frame: move (or teleport by ``jump``), read the odometry with ``excess`` (m/s,
        rad/s) beyond its bound, then step the localizer with the compass and the view."""
        u = self.rng.uniform(-1.0, 1.0, 6)
        odometry = None
        if not self.first:
            self.truth = arc(self.truth, v, w, DT)
            odometry = Odometry(v + 0.9 * u[0] * BOUNDS.speed_error + excess[0],
                                w + 0.9 * u[1] * BOUNDS.yaw_rate_error + excess[1], DT)
        self.first = False
        if jump is not None:
            t = self.truth
            self.truth = Pose(t.x + jump[0], t.y + jump[1], t.theta + jump[2])
        obs = noisy_view(self.truth, self.L, self.offset, u[2:5]) if view else None
        return self.loc.step(odometry, noisy_compass(self.truth.theta, u[5]), obs)

    def inside(self, step: LocalizerStep) -> bool:
        """Whether the set after ``step`` holds the true pose."""
        return step.updated.contains(*self.truth.as_tuple())


def _chord_step(p: Pose, v: float, w: float, h: float) -> Pose:
    """The unicycle's exact arc over h seconds: a chord of length v h sinc(w h / 2) along the
    mid-step heading (np.sinc(u) = sin(pi u) / (pi u))."""
    chord = v * h * float(np.sinc(w * h / (2 * math.pi)))
    mid = p.theta + 0.5 * w * h
    return Pose(p.x + chord * math.cos(mid), p.y + chord * math.sin(mid), p.theta + w * h)


def make_run(cfg: Config, frames: int, seed: int) -> list[dict[str, Any]]:
    """A smooth drive of ``cfg`` and its sensor readings (uniform within 90 % of each bound):
    per frame the odometry of the previous step, the compass, the observation, the truth."""
    rng = np.random.default_rng(seed)
    dt = cfg.sim.dt
    L = cfg.floor.tile_size
    off = cfg.camera.offset
    nz = cfg.noise
    e = cfg.position_error
    e3 = cfg.vision.heading_error
    pose = Pose(*cfg.sim.initial_pose)
    out: list[dict[str, Any]] = []
    odo = None
    for k in range(frames):
        y1, y2, y3 = observe(pose, L, off)
        u = rng.uniform(-0.9, 0.9, 6)
        out.append({
            "odometry": odo,
            "compass": math.remainder(pose.theta + u[0] * nz.compass_error, TWO_PI),
            "observation": Observation(y1 + u[1] * e, y2 + u[2] * e, y3 + u[3] * e3, e, e3),
            "truth": pose,
        })
        v = 0.5 + 0.3 * math.sin(0.07 * k)
        w = 0.6 * math.sin(0.013 * k)
        for _ in range(10):
            pose = _chord_step(pose, v, w, dt / 10)
        odo = Odometry(v + u[4] * nz.speed_error, w + u[5] * nz.yaw_rate_error, dt)
    return out


def localizer_of(cfg: Config) -> Localizer:
    """A fresh localizer of ``cfg`` from its initial box (as the frame loop builds it)."""
    bounds = SensorBounds(cfg.noise.speed_error, cfg.noise.yaw_rate_error, cfg.noise.compass_error)
    return Localizer(tile_size=cfg.floor.tile_size, camera_offset=cfg.camera.offset,
                     bounds=bounds, config=cfg.localizer, initial=initial_box(cfg))


def time_step(cfg: Config, run: list[dict[str, Any]], repeats: int) -> float:
    """``Localizer.step`` over ``run``, microseconds a frame on :func:`timing.clock`, best of
    ``repeats`` passes (each from a fresh localizer)."""
    best = math.inf
    args = [(f["odometry"], f["compass"], f["observation"], f["truth"]) for f in run]
    for _ in range(repeats):
        step = localizer_of(cfg).step
        t0 = timing.clock()
        for a in args:
            step(*a)
        best = min(best, timing.clock() - t0)
    return best / len(run) * 1e6
