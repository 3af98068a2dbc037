"""The control panel: playback, setpoint, localizer and vision options, floor and camera, layers,
faults and recording; and the readouts the loop refreshes.

Every callback only builds a command (:mod:`tileviz.app.commands`) and hands it to ``submit``;
the loop thread applies it between frames. Callbacks are ``async`` so viser runs them on its event
loop in the order the browser sent them (a slider drag arrives in order); ``submit`` never blocks.
A value the command refuses becomes a one-line note instead. Changes the *server* makes to a
control (``handle.value = ...`` in :meth:`Controls.refresh`) call the callbacks too, with
``event.client`` None: those are ignored.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

from tileviz.app import commands as C
from tileviz.config import (
    EXTRACTORS,
    FLOOR_STYLES,
    MODES,
    PPM_RANGE,
    SEED_RANGE,
    SETPOINTS,
    TILE_SIZE_RANGE,
    Config,
)
from tileviz.datasets.mcap_export import mcap_missing
from tileviz.sim.camera import FAULT_KINDS
from tileviz.sim.source import ODOMETRY_FAULTS

if TYPE_CHECKING:
    from viser import (
        GuiButtonHandle,
        GuiCheckboxHandle,
        GuiEvent,
        GuiFolderHandle,
        GuiInputHandle,
        SceneClickEvent,
        TransformControlsEvent,
        ViserServer,
    )

__all__ = ["Controls", "format_region"]

FAULTS = ODOMETRY_FAULTS + FAULT_KINDS
"""Faults the simulator can inject (``SimSource.inject``): its odometry faults, then the
camera's."""

HELP = """
**The scene.** The tiled floor as its grout lines (the photo-like floor texture is a layer to
switch on: slow without a GPU), the robot (grey) and its camera's footprint (yellow). The **pink
arrow** is the true pose: only the simulator (or a dataset's ground truth) knows it.

**The boxes.** **Green**: the *prediction*, every pose the odometry and the compass allow before
the camera is looked at. **Blue**: the *set* after the camera's view cut it down (the
*contraction*); several blue boxes are candidate places the view cannot tell apart. The **blue
wedge** is the heading interval. Unless the status is `lost`, the true pose is inside the blue
set whenever the sensors respect their declared bounds. The boxes are about a centimetre wide:
the **magnified inset** (left panel) draws them around the truth, with a scale bar.

**Statuses.** `contracted`: the view shrank the set. `predicted`: no usable view this frame
(odometry and compass only, the set grows). `rejected`: the view disagrees with the set (an
outlier) and was ignored. `lost`: the method has no set it can vouch for (after a kidnap or a
wheel slip beyond the bounds; Relocalize or Reset).

**Playback.** *Step* pauses and advances exactly one frame (the next stored one, or a new one
at the end). *Step back* and the *timeline* show stored frames as they were; nothing is
recomputed. *Go live* jumps to the newest frame.

**The left panel.** The camera view and each stage of the image pipeline (report Fig 4.2 and 4.3)
with, under them, the robust extractor's checks of the frame on screen (the readings tried, each
check's value, limit and result, and the check that refused the frame), or the plots: *Is the view
within its bound of the true pose?* draws, per coordinate, how far the view is from the truth (at
the tile and quarter turn that fit best) over the bound the view declared: at or below the grey
line at 1, the view agrees (report Fig 6.3 draws the same as six residuals; `--output-file` writes
those), *Size of the set* the widths of the blue set, *Distance from the set's centre to the truth*
its error. Orange: the Monte Carlo Localization baseline, calibrated to the views' measured errors
(particles and 95 % ellipse), when switched on.

**Without a GPU** the browser draws in software and the page runs slower: the floor's texture is
a layer to switch on (Layers), off at the start.
"""
"""The page's "How to read this page" text (markdown)."""

LAYER_TITLES = {
    "floor": "Floor texture (slow without a GPU)", "grid": "Tile grid", "robot": "Robot",
    "footprint": "Camera footprint",
    "truth": "True pose (pink)", "prediction": "Prediction (green)",
    "boxes": "Contracted boxes (blue)", "wedge": "Heading interval", "setpoint": "Setpoint (red)",
    "path": "Path", "trails": "Trails", "particles": "MCL particles (orange)",
}


def _set_layer(name: str, box: GuiCheckboxHandle) -> C.Command:
    """The command that shows or hides layer ``name`` as its checkbox says."""
    return C.SetLayer(name, bool(box.value))


class Controls:
    """Builds the control panel on ``server.gui`` and the target gizmo in ``server.scene``.

    ``submit``: puts a command on the loop's queue (never blocks). ``cfg``: the starting
    configuration (initial slider values). ``layers``: initial layer visibility. ``display``,
    ``playing``, ``speed`` (x real time), ``max_speed``, ``mcl`` (the MCL baseline runs):
    initial states. ``replay``: what is replayed (a dataset) instead of simulated, or None: the
    controls that steer the simulator (setpoint, kidnap, seed, floor and camera, faults, recording)
    are hidden then and the noise sliders, showing the dataset's declared bounds, are disabled.
    """

    def __init__(self, server: ViserServer, submit: Callable[[C.Command], None], cfg: Config, *,
                 layers: dict[str, bool], display: bool, playing: bool, speed: float = 1.0,
                 max_speed: bool = False, mcl: bool = False, replay: str | None = None,
                 region: tuple[float, float, float, float] = (-2.0, -2.0, 2.0, 2.0)) -> None:
        self.server = server
        self._submit = submit
        gui = server.gui
        self.status = gui.add_html("<b>starting</b>: computing the first frame (the first start "
                                   "after an install compiles the vision kernels: up to a "
                                   "minute, once)")
        with gui.add_folder("How to read this page", expand_by_default=False):
            gui.add_markdown(HELP)
        if replay is not None:
            gui.add_markdown(f"Replaying `{replay}`: setpoint, kidnap, noise, faults, floor and "
                             "recording belong to the simulator. Mode and extractor replay from "
                             "frame 0.")

        with gui.add_folder("Playback"):
            self.play = gui.add_button("Pause" if playing else "Play")
            self.step = gui.add_button("Step")
            self.step_back = gui.add_button("Step back")
            self.live = gui.add_button("Go live")
            self.timeline = gui.add_slider("Timeline", min=0, max=1, step=1, initial_value=0)
            self.speed = gui.add_slider("Speed (x real time)", min=0.1, max=10.0, step=0.1,
                                        initial_value=min(max(speed, 0.1), 10.0))
            self.max_speed = gui.add_checkbox("As fast as possible", max_speed)
            self.follow = gui.add_checkbox("Follow the robot", True,
                                           hint="while playing, the view moves with the robot")
        self._on_click(self.play, C.TogglePlay)
        self._on_click(self.step, C.Step)
        self._on_click(self.step_back, C.StepBack)
        self._on_click(self.live, C.Live)
        self._on_change(self.timeline, lambda: C.Seek(int(self.timeline.value)))
        self._on_change(self.speed, lambda: C.SetSpeed(float(self.speed.value)))
        self._on_change(self.max_speed, lambda: C.SetMaxSpeed(bool(self.max_speed.value)))
        self._on_change(self.follow, lambda: C.SetFollow(bool(self.follow.value)))

        with gui.add_folder("Robot"):
            self.setpoint = gui.add_dropdown("Setpoint", SETPOINTS, initial_value=cfg.sim.setpoint)
            self.pick = gui.add_button("Click the floor to set the target")
            self.target = gui.add_vector2("Manual target (m)", cfg.sim.manual_target, step=0.1)
            self.waypoints = gui.add_text(
                "Waypoints (x, y; ...)", "; ".join(f"{x:g}, {y:g}" for x, y in cfg.sim.waypoints))
            self.set_waypoints = gui.add_button("Drive the waypoints")
            self.kidnap = gui.add_button("Kidnap (teleport the robot)")
            self.relocalize = gui.add_button("Relocalize (tell the true pose)")
            self._region_default = format_region(region)
            """The region the page offered last; the text follows the default until edited."""
            self.region = gui.add_text("Region x0, y0, x1, y1 (m)", self._region_default,
                                       hint="where the robot is, as far as you know: "
                                            "re-localization assumes it stays in here")
            self.relocalize_region = gui.add_button("Re-localize in the region")
            self.seed = gui.add_number("Seed", cfg.sim.seed, min=SEED_RANGE[0], max=SEED_RANGE[1],
                                      step=1)
            self.reset = gui.add_button("Reset the run")
        self._on_change(self.setpoint, lambda: C.SetSetpoint(str(self.setpoint.value)))
        self._on_change(self.target, lambda: C.SetManualTarget(*self.target.value))
        self._on_click(self.set_waypoints,
                       lambda: C.SetWaypoints(C.parse_waypoints(self.waypoints.value)))
        self._on_click(self.kidnap, C.Kidnap)
        self._on_click(self.relocalize, C.Relocalize)
        self._on_click(self.relocalize_region,
                       lambda: C.RelocalizeRegion(C.parse_region(self.region.value)))
        self._on_click(self.reset, lambda: C.Reset(seed=_integer("seed", self.seed.value)))
        self._on_pick()

        with gui.add_folder("Localizer and vision"):
            self.mode = gui.add_dropdown("Mode", MODES, initial_value=cfg.localizer.mode)
            self.extractor = gui.add_dropdown("Extractor", EXTRACTORS,
                                              initial_value=cfg.vision.extractor)
            n = cfg.noise
            self.speed_error = gui.add_slider("Speed bound (m/s)", min=0.0, max=0.2, step=0.001,
                                              initial_value=n.speed_error)
            self.yaw_error = gui.add_slider("Yaw rate bound (rad/s)", min=0.0, max=0.2,
                                            step=0.001, initial_value=n.yaw_rate_error)
            self.compass_error = gui.add_slider("Compass bound (rad)", min=0.0, max=0.5,
                                                step=0.001, initial_value=n.compass_error)
            self.fraction = gui.add_slider("Noise / bound", min=0.0, max=3.0, step=0.05,
                                           initial_value=n.fraction)
            ix, _, it = cfg.localizer.truth_inflation
            self.inflation_xy = gui.add_slider("Truth inflation x, y (m)", min=0.0, max=2.0,
                                               step=0.01, initial_value=ix)
            self.inflation_t = gui.add_slider("Truth inflation heading (rad)", min=0.0,
                                              max=1.5, step=0.01, initial_value=it)
            loc = cfg.localizer
            self.fault_on = gui.add_checkbox("Fault model (track through slips)",
                                             loc.fault_speed > 0 or loc.fault_yaw_rate > 0)
            self.fault_speed = gui.add_slider("Fault speed (m/s)", min=0.0, max=1.0, step=0.01,
                                              initial_value=loc.fault_speed or 0.2)
            self.fault_yaw = gui.add_slider("Fault yaw rate (rad/s)", min=0.0, max=1.0,
                                            step=0.01, initial_value=loc.fault_yaw_rate or 0.1)
            self.mcl = gui.add_checkbox("Monte Carlo Localization (orange)", mcl)
        self._on_change(self.mode, lambda: C.SetMode(self.mode.value))
        self._on_change(self.extractor, lambda: C.SetExtractor(self.extractor.value))
        self._on_change(self.mcl, lambda: C.SetMcl(bool(self.mcl.value)))
        for h in (self.speed_error, self.yaw_error, self.compass_error, self.fraction):
            self._on_change(h, lambda: C.SetNoise(self.speed_error.value, self.yaw_error.value,
                                                  self.compass_error.value, self.fraction.value))
        fault_inputs: tuple[GuiInputHandle[Any], ...] = (self.fault_on, self.fault_speed,
                                                         self.fault_yaw)
        for fh in fault_inputs:
            self._on_change(fh, lambda: C.SetFaultModel(self.fault_speed.value,
                                                       self.fault_yaw.value,
                                                       bool(self.fault_on.value)))
        for h in (self.inflation_xy, self.inflation_t):
            self._on_change(h, lambda: C.SetInflation(self.inflation_xy.value,
                                                      self.inflation_t.value))

        folders: dict[str, GuiFolderHandle] = {}
        with gui.add_folder("Floor and camera", expand_by_default=False) as folders["floor"]:
            self.tile_size = gui.add_number("Tile size L (m)", cfg.floor.tile_size,
                                            min=TILE_SIZE_RANGE[0], max=TILE_SIZE_RANGE[1],
                                            step=0.001)
            self.ppm = gui.add_number("Pixels per metre", cfg.camera.ppm, min=PPM_RANGE[0],
                                      max=PPM_RANGE[1], step=0.01)
            self.floor_style = gui.add_dropdown("Floor style", tuple(FLOOR_STYLES),
                                                initial_value="default")
            self.restart = gui.add_button("Restart with this floor and camera")
        self._on_click(self.restart, lambda: C.Restart(self.tile_size.value, self.ppm.value,
                                                       self.floor_style.value))

        with gui.add_folder("Layers", expand_by_default=False):
            self.display = gui.add_checkbox("Stream stage images", display)
            self.layers = {name: gui.add_checkbox(LAYER_TITLES[name], layers[name])
                           for name in C.LAYERS}
        self._on_change(self.display, lambda: C.SetDisplay(bool(self.display.value)))
        for name, box in self.layers.items():
            self._on_change(box, partial(_set_layer, name, box))

        with gui.add_folder("Faults", expand_by_default=False) as folders["faults"]:
            self.fault = gui.add_dropdown("Fault", FAULTS, initial_value="slip")
            self.fault_frames = gui.add_number("Frames (0: default)", 0, min=0, max=100000,
                                               step=1)
            self.inject = gui.add_button("Inject")
        self._on_click(self.inject, lambda: C.Inject(
            str(self.fault.value), _integer("frames", self.fault_frames.value) or None))

        with gui.add_folder("Record") as folders["record"]:
            self.record_name = gui.add_text("Dataset name", "live-run")
            self.record = gui.add_button("Start recording")
            missing = mcap_missing()
            self.export = gui.add_button(
                "Export MCAP" if missing is None else "Export MCAP (not installed)",
                disabled=missing is not None,
                hint=missing or "Write the last recording as NAME.mcap beside its folder, "
                "for Foxglove (as `python -m tileviz replay NAME --mcap` does)")
            if missing is not None:
                gui.add_markdown(f"*{missing}*")
            self.export_page = gui.add_button(
                "Export page", hint="Write the last recording as NAME.html beside its folder: "
                "one web page that plays the run offline (as `python -m tileviz export-html "
                "NAME NAME.html` does)")
        self._recording = False
        self._on_click(self.record, lambda: (C.StopRecording() if self._recording
                                             else C.StartRecording(self.record_name.value)))
        self._on_click(self.export, C.ExportMcap)
        self._on_click(self.export_page, C.ExportPage)

        tx, ty = cfg.sim.manual_target
        self.gizmo = server.scene.add_transform_controls(
            "/target_gizmo", scale=0.6, disable_rotations=True, active_axes=(True, True, False),
            depth_test=False, position=(tx, ty, 0.05), visible=cfg.sim.setpoint == "manual")
        self.simulator = replay is None
        if not self.simulator:
            hidden: tuple[Any, ...] = (self.setpoint, self.pick, self.target, self.waypoints,
                                       self.set_waypoints, self.kidnap, self.seed,
                                       *folders.values())  # every kind of handle
            for node in hidden:
                node.visible = False
            for slider in (self.speed_error, self.yaw_error, self.compass_error, self.fraction):
                slider.disabled = True
            self.reset.label = "Replay from frame 0"
            self.gizmo.visible = False

        @self.gizmo.on_update
        async def _on_gizmo(event: TransformControlsEvent) -> None:
            if event.client is None or event.phase != "end":
                return
            x, y = float(event.target.position[0]), float(event.target.position[1])
            self._make(lambda: C.SetManualTarget(x, y))

    # ------------------------------------------------------------------ wiring
    def _make(self, factory: Callable[[], C.Command]) -> None:
        try:
            cmd = factory()
        except (ValueError, TypeError) as e:
            cmd = C.Report(f"refused: {e}")
        self._submit(cmd)

    def _on_click(self, handle: GuiButtonHandle, factory: Callable[[], C.Command]) -> None:
        @handle.on_click
        async def _(event: GuiEvent[GuiButtonHandle]) -> None:
            if event.client is not None:
                self._make(factory)

    def _on_change(self, handle: GuiInputHandle[Any], factory: Callable[[], C.Command]) -> None:
        @handle.on_update
        async def _(event: GuiEvent[GuiInputHandle[Any]]) -> None:
            if event.client is not None:
                self._make(factory)

    def _on_pick(self) -> None:
        scene = self.server.scene

        @self.pick.on_click
        async def _on_pick(event: GuiEvent[GuiButtonHandle]) -> None:
            if event.client is None:
                return
            self.pick.disabled = True

            # viser runs async callbacks too; its signature says sync
            @scene.on_click()  # type: ignore[arg-type]
            async def picked(click: SceneClickEvent) -> None:
                scene.remove_click_callback(picked)
                self.pick.disabled = False
                point = floor_point(click.ray_origin, click.ray_direction)
                if point is None:
                    self._submit(C.Report("that click did not hit the floor"))
                else:
                    self._make(lambda: C.SetManualTarget(*point))

    # ------------------------------------------------------------------ refresh (loop thread)
    def refresh(self, *, first: int, last: int, shown: int, playing: bool, setpoint: str,
                target: tuple[float, float], recording: bool, status: str,
                region: tuple[float, float, float, float] | None = None) -> None:
        """Bring the controls the loop changes up to date (values set here are not echoed back
        as commands)."""
        # (*) a handle's value is settable; mypy sees viser's props field as read-only
        label = "Pause" if playing else "Play"
        if self.play.label != label:
            self.play.label = label
        hi = max(last, first + 1)
        if self.timeline.min != first:
            self.timeline.min = first
        if self.timeline.max != hi:
            self.timeline.max = hi
        if shown >= 0 and self.timeline.value != shown:
            self.timeline.value = shown  # type: ignore[misc]  # (*)
        if not self.simulator:
            setpoint = "replay"  # no simulator to steer: nothing below applies
        elif self.setpoint.value != setpoint:
            self.setpoint.value = setpoint  # type: ignore[misc]  # (*)
        self.gizmo.visible = setpoint == "manual"
        if setpoint == "manual" and tuple(self.target.value) != tuple(target):
            self.target.value = target  # type: ignore[misc]  # (*)
            self.gizmo.position = (target[0], target[1], 0.05)
        if region is not None:
            offered = format_region(region)
            if offered != self._region_default:
                if self.region.value == self._region_default:  # not edited: follow the floor
                    self.region.value = offered  # type: ignore[misc]  # (*)
                self._region_default = offered
        self._recording = recording
        label = "Stop recording" if recording else "Start recording"
        if self.record.label != label:
            self.record.label = label
        if self.status.content != status:
            self.status.content = status


def format_region(region: tuple[float, float, float, float]) -> str:
    """A region (x0, y0, x1, y1, metres) as the text the region field takes."""
    return ", ".join(f"{v:g}" for v in region)


def floor_point(origin: tuple[float, float, float],
                direction: tuple[float, float, float]) -> tuple[float, float] | None:
    """Where a ray (world frame, m) meets the floor plane z = 0, or None if it does not."""
    oz, dz = float(origin[2]), float(direction[2])
    if not (math.isfinite(oz) and math.isfinite(dz)) or dz >= 0.0 or oz <= 0.0:
        return None
    s = -oz / dz
    x, y = float(origin[0]) + s * float(direction[0]), float(origin[1]) + s * float(direction[1])
    if not (math.isfinite(x) and math.isfinite(y)):
        return None
    return (x, y)


def _integer(name: str, value: object) -> int:
    v = float(value)  # type: ignore[arg-type]
    if not math.isfinite(v) or v != int(v):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    return int(v)
