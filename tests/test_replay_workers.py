"""The replay's vision workers start warm: forked from a fork server that loaded the vision code
and the robust extractor's compiled kernels once (tileviz.pipeline.worker_start)."""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import pytest

from tileviz.config import Config
from tileviz.pipeline.workers import worker_context
from tileviz.vision import extract
from tileviz.vision.robust import (
    dip_kernel,
    fit_kernel,
    heading_kernel,
    kernel,
    lattice_kernel,
    projection_kernel,
)
from tileviz.vision.warmup import synthetic_view

KERNELS = ("part_profiles", "part_rows")
DIP_KERNELS = ("dip_rows", "part_summary", "part_layout", "dip_recentre")


PROJECTION_KERNELS = ("grout_score", "profile_arrays", "profile_dips", "view_spans")


HEADING_KERNELS = ("heading_magnitudes", "heading_votes", "kth_largest")
FIT_KERNELS = ("fit_arrays",)
LATTICE_KERNELS = ("clip_lines", "missing_line")


def _loaded_kernels() -> dict[str, int]:
    """How many compiled signatures each public kernel holds in this process."""
    out = {name: len(getattr(kernel, name).signatures) for name in KERNELS}
    out.update((name, len(getattr(dip_kernel, name).signatures)) for name in DIP_KERNELS)
    out.update((name, len(getattr(projection_kernel, name).signatures))
               for name in PROJECTION_KERNELS)
    out.update((name, len(getattr(heading_kernel, name).signatures)) for name in HEADING_KERNELS)
    out.update((name, len(getattr(fit_kernel, name).signatures)) for name in FIT_KERNELS)
    out.update((name, len(getattr(lattice_kernel, name).signatures)) for name in LATTICE_KERNELS)
    return out


@pytest.mark.parametrize("extractor", ["robust", "faithful"])
def test_warm_up_view_is_read_by_both_extractors(extractor: str) -> None:
    """The warm-up view is a floor both extractors accept, so warming up runs the whole robust
    chain (a refused view would stop before the later kernels)."""
    cfg = Config()
    res = extract(synthetic_view(cfg), camera=cfg.camera, tile_size=cfg.floor.tile_size,
                  vision=replace(cfg.vision, extractor=extractor))
    assert res.accepted, res.reason


@pytest.mark.skipif(sys.platform != "linux", reason="the fork server is used where it exists; "
                    "this test checks it on Linux")
def test_workers_start_with_the_kernels_loaded() -> None:
    """A worker of the replay's context holds every compiled kernel before its first frame."""
    ctx = worker_context()
    assert ctx.get_start_method() == "forkserver"
    with ProcessPoolExecutor(1, mp_context=ctx) as pool:
        loaded = pool.submit(_loaded_kernels).result(timeout=600)
    assert loaded == dict.fromkeys(
        KERNELS + DIP_KERNELS + PROJECTION_KERNELS + HEADING_KERNELS + FIT_KERNELS
        + LATTICE_KERNELS, 1)


def _parent_pid() -> int:
    import os

    return os.getppid()


@pytest.mark.skipif(sys.platform != "linux", reason="the fork server is used where it exists; "
                    "this test checks it on Linux")
def test_workers_come_from_the_server_started_ahead() -> None:
    """The replay command starts the workers' fork server before it loads anything else
    (start_worker_server); the replay's workers are then forked from that very server (not
    from a second one started at the pool), and starting it again keeps it."""
    from multiprocessing import forkserver

    from tileviz.pipeline.worker_server import start_worker_server

    assert start_worker_server()
    server = forkserver._forkserver._forkserver_pid
    assert server is not None
    assert start_worker_server()
    assert forkserver._forkserver._forkserver_pid == server
    with ProcessPoolExecutor(1, mp_context=worker_context()) as pool:
        assert pool.submit(_parent_pid).result(timeout=600) == server


def _runs_ok(code: str) -> None:
    """Run ``code`` in a fresh Python process (what is imported there is its own); it must
    succeed and print ``ok`` last."""
    import subprocess

    out = subprocess.run([sys.executable, "-c", code + "; print('ok')"], capture_output=True,
                         text=True, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1:] == ["ok"], out.stdout


def test_replay_main_process_does_not_load_the_extractor_kernels() -> None:
    """The main process of a replay with workers imports the frame loop and the dataset reader
    but not the robust extractor nor numba (about 0.4 s of CPU at every start): only the
    workers extract, and the extractor is imported on first use."""
    code = ("import sys, tileviz.cli, tileviz.pipeline.replay, tileviz.pipeline.workers; "
            "bad = [m for m in ('numba', 'tileviz.vision.robust') if m in sys.modules]; "
            "assert not bad, bad")
    _runs_ok(code)


def test_pipeline_package_loads_the_frame_loop_on_first_use() -> None:
    """Importing the workers' server module loads neither the frame loop nor OpenCV (so the
    replay command can start the server first thing), and the package's names still work."""
    code = ("import sys, tileviz.pipeline.worker_server as s; "
            "assert 'cv2' not in sys.modules and 'tileviz.pipeline.frame_loop' not in "
            "sys.modules, sorted(m for m in sys.modules if m.startswith(('cv2', 'tileviz'))); "
            "from tileviz.pipeline import FrameLoop, FrameRecord; "
            "import tileviz.pipeline.frame_loop as f; assert FrameLoop is f.FrameLoop")
    _runs_ok(code)


def test_extract_loads_the_kernels_before_its_first_image(tmp_path: Path) -> None:
    """``tileviz extract`` warms the robust extractor up before the first image, so that image's
    stage timings (``--json``) are its own and not the kernels' one-off loading: in a fresh
    process, when the command extracts its first image every kernel the replay's workers
    start with is loaded already."""
    import cv2

    image = tmp_path / "view.png"
    cv2.imwrite(str(image), synthetic_view(Config()))
    names = {"kernel": KERNELS, "dip_kernel": DIP_KERNELS,
             "projection_kernel": PROJECTION_KERNELS,
             "heading_kernel": HEADING_KERNELS, "fit_kernel": FIT_KERNELS,
             "lattice_kernel": LATTICE_KERNELS}
    loaded = " + ".join(f"[len(getattr({m}, n).signatures) for n in {v!r}]"
                        for m, v in names.items())
    code = ("from tileviz.vision.robust import kernel, dip_kernel, projection_kernel, "
            "heading_kernel, fit_kernel, lattice_kernel; import tileviz.vision.cli as cli; "
            "seen = []; "
            "real = cli.extract; "
            f"cli.extract = lambda *a, **k: (seen.append({loaded}), real(*a, **k))[1]; "
            f"status = cli.main('extract', [{str(image)!r}, '--json']); "
            "assert status == 0 and len(seen) == 1 and all(seen[0]), (status, seen)")
    _runs_ok(code)
