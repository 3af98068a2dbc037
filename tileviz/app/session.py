"""The live run behind the server: source -> runner -> history, driven by commands.

:class:`Session` holds everything that changes while the demo runs (the source of frames, the
runner, the history, the playback state, the files being written) and nothing of viser: the app's
loop thread is its only caller (``apply`` a command, ``advance`` one frame), so no lock is needed
on the simulation. Tests drive it directly.

The source (:mod:`tileviz.app.sources`) is the simulator, a recorded dataset replayed with the
same reader and frame loop as ``python -m tileviz replay`` (``SessionOptions.dataset``), or a
ROS run followed live (``SessionOptions.ros``: its messages combined as ``python -m tileviz
ros`` combines them). A replay pauses at its last frame (or at a bad row, with a note naming
it); commands only a simulator understands (:data:`tileviz.app.commands.SIMULATOR_ONLY`) leave
a note and change nothing, as do those a live ROS run cannot honour
(:data:`tileviz.app.commands.NOT_LIVE`); a new localizer mode, extractor or inflation replays
a dataset from frame 0, and applies from the next frame on otherwise. ``SessionOptions.foxglove``
also serves every new frame to Foxglove (:class:`tileviz.ros.foxglove_live.FoxgloveLive`).

Positions: the history numbers its entries 0, 1, 2, ... (a *position*); an entry's record keeps
the source's frame index. They differ only after a frame failed (a gap in frame indices).
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, assert_never, cast

import numpy as np

from tileviz.app import commands as C
from tileviz.app.history import Encoder, Entry, History, ParticleView
from tileviz.app.outputs import output_path, sanitize_name
from tileviz.app.recorder import ExportJob, Recorder
from tileviz.cliutil import one_line
from tileviz.config import Config, LocalizerConfig, NoiseConfig, with_floor_style
from tileviz.pipeline import FrameLoop, FrameRecord, initial_box
from tileviz.pipeline.replay import relocalize_after
from tileviz.sim.camera import FAULT_KINDS
from tileviz.summary import RunTally, outside_region

if TYPE_CHECKING:
    from tileviz.app.sources import LiveSimulator

__all__ = ["MCL", "REGION_MARGIN", "Session", "SessionOptions"]

MCL = "mcl"
"""The MCL baseline's name in the frame loop and its records."""


REGION_MARGIN = 0.5
"""Metres added around the path the robot follows for the page's default re-localization
region (:meth:`Session.default_region`): the controller's overshoot stays well inside it."""


@dataclass(frozen=True)
class SessionOptions:
    """How the live run starts (the ``serve`` options of report table 6.1 and a few more).

    ``history``: frames kept for stepping back (>= 2). ``display``: keep and stream the pipeline
    stage images. ``intervals``: show the interval boxes. ``interactive``: start paused.
    ``out_dir``: the only folder files are written to. ``output_file``: name of the CSV of the six
    equivalence residuals per frame (None: no CSV). ``speed``: multiple of real time;
    ``max_speed``: as fast as possible.
    """

    history: int = 2000
    display: bool = True
    intervals: bool = True
    interactive: bool = False
    out_dir: Path = Path("runs")
    output_file: str | None = None
    speed: float = 1.0
    max_speed: bool = False
    mcl: bool = False
    """Run the Monte Carlo Localization baseline beside the interval localizer."""
    mcl_particles: int = 1000
    """Its largest particle count (KLD-sampling keeps between 100 and this many)."""
    renderer: Any = None
    """A renderer for the simulator (tests); None = the real floor renderer."""
    start_frame: int = 0
    """The frame shown first (frame index): the frames before it are computed on start, without
    stage images."""
    relocalize_region: tuple[float, float, float, float] | None = None
    """(x0, y0, x1, y1), metres: whenever the localizer is ``lost`` it restarts from "somewhere in
    this region" at the next frame (``Localizer.relocalize``)."""
    dataset: Path | None = None
    """Replay this tileviz-dataset/1 folder instead of simulating (the Config passed to the
    session should be :func:`tileviz.datasets.replay_config` of its meta)."""
    ros: Any = None
    """Follow this ROS run (a :class:`tileviz.ros.viewer.RosFeed`) instead of simulating (the
    Config should be its combiner's ``cfg``)."""
    foxglove: int | None = None
    """Also serve each new frame live to Foxglove on 127.0.0.1 at this port (0: any free one),
    the topics of ``replay --mcap``."""
    lens: str | None = None
    """The simulator's camera is this real camera (:data:`tileviz.sim.lens.LENSES`): raw images
    through a tilted, distorting lens, rectified to the configured camera's view before vision;
    the view bound grows as ``docs/dataset-format.md`` says for a ``camera_model``."""


MAX_NOTE = 400
"""Longest note, characters."""


@dataclass
class Note:
    """A one-line message for the GUI (``level``: info or error), with the wall time."""

    text: str
    level: str = "info"
    when: float = field(default_factory=time.time)


class Session:
    """The simulation + localizer run and its playback state (see the module docstring)."""

    def __init__(self, cfg: Config, options: SessionOptions | None = None) -> None:
        self.options = options or SessionOptions()
        o = self.options
        self.history = History(o.history)
        self.encoder = Encoder()
        self.playing = not o.interactive
        self.speed = float(o.speed)
        self.max_speed = bool(o.max_speed)
        self.display = bool(o.display)
        self.layers: dict[str, bool] = {name: True for name in C.LAYERS}
        for name in ("prediction", "boxes", "wedge"):
            self.layers[name] = bool(o.intervals)
        self.notes: deque[Note] = deque(maxlen=8)
        self.follow = True
        """The view follows the robot while playing."""
        self.panel = "camera"
        """What the left panel shows under the inset (``commands.PANEL_VIEWS``)."""
        self.errors = 0
        """Frames that raised (logged, skipped)."""
        self.degraded = False
        """True after a frame failed: the localizer missed a motion, its set may miss the truth
        until Relocalize or Reset."""
        self.version = 0
        """Bumped on every change worth showing."""
        self.world_version = 0
        """Bumped when the static scene (floor, path, waypoints) changes."""
        self.shown = -1
        """History position of the frame shown (-1: none yet)."""
        self.recorder = Recorder(self.note)
        """The dataset being recorded, the last one recorded and its export (MCAP or page)."""
        self.csv: Any = None
        self.csv_path: Path | None = None
        self._kidnap_rng = np.random.default_rng(np.random.SeedSequence([cfg.sim.seed, 0xC1D]))
        self.frames_computed = 0
        self.rate = 0.0
        """Computed frames per second (moving average)."""
        self._rate_t = time.perf_counter()
        self._rate_n = 0
        self.cfg = cfg
        self._unstyled = cfg
        """The configuration before any floor style (``Restart.style`` "default" goes back)."""
        self.setpoint_kind = cfg.sim.setpoint
        self._mcl_wanted = bool(o.mcl)
        self._region_broken = False
        """The robot was seen outside the current re-localization region (said once)."""
        self.ended: str | None = None
        """Why the source has no more frames (a replay's end or bad row), or None."""
        self._waiting = ""
        """Why a live source has had no frame for a while (said once), or ""."""
        self.foxglove: Any = None
        """The live Foxglove server (:class:`tileviz.ros.foxglove_live.FoxgloveLive`) or None."""
        if o.foxglove is not None:
            from tileviz.ros.foxglove_live import FoxgloveLive

            self.foxglove = FoxgloveLive(o.foxglove)  # CliError: no SDK, a busy port
        self._build(cfg)
        # the floor as its tile grid; the textured floor is a layer to switch on: without a GPU
        # (software WebGL) every pixel it fills costs the browser (docs/demo.md, "Without a GPU")
        self.layers["floor"] = False
        if not self.source.simulator:
            self.layers["setpoint"] = False  # a dataset has none
        if o.output_file is not None:
            self._open_csv()

    # ------------------------------------------------------------------ run set-up
    def _build(self, cfg: Config) -> None:
        from tileviz.app.sources import make_source  # pymunk: only when a run starts

        self.source = make_source(cfg, dataset=self.options.dataset,
                                  renderer=self.options.renderer, lens=self.options.lens,
                                  ros=self.options.ros)
        floor_half = getattr(self.source, "floor_half_size", None)
        if floor_half is not None:  # a dataset: a floor under its whole true path
            half = floor_half(cfg.sim.room_half_size)
            cfg = replace(cfg, sim=replace(cfg.sim, room_half_size=half))
            self.setpoint_kind = "dataset"
        self.cfg = cfg
        self.ended = None
        self.runner = FrameLoop(self._lens_bound(cfg), keep_stages=self.display)
        """The frame loop: the interval localizer and, when on, the MCL baseline (:data:`MCL`)."""
        if self._mcl_wanted:
            self._start_mcl(initial_box(cfg))
        self.history.clear()
        self.tally = RunTally()
        self.shown = -1
        self.degraded = False
        self.world_version += 1
        self.version += 1

    def _open_csv(self) -> None:
        from tileviz.pipeline.outputs import RESIDUAL_COLUMNS, CsvOut

        name = self.options.output_file or "residuals"
        self.csv_path = output_path(self.options.out_dir, name, suffix=".csv",
                                    default="residuals")
        self.csv = CsvOut(self.csv_path, RESIDUAL_COLUMNS)
        self.note(f"writing the equivalence residuals to {self.csv_path}")

    def _new_run_files(self) -> None:
        """A new run (reset/restart): close the recording; start a fresh residual CSV."""
        self.recorder.cancel("the run restarted")
        if self.csv is not None:
            self.csv.close()
            self.csv = None
            self._open_csv()

    def close(self) -> None:
        """Close every file being written and stop the encoder thread (idempotent); waits for an
        export in progress."""
        self.encoder.close()
        self.recorder.close()
        if self.csv is not None:
            self.csv.close()
            self.csv = None
        if self.foxglove is not None:
            self.foxglove.close()
            self.foxglove = None

    def _lens_bound(self, cfg: Config) -> Config:
        """``cfg`` for the localizer: with a simulated lens, the view bound grows by what the
        rectification may move (as a dataset's ``camera_model`` makes ``replay`` do; a dataset's
        configuration has that already)."""
        rect = self.source.rectifier
        if rect is None or not self.source.simulator:
            return cfg
        from tileviz.datasets.camera_model import view_margin

        px, rad = view_margin(rect.model, rect)
        return replace(cfg, vision=replace(cfg.vision,
                                           position_error_px=cfg.vision.position_error_px + px,
                                           heading_error=cfg.vision.heading_error + rad))

    # ------------------------------------------------------------------ notes
    def note(self, text: str, level: str = "info") -> None:
        """A message for the GUI; errors also go to stderr as one line. The text is made one
        line and cut to :data:`MAX_NOTE` characters (it may quote what a visitor typed)."""
        text = one_line(text)
        if len(text) > MAX_NOTE:
            text = text[: MAX_NOTE - 3] + "..."
        self.notes.append(Note(text, level))
        if level == "error":
            sys.stderr.write(f"tileviz serve: {text}\n")
            sys.stderr.flush()
        self.version += 1

    # ------------------------------------------------------------------ frames
    @property
    def frame_period(self) -> float:
        """Seconds between frames while playing (0: as fast as possible, or as they come from a
        source on its own clock)."""
        if self.max_speed or self.source.realtime:
            return 0.0
        return self.cfg.sim.dt / self.speed

    def robot_start(self) -> tuple[float, float]:
        """Where the robot starts (x, y), metres: the run's initial pose."""
        x, y = self.cfg.sim.initial_pose[:2]
        return float(x), float(y)

    def default_region(self) -> tuple[float, float, float, float]:
        """The re-localization region the page offers (x0, y0, x1, y1, metres): where the robot
        drives, plus :data:`REGION_MARGIN`: the Lissajous curve's square, the waypoints'
        bounding box, else (a manual target anywhere, a dataset) the floor drawn."""
        sim = self.cfg.sim
        m = REGION_MARGIN
        if self.setpoint_kind == "lissajous":
            h = sim.lissajous_amplitude + m
            return (-h, -h, h, h)
        if self.setpoint_kind == "waypoints" and sim.waypoints:
            xs = [p[0] for p in sim.waypoints]
            ys = [p[1] for p in sim.waypoints]
            return (min(xs) - m, min(ys) - m, max(xs) + m, max(ys) + m)
        h = sim.room_half_size
        return (-h, -h, h, h)

    def shown_entry(self) -> Entry | None:
        """The entry being shown, or None before the first frame."""
        if self.shown < 0 or self.shown not in self.history:
            return None
        return self.history.get(self.shown)

    def display_position(self) -> int:
        """The position to draw now: the shown one, except while playing live when its images
        are still being encoded: then the newest frame before it that is ready (one frame of
        lag instead of a wait)."""
        pos = self.shown
        if self.playing and pos >= 0:
            for p in range(pos, max(self.history.first, pos - 16) - 1, -1):
                if self.history.get(p).ready:
                    return p
        return pos

    def skip_to(self, index: int, stopped: Callable[[], bool] | None = None) -> None:
        """Compute frames until the shown one has frame index ``index`` or more (the frames on the
        way keep no stage images), or the source ends (then the note says so), or ``stopped()``
        says so between two frames."""
        keep = self.runner.keep_stages
        display, self.display = self.display, False
        self.runner.keep_stages = False
        try:
            while index > 0:
                if stopped is not None and stopped():
                    return
                entry = self.shown_entry()
                if entry is not None and entry.index >= index - 1:
                    break
                if self.compute() is None and (self.ended is not None or self.errors > 100):
                    return
        finally:
            self.display = display
            self.runner.keep_stages = keep
        entry = self.shown_entry()
        if entry is None or entry.index < index:
            self.compute()

    def advance(self) -> bool:
        """Show the next frame: the next stored one, or a new one when the newest is shown.
        Returns False when a new frame failed (logged; the run goes on)."""
        if self.shown < self.history.last:
            self.shown += 1
            self.version += 1
            return True
        return self.compute() is not None

    def compute(self) -> Entry | None:
        """Make one new frame (source -> runner -> history) and show it. A frame that raises is
        logged as one line and skipped; None then. At the source's end (a replay's last frame or
        bad row) the run pauses with a note; None then."""
        from tileviz.app.sources import SourceEnded, SourceWaiting

        before = self.source.index
        try:
            frame = next(self.source)
        except SourceWaiting as e:
            if str(e) and str(e) != self._waiting:
                self.note(str(e))
            self._waiting = str(e)
            return None
        except SourceEnded as e:
            self.playing = False
            if self.ended != str(e):
                self.ended = str(e)
                self.note(f"{e} (step back or scrub the timeline; Reset replays from frame 0)",
                          e.level)
            return None
        except Exception as e:  # noqa: BLE001 - the loop must survive any frame
            self._frame_failed(before, f"simulator: {e}", missed=self.source.index != before)
            return None
        # a lens camera's raw image, as a robot logs it
        self.recorder.write(frame, self.cfg, self.source.rectifier)
        lens_stages: dict[str, np.ndarray] | None = None
        try:
            shown = None
            rect = self.source.rectifier
            if rect is not None:
                # vision reads the gray view, as replay does; the colour view only when shown
                raw = frame.image
                frame = replace(frame, image=rect.gray(raw))
                if self.display:
                    shown = rect(raw)
                    if self.runner.keep_stages:
                        lens_stages = {"raw": raw, "rectified": shown}
            for n in self.source.prime(self.runner):
                self.note(n.text, n.level)
                self.degraded = self.degraded or n.degrades
            rec = self.runner.process(frame)
            if shown is not None:  # the camera panel shows the colour view
                rec = replace(rec, image=shown)
        except Exception as e:  # noqa: BLE001
            self._frame_failed(frame.index, str(e), missed=True)
            return None
        if self.csv is not None:
            from tileviz.pipeline.outputs import residual_row

            self.csv.row(residual_row(rec))
        if self.foxglove is not None:
            self._serve_foxglove(rec)
        particles = self._mcl_view(rec)
        entry = Entry.make(rec, stages=self.display, encoder=self.encoder, mcl=particles,
                           before=lens_stages)
        self.shown = self.history.append(entry)
        self.tally.add(rec)
        if outside_region(rec) and not self._region_broken:
            self._region_broken = True
            assert rec.step is not None and rec.step.region is not None
            x0, y0, x1, y1 = rec.step.region
            self.note(f"the robot left the re-localization region ({x0:g}, {y0:g})-({x1:g}, "
                      f"{y1:g}) m at frame {rec.index}: the hypothesis is broken and the set "
                      "may miss the truth (re-localize in a larger region, or Reset)", "error")
        region = self.options.relocalize_region
        if region is not None and rec.status == "lost":
            if relocalize_after(self.runner, region, rec):  # from the next frame on
                self._region_broken = False
        self.frames_computed += 1
        self._count_rate()
        self.version += 1
        return entry

    def _serve_foxglove(self, rec: FrameRecord) -> None:
        """``rec`` to the Foxglove server, stamped with the run's time (``rec.t``, as ``replay
        --mcap`` stamps it); status ``lost`` while the run is degraded. A failure stops the
        server, not the run (a note)."""
        try:
            self.foxglove.publish(rec, round(rec.t * 1e9),
                                  status="lost" if self.degraded else None)
        except Exception as e:  # noqa: BLE001 - the page goes on without Foxglove
            self.note(f"Foxglove stopped at frame {rec.index}: {e}", "error")
            self.foxglove.close()
            self.foxglove = None

    # ------------------------------------------------------------------ MCL baseline
    @property
    def mcl(self) -> Any:
        """The MCL baseline (:class:`tileviz.baselines.MclEstimator`) when on, else None."""
        return self.runner.estimators.get(MCL)

    def _start_mcl(self, box: Any) -> None:
        """(Re)start the MCL baseline in ``box``, stepped by the frame loop from the next frame
        on; if it raises it leaves the loop, not stopping the demo (:meth:`_mcl_view`). The
        calibrated filter (:func:`tileviz.baselines.mcl.calibrated_config`: the measured view
        error model, roughening, KLD-sampling up to ``mcl_particles`` particles, AMCL recovery),
        as ``tileviz evaluate`` runs it under the name ``mcl``."""
        from tileviz.baselines import MclEstimator
        from tileviz.baselines.mcl import calibrated_config

        config = calibrated_config(particles=self.options.mcl_particles, seed=self.cfg.sim.seed)
        self.runner.add(MCL, MclEstimator.from_config(self.cfg, initial=box, config=config,
                                                      bounds=self.runner.bounds), optional=True)

    def _mcl_view(self, rec: FrameRecord) -> ParticleView | None:
        """The particles MCL left at this frame, or None (off, or it failed here: a note)."""
        if MCL in rec.dropped:
            self._mcl_wanted = False
            self.note(f"MCL stopped at frame {rec.index}: {rec.dropped[MCL]}", "error")
            return None
        est = rec.estimates.get(MCL)
        return ParticleView.of(est, rec.truth) if est is not None else None

    def _set_mcl(self, cmd: C.SetMcl) -> None:
        self._mcl_wanted = bool(cmd.on)
        if not cmd.on:
            self.runner.remove(MCL)
        elif self.mcl is None:
            primary = self.runner.primary
            hull = primary.current.hull() if primary is not None else None
            self._start_mcl(hull if hull is not None else initial_box(self.cfg))

    def _frame_failed(self, index: int, message: str, *, missed: bool) -> None:
        """Log a frame that raised. ``missed``: the simulator moved on without the localizer
        seeing that motion, so its set no longer vouches for the truth (``degraded``)."""
        self.errors += 1
        if missed:
            self.degraded = True
            tail = " (skipped; the localizer missed this motion: Relocalize or Reset)"
        else:
            tail = " (nothing moved; the frame is tried again)"
        self.note(f"frame {index}: {message}{tail}", "error")

    def _count_rate(self) -> None:
        self._rate_n += 1
        now = time.perf_counter()
        span = now - self._rate_t
        if span >= 0.5:
            self.rate = self._rate_n / span
            self._rate_t = now
            self._rate_n = 0

    # ------------------------------------------------------------------ recording
    @property
    def recording_active(self) -> bool:
        """True while recording or waiting for the next new frame to start a recording."""
        return self.recorder.active

    @property
    def last_recording(self) -> Path | None:
        """The last finished recording with at least one frame (what Export MCAP and Export
        page export)."""
        return self.recorder.last

    @property
    def export(self) -> ExportJob | None:
        """The export (MCAP or page) running in the background, if any."""
        return self.recorder.export

    def poll(self) -> None:
        """Note what background work finished since the last call (the loop calls this)."""
        self.recorder.poll()

    # ------------------------------------------------------------------ commands
    def apply(self, cmd: C.Command) -> None:
        """Apply one command (:mod:`tileviz.app.commands`). Bad values raise ValueError naming
        them; nothing is changed then."""
        what = C.SIMULATOR_ONLY.get(type(cmd))
        verb = "following" if self.source.realtime else "replaying"
        if what is not None and not self.source.simulator:
            self.note(f"{C.label(cmd)}: {what} belongs to the simulator; "
                      f"{verb} {self.source.describe()} (nothing changed)")
            return
        what = C.NOT_LIVE.get(type(cmd))
        if what is not None and self.source.realtime:
            self.note(f"{C.label(cmd)}: {what} cannot be done on a live run; {verb} "
                      f"{self.source.describe()} (nothing changed)")
            return
        match cmd:
            case C.Play():
                self.playing = True
            case C.Pause():
                self.playing = False
            case C.TogglePlay():
                self.playing = not self.playing
            case C.Step():
                self.playing = False
                self.advance()
            case C.StepBack():
                self.playing = False
                if self.shown > self.history.first:
                    self.shown -= 1
            case C.Seek(index=index):
                self.playing = False
                if len(self.history):
                    self.shown = min(max(index, self.history.first), self.history.last)
            case C.Live():
                self.shown = self.history.last
            case C.SetSpeed(factor=factor):
                self.speed = float(factor)
            case C.SetMaxSpeed(on=on):
                self.max_speed = bool(on)
            case C.SetSetpoint():
                self._set_setpoint(cmd)
            case C.SetManualTarget():
                self._set_manual_target(cmd)
            case C.SetWaypoints():
                self._set_waypoints(cmd)
            case C.Kidnap():
                self._kidnap(cmd)
            case C.Relocalize():
                self._relocalize()
            case C.RelocalizeRegion(region=region):
                self._relocalize_region(region)
            case C.Reset():
                self._reset(cmd)
            case C.Restart():
                self._restart(cmd)
            case C.SetMode():
                self._set_mode(cmd)
            case C.SetExtractor():
                self._set_extractor(cmd)
            case C.SetNoise():
                self._set_noise(cmd)
            case C.SetInflation():
                self._set_inflation(cmd)
            case C.SetFaultModel():
                self._set_fault_model(cmd)
            case C.SetDisplay(on=on):
                self.display = bool(on)
                self.runner.keep_stages = self.display
            case C.SetMcl():
                self._set_mcl(cmd)
            case C.SetLayer(layer=layer, visible=visible):
                self.layers[layer] = bool(visible)
            case C.Inject(kind=kind, frames=frames):
                if self.source.rectifier is not None and kind in FAULT_KINDS:
                    raise ValueError(f"the {kind} fault is not drawn through a lens (--lens): "
                                     "odometry faults only")
                self._simulator.inject(kind, frames=frames)
                self.note(f"fault {kind} injected")
            case C.StartRecording():
                self.recorder.ask(output_path(self.options.out_dir, sanitize_name(cmd.name)),
                                  self.playing)
            case C.StopRecording():
                self.recorder.stop_asked()
            case C.ExportMcap():
                self.recorder.export_mcap()
            case C.ExportPage():
                self.recorder.export_page()
            case C.Report(text=text, level=level):
                self.note(text, level)
            case C.SetFollow(on=on):
                self.follow = bool(on)
            case C.ShowPanel(view=view):
                self.panel = view
            case _:
                assert_never(cmd)
        self.version += 1

    @property
    def _simulator(self) -> LiveSimulator:
        """The source as the simulator: only for the commands :meth:`apply` let through
        (``commands.SIMULATOR_ONLY`` are refused on a replay)."""
        return cast("LiveSimulator", self.source)

    def _set_setpoint(self, cmd: C.SetSetpoint) -> None:
        self._simulator.set_setpoint(cmd.kind)
        self._setpoint_changed(cmd.kind)

    def _set_manual_target(self, cmd: C.SetManualTarget) -> None:
        self._simulator.set_manual_target(cmd.x, cmd.y)
        self._setpoint_changed("manual", sim={"manual_target": (cmd.x, cmd.y)})

    def _set_waypoints(self, cmd: C.SetWaypoints) -> None:
        self._simulator.set_waypoints(cmd.points)
        self._setpoint_changed("waypoints", sim={"waypoints": tuple(cmd.points)})

    def _setpoint_changed(self, kind: str, sim: dict[str, Any] | None = None) -> None:
        self.setpoint_kind = kind
        self.cfg = replace(self.cfg, sim=replace(self.cfg.sim, setpoint=kind, **(sim or {})))
        self.world_version += 1

    def _kidnap(self, cmd: C.Kidnap) -> None:
        if cmd.pose is None:
            a = 0.8 * self.cfg.sim.lissajous_amplitude
            x, y = self._kidnap_rng.uniform(-a, a, 2)
            theta = self._kidnap_rng.uniform(-math.pi, math.pi)
        else:
            x, y, theta = cmd.pose
        self._simulator.kidnap(float(x), float(y), float(theta))
        self.note(f"kidnapped the robot to ({x:.2f}, {y:.2f}, {math.degrees(theta):.0f} deg); "
                  "the localizer was not told")

    def _relocalize(self) -> None:
        pose = self.source.pose
        if pose is None:
            self.note("Relocalize: the true pose of the next frame is not known (a dataset "
                      "without x, y, theta, or its end); nothing changed")
            return
        box = initial_box(self.cfg, pose=pose.as_tuple())
        self.runner.reset(box)
        if self.mcl is not None:
            self._start_mcl(box)  # a fresh filter (its seed's particles), as at the start
        self.degraded = False
        self.note("localizer restarted at the true pose (within the initial pose error)")

    def _relocalize_region(self, region: tuple[float, float, float, float]) -> None:
        primary = self.runner.primary
        if primary is None:
            self.note("Re-localize: no interval localizer runs; nothing changed")
            return
        last = self.history.get(self.history.last) if len(self.history) else None
        compass = last.record.compass if last is not None else None
        # the pose of the last frame computed; ValueError (too large): nothing changed
        n = primary.localizer.relocalize(region, compass=compass)
        self.degraded = False
        self._region_broken = False
        x0, y0, x1, y1 = region
        self.note(f"localizer restarted somewhere in ({x0:g}, {y0:g})-({x1:g}, {y1:g}) m "
                  f"(up to {n} candidates; keep the robot in the region)")

    def _reset(self, cmd: C.Reset) -> None:
        cfg = self.cfg
        if cmd.seed is not None:
            cfg = replace(cfg, sim=replace(cfg.sim, seed=int(cmd.seed)))
        self._new_run(cfg)
        if self.source.restart_on_settings:
            self._replay_from_start("Reset")
        else:
            self.compute()
            self.note(f"Reset: a new run from frame 0 (seed {self.cfg.sim.seed})")

    def _new_run(self, cfg: Config) -> None:
        """Forget the old run (its notes, frames and files) and build a new one with ``cfg``;
        the caller shows its frame 0 at once, so nothing of the old run stays on screen."""
        self.notes.clear()
        self._new_run_files()
        self._build(cfg)

    def _replay_from_start(self, why: str) -> None:
        """A replay started again: show its frame 0 at once, and say so."""
        self.compute()
        self.note(f"{why}: replaying {self.source.describe()} from frame 0")

    def _restart(self, cmd: C.Restart) -> None:
        floor = self._unstyled.floor.with_tile_size(float(cmd.tile_size))
        camera = replace(self.cfg.camera, ppm=float(cmd.ppm))
        vision = replace(self._unstyled.vision, extractor=self.cfg.vision.extractor)
        cfg = replace(self.cfg, floor=floor, camera=camera, vision=vision)  # validates
        cfg = with_floor_style(cfg, cmd.style)
        self._new_run(cfg)
        self.compute()
        self.note(f"new run: tile size {cmd.tile_size:g} m, {cmd.ppm:g} px/m, floor style "
                  f"{cmd.style}")

    def _reconfigure(self, cfg: Config, what: str = "new settings") -> None:
        """New localizer or vision settings: from the next frame on (the simulator), or from frame
        0 (a replay: its boxes are then those ``replay`` writes with these settings)."""
        if self.source.restart_on_settings:
            if cfg == self.cfg:
                return
            self._new_run_files()
            self._build(cfg)
            self._replay_from_start(what)
            return
        self.runner.reconfigure(self._lens_bound(cfg))
        self.cfg = cfg

    def _set_mode(self, cmd: C.SetMode) -> None:
        self._reconfigure(replace(self.cfg, localizer=replace(self.cfg.localizer, mode=cmd.mode)),
                          f"mode {cmd.mode}")

    def _set_extractor(self, cmd: C.SetExtractor) -> None:
        vision = replace(self.cfg.vision, extractor=cmd.extractor)
        self._reconfigure(replace(self.cfg, vision=vision), f"extractor {cmd.extractor}")

    def _set_noise(self, cmd: C.SetNoise) -> None:
        noise = NoiseConfig(cmd.speed_error, cmd.yaw_rate_error, cmd.compass_error, cmd.fraction)
        self._simulator.set_noise(noise)
        self._reconfigure(replace(self.cfg, noise=noise))
        if self.mcl is not None:
            self.mcl.mcl.bounds = self.runner.bounds  # its motion noise and compass likelihood
        self.recorder.stop("the declared bounds changed; its meta.json would be wrong")

    def _set_inflation(self, cmd: C.SetInflation) -> None:
        loc: LocalizerConfig = replace(self.cfg.localizer,
                                       truth_inflation=(cmd.xy, cmd.xy, cmd.theta))
        self._reconfigure(replace(self.cfg, localizer=loc), "truth inflation")

    def _set_fault_model(self, cmd: C.SetFaultModel) -> None:
        speed, yaw_rate = (cmd.speed, cmd.yaw_rate) if cmd.on else (0.0, 0.0)
        loc: LocalizerConfig = replace(self.cfg.localizer, fault_speed=speed,
                                       fault_yaw_rate=yaw_rate)
        self._reconfigure(replace(self.cfg, localizer=loc),
                          f"fault model {speed:g} m/s, {yaw_rate:g} rad/s" if cmd.on
                          else "fault model off")
