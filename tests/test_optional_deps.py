"""Without the [ros] extra: the CLI's help works, and the commands that need it say so in one
line naming the fix."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tileviz.testing.extras import ROS_MODULES
from tileviz.testing.extras import WITHOUT_ROS as BLOCK


def _run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", BLOCK, *args], capture_output=True, text=True,
                          timeout=120, cwd=cwd)


def test_help_and_one_line_errors_without_the_ros_extra(tmp_path: Path) -> None:
    r = _run("--help")
    assert r.returncode == 0 and "import-bag" in r.stdout and "calibrate" in r.stdout
    assert _run("import-bag", "--help").returncode == 0
    r = _run("import-bag", str(tmp_path), str(tmp_path / "o"), "--image-topic", "/c",
             "--odom-topic", "/o", "--tile-size", "1", "--ppm", "200", "--camera-offset", "0,0",
             "--speed-error", "0", "--yaw-rate-error", "0", "--compass-error", "0")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1
    assert "needs the rosbags package: pip install -e '.[ros]'" in lines[0]
    ds = tmp_path / "ds"
    assert _run("record", str(ds), "--duration", "0.2", "--quiet").returncode == 0
    r = _run("replay", str(ds), "--out", str(tmp_path / "r.csv"), "--mcap",
             str(tmp_path / "r.mcap"), "--quiet", "--jobs", "1")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "pip install -e '.[ros]'" in lines[0]


def test_the_pages_mcap_button_is_greyed_with_the_install_line_without_the_extra(
        monkeypatch) -> None:
    import viser

    from tileviz.app.commands import LAYERS
    from tileviz.app.gui import Controls
    from tileviz.config import preset
    from tileviz.datasets.mcap_export import mcap_missing

    assert mcap_missing() is None  # the test extra has it
    for m in ROS_MODULES[1:]:  # the MCAP writer's
        monkeypatch.setitem(sys.modules, m, None)  # as if not installed
    line = mcap_missing()
    assert line is not None and "pip install -e '.[ros]'" in line and "--mcap" not in line
    server = viser.ViserServer(port=0, verbose=False)
    try:
        c = Controls(server, lambda cmd: None, preset("default"),
                     layers=dict.fromkeys(LAYERS, True), display=True,
                     playing=False)
        assert c.export.disabled and "not installed" in c.export.label
        assert c.export.hint == line
    finally:
        server.stop()


def test_a_bench_without_the_test_extra_names_it_in_one_line() -> None:
    """The vision study's photo floors need scikit-image (the test extra): without it, the bench
    says so in one line and exits 2, instead of a traceback."""
    block = ("import runpy, sys\n"
             "sys.modules['skimage'] = None  # as if not installed\n"
             "sys.argv = ['bench/vision_study.py', '--families', 'photo',\n"
             "            '--views-per-family', '1', '--corrupted-per-family', '0']\n"
             "runpy.run_path('bench/vision_study.py', run_name='__main__')\n")
    r = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True,
                       timeout=300, cwd=Path(__file__).resolve().parents[1])
    lines = r.stdout.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, (r.stdout, r.stderr[-2000:])
    assert "scikit-image is missing" in lines[0] and "pip install -e '.[test]'" in lines[0]
