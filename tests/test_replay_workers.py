"""The replay's vision workers start warm: forked from a fork server that loaded the vision code
and the robust extractor's compiled kernels once (tileviz.pipeline.worker_start)."""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import pytest

from tileviz.config import Config
from tileviz.pipeline.worker_start import synthetic_view
from tileviz.pipeline.workers import worker_context
from tileviz.vision import extract
from tileviz.vision.robust import kernel

KERNELS = ("dip_rows", "grout_score", "part_profiles", "part_rows", "part_summary",
           "profile_arrays", "profile_dips", "view_spans")


def _loaded_kernels() -> dict[str, int]:
    """How many compiled signatures each public kernel holds in this process."""
    return {name: len(getattr(kernel, name).signatures) for name in KERNELS}


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
@pytest.mark.skipif(not kernel.AVAILABLE, reason="numba not installed: no compiled kernels")
def test_workers_start_with_the_kernels_loaded() -> None:
    """A worker of the replay's context holds every compiled kernel before its first frame."""
    ctx = worker_context()
    assert ctx.get_start_method() == "forkserver"
    with ProcessPoolExecutor(1, mp_context=ctx) as pool:
        loaded = pool.submit(_loaded_kernels).result(timeout=600)
    assert loaded == dict.fromkeys(KERNELS, 1)
