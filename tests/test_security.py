"""What a page visitor can make the demo server do (issue 33, SECURITY.md): pages of other sites
are not served, typed text and waypoints are bounded, notes stay one short line, a recording
stops before the disk fills, and listening beyond this machine is said."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from tileviz.app import commands as C
from tileviz.app.guard import is_loopback, origin_problem
from tileviz.app.session import MAX_NOTE, Session, SessionOptions
from tileviz.config import preset


@pytest.mark.parametrize(("origin", "host", "loopback_only", "served"), [
    (None, "127.0.0.1:8080", True, True),  # a program, not a page
    ("http://127.0.0.1:8080", "127.0.0.1:8080", True, True),  # the page this server served
    ("http://localhost:8080", "localhost:8080", True, True),
    ("http://[::1]:8080", "[::1]:8080", True, True),
    ("https://evil.example", "127.0.0.1:8080", True, False),  # another site's page
    ("http://127.0.0.1:9999", "127.0.0.1:8080", True, False),  # another local server's page
    ("http://evil.example:8080", "evil.example:8080", True, False),  # DNS rebinding
    ("null", "127.0.0.1:8080", True, False),  # a file or a sandboxed frame
    ("chrome-extension://abc", "127.0.0.1:8080", True, False),
    ("http://robot.lan:8080", "robot.lan:8080", False, True),  # --host 0.0.0.0, its own page
    ("http://evil.example", "robot.lan:8080", False, False),
])
def test_which_pages_are_served(origin, host, loopback_only, served) -> None:
    assert (origin_problem(origin, host, loopback_only=loopback_only) is None) == served


def test_loopback_names() -> None:
    assert all(map(is_loopback, ["127.0.0.1", "127.8.0.1", "::1", "[::1]", "localhost"]))
    assert not any(map(is_loopback, ["0.0.0.0", "::", "192.168.1.2", "example.com", ""]))


@pytest.mark.slow
def test_a_page_of_another_site_is_closed_before_it_is_served(tmp_path: Path) -> None:
    import websockets

    from tileviz.app.server import App
    from tileviz.testing.wsclient import subprotocol

    app = App(preset("default"), SessionOptions(out_dir=tmp_path, interactive=True), port=0)
    app.start()
    url = f"ws://127.0.0.1:{app.port}"

    async def visit(origin: str | None) -> tuple[int | None, int]:
        headers = {"Origin": origin} if origin else {}
        async with websockets.connect(url, subprotocols=[subprotocol()], max_size=None,
                                      compression=None, additional_headers=headers) as ws:
            got = 0
            try:
                while got < 3:
                    await asyncio.wait_for(ws.recv(), timeout=120)
                    got += 1
            except websockets.exceptions.ConnectionClosed:
                pass
            return ws.close_code, got

    try:
        code, got = asyncio.run(visit("https://evil.example"))
        assert code == 1008 and got == 0  # closed, nothing sent
        for origin in (None, f"http://127.0.0.1:{app.port}"):
            code, got = asyncio.run(visit(origin))
            assert got == 3  # served: the scene comes
        deadline = 100
        while deadline and not any("refused a websocket connection" in n.text
                                   for n in app.session.notes):
            asyncio.run(asyncio.sleep(0.1))
            deadline -= 1
        assert any("a page of https://evil.example is not this server's" in n.text
                   for n in app.session.notes)
    finally:
        app.stop()


def test_typed_text_and_waypoints_are_bounded() -> None:
    with pytest.raises(ValueError, match="at most 1000 waypoints"):
        C.parse_waypoints("; ".join(f"{i}, 0" for i in range(C.MAX_WAYPOINTS + 1)))
    with pytest.raises(ValueError, match="at most 1000 waypoints"):
        C.SetWaypoints(tuple((float(i), 0.0) for i in range(C.MAX_WAYPOINTS + 1)))
    with pytest.raises(ValueError, match="at most 20000 are read"):
        C.parse_waypoints("1, 2; " * 10_000)
    with pytest.raises(ValueError, match="at most 20000 are read"):
        C.parse_region("1 " * 20_000)
    with pytest.raises(ValueError, match="at most 20000 are read"):
        C.StartRecording("x" * 30_000)
    with pytest.raises(ValueError) as e:
        C.parse_waypoints("1, 2; " + "y" * 10_000)
    assert len(str(e.value)) < 120  # the bad piece is quoted, cut short
    assert len(C.parse_waypoints("; ".join(f"{i}, 0" for i in range(1000)))) == 1000


def test_notes_are_one_short_line(tmp_path: Path) -> None:
    s = Session(preset("default"), SessionOptions(out_dir=tmp_path, display=False))
    s.note("first\nsecond\r\nthird\x1b[31m" + "z" * 5000, "info")
    text = s.notes[-1].text
    assert "\n" not in text and "\r" not in text and "\x1b" not in text
    assert len(text) <= MAX_NOTE and text.startswith("first second third\\x1b[31mzz")
    s.close()


def test_a_recording_stops_before_the_disk_fills(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    import tileviz.app.recorder as recorder
    from tileviz.datasets import DatasetSource

    free = [10 << 30]
    monkeypatch.setattr(recorder, "free_bytes", lambda path: free[0])
    s = Session(preset("default"), SessionOptions(out_dir=tmp_path, display=False))
    s.apply(C.StartRecording("visitor"))
    for _ in range(25):
        s.compute()
    assert s.recorder.writer is not None and s.recorder.writer.count == 25
    free[0] = 200 << 20  # the disk is filling up
    for _ in range(30):
        s.compute()
    assert s.recorder.writer is None  # stopped at the next look, frame 40
    assert "recorded 40 frames" in s.notes[-1].text and "left free on its disk" in s.notes[-1].text
    assert s.notes[-1].level == "error"
    src = DatasetSource(tmp_path / "visitor")
    assert len(list(src)) == 40 and src.ended_early is None  # closed: a whole dataset
    with pytest.raises(ValueError, match="no room to export"):
        s.recorder.export_mcap()
    s.apply(C.StartRecording("again"))
    s.compute()
    assert s.recorder.writer is None and "cannot record" in s.notes[-1].text
    assert not (tmp_path / "again").exists()
    s.close()


@pytest.mark.slow
def test_listening_beyond_this_machine_is_said(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    from tileviz.app.serve_cli import main

    assert main("serve", ["--frames", "1", "--port", "0", "--out-dir", str(tmp_path)]) == 0
    assert "beyond this machine" not in capsys.readouterr().out
    assert main("serve", ["--frames", "1", "--port", "0", "--host", "0.0.0.0",
                          "--out-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert ("listening on 0.0.0.0 port" in out and "beyond this machine: anyone who can reach "
            "it can drive the run" in out)
