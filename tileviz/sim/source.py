"""The simulator as a frame source: an endless iterator of :class:`tileviz.types.FrameInput`.

Frame k carries the image rendered at the true pose k, the compass read at frame k, and the
odometry measured over the motion from pose k to pose k+1 (``docs/dataset-format.md``). So
``next()`` renders pose k, runs the controller on pose k, steps the world to pose k+1 and measures
that step, then returns frame k; the world is then already at pose k+1.

Commands (:meth:`SimSource.set_setpoint`, :meth:`~SimSource.kidnap`, :meth:`~SimSource.reset`,
:meth:`~SimSource.set_noise`, :meth:`~SimSource.inject`, ...) are meant to be called by the app
loop *between* ``next()`` calls, never from another thread. A command issued after frame k was
returned acts on pose k+1: a kidnap moves pose k+1 (frame k's odometry, already measured, knows
nothing of it); a new setpoint steers the step k+1 -> k+2.

Randomness: one ``numpy`` SeedSequence from ``SimConfig.seed`` gives independent streams for the
true start pose (uniform within ``initial_pose_error`` of ``initial_pose``), the sensor errors, the
image noise and the faults. The same seed and the same commands give the same frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from tileviz.config import Config, NoiseConfig, finite_number
from tileviz.sim.controller import Controller, Gains
from tileviz.sim.sensors import OdometryFault, Sensors
from tileviz.sim.setpoints import Lissajous, ManualTarget, Setpoint, Waypoints
from tileviz.sim.world import StepTruth, World
from tileviz.types import FrameInput, Pose

ODOMETRY_FAULTS = ("slip", "odometry_outlier")
"""Faults the sensors produce; any other kind but ``kidnap`` goes to the camera renderer."""


class Renderer(Protocol):
    """What SimSource needs from a camera: ``tileviz.sim.camera.FloorRenderer`` fits."""

    def render(self, pose: Pose, rng: np.random.Generator | None = None,
               faults: Any = None) -> np.ndarray: ...


class BlankRenderer:
    """A camera that sees nothing: a uniform gray HxWx3 uint8 image of the camera's size. For runs
    about motion only (tests, benchmarks of the simulation step); faults are ignored."""

    def __init__(self, width: int, height: int, gray: int = 128) -> None:
        self.image = np.full((int(height), int(width), 3), gray, dtype=np.uint8)
        self.image.flags.writeable = False

    def render(self, pose: Pose, rng: np.random.Generator | None = None,
               faults: Any = None) -> np.ndarray:
        return self.image


@dataclass
class ActiveFault:
    """A fault in progress: ``kind``, frames still to go, its parameters."""

    kind: str
    remaining: int
    params: dict[str, Any] = field(default_factory=dict)
    anchor: tuple[tuple[float, float], tuple[float, float]] | None = None
    """World points (metres) of an edge fault's line once it was first drawn: a cable, a box
    or a shadow edge lies on the floor and stays there while the robot moves."""
    resolved: bool = False
    """True once the parameters left out were drawn (on the fault's first frame)."""


class SimSource:
    """Simulated robot + camera, yielding one FrameInput per ``next()`` (endless).

    ``renderer``: anything with ``render(pose, rng=None, faults=None)`` returning an HxWx3 uint8
    image; by default a ``tileviz.sim.camera.FloorRenderer(cfg.floor, cfg.camera)``.
    ``gains``: controller gains. ``substeps``: physics substeps a frame.
    """

    def __init__(self, cfg: Config, *, renderer: Renderer | None = None,
                 gains: Gains | None = None, substeps: int = 5) -> None:
        self._renderer_given = renderer
        self.gains = gains or Gains()
        self.substeps = substeps
        s = cfg.sim
        self._setpoint_spec: tuple[str, Any] = (
            s.setpoint,
            {"lissajous": None, "manual": tuple(s.manual_target),
             "waypoints": tuple(tuple(p) for p in s.waypoints)}[s.setpoint],
        )
        self._start(cfg)

    # ------------------------------------------------------------------ set-up
    def _start(self, cfg: Config) -> None:
        self.cfg = cfg
        s = cfg.sim
        init_ss, sensor_ss, image_ss, fault_ss = np.random.SeedSequence(s.seed).spawn(4)
        rng0 = np.random.default_rng(init_ss)
        err = np.asarray(s.initial_pose_error, dtype=float)
        # strictly inside the declared error, so rounding never puts the truth outside the box
        start = np.asarray(s.initial_pose, dtype=float) + rng0.uniform(-0.999, 0.999, 3) * err
        self.world = World(s, pose=Pose(*(float(v) for v in start)), substeps=self.substeps)
        self.controller = Controller(s.wheel_base, s.max_wheel_speed, self.gains)
        self.sensors = Sensors(cfg.noise, np.random.default_rng(sensor_ss))
        self._image_rng = np.random.default_rng(image_ss)
        self._fault_rng = np.random.default_rng(fault_ss)
        if self._renderer_given is not None:
            self.renderer: Renderer = self._renderer_given
        elif getattr(self, "_rendered_for", None) != (cfg.floor, cfg.camera):
            from tileviz.sim.camera import FloorRenderer  # lazy: it pulls OpenCV in

            self.renderer = FloorRenderer(cfg.floor, cfg.camera)
            self._rendered_for = (cfg.floor, cfg.camera)
        self.index = 0
        """Index of the next frame ``next()`` returns."""
        self.faults: list[ActiveFault] = []
        self.last_step: StepTruth | None = None
        """The true motion of the last frame returned (pose k to k+1)."""
        self.last_faults: tuple[str, ...] = ()
        """Fault kinds active on the last frame returned (``kidnap`` on the first frame at the
        teleported pose)."""
        self._labels: list[str] = []
        self.setpoint: Setpoint = self._build_setpoint()

    def _build_setpoint(self) -> Setpoint:
        kind, arg = self._setpoint_spec
        if kind == "lissajous":
            return Lissajous(self.cfg.sim.lissajous_amplitude, self.cfg.sim.lissajous_omega)
        if kind == "manual":
            return ManualTarget(*arg)
        return Waypoints(arg)

    # ------------------------------------------------------------------ iteration
    def __iter__(self) -> SimSource:
        return self

    def __next__(self) -> FrameInput:
        k = self.index
        dt = self.cfg.sim.dt
        t = k * dt
        pose = self.world.pose
        compass = self.sensors.compass(pose.theta)
        camera_faults = [f for f in self.faults if f.kind not in ODOMETRY_FAULTS]
        image = self._render(pose, camera_faults)
        target = self.setpoint.target(t, pose)
        self.world.set_wheel_speeds(*self.controller.command(pose, target, dt))
        # the step lasts t[k+1] - t[k] exactly as a replay computes it from the frame times, so a
        # replay of a recording reproduces the live run bit for bit (docs/dataset-format.md:
        # t rules)
        step = self.world.step((k + 1) * dt - t)
        odometry = self.sensors.odometry(step, self._odometry_fault(step))
        self.last_step = step
        self.last_faults = tuple(self._labels) + tuple(f.kind for f in self.faults)
        self._labels = []
        for f in self.faults:
            f.remaining -= 1
        self.faults = [f for f in self.faults if f.remaining > 0]
        self.index = k + 1
        return FrameInput(
            index=k,
            t=t,
            image=image,
            odometry=odometry,
            compass=compass,
            truth=pose,
            setpoint=(target.x, target.y),
            faults=self.last_faults,
        )

    def _render(self, pose: Pose, camera_faults: list[ActiveFault]) -> np.ndarray:
        if camera_faults:
            spec = [(f.kind, self._fault_params(f, pose)) for f in camera_faults]
            return self.renderer.render(pose, rng=self._image_rng, faults=spec)
        return self.renderer.render(pose, rng=self._image_rng)

    def _fault_params(self, fault: ActiveFault, pose: Pose) -> dict[str, Any]:
        """A camera fault's parameters at ``pose``. On its first frame the parameters left out
        are drawn (from the image noise stream) and kept for the fault's whole duration; an
        edge fault (cable, box, shadow) is then pinned to the floor, so later frames see it
        where the robot's motion puts it. A renderer without ``resolve_faults`` gets the
        parameters as given."""
        from tileviz.sim.camera import EDGE_FAULTS, edge_in_image, edge_to_floor

        resolve = getattr(self.renderer, "resolve_faults", None)
        if resolve is None:
            return dict(fault.params)
        if not fault.resolved:
            fault.params = resolve([(fault.kind, fault.params)], self._image_rng)[0][1]
            fault.resolved = True
            if fault.kind in EDGE_FAULTS:
                fault.anchor = edge_to_floor(fault.params["angle"], fault.params["offset"],
                                             pose, self.cfg.camera)
            return dict(fault.params)
        params = dict(fault.params)
        if fault.anchor is not None:
            params["angle"], params["offset"] = edge_in_image(*fault.anchor, pose,
                                                              self.cfg.camera)
        return params

    def _odometry_fault(self, step: StepTruth) -> OdometryFault | None:
        dv = dw = 0.0
        for f in self.faults:
            if f.kind == "slip":
                # the wheels turn more than the robot moves: the reading runs ahead of the truth
                sign = 1.0 if step.speed >= 0 else -1.0
                dv += sign * f.params["speed"]
                dw += f.params["yaw_rate"]
            elif f.kind == "odometry_outlier":
                sv, sw = self._fault_rng.choice([-1.0, 1.0], size=2)
                dv += float(sv) * f.params["speed"]
                dw += float(sw) * f.params["yaw_rate"]
        if dv == 0.0 and dw == 0.0:
            return None
        return OdometryFault(dv, dw)

    # ------------------------------------------------------------------ commands
    @property
    def pose(self) -> Pose:
        """The true pose of the next frame (pose k+1 after frame k was returned)."""
        return self.world.pose

    def set_setpoint(self, kind: str, *, target: tuple[float, float] | None = None,
                     waypoints: Sequence[tuple[float, float]] | None = None) -> None:
        """Switch the setpoint: ``lissajous``; ``manual`` (``target`` (x, y) m, default the
        config's); ``waypoints`` (``waypoints`` [(x, y), ...] m, default the config's)."""
        if kind == "lissajous":
            spec: tuple[str, Any] = ("lissajous", None)
        elif kind == "manual":
            tx, ty = target if target is not None else self.cfg.sim.manual_target
            spec = ("manual", (finite_number("manual target x", tx),
                               finite_number("manual target y", ty)))
        elif kind == "waypoints":
            pts = waypoints if waypoints is not None else self.cfg.sim.waypoints
            spec = ("waypoints", tuple(
                (finite_number(f"waypoint {i} x", p[0]), finite_number(f"waypoint {i} y", p[1]))
                for i, p in enumerate(pts)))
            if not spec[1]:
                raise ValueError("waypoints must hold at least one point")
        else:
            raise ValueError(f"setpoint must be one of lissajous, manual, waypoints; got {kind!r}")
        self._setpoint_spec = spec
        self.setpoint = self._build_setpoint()
        self.controller.reset()

    def set_manual_target(self, x: float, y: float) -> None:
        """Drive to (x, y), metres, and stop there."""
        self.set_setpoint("manual", target=(x, y))

    def set_waypoints(self, points: Sequence[tuple[float, float]]) -> None:
        """Loop through ``points`` [(x, y), ...], metres."""
        self.set_setpoint("waypoints", waypoints=points)

    def kidnap(self, x: float, y: float, theta: float) -> None:
        """Teleport the robot to (x, y, theta) (m, m, rad) at rest; the sensors are not told."""
        pose = Pose(finite_number("kidnap x", x), finite_number("kidnap y", y),
                    finite_number("kidnap theta", theta))
        self.world.teleport(pose)
        self.controller.reset()
        self._labels.append("kidnap")

    def reset(self, seed: int | None = None, cfg: Config | None = None) -> None:
        """Start again at frame 0 (same seed unless ``seed``; new config if ``cfg``). The current
        setpoint kind and its points are kept; faults are cleared."""
        new = cfg if cfg is not None else self.cfg
        if seed is not None:
            if int(seed) != seed or seed < 0:
                raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
            new = replace(new, sim=replace(new.sim, seed=int(seed)))
        self._start(new)

    def set_noise(self, noise: NoiseConfig) -> None:
        """New sensor error bounds and noise, from the next reading on."""
        if not isinstance(noise, NoiseConfig):
            raise ValueError(f"noise must be a NoiseConfig, got {type(noise).__name__}")
        self.cfg = replace(self.cfg, noise=noise)
        self.sensors.noise = noise

    def inject(self, kind: str, *, frames: int | None = None, **params: float) -> None:
        """Start a fault on the next frame, lasting ``frames`` frames.

        - ``slip`` (default 40 frames = 2 s at 20 Hz): the wheels slip: the odometry reads
          ``speed`` m/s (default 0.1, along the motion) and ``yaw_rate`` rad/s (default 0.05)
          more than the truth, on top of its bounded noise — beyond the default bounds.
        - ``odometry_outlier`` (default 1 frame): readings off by +-``speed`` (default 0.5 m/s)
          and +-``yaw_rate`` (default 0.5 rad/s), random signs.
        - ``kidnap``: same as :meth:`kidnap` with ``x``, ``y``, ``theta``.
        - a camera fault of ``tileviz.sim.camera.FAULT_KINDS`` (cable, box, shadow, glare,
          motion_blur, dropout) is handed to the renderer as ``faults=[(kind, params)]`` for
          ``frames`` frames (default 1); parameters left out are drawn on its first frame from
          the image noise stream and kept; ``angle``/``offset`` of a cable, box or shadow are
          the image frame's on that first frame, after which the edge stays put on the floor
          while the robot moves. A 2 s dropout at 20 Hz: ``inject("dropout", frames=40)``.
        """
        if kind == "kidnap":
            missing = [k for k in ("x", "y", "theta") if k not in params]
            if missing:
                raise ValueError(f"kidnap needs {', '.join(missing)}")
            self.kidnap(params["x"], params["y"], params["theta"])
            return
        defaults: dict[str, dict[str, float]] = {
            "slip": {"speed": 0.1, "yaw_rate": 0.05},
            "odometry_outlier": {"speed": 0.5, "yaw_rate": 0.5},
        }
        default_frames = {"slip": 40}.get(kind, 1)
        n = default_frames if frames is None else frames
        if int(n) != n or n < 1:
            raise ValueError(f"fault frames must be an integer >= 1, got {frames!r}")
        if kind not in defaults:
            self._check_camera_fault(kind, params)
            self.faults.append(ActiveFault(kind, int(n), dict(params)))
            return
        values = dict(defaults[kind])
        for name, v in params.items():
            if name not in values:
                raise ValueError(f"unknown parameter {name!r} for fault {kind!r}")
            values[name] = finite_number(f"{kind} {name}", v)
            if values[name] < 0:
                raise ValueError(f"{kind} {name} must be >= 0, got {v!r}")
        self.faults.append(ActiveFault(kind, int(n), values))

    def _check_camera_fault(self, kind: str, params: dict[str, Any]) -> None:
        """Refuse a bad camera fault now, not on every frame it would last."""
        from tileviz.sim.camera import FAULT_KINDS, FloorRenderer

        if kind not in FAULT_KINDS:
            raise ValueError(
                f"unknown fault {kind!r} (choose from kidnap, {', '.join(ODOMETRY_FAULTS)}, "
                f"{', '.join(FAULT_KINDS)})")
        if isinstance(self.renderer, FloorRenderer):
            # a dry run without noise: the renderer names any bad parameter
            self.renderer.render(self.world.pose, rng=None, faults=[(kind, dict(params))])

    def lissajous_path(self, n: int = 400) -> list[tuple[float, float]]:
        """One lap of the configured Lissajous curve, for drawing (metres)."""
        return Lissajous(self.cfg.sim.lissajous_amplitude, self.cfg.sim.lissajous_omega).path(n)
