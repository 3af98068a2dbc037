"""The robust extractor's shortcuts change nothing: reusing one heading's warp and profiles when
a wide grout band asks for a wider window, and measuring in parts only the dips that can be
kept as lines, give the same result, field for field, as the full computation."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from tileviz.config import FLOOR_STYLES, VisionConfig, floor_style, preset
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision import extract
from tileviz.vision.robust import extractor, profiles

ROBUST = VisionConfig(extractor="robust")


def _same(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)  # type: ignore[union-attr]
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True
    return a == b


@pytest.mark.parametrize("preset_name", ["default", "seed"])
@pytest.mark.parametrize("style", list(FLOOR_STYLES))
def test_the_shortcuts_give_the_full_computation(
    monkeypatch: pytest.MonkeyPatch, preset_name: str, style: str
) -> None:
    cfg = preset(preset_name)
    floor = floor_style(cfg.floor, style)
    r = FloorRenderer(floor, cfg.camera)
    rng = np.random.default_rng(5)
    images = [r.render(Pose(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4)), rng)
              for _ in range(3)]

    def run_all() -> list:
        return [extract(img, camera=cfg.camera, tile_size=floor.tile_size, vision=ROBUST)
                for img in images]

    fast = run_all()
    full_measure = profiles.measure

    def measure_fully(run: object, y3: float, attempt: int = 1) -> list:
        return full_measure(run, y3, attempt, reuse=False, every=True)  # type: ignore[arg-type]

    monkeypatch.setattr(extractor, "measure", measure_fully)
    full = run_all()
    assert any(res.accepted for res in fast)
    for a, b in zip(fast, full, strict=True):
        for f in fields(a):
            if f.name != "timings":
                assert _same(getattr(a, f.name), getattr(b, f.name)), (style, f.name)
