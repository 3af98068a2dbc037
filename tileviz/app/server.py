"""``python -m tileviz serve`` / ``python serve.py``: the live demo in the browser (viser).

:class:`App` owns the viser server, a queue of commands and one loop thread. GUI callbacks only
put commands on the queue. The loop thread drains the queue between frames, advances the run
(:class:`tileviz.app.session.Session`: simulator -> runner -> history) and pushes the frame being
shown to the scene, the image panels, the plots and the readouts, at most ``push_rate`` times a
second (the browser cannot take more than ~60 updates a second; the loop itself runs faster).
An exception inside a frame is logged as one line, shown in the GUI, and the loop goes on.

Its command line (``python -m tileviz serve``) is :mod:`tileviz.app.serve_cli`.
"""

from __future__ import annotations

import html
import math
import queue
import socket
import threading
import time
import warnings
from typing import TYPE_CHECKING

import numpy as np

from tileviz.app import commands as C
from tileviz.app.history import METRIC_NAMES, Entry
from tileviz.app.plots import summary
from tileviz.app.scene import TRAIL_SEGMENTS
from tileviz.app.session import Session, SessionOptions
from tileviz.cliutil import (
    CliError,
)
from tileviz.config import (
    Config,
    LocalizerConfig,
)
from tileviz.core.localizer import FAULT_MAX_REJECTIONS, LocalizerStep

if TYPE_CHECKING:
    from viser import GuiButtonGroupHandle, GuiEvent, ViserServer

__all__ = ["App", "fault_line", "port_free"]

_COL = {name: i for i, name in enumerate(METRIC_NAMES)}
VIEW_LABELS = {"camera": "Camera", "stages": "Camera and stages", "plots": "Plots"}
"""The left panel's choices (``commands.PANEL_VIEWS``) as the button group shows them."""
FOLLOW_OFFSET = (0.0, -2.2, 2.6)
"""Where the initial view stands relative to the robot, metres (behind it to the south, up)."""
DEFAULT_PORT = 8080
"""Where ``serve`` listens unless ``--port`` says otherwise (the next free port if it is busy)."""
QUEUE_SIZE = 1000
"""Commands waiting at most; a flood beyond it is dropped (and counted)."""
HEAP_TRIM_PERIOD = 60.0
"""Seconds between two returns of the heaps' free pages to the system (App._return_freed_memory)."""


class App:
    """The live demo: a viser server + the loop thread (see the module docstring).

    ``cfg``: the run's configuration. ``options``: how the session starts. ``host``/``port``: where
    to listen (port 0: any free port; a busy port: the next free one, or CliError when
    ``strict_port``). ``push_rate``: scene updates per second at most;
    ``image_rate``: image panel updates per second at most while playing (a paused or stepped
    frame always shows its images); ``plot_rate``: plot updates per second at most;
    ``readout_rate``: status text and timeline updates per second at most while playing (a
    paused or stepped frame, a new note and a change of play state or recording refresh them at
    once);
    ``plot_window``: frames in the plots. ``frames``: pause after that many frames of the run.
    """

    def __init__(self, cfg: Config, options: SessionOptions | None = None, *,
                 host: str = "127.0.0.1", port: int = 8080, strict_port: bool = False,
                 push_rate: float = 20.0, image_rate: float = 5.0, plot_rate: float = 4.0,
                 readout_rate: float = 5.0,
                 plot_window: int = 1000, verbose: bool = False,
                 frames: int | None = None) -> None:
        self.cfg = cfg
        self.frames = frames
        """Pause once the run has made this many frames (None: never)."""
        self.strict_port = strict_port
        self.image_rate = float(image_rate)
        self._next_images = 0.0
        self.readout_rate = float(readout_rate)
        self._next_readout = 0.0
        self._readout_key: object = None
        self.options = options or SessionOptions()
        self.host = host
        self.requested_port = port
        self.push_rate = float(push_rate)
        self.plot_rate = float(plot_rate)
        self.plot_window = int(plot_window)
        self.verbose = verbose
        self.queue: queue.Queue[C.Command | None] = queue.Queue(maxsize=QUEUE_SIZE)
        self.dropped = 0
        """Commands refused because the queue was full."""
        self.session: Session | None = None
        self.server: ViserServer | None = None
        self.pushes = 0
        """Scene/panel pushes so far."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._started = threading.Event()
        self._failure: BaseException | None = None
        self._push_failed = False
        """The last push raised (it is made again at the next push, said only if that fails)."""

    # ------------------------------------------------------------------ lifecycle
    def start(self, timeout: float = 120.0) -> None:
        """Start viser and the loop thread; return once the first frame is shown (or raise what
        stopped the start)."""
        import viser

        from tileviz.app.gui import Controls
        from tileviz.app.inset import InsetView
        from tileviz.app.panels import ImagePanels
        from tileviz.app.plots import Plots
        from tileviz.app.scene import SceneView

        # A browser tab closed between listing the clients and moving their views (following
        # the robot) is expected: viser would warn in the user's terminal that the move "will
        # never be delivered". Nothing is lost (the tab is gone).
        warnings.filterwarnings("ignore", message=r"Queued a \w+ on a closed connection",
                                category=UserWarning)
        if self.strict_port and self.requested_port != 0 and not port_free(self.host,
                                                                            self.requested_port):
            raise CliError(f"port {self.requested_port} on {self.host} is busy (another tileviz "
                           "serve?): stop it or choose another --port")
        self.session = Session(self.cfg, self.options)
        s = self.session
        self.server = viser.ViserServer(host=self.host, port=self.requested_port,
                                        verbose=self.verbose)
        server = self.server
        if self.strict_port and self.requested_port not in (0, self.port):
            self.stop()
            raise CliError(f"port {self.requested_port} on {self.host} is busy (another tileviz "
                           "serve?): stop it or choose another --port")
        self._guard(server)
        server.gui.configure_theme(control_width="medium", show_share_button=False,
                                   titlebar_content=None)
        server.scene.set_up_direction("+z")
        # the robot at its start, seen from behind and above (the view follows it while playing)
        rx, ry = s.robot_start()
        server.initial_camera.position = (rx + FOLLOW_OFFSET[0], ry + FOLLOW_OFFSET[1],
                                          FOLLOW_OFFSET[2])
        server.initial_camera.look_at = (rx, ry, 0.0)
        server.scene.configure_default_lights(enabled=True, cast_shadow=False)
        # no image-based lighting: with software WebGL (no GPU) the environment map made every lit
        # mesh cost seconds a frame (bench/bench_page.py); the default lights light the scene
        server.scene.configure_environment_map(None)
        self.scene = SceneView(server.scene, pool=max(1, self.cfg.localizer.max_boxes),
                               particles=self.options.mcl_particles)
        self.controls = Controls(server, self.submit, self.cfg, layers=s.layers,
                                 display=s.display, playing=s.playing, speed=s.speed,
                                 max_speed=s.max_speed, mcl=s.mcl is not None,
                                 replay=None if s.source.simulator else s.source.describe())
        panel = server.gui.add_panel()
        with panel.add_tab("The set, camera and plots"):
            self.inset = InsetView(server.gui)
            self.view = server.gui.add_button_group("Below", tuple(VIEW_LABELS.values()))
            with server.gui.add_folder("Camera and image pipeline") as self.images_folder:
                self.panels = ImagePanels(server.gui, width=self.cfg.camera.width,
                                          height=self.cfg.camera.height)
            with server.gui.add_folder("Plots", visible=False) as self.plots_folder:
                self.plots = Plots(server.gui)
        panel.dock_left()
        panel.set_width(380)
        # the controls docked at the right edge, not floating over the scene: the 3-D view gets
        # only the window's middle, which it does not share, and without a GPU every pixel of
        # the view costs the browser on every frame (bench/bench_page_parts.py)
        server.gui.main_panel.dock_right()
        self._panel_view = s.panel
        view_of_label = {label: view for view, label in VIEW_LABELS.items()}

        @self.view.on_click
        async def _(event: GuiEvent[GuiButtonGroupHandle]) -> None:
            if event.client is not None:
                self.submit(C.ShowPanel(view_of_label[str(event.target.value)]))

        self._world_version = -1
        self._contained: dict[str, float] | None = None
        self._pushed_version = -1
        self._thread = threading.Thread(target=self._run, name="tileviz-loop", daemon=True)
        self._thread.start()
        threading.Thread(target=self._return_freed_memory, name="tileviz-heap",
                         daemon=True).start()
        if not self._started.wait(timeout):
            self.stop()
            raise RuntimeError("the loop thread did not start in time")
        if self._failure is not None:
            failure = self._failure
            self.stop()
            raise failure

    def _return_freed_memory(self) -> None:
        """Every :data:`HEAP_TRIM_PERIOD` seconds until the server stops, hand the heaps' free
        pages back to the system (:func:`tileviz.pipeline.heap.return_freed_memory`): over hours
        of clients coming and going they fragment, and the resident set would creep up although
        the memory in use does not."""
        from tileviz.pipeline.heap import return_freed_memory

        while not self._stop.wait(HEAP_TRIM_PERIOD):
            if not return_freed_memory():
                return

    def _guard(self, server: ViserServer) -> None:
        """Pages of other sites the user has open must not drive the demo: their websocket
        connections are closed unserved (:mod:`tileviz.app.guard`, SECURITY.md)."""
        from tileviz.app.guard import refuse_foreign_pages

        assert self.session is not None
        if not refuse_foreign_pages(server, self.host,
                                    lambda text: self.submit(C.Report(text, "error"))):
            self.session.note("this viser version does not let tileviz check which pages "
                              "connect: any page the browser has open may drive the demo",
                              "error")

    @property
    def port(self) -> int:
        """The port actually listened on."""
        assert self.server is not None, "the server is not started"
        return int(self.server.get_port())

    @property
    def url(self) -> str:
        host = self.host if self.host not in ("0.0.0.0", "::", "") else "127.0.0.1"
        if ":" in host:
            host = f"[{host}]"
        return f"http://{host}:{self.port}/"

    def stop(self) -> None:
        """Stop the loop (after the frame in progress), close files and the server."""
        self._stop.set()
        try:
            self.queue.put_nowait(None)  # wake the loop
        except queue.Full:
            pass
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=10.0)
        if self.session is not None:
            self.session.close()
        if self.server is not None:
            self.server.stop()
            self.server = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive() and not self._stop.is_set()

    def submit(self, cmd: C.Command) -> None:
        """Queue a command for the loop (never blocks; dropped when the queue is full)."""
        try:
            self.queue.put_nowait(cmd)
        except queue.Full:
            self.dropped += 1

    # ------------------------------------------------------------------ loop thread
    def _run(self) -> None:
        s = self.session
        assert s is not None
        try:
            if len(s.history) == 0:
                s.skip_to(self.options.start_frame)
            self._push(force=True)
        except BaseException as e:  # noqa: BLE001 - reported by start()
            self._failure = e
            self._started.set()
            return
        self._started.set()
        next_frame = next_push = time.perf_counter()
        push_period = 1.0 / self.push_rate
        last_plot = 0.0
        while not self._stop.is_set():
            now = time.perf_counter()
            # wait for a command until the next frame is due (or a push is due)
            wait = max(0.0, next_frame - now) if s.playing else 0.25
            if s.version != self._pushed_version:
                wait = min(wait, max(0.0, next_push - now))
            self._drain(wait)
            if self._stop.is_set():
                break
            s.poll()
            now = time.perf_counter()
            if s.playing and now >= next_frame:
                try:
                    s.advance()  # catches what a frame raises; this guards the rest
                except Exception as e:  # noqa: BLE001 - the loop must go on
                    s.note(f"loop: {type(e).__name__}: {e}", "error")
                if self.frames is not None and s.frames_computed >= self.frames:
                    s.playing = False
                period = s.frame_period
                next_frame = max(next_frame + period, now - 0.25) if period > 0 else now
            if s.version != self._pushed_version and now >= next_push:
                plots = now - last_plot >= 1.0 / self.plot_rate
                self._push(plots=plots)
                # on a schedule, so a loop a little faster than the cap still pushes at the cap
                next_push = max(next_push + push_period, now - push_period)
                if plots:
                    last_plot = now

    def _drain(self, wait: float) -> None:
        """Apply every queued command; block up to ``wait`` seconds for the first one."""
        s = self.session
        assert s is not None
        try:
            cmd = self.queue.get(timeout=wait) if wait > 0 else self.queue.get_nowait()
        except queue.Empty:
            return
        while True:
            if cmd is not None:
                try:
                    s.apply(cmd)
                except Exception as e:  # noqa: BLE001 - a bad command must not stop the loop
                    s.note(f"{type(cmd).__name__}: {e}", "error")
            try:
                cmd = self.queue.get_nowait()
            except queue.Empty:
                return

    def _push(self, *, force: bool = False, plots: bool = True) -> None:
        """Show the current frame (scene, panels, readouts; plots when ``plots``)."""
        s = self.session
        assert s is not None
        try:
            # one batch: the browser applies the frame's updates together, and viser wakes its
            # sender once per push instead of once per message (nothing is held back: the block
            # ends with the push)
            assert self.server is not None
            with self.server.atomic():
                self._push_inner(plots or force)
        except Exception as e:  # noqa: BLE001 - drawing must not stop the loop
            if not self._push_failed:
                # viser's push can race its own event loop (it sets an asyncio.Event from this
                # thread: "deque mutated during iteration"); the next push redraws the frame
                self._push_failed = True
                return
            s.note(f"display: {e}", "error")
        self._push_failed = False
        self._pushed_version = s.version
        self.pushes += 1

    def _push_inner(self, plots: bool) -> None:
        s = self.session
        assert s is not None
        if s.world_version != self._world_version:
            self._world_version = s.world_version
            self.scene.set_world(s.cfg, path=s.source.path(), waypoints=s.cfg.sim.waypoints,
                                 setpoint_kind=s.setpoint_kind, closed=s.source.path_closed)
        self.scene.apply_layers(s.layers)
        pos = s.display_position()
        entry = s.history.get(pos) if pos in s.history else None
        if entry is not None:
            rows = s.history.window(pos, self.plot_window)
            self._contained = summary(rows)
            trail = rows[-(TRAIL_SEGMENTS + 1):]
            # the long trails at the plot rate; their newest part (the heads) with every push
            self.scene.show(entry.record, trail[:, [_COL["truth_x"], _COL["truth_y"]]],
                            trail[:, [_COL["est_x"], _COL["est_y"]]],
                            full=plots or not s.playing, mcl=entry.mcl)
            now = time.perf_counter()
            switched = s.panel != self._panel_view
            if switched:
                self._panel_view = s.panel
                self.images_folder.visible = s.panel != "plots"
                self.plots_folder.visible = s.panel == "plots"
            if not s.playing or now >= self._next_images or switched:
                # the browser decodes every image it gets: while playing, images at image_rate;
                # only the images the left panel shows
                self.inset.show(entry.record, s.cfg.floor.tile_size)
                if s.panel != "plots":
                    self.panels.show(entry, s.display, stages=s.panel == "stages")
                self._next_images = max(self._next_images + 1.0 / self.image_rate, now)
            if (plots or switched) and s.panel == "plots":
                self.plots.update(rows)
            if s.follow and s.playing:
                self._follow(entry)
        # the readouts change every frame; while playing, a person reads them a few times a
        # second, and every refresh makes the browser lay out and redraw the panel
        now = time.perf_counter()
        key = (s.playing, s.recording_active, s.setpoint_kind, len(s.history) == 0,
               id(s.notes[-1]) if s.notes else None)
        if s.playing and key == self._readout_key and now < self._next_readout:
            return
        self._readout_key = key
        self._next_readout = max(self._next_readout + 1.0 / self.readout_rate, now)
        self.controls.refresh(first=s.history.first, last=s.history.last, shown=pos,
                              playing=s.playing, setpoint=s.setpoint_kind,
                              target=tuple(s.cfg.sim.manual_target),  # type: ignore[arg-type]
                              recording=s.recording_active,
                              status=self.status_text(entry, live=s.shown == s.history.last))

    def _follow(self, entry: Entry) -> None:
        """Move every client's view with the robot (its true pose, else the set's centre),
        keeping the user's angle and distance."""
        r = entry.record
        hull = r.updated.hull()
        if r.truth is not None:
            x, y = r.truth.x, r.truth.y
        elif hull is not None and r.status != "lost":
            x, y, _ = hull.centre
        else:
            return
        if not (math.isfinite(x) and math.isfinite(y)):
            return
        assert self.server is not None
        for client in self.server.get_clients().values():
            cam = client.camera
            try:
                look = cam.look_at
                dx, dy = x - float(look[0]), y - float(look[1])
                if math.hypot(dx, dy) > 1e-3:
                    # viser moves look_at with the position: the view is translated
                    cam.position = np.asarray(cam.position) + (dx, dy, 0.0)
            except (AssertionError, ValueError):
                continue  # a client whose camera is not known yet

    def status_text(self, entry: Entry | None, *, live: bool) -> str:
        """The readout of ``entry`` as HTML: a box of fixed height (frame, status, widths, error,
        rates; it scrolls if it must, so the controls under it never move), then the newest notes
        in a second box of fixed height."""
        s = self.session
        assert s is not None
        lines: list[str] = []
        state = "playing" if s.playing else "paused"
        if entry is None:
            lines.append(f"<b>no frame yet</b> ({state})")
        else:
            r = entry.record
            hull = r.updated.hull()
            lines.append(f"<b>frame {r.index}</b>, t = {r.t:.2f} s, {state}"
                         f"{'' if live else ' (from the history)'}")
            lines.append(f"status <b>{r.status}</b>: {html.escape(STATUS_WORDS.get(r.status, ''))}"
                         f", {len(r.updated)} box(es)")
            fault = fault_line(r.step, s.cfg.localizer)
            if fault:
                lines.append(fault)
            reason = r.vision.reason
            lines.append("camera view used" if r.vision.observation is not None
                         else f"camera view not used: {html.escape(reason)}")
            if hull is not None:
                wx, wy, wt = hull.widths
                lines.append(f"set {100 * wx:.1f} x {100 * wy:.1f} cm, heading "
                             f"{math.degrees(wt):.2f} deg wide")
                if r.truth is not None:
                    cx, cy, ct = hull.centre
                    err = math.hypot(r.truth.x - cx, r.truth.y - cy)
                    inside = r.truth_inside()
                    mark = {True: "inside", False: "<b>OUTSIDE</b>",
                            None: "not vouched for"}[inside]
                    et = abs(math.degrees(math.remainder(r.truth.theta - ct, 2 * math.pi)))
                    lines.append(f"centre {100 * err:.1f} cm, {et:.2f} deg from the truth; truth "
                                 f"{mark}")
            if entry.mcl is not None and r.truth is not None:
                m = entry.mcl
                err = math.hypot(r.truth.x - m.mean[0], r.truth.y - m.mean[1])
                where = "inside" if m.covered else "<b>outside</b>"
                lines.append(f"MCL ({len(m.particles)} particles): mean {100 * err:.1f} cm off,"
                             f" truth {where} its 95 % ellipse")
            ms = r.timings.get("vision_ms", 0.0) + r.timings.get("localizer_ms", 0.0)
            lines.append(f"frame time {ms:.1f} ms (vision {r.timings.get('vision_ms', 0.0):.1f},"
                         f" localizer {r.timings.get('localizer_ms', 0.0):.2f})")
        c = self._contained
        if entry is not None and c is not None and c["frames"] > 0:
            lines.append(f"truth inside the set in {100 * c['contained']:.1f} % of the last "
                         f"{c['frames']:.0f} frames it vouched for")
        rate = f"{s.rate:.0f} frames/s" if s.playing else "-"
        lines.append(f"loop {rate}, history {len(s.history)}/{s.history.capacity}, "
                     f"mode {s.cfg.localizer.mode}, extractor {s.cfg.vision.extractor}")
        notes: list[str] = []
        recent = list(s.notes)[-3:]
        if not s.source.simulator:
            # its end stays in view after newer notes pushed the note about it out
            said = s.ended is not None and any(n.text.startswith(s.ended) for n in recent)
            notes.append(f"replaying <code>{html.escape(s.source.describe())}</code>"
                         + (f": <b>{html.escape(s.ended)}</b>" if s.ended and not said else ""))
        writer = s.recorder.writer
        if writer is not None:
            notes.append(f"recording to <code>{html.escape(str(s.recorder.path))}</code> "
                         f"({writer.count} frames)")
        if s.degraded:
            notes.append("<b>a frame failed: the set may miss the truth (Relocalize or "
                         "Reset)</b>")
        for n in reversed(recent):  # newest first
            notes.append(("<b>error:</b> " if n.level == "error" else "") + html.escape(n.text))
        return (f'<div class="tileviz-status" style="{STATUS_STYLE}">{"<br>".join(lines)}</div>'
                f'<div class="tileviz-notes" style="{NOTES_STYLE}">{"<br>".join(notes)}</div>')


def fault_line(step: LocalizerStep | None, loc: LocalizerConfig) -> str:
    """The fault model's state at one frame, in words ('' when there is nothing to say): the
    candidates of a re-localization in a region, the frame of a followed fault
    (``LocalizerStep.fault_frame``) and the views in a row that fitted neither the set nor the
    fault set, out of the number that makes the status ``lost``."""
    if step is None or step.status == "lost":
        return ""
    parts = []
    if step.relocalizing:
        parts.append(f"re-localizing: {len(step.updated)} candidate(s) in the region")
    if not (loc.fault_speed or loc.fault_yaw_rate) or loc.max_slip != (0.0, 0.0) or (
            loc.mode != "autonomous"):
        return "; ".join(parts)
    if step.fault_frame > 0:
        parts.append(f"tracking through a fault: frame {step.fault_frame} of the fault set")
    if step.rejections > 0:
        limit = min(loc.max_rejections, FAULT_MAX_REJECTIONS)
        parts.append(f"{step.rejections} view(s) in a row fit neither set ({limit} make it lost)")
    return "; ".join(parts)


STATUS_WORDS = {
    "contracted": "the camera's view shrank the set",
    "predicted": "no usable view: odometry and compass only",
    "rejected": "the view disagrees with the set (an outlier), ignored",
    "lost": "no set the method can vouch for",
}
"""The statuses in plain words (``tileviz.types.STATUSES``)."""
_BOX = ("box-sizing:border-box;overflow-y:auto;font-size:0.8em;line-height:1.35em;"
        "padding:0.2em 0.4em;")
STATUS_STYLE = _BOX + "height:12.4em;"
"""Fixed height: the status block never grows, so the buttons under it never move."""
NOTES_STYLE = _BOX + "height:5.6em;margin-top:0.2em;border-top:1px solid #8884;opacity:0.85;"


def port_free(host: str, port: int) -> bool:
    """True when a TCP server could listen on ``host``:``port`` now (as asyncio's servers do, with
    SO_REUSEADDR); False when it is taken (or the address is not this machine's)."""
    try:
        family, kind, proto, _, addr = socket.getaddrinfo(host or None, port,
                                                          type=socket.SOCK_STREAM)[0]
        with socket.socket(family, kind, proto) as sock:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind(addr)
    except OSError:
        return False
    return True
