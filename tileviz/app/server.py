"""``python -m tileviz serve`` / ``python serve.py``: the live demo in the browser (viser).

:class:`App` owns the viser server, a queue of commands and one loop thread. GUI callbacks only
put commands on the queue. The loop thread drains the queue between frames, advances the run
(:class:`tileviz.app.session.Session`: simulator -> runner -> history) and pushes the frame being
shown to the scene, the image panels, the plots and the readouts, at most ``push_rate`` times a
second (:class:`tileviz.app.schedule.LoopSchedule` paces frames and pushes; each part refreshes
at its own :class:`~tileviz.app.schedule.RateLimit`). The readout is
:func:`tileviz.app.status.render_status` of the session's state. An exception inside a frame is
logged as one line, shown in the GUI, and the loop goes on.

Its command line (``python -m tileviz serve``) is :mod:`tileviz.app.serve_cli`.
"""

from __future__ import annotations

import contextlib
import io
import math
import queue
import socket
import sys
import threading
import time
import warnings
from typing import TYPE_CHECKING

import numpy as np

from tileviz.app import commands as C
from tileviz.app.history import METRIC_NAMES, Entry
from tileviz.app.plots import summary
from tileviz.app.scene import TRAIL_SEGMENTS
from tileviz.app.schedule import LoopSchedule, RateLimit
from tileviz.app.session import Session, SessionOptions
from tileviz.app.status import StatusState, render_status
from tileviz.cliutil import CliError
from tileviz.config import Config

if TYPE_CHECKING:
    from viser import GuiButtonGroupHandle, GuiEvent, ViserServer

__all__ = ["App", "port_free"]

_COL = {name: i for i, name in enumerate(METRIC_NAMES)}
VIEW_LABELS = {"camera": "Camera", "stages": "Camera and stages", "plots": "Plots"}
"""The left panel's choices (``commands.PANEL_VIEWS``) as the button group shows them."""
FOLLOW_OFFSET = (0.0, -3.0, 3.4)
"""Where the initial view stands relative to the robot, metres (behind it to the south, up)."""
PANEL_TAB = "Set, camera, plots"
"""The left panel's tab (short enough to be read whole)."""
LEFT_PANEL_PX = 345
"""The left panel's width: the 320 px camera view and its margins."""
RIGHT_PANEL_PX = 300
"""The control panel's width: the scene keeps half of a 1280 px wide window."""
STARTING_NOTE = ("**Starting: computing the first frame.** The first start after an install "
                 "compiles the vision kernels (up to a minute, once); the set, the camera view "
                 "and the plots appear here when it is done.")
"""What the left panel says until the first frame is shown."""
HIDE_SOFTWARE_WEBGL_NOTICE = "<style>#webgl-software-rendering{display:none !important}</style>"
"""Hides viser's notice that WebGL runs in software (it would cover the scene on a machine
without a GPU); ``docs/demo.md``, "Without a GPU", says what that costs."""
DEFAULT_PORT = 8080
"""Where ``serve`` listens unless ``--port`` says otherwise (the next free port if it is busy)."""
QUEUE_SIZE = 1000
"""Commands waiting at most; a flood beyond it is dropped (and counted)."""
HEAP_TRIM_PERIOD = 60.0
"""Seconds between two returns of the heaps' free pages to the system (App._return_freed_memory)."""
START_POLL = 0.1
"""Seconds between two looks at ``App.start``'s cancel event while the first frame is made."""


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
        self._images = RateLimit(self.image_rate)
        self.readout_rate = float(readout_rate)
        self._readouts = RateLimit(self.readout_rate)
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
        # the session's files are closed by whoever is last: stop(), or the loop thread when
        # stop() gave up waiting for its frame (a file is never closed under its writer)
        self._closing = threading.Lock()
        self._loop_ended = False
        self._close_on_loop_end = False
        self._push_failed = False
        """The last push raised (it is made again at the next push, said only if that fails)."""

    # ------------------------------------------------------------------ lifecycle
    def start(self, timeout: float = 120.0, cancel: threading.Event | None = None) -> bool:
        """Start viser and the loop thread; return True once the first frame is shown (or raise
        what stopped the start, or the loop's not starting within ``timeout`` s). When
        ``cancel`` is set first (Ctrl-C while the first run after an install compiles the
        vision kernels), stop without waiting for that frame and return False."""
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
        # viser prints its address as it starts listening; tileviz says where to go once the
        # first frame is shown (serve's 'open ...' line), so that banner is kept unless verbose
        with contextlib.redirect_stdout(sys.stdout if self.verbose else io.StringIO()):
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
        # no image-based lighting: with software WebGL (no GPU) the environment map makes every
        # lit mesh costly to draw (docs/demo.md, "Without a GPU"); the default lights light it
        server.scene.configure_environment_map(None)
        self.scene = SceneView(server.scene, pool=max(1, self.cfg.localizer.max_boxes),
                               particles=self.options.mcl_particles)
        self.controls = Controls(server, self.submit, self.cfg, layers=s.layers,
                                 display=s.display, playing=s.playing, speed=s.speed,
                                 max_speed=s.max_speed, mcl=s.mcl is not None,
                                 replay=None if s.source.simulator else s.source.describe(),
                                 live=s.source.realtime, region=s.default_region())
        # no GPU: the browser's notice that WebGL runs in software would cover the scene; the
        # page's help says what that costs (the floor texture layer is off by default)
        server.gui.add_html(HIDE_SOFTWARE_WEBGL_NOTICE)
        panel = server.gui.add_panel()
        with panel.add_tab(PANEL_TAB):
            self.starting = server.gui.add_markdown(STARTING_NOTE)
            self.inset = InsetView(server.gui)
            self.view = server.gui.add_button_group("Below", tuple(VIEW_LABELS.values()))
            with server.gui.add_folder("Camera and image pipeline") as self.images_folder:
                self.panels = ImagePanels(server.gui, width=self.cfg.camera.width,
                                          height=self.cfg.camera.height)
            with server.gui.add_folder("Plots", visible=False) as self.plots_folder:
                self.plots = Plots(server.gui)
        panel.dock_left()
        panel.set_width(LEFT_PANEL_PX)
        # the controls docked at the right edge, not floating over the scene: the 3-D view gets
        # only the window's middle, which it does not share, and without a GPU every pixel of
        # the view costs the browser on every frame (docs/demo.md, "Without a GPU")
        server.gui.main_panel.dock_right()
        server.gui.main_panel.set_width(RIGHT_PANEL_PX)
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
        deadline = time.monotonic() + timeout
        while not self._started.wait(START_POLL):
            if cancel is not None and cancel.is_set():
                # the loop is inside its first frame (or the frames up to --start-frame): it
                # closes the session's files itself once that frame ends
                self.stop(wait=0.0)
                return False
            if time.monotonic() >= deadline:
                self.stop()
                raise RuntimeError("the loop thread did not start in time")
        if self._failure is not None:
            failure = self._failure
            self.stop()
            raise failure
        return True

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

    def stop(self, wait: float = 10.0) -> None:
        """Stop the loop (after the frame in progress, waiting ``wait`` s at most for it), close
        files and the server. A loop still inside its frame after ``wait`` closes the session's
        files itself when that frame ends."""
        self._stop.set()
        try:
            self.queue.put_nowait(None)  # wake the loop
        except queue.Full:
            pass
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=wait)
        if self.session is not None:
            with self._closing:
                live = (self._thread is not None and self._thread.is_alive()
                        and not self._loop_ended)
                self._close_on_loop_end = live
            if not live:
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
        """The loop thread: :meth:`_loop`, then close the session's files if :meth:`stop`
        left that to it."""
        try:
            self._loop()
        finally:
            with self._closing:
                self._loop_ended = True
                close = self._close_on_loop_end
            if close and self.session is not None:
                self.session.close()

    def _loop(self) -> None:
        s = self.session
        assert s is not None
        try:
            if len(s.history) == 0:
                s.skip_to(self.options.start_frame, stopped=self._stop.is_set)
            self._push(force=True)
        except BaseException as e:  # noqa: BLE001 - reported by start()
            self._failure = e
            self._started.set()
            return
        self._started.set()
        sched = LoopSchedule(self.push_rate, self.plot_rate, time.perf_counter())
        while not self._stop.is_set():
            now = time.perf_counter()
            # wait for a command until the next frame is due (or a push is due)
            self._drain(sched.wait(now, playing=s.playing,
                                   push_pending=s.version != self._pushed_version))
            if self._stop.is_set():
                break
            s.poll()
            now = time.perf_counter()
            if s.playing and sched.frame_due(now):
                try:
                    s.advance()  # catches what a frame raises; this guards the rest
                except Exception as e:  # noqa: BLE001 - the loop must go on
                    s.note(f"loop: {type(e).__name__}: {e}", "error")
                if self.frames is not None and s.frames_computed >= self.frames:
                    s.playing = False
                sched.frame_made(now, s.frame_period)
            if s.version != self._pushed_version and sched.push_due(now):
                # on a schedule, so a loop a little faster than the cap still pushes at the cap
                self._push(plots=sched.pushed(now))

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
                    s.note(f"{C.label(cmd)}: {e}", "error")
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
            if self.starting.visible:
                self.starting.visible = False  # the first frame is shown: the panels take over
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
            if not s.playing or self._images.due(now) or switched:
                # the browser decodes every image it gets: while playing, images at image_rate;
                # only the images the left panel shows
                self.inset.show(entry.record, s.cfg.floor.tile_size)
                if s.panel != "plots":
                    self.panels.show(entry, s.display, stages=s.panel == "stages")
                self._images.spend(now)
            if (plots or switched) and s.panel == "plots":
                self.plots.update(rows)
            if s.follow and s.playing:
                self._follow(entry)
        # the readouts change every frame; while playing, a person reads them a few times a
        # second, and every refresh makes the browser lay out and redraw the panel
        now = time.perf_counter()
        key = (s.playing, s.recording_active, s.setpoint_kind, len(s.history) == 0,
               id(s.notes[-1]) if s.notes else None)
        if s.playing and key == self._readout_key and not self._readouts.due(now):
            return
        self._readout_key = key
        self._readouts.spend(now)
        self.controls.refresh(first=s.history.first, last=s.history.last, shown=pos,
                              playing=s.playing, setpoint=s.setpoint_kind,
                              target=tuple(s.cfg.sim.manual_target),  # type: ignore[arg-type]
                              recording=s.recording_active,
                              status=render_status(StatusState.of(
                                  s, entry, self._contained, live=s.shown == s.history.last)),
                              region=s.default_region())

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
