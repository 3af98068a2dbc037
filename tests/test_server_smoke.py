"""Headless smoke test of the live server: a websocket client speaking viser's protocol sees the
scene and the controls, and a Step advances exactly one frame. Plus the command line."""

from __future__ import annotations

import asyncio
import math
import os
import re
import subprocess
import sys
import threading
import urllib.request
from pathlib import Path

import pytest

from tileviz.app.server import App
from tileviz.app.session import Session, SessionOptions
from tileviz.config import preset
from tileviz.summary import FAITHFUL_NOTE
from tileviz.testing.wsclient import ViserClient, serving, stop_serve

REPO = Path(__file__).resolve().parents[1]
UPDATE_TYPES = {
    "SetPositionMessage", "SetOrientationMessage", "SceneNodeUpdateMessage",
    "SetSceneNodeVisibilityMessage", "GuiUpdateMessage",
}


@pytest.fixture()
def app(tmp_path):
    a = App(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True), port=0)
    a.start()
    yield a
    a.stop()


def uuid_of(c: ViserClient, label: str, kind: str) -> str:
    return c.gui_uuid(label, kind)


def test_scene_and_controls_arrive_and_step_advances_one_frame(app):
    async def scenario() -> None:
        async with ViserClient(app.url) as c:
            await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage")
            names = {m.get("name") for m in c.messages if "props" in m and "name" in m}
            for node in ("/floor", "/grid", "/robot", "/robot/body", "/robot/footprint", "/truth",
                         "/intervals/boxes/0", "/intervals/prediction/0", "/intervals/wedge",
                         "/setpoint", "/path", "/trails/truth", "/trails/estimate",
                         "/target_gizmo"):
                assert node in names, node
            labels = {m["props"].get("label") for m in c.messages
                      if isinstance(m.get("props"), dict)}
            for label in ("Play", "Step", "Step back", "Timeline", "Speed (x real time)",
                          "Setpoint", "Mode", "Extractor", "Speed bound (m/s)",
                          "Kidnap (teleport the robot)", "Reset the run", "Start recording",
                          "camera view"):
                assert label in labels, label
            assert len(list(c.of_type("GuiUplotMessage"))) == 4  # residuals, widths, error, MCL

            timeline = uuid_of(c, "Timeline", "GuiSliderMessage")
            camera = uuid_of(c, "camera view", "GuiImageMessage")
            display = uuid_of(c, "Stream stage images", "GuiCheckboxMessage")

            def camera_jpeg(start: int = 0) -> list[bytes]:
                return [m["updates"]["_data"] for m in c.messages[start:]
                        if m.get("type") == "GuiUpdateMessage" and m.get("uuid") == camera
                        and "_data" in m["updates"]]

            frame0 = camera_jpeg()[-1]
            assert frame0[:2] == b"\xff\xd8"  # a JPEG of the camera view
            assert app.session.history.last == 0
            # the stages are sent once the left panel shows them
            stages = {m["uuid"] for m in c.of_type("GuiImageMessage")
                      if m["props"].get("label") == ""}
            mark = len(c.messages)
            view = uuid_of(c, "Below", "GuiButtonGroupMessage")
            await c.send({"type": "GuiUpdateMessage", "uuid": view,
                          "updates": {"value": "Camera and stages"}})
            await c.wait_for(lambda m: m.get("uuid") in stages
                             and "_data" in m.get("updates", {}), start=mark)

            mark = len(c.messages)
            await c.click("Step")
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and m.get("uuid") == timeline and m["updates"].get("value") == 1,
                             start=mark)
            # a later command is applied after the Step: once its effect is back, the Step is
            # over, and it made exactly one frame
            await c.send({"type": "GuiUpdateMessage", "uuid": display,
                          "updates": {"value": False}})
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and m["updates"].get("visible") is False, start=mark)
            assert (app.session.history.last, app.session.shown) == (1, 1)
            truth = app.session.shown_entry().record.truth
            robot = [m for m in c.messages[mark:]
                     if m.get("type") == "SetPositionMessage" and m.get("name") == "/robot"]
            assert robot and tuple(robot[-1]["position"][:2]) == pytest.approx((truth.x, truth.y))
            frame1 = camera_jpeg(mark)[-1]
            assert frame1 != frame0
            # no node is created per frame: only updates after the first sync
            assert {m["type"] for m in c.messages[mark:]} <= UPDATE_TYPES

            mark = len(c.messages)
            await c.click("Step back")
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and m.get("uuid") == timeline and m["updates"].get("value") == 0,
                             start=mark)
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and m.get("uuid") == camera and "_data" in m["updates"], start=mark)
            assert camera_jpeg(mark)[-1] == frame0  # the stored frame, byte for byte
            assert app.session.history.last == 1

    asyncio.run(scenario())


def test_a_refused_gui_value_becomes_a_note_and_the_loop_goes_on(app):
    async def scenario() -> None:
        async with ViserClient(app.url) as c:
            await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage")
            text = uuid_of(c, "Waypoints (x, y; ...)", "GuiTextMessage")
            await c.send({"type": "GuiUpdateMessage", "uuid": text,
                          "updates": {"value": "1, 2; banana"}})
            await c.click("Drive the waypoints")
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and "waypoint 1" in str(m["updates"].get("content", "")))
            await c.click("Step")
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and "frame 1" in str(m["updates"].get("content", "")))
            assert app.running

    asyncio.run(scenario())


def test_the_target_follows_a_click_on_the_floor_and_the_gizmo(app):
    async def scenario() -> None:
        async with ViserClient(app.url) as c:
            await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage")
            mark = len(c.messages)
            await c.click("Click the floor to set the target")
            # the server now listens for clicks in the scene
            await c.wait_for(lambda m: m.get("type") == "ScenePointerEnableMessage"
                             and m.get("event_type") == "click" and m.get("modifiers"),
                             start=mark)
            # a click whose ray goes from (1.5, -2, 4) straight down hits the floor at (1.5, -2)
            await c.send({"type": "ScenePointerMessage", "event_type": "click",
                          "ray_origin": (1.5, -2.0, 4.0), "ray_direction": (0.0, 0.0, -1.0),
                          "screen_pos": ((0.5, 0.5),), "modifier": None})
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and m["updates"].get("value") == "manual", start=mark)
            assert app.session.setpoint_kind == "manual"
            assert app.session.cfg.sim.manual_target == pytest.approx((1.5, -2.0))

            mark = len(c.messages)
            for msg in ({"type": "TransformControlsDragStartMessage", "name": "/target_gizmo"},
                        {"type": "TransformControlsUpdateMessage", "name": "/target_gizmo",
                         "wxyz": (1.0, 0.0, 0.0, 0.0), "position": (-0.5, 2.5, 0.05)},
                        {"type": "TransformControlsDragEndMessage", "name": "/target_gizmo"}):
                await c.send(msg)
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and m["updates"].get("value") == [-0.5, 2.5], start=mark)
            assert app.session.cfg.sim.manual_target == pytest.approx((-0.5, 2.5))
            await c.click("Step")
            await c.wait_for(lambda m: m.get("type") == "GuiUpdateMessage"
                             and "frame 1" in str(m["updates"].get("content", "")))
            assert app.session.shown_entry().record.setpoint == pytest.approx((-0.5, 2.5))

    asyncio.run(scenario())


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "tileviz", "serve", *args], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("args, word", [
    (["--port", "http"], "--port"),
    (["--port", "70000"], "--port"),
    (["--tile-size", "-1"], "--tile-size"),
    (["--ppm", "nan"], "--ppm"),
    (["--ppm", "0"], "--ppm must be a finite number >= 20 and <= 2000"),
    (["--ppm", "5"], "--ppm must be a finite number >= 20 and <= 2000"),
    (["--seed", "-1"], "--seed must be >= 0 and <= 4294967295"),
    (["--preset", "mars"], "--preset"),
    (["--history", "0"], "--history"),
])
def test_bad_options_give_one_line_and_exit_2(args, word):
    r = run_cli(*args)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and word in lines[0] and "Traceback" not in r.stderr


def test_table_6_1_options_reach_the_run(tmp_path):
    from tileviz.app.serve_cli import options_from_args, parser, serve_config

    args = parser().parse_args(["--interactive", "--no-intervals", "--no-display", "--ppm", "150",
                                "--tile-size", "0.5", "--output-file", "eq.csv", "--preset",
                                "seed", "--out-dir", str(tmp_path)])
    cfg, options = serve_config(args), options_from_args(args)
    assert (cfg.camera.ppm, cfg.floor.tile_size, cfg.camera.width) == (150.0, 0.5, 256)
    assert options.interactive and not options.display and not options.intervals
    assert options.output_file == "eq.csv" and options.out_dir == tmp_path
    defaults = options_from_args(parser().parse_args([]))
    assert defaults.display and defaults.intervals and not defaults.interactive
    assert defaults.history >= 2000 and parser().parse_args([]).host == "127.0.0.1"
    s = Session(cfg, options)
    assert not s.playing and not s.runner.keep_stages
    assert not any(s.layers[k] for k in ("prediction", "boxes", "wedge"))
    s.close()
    assert (tmp_path / "eq.csv").exists()


def test_serve_prints_the_url_serves_the_page_and_stops_on_ctrl_c(tmp_path):
    with serving(["--port", "0", "--out-dir", str(tmp_path), "--output-file", "res.csv"],
                 cwd=tmp_path) as (proc, url):
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/", url), url  # loopback by default
        page = urllib.request.urlopen(url, timeout=300).read().decode()
        assert "<html" in page.lower()
        out, err = stop_serve(proc)
    assert proc.returncode == 0, err
    assert "stopped" in out and "Traceback" not in err
    rows = (tmp_path / "res.csv").read_text().splitlines()
    assert rows[0].startswith("index,t,r1") and len(rows) >= 2


def test_the_page_fetches_nothing_from_the_internet():
    import viser

    page = (Path(viser.__file__).parent / "client" / "build" / "index.html").read_text()
    urls = set(re.findall(r"https?://[^\s\"'`)]+", page))
    assert urls <= {"http://www.w3.org/2000/svg"}, urls


def test_frames_runs_n_frames_prints_a_summary_and_exits_0(tmp_path):
    r = run_cli("--frames", "5", "--port", "0", "--max-speed", "--out-dir", str(tmp_path))
    assert r.returncode == 0, r.stderr
    summary = [line for line in r.stdout.splitlines() if "frames/s" in line]
    assert len(summary) == 1, r.stdout
    assert summary[0].startswith("tileviz serve: 5 frames in ")
    assert "statuses: " in summary[0] and "truth inside the set in" in summary[0]
    assert FAITHFUL_NOTE not in summary[0]  # the robust extractor's views keep their bounds
    assert "Traceback" not in r.stderr
    # the address once, when the first frame is shown: viser's own banner is not printed first
    assert r.stdout.splitlines()[0].startswith("tileviz serve: open http://127.0.0.1:")
    assert "Websocket" not in r.stdout


def slow_start_app(tmp_path: Path, release: threading.Event) -> App:
    """An app whose first frame is not rendered until ``release`` is set (as the first start
    after an install waits for the vision kernels to compile); it shows, once started, as
    ``app.starting`` is set."""
    from tileviz.sim.camera import FloorRenderer

    cfg = preset("default")

    class SlowFirstFrame(FloorRenderer):
        def render(self, *args, **kwargs):
            release.wait(300)
            return super().render(*args, **kwargs)

    return App(cfg, SessionOptions(out_dir=tmp_path, interactive=True,
                                   renderer=SlowFirstFrame(cfg.floor, cfg.camera)), port=0)


def wait_until_starting(a: App) -> None:
    """Wait until ``a``'s page is built (its first frame may still be in progress)."""
    for _ in range(1200):
        if getattr(a, "starting", None) is not None:
            return
        threading.Event().wait(0.05)


def test_the_page_says_it_is_starting_until_the_first_frame(tmp_path):
    """Until the first frame is computed (the first start compiles the vision kernels) the left
    panel says so in place of the empty set and camera view; the first push hides the note."""
    from tileviz.app.server import STARTING_NOTE

    release = threading.Event()  # the first frame takes as long as the test says
    a = slow_start_app(tmp_path, release)
    starter = threading.Thread(target=a.start)
    starter.start()
    try:
        wait_until_starting(a)
        assert a.starting.visible and a.starting.content == STARTING_NOTE
        assert "compiles the vision kernels" in STARTING_NOTE
        assert "starting" in a.controls.status.content
        release.set()
        starter.join(120)
        assert a.starting.visible is False  # the first frame is shown: the panels take over
    finally:
        release.set()
        starter.join(120)
        a.stop()


def test_ctrl_c_while_the_first_frame_is_made_stops_without_waiting_for_it(tmp_path):
    """Ctrl-C (serve's stop event) while the first frame is still being made (the first run
    after an install compiles the vision kernels for up to minutes) stops the app at once: the
    start returns False and the page is no longer served, while that frame is still held."""
    release = threading.Event()  # the first frame is not made until the test is done
    a = slow_start_app(tmp_path, release)
    cancel = threading.Event()
    result: list[bool] = []
    starter = threading.Thread(target=lambda: result.append(a.start(cancel=cancel)))
    starter.start()
    try:
        wait_until_starting(a)
        url = a.url
        urllib.request.urlopen(url, timeout=30).close()  # served while it starts
        cancel.set()
        starter.join(120)
        assert not starter.is_alive()
        assert result == [False]
        with pytest.raises(OSError):  # refused: no longer served
            urllib.request.urlopen(url, timeout=30).close()
    finally:
        release.set()
        starter.join(120)
        a.stop()


def test_a_stop_on_the_way_to_the_start_frame_closes_the_csv_after_the_frame_in_progress(
        tmp_path):
    """Ctrl-C while serve computes the frames up to ``--start-frame``: the start returns at once,
    the loop ends the frame in progress, computes no further one, and only then closes the CSV
    of residuals it writes a row to per frame: every row in it is whole."""
    from tileviz.sim.camera import FloorRenderer

    cfg = preset("default")
    release = threading.Event()
    frames: list[int] = []

    class SlowThirdFrame(FloorRenderer):
        def render(self, *args, **kwargs):
            frames.append(1)
            if len(frames) == 3:
                release.wait(300)
            return super().render(*args, **kwargs)

    a = App(cfg, SessionOptions(out_dir=tmp_path, interactive=True, output_file="res",
                                start_frame=50, renderer=SlowThirdFrame(cfg.floor, cfg.camera)),
            port=0)
    cancel = threading.Event()
    result: list[bool] = []
    starter = threading.Thread(target=lambda: result.append(a.start(cancel=cancel)))
    starter.start()
    try:
        for _ in range(2400):
            if len(frames) >= 3:
                break
            threading.Event().wait(0.05)
        cancel.set()
        starter.join(120)
        assert result == [False]
        assert a.session is not None and a.session.csv is not None  # its writer is mid-frame
        release.set()
        assert a._thread is not None
        a._thread.join(120)
        assert a.session.csv is None  # closed by the loop, after its frame
        assert len(frames) == 3  # no frame after the stop
        rows = (tmp_path / "res.csv").read_text(encoding="utf-8").splitlines()
        assert len(rows) == 1 + 3  # the header and one whole row per frame
        assert len({row.count(",") for row in rows}) == 1
    finally:
        release.set()
        starter.join(120)
        a.stop()


def test_frames_with_the_faithful_extractor_says_its_views_break_their_bounds(tmp_path):
    r = run_cli("--frames", "5", "--port", "0", "--max-speed", "--out-dir", str(tmp_path),
                "--extractor", "faithful")
    assert r.returncode == 0, r.stderr
    (summary,) = [line for line in r.stdout.splitlines() if "frames/s" in line]
    assert f"vouched for; {FAITHFUL_NOTE}" in summary


def test_a_requested_busy_port_is_one_line_and_the_default_says_where_it_went(tmp_path):
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        r = run_cli("--port", str(port), "--frames", "1", "--out-dir", str(tmp_path))
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and f"port {port} on 127.0.0.1 is busy" in lines[0], r.stderr
        assert "open http" not in r.stdout
        # without --port the server takes the next free one and says so
        app = App(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True),
                  port=port)
        app.start()
        try:
            assert app.port != port
        finally:
            app.stop()


def test_the_view_follows_the_robot_while_playing(tmp_path):
    a = App(preset("default"), SessionOptions(out_dir=tmp_path), port=0)
    a.start()
    try:
        async def scenario() -> None:
            async with ViserClient(a.url) as c:
                await c.wait_for(lambda m: m.get("type") == "ReplayDoneMessage")
                mark = len(c.messages)
                # the server moves this client's view: its look-at point goes with the robot
                m = await c.wait_for(lambda m: m.get("type") == "SetCameraLookAtMessage",
                                     start=mark, timeout=600)
                x, y = float(m["look_at"][0]), float(m["look_at"][1])
                path = [e.record.truth for e in map(a.session.history.get, range(
                    a.session.history.first, a.session.history.last + 1))]
                assert min(math.hypot(p.x - x, p.y - y) for p in path) < 1e-6

        asyncio.run(scenario())
    finally:
        a.stop()
