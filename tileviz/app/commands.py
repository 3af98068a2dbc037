"""Commands the GUI (or a test) puts on the app's queue; the loop thread applies them between
frames.

Every command is a small frozen dataclass that checks its own arguments when it is made: a bad
value raises ValueError naming the quantity, so a GUI callback can report it and enqueue nothing.
Units: metres, radians, seconds (``speed`` is a multiple of real time).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from tileviz.config import (
    EXTRACTORS,
    FLOOR_STYLES,
    MODES,
    PPM_RANGE,
    SEED_RANGE,
    SETPOINTS,
    TILE_SIZE_RANGE,
    Extractor,
    Mode,
    finite_number,
)

__all__ = [
    "LABELS", "LAYERS", "MAX_TEXT", "MAX_WAYPOINTS", "NOT_LIVE", "PANEL_VIEWS", "SIMULATOR_ONLY",
    "Command", "Inject", "Kidnap", "Live", "Pause",
    "ExportMcap", "ExportPage", "Play", "Relocalize", "RelocalizeRegion", "Report", "SetFollow",
    "ShowPanel",
    "Reset", "Restart", "Seek", "SetDisplay", "SetExtractor", "SetInflation", "SetLayer",
    "SetFaultModel", "SetManualTarget", "SetMaxSpeed", "SetMcl", "SetMode", "SetNoise",
    "SetSetpoint", "SetSpeed",
    "SetWaypoints", "StartRecording", "Step", "StepBack", "StopRecording", "TogglePlay",
    "label", "parse_region", "parse_waypoints",
]

LAYERS = (
    "floor", "grid", "robot", "footprint", "truth", "prediction", "boxes", "wedge", "setpoint",
    "path", "trails", "particles",
)
"""Scene layers the GUI can show or hide."""

MAX_SPEED_FACTOR = 50.0
"""Upper bound of the playback speed, a multiple of real time."""
MAX_WAYPOINTS = 1000
"""Most waypoints a setpoint takes (each is drawn for every client)."""
MAX_TEXT = 20_000
"""Longest text (characters) a text box's command parses."""


def _text(name: str, text: object) -> str:
    if not isinstance(text, str):
        raise ValueError(f"{name} must be text, got {type(text).__name__}")
    if len(text) > MAX_TEXT:
        raise ValueError(f"{name} is {len(text)} characters long, at most {MAX_TEXT} are read")
    return text


def _short(text: str, n: int = 60) -> str:
    """``repr`` of a piece of typed text, cut to about ``n`` characters."""
    return repr(text if len(text) <= n else text[:n] + "...")


def _in_range(name: str, value: object, lo: float, hi: float) -> float:
    v = finite_number(name, value)
    if not lo <= v <= hi:
        raise ValueError(f"{name} must be in [{lo:g}, {hi:g}], got {v:g}")
    return v


def _choice(name: str, value: object, options: Sequence[str]) -> None:
    if value not in options:
        raise ValueError(f"{name} must be one of {', '.join(options)}; got {value!r}")


@dataclass(frozen=True)
class Play:
    """Run: replay the history forward from the shown frame, then compute new frames."""


@dataclass(frozen=True)
class Pause:
    """Stop advancing (the shown frame stays)."""


@dataclass(frozen=True)
class TogglePlay:
    """Play when paused, pause when playing."""


@dataclass(frozen=True)
class Step:
    """Pause and advance exactly one frame (the next stored one, or a new one at the end)."""


@dataclass(frozen=True)
class StepBack:
    """Pause and show the previous stored frame."""


@dataclass(frozen=True)
class Seek:
    """Pause and show the stored frame ``index`` (clamped to the history)."""

    index: int

    def __post_init__(self) -> None:
        v = finite_number("frame index", self.index)
        if v != int(v):
            raise ValueError(f"frame index must be an integer, got {self.index!r}")
        object.__setattr__(self, "index", int(v))


@dataclass(frozen=True)
class Live:
    """Show the newest frame (and keep playing if playing)."""


@dataclass(frozen=True)
class SetSpeed:
    """Playback speed, a multiple of real time (1 = one frame per ``dt``)."""

    factor: float

    def __post_init__(self) -> None:
        _in_range("speed", self.factor, 0.01, MAX_SPEED_FACTOR)


@dataclass(frozen=True)
class SetMaxSpeed:
    """Run as fast as the machine allows (``on``) or at the chosen speed."""

    on: bool


@dataclass(frozen=True)
class SetSetpoint:
    """Switch the setpoint kind: lissajous, manual or waypoints."""

    kind: str

    def __post_init__(self) -> None:
        _choice("setpoint", self.kind, SETPOINTS)


@dataclass(frozen=True)
class SetManualTarget:
    """Drive to (x, y), metres (switches the setpoint to manual)."""

    x: float
    y: float

    def __post_init__(self) -> None:
        _in_range("target x", self.x, -1e4, 1e4)
        _in_range("target y", self.y, -1e4, 1e4)


@dataclass(frozen=True)
class SetWaypoints:
    """Loop through ``points`` [(x, y), ...], metres (switches the setpoint to waypoints)."""

    points: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        if not self.points:
            raise ValueError("waypoints must hold at least one point")
        if len(self.points) > MAX_WAYPOINTS:
            raise ValueError(f"at most {MAX_WAYPOINTS} waypoints, got {len(self.points)}")
        for i, (x, y) in enumerate(self.points):
            _in_range(f"waypoint {i} x", x, -1e4, 1e4)
            _in_range(f"waypoint {i} y", y, -1e4, 1e4)


def parse_waypoints(text: str) -> tuple[tuple[float, float], ...]:
    """``"x1, y1; x2, y2; ..."`` (metres) as points; ValueError naming the bad piece (at most
    :data:`MAX_TEXT` characters and :data:`MAX_WAYPOINTS` points are read)."""
    points: list[tuple[float, float]] = []
    for i, piece in enumerate(p for p in _text("waypoints", text).replace("\n", ";").split(";")
                              if p.strip()):
        if i >= MAX_WAYPOINTS:
            raise ValueError(f"at most {MAX_WAYPOINTS} waypoints are read")
        parts = [s for s in piece.replace(",", " ").split() if s]
        if len(parts) != 2:
            raise ValueError(f"waypoint {i}: expected 'x, y', got {_short(piece.strip())}")
        x = finite_number(f"waypoint {i} x", parts[0])
        y = finite_number(f"waypoint {i} y", parts[1])
        points.append((x, y))
    if not points:
        raise ValueError("waypoints must hold at least one point ('x, y; x, y; ...')")
    return tuple(points)


@dataclass(frozen=True)
class Kidnap:
    """Teleport the robot (the localizer is not told). ``pose`` (x, y, theta) in m, m, rad, or
    None for a random pose inside the Lissajous area."""

    pose: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.pose is not None:
            x, y, t = self.pose
            _in_range("kidnap x", x, -1e4, 1e4)
            _in_range("kidnap y", y, -1e4, 1e4)
            _in_range("kidnap theta", t, -1e3, 1e3)


@dataclass(frozen=True)
class Relocalize:
    """Tell the localizer the robot's true pose (within the configured initial pose error)."""


@dataclass(frozen=True)
class RelocalizeRegion:
    """Restart the localizer from "somewhere in ``region``" = (x0, y0, x1, y1), metres, heading
    from the compass (``Localizer.relocalize``: one candidate box per tile cell that fits the
    view, dropped as the motion takes them out of the region; the robot must stay in it until one
    candidate is left)."""

    region: tuple[float, float, float, float]

    def __post_init__(self) -> None:
        if len(self.region) != 4:
            raise ValueError(f"region must be x0, y0, x1, y1 (m), got {self.region!r}")
        x0, y0, x1, y1 = (_in_range(f"region {n}", v, -1e4, 1e4)
                          for n, v in zip(("x0", "y0", "x1", "y1"), self.region, strict=True))
        if x0 > x1 or y0 > y1:
            raise ValueError(f"region needs x0 <= x1 and y0 <= y1, got {self.region!r}")


def parse_region(text: str) -> tuple[float, float, float, float]:
    """``"x0, y0, x1, y1"`` (metres) as a region; ValueError naming the problem."""
    parts = [p for p in _text("region", text).replace(",", " ").split() if p]
    if len(parts) != 4:
        raise ValueError(f"region: expected 'x0, y0, x1, y1', got {_short(text.strip())}")
    x0, y0, x1, y1 = (finite_number(f"region {n}", p)
                      for n, p in zip(("x0", "y0", "x1", "y1"), parts, strict=True))
    return (x0, y0, x1, y1)


@dataclass(frozen=True)
class Reset:
    """Start the run again from frame 0 (``seed``: a new noise seed, or None to keep it)."""

    seed: int | None = None

    def __post_init__(self) -> None:
        lo, hi = SEED_RANGE
        if self.seed is not None and (int(self.seed) != self.seed or not lo <= self.seed <= hi):
            raise ValueError(f"seed must be an integer in [{lo}, {hi}], got {self.seed!r}")


@dataclass(frozen=True)
class Restart:
    """Start a new run with another floor or camera: tile size L (m), ppm (pixels/m) and the
    floor style (a key of ``tileviz.config.FLOOR_STYLES``)."""

    tile_size: float
    ppm: float
    style: str = "default"

    def __post_init__(self) -> None:
        _in_range("tile size", self.tile_size, *TILE_SIZE_RANGE)
        _in_range("ppm", self.ppm, *PPM_RANGE)
        _choice("floor style", self.style, tuple(FLOOR_STYLES))


@dataclass(frozen=True)
class SetMode:
    """Localizer mode: autonomous, truth or odometry."""

    mode: Mode

    def __post_init__(self) -> None:
        _choice("mode", self.mode, MODES)


@dataclass(frozen=True)
class SetExtractor:
    """Vision extractor: faithful or robust."""

    extractor: Extractor

    def __post_init__(self) -> None:
        _choice("extractor", self.extractor, EXTRACTORS)


@dataclass(frozen=True)
class SetNoise:
    """Sensor error bounds (m/s, rad/s, rad) and the share of each bound the simulated noise uses
    (``fraction`` > 1 breaks the declared bounds on purpose)."""

    speed_error: float
    yaw_rate_error: float
    compass_error: float
    fraction: float = 1.0

    def __post_init__(self) -> None:
        _in_range("speed error bound", self.speed_error, 0.0, 1.0)
        _in_range("yaw rate error bound", self.yaw_rate_error, 0.0, 1.0)
        _in_range("compass error bound", self.compass_error, 0.0, math.pi)
        _in_range("noise fraction", self.fraction, 0.0, 5.0)


@dataclass(frozen=True)
class SetInflation:
    """Truth mode: half-widths added around the true pose, metres (x and y) and radians."""

    xy: float
    theta: float

    def __post_init__(self) -> None:
        _in_range("inflation x/y", self.xy, 0.0, 10.0)
        _in_range("inflation theta", self.theta, 0.0, math.pi)


@dataclass(frozen=True)
class SetFaultModel:
    """The localizer's fault model (``LocalizerConfig.fault_speed``, ``fault_yaw_rate``): how
    much faster than its odometry bounds a fault may move the robot, m/s and rad/s; ``on``
    False turns it off (0, 0)."""

    speed: float
    yaw_rate: float
    on: bool = True

    def __post_init__(self) -> None:
        _in_range("fault model speed", self.speed, 0.0, 10.0)
        _in_range("fault model yaw rate", self.yaw_rate, 0.0, 10.0)


@dataclass(frozen=True)
class SetDisplay:
    """Stream the pipeline stage images (and keep them in the history) or not."""

    on: bool


@dataclass(frozen=True)
class SetFollow:
    """Move the view with the robot while playing (``on``), or leave it where the user put it."""

    on: bool


PANEL_VIEWS = ("camera", "stages", "plots")
"""What the left panel shows under the inset: the camera view, the camera view and every
pipeline stage, or the plots (only what is shown is sent to the browser)."""


@dataclass(frozen=True)
class ShowPanel:
    """Show ``view`` (:data:`PANEL_VIEWS`) in the left panel."""

    view: str

    def __post_init__(self) -> None:
        _choice("panel view", self.view, PANEL_VIEWS)


@dataclass(frozen=True)
class SetMcl:
    """Run the Monte Carlo Localization baseline beside the interval localizer (``on``); it starts
    from the initial box of the run (or, switched on mid-run, from the interval set's hull)."""

    on: bool


@dataclass(frozen=True)
class SetLayer:
    """Show or hide one scene layer (:data:`LAYERS`)."""

    layer: str
    visible: bool

    def __post_init__(self) -> None:
        _choice("layer", self.layer, LAYERS)


@dataclass(frozen=True)
class Inject:
    """Start a simulated fault (``tileviz.sim.source.SimSource.inject``) lasting ``frames``
    frames (None: the fault's default)."""

    kind: str
    frames: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str) or not self.kind:
            raise ValueError(f"fault kind must be a name, got {self.kind!r}")
        if self.frames is not None and (int(self.frames) != self.frames
                                        or not 1 <= self.frames <= 100_000):
            raise ValueError(f"fault frames must be an integer in [1, 100000], "
                             f"got {self.frames!r}")


@dataclass(frozen=True)
class StartRecording:
    """Write every new frame to a dataset folder ``name`` (sanitized) under the output folder."""

    name: str

    def __post_init__(self) -> None:
        _text("dataset name", self.name)


@dataclass(frozen=True)
class StopRecording:
    """Close the dataset being recorded."""


@dataclass(frozen=True)
class ExportMcap:
    """Export the last finished recording as an MCAP file for Foxglove, written beside its
    dataset folder (``NAME.mcap``): the file ``python -m tileviz replay NAME --mcap`` writes."""


@dataclass(frozen=True)
class ExportPage:
    """Export the last finished recording as a web page that plays offline, written beside its
    dataset folder (``NAME.html``): the page ``python -m tileviz export-html NAME NAME.html``
    writes."""


@dataclass(frozen=True)
class Report:
    """A one-line message for the GUI's notes (``level`` info or error; errors also go to
    stderr), e.g. a GUI input that was refused."""

    text: str
    level: str = "error"

    def __post_init__(self) -> None:
        _choice("level", self.level, ("info", "error"))


Command = (
    Play | Pause | TogglePlay | Step | StepBack | Seek | Live | SetSpeed | SetMaxSpeed
    | SetSetpoint | SetManualTarget | SetWaypoints | Kidnap | Relocalize | RelocalizeRegion
    | Reset | Restart
    | SetMode | SetExtractor | SetNoise | SetInflation | SetFaultModel | SetDisplay | SetMcl
    | SetLayer | Inject
    | StartRecording | StopRecording | ExportMcap | ExportPage | Report | SetFollow | ShowPanel
)
"""Any command the loop understands."""

LABELS: dict[type[Command], str] = {
    Play: "Play", Pause: "Pause", TogglePlay: "Play", Step: "Step", StepBack: "Step back",
    Seek: "Timeline", Live: "Go live", SetSpeed: "Speed", SetMaxSpeed: "As fast as possible",
    SetSetpoint: "Setpoint", SetManualTarget: "Manual target",
    SetWaypoints: "Drive the waypoints", Kidnap: "Kidnap", Relocalize: "Relocalize",
    RelocalizeRegion: "Re-localize in the region", Reset: "Reset",
    Restart: "Floor and camera", SetMode: "Mode", SetExtractor: "Extractor",
    SetNoise: "Noise bounds", SetInflation: "Truth inflation", SetFaultModel: "Fault model",
    SetDisplay: "Stage images", SetMcl: "Monte Carlo Localization", SetLayer: "Layers",
    Inject: "Inject a fault", StartRecording: "Start recording",
    StopRecording: "Stop recording", ExportMcap: "Export MCAP",
    ExportPage: "Export page", Report: "Note",
    SetFollow: "Follow the robot", ShowPanel: "Panel",
}
"""What the page calls the control that sends each command (a refused command's note names
the control, not the class)."""


def label(cmd: Command) -> str:
    """The page's name for the control that sent ``cmd`` (:data:`LABELS`)."""
    return LABELS.get(type(cmd), "a control")


SIMULATOR_ONLY: dict[type[Command], str] = {
    SetSetpoint: "the setpoint", SetManualTarget: "the setpoint", SetWaypoints: "the setpoint",
    Kidnap: "kidnap", SetNoise: "the sensor noise", Inject: "fault injection",
    Restart: "a new floor or camera", StartRecording: "recording", StopRecording: "recording",
}
"""Commands that steer the simulator, and what they change: a replay refuses them with a note."""

NOT_LIVE: dict[type[Command], str] = {Reset: "a new run from frame 0"}
"""Commands a source on its own clock (a ROS run, ``serve --ros``) refuses with a note, and
what they would do: its robot has moved on, the start pose no longer holds."""
