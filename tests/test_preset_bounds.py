"""The presets' declared observation bounds hold on their own cameras (fixed seeds)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tileviz.config import preset
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision import extract, observation_error


@pytest.mark.parametrize("name", ["default", "seed"])
def test_every_accepted_view_is_inside_the_preset_bound(name: str) -> None:
    cfg = preset(name)
    rng = np.random.default_rng(2024)
    accepted = 0
    n = 150
    renderers = [FloorRenderer(replace(cfg.floor, seed=s), cfg.camera) for s in range(3)]
    for i in range(n):
        renderer = renderers[i % 3]
        pose = Pose(*rng.uniform(-20, 20, 2), rng.uniform(-math.pi, math.pi))
        r = extract(renderer.render(pose, rng), camera=cfg.camera,
                    tile_size=cfg.floor.tile_size, vision=cfg.vision)
        if r.observation is None:
            continue
        accepted += 1
        e = observation_error(r.observation, pose, cfg.floor.tile_size, cfg.camera.offset)
        assert max(abs(e[0]), abs(e[1])) <= r.observation.position_error, (i, pose, e)
        assert abs(e[2]) <= r.observation.heading_error, (i, pose, e)
    # the tight bound does not buy its precision by refusing the views
    assert accepted >= 0.9 * n
