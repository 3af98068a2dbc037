"""Floor styles (light grout, wide grout, a photograph on the tiles, uneven lighting): the
renderer draws them, the robust extractor reads them within its declared bounds, ``record``
takes ``--floor-style`` and the demo restarts with one."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tileviz.app import commands as C
from tileviz.app.session import Session
from tileviz.cli import main
from tileviz.config import FLOOR_STYLES, PERFECT_FLOOR, floor_style, preset, with_floor_style
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision import extract, observation_error


@pytest.mark.parametrize("name", FLOOR_STYLES)
def test_every_floor_style_is_read_within_the_declared_bound(name: str) -> None:
    """Each style, its floor declared as the style makes it (kind, lattice tolerance): most of
    its views are read, each within its own bound (the mosaic's seams, darker and wider than
    its grout, included)."""
    cfg = with_floor_style(preset("default"), name)
    r = FloorRenderer(cfg.floor, cfg.camera)
    rng = np.random.default_rng(11)
    accepted = 0
    for _ in range(6):
        pose = Pose(*rng.uniform(-9, 9, 2), rng.uniform(-4, 4))
        res = extract(r.render(pose, rng), camera=cfg.camera, tile_size=1.0, vision=cfg.vision,
                      floor=cfg.floor.model)
        if res.accepted:
            accepted += 1
            e = observation_error(res.observation, pose, 1.0, cfg.camera.offset)
            assert max(abs(e[0]), abs(e[1])) <= res.observation.position_error
            assert abs(e[2]) <= res.observation.heading_error
    assert accepted >= 3, name


def test_a_checkerboard_is_read_when_declared_and_recognised_when_not() -> None:
    """Light and dark tiles edge to edge, no grout: declared ``checker``, read from the edge
    image within the bound; undeclared, recognised from its tile edges and read alike."""
    cfg = with_floor_style(preset("default"), "checker")
    r = FloorRenderer(cfg.floor, cfg.camera)
    rng = np.random.default_rng(5)
    for model in (cfg.floor.model, PERFECT_FLOOR):
        accepted = 0
        for _ in range(6):
            pose = Pose(*rng.uniform(-9, 9, 2), rng.uniform(-4, 4))
            res = extract(r.render(pose, rng), camera=cfg.camera, tile_size=1.0,
                          vision=cfg.vision, floor=model)
            if res.accepted:
                accepted += 1
                e = observation_error(res.observation, pose, 1.0, cfg.camera.offset)
                assert max(abs(e[0]), abs(e[1])) <= res.observation.position_error
                assert abs(e[2]) <= res.observation.heading_error
        assert accepted >= 5, model


def test_styles_change_what_the_camera_sees() -> None:
    cfg = preset("default")
    pose = Pose(0.4, 0.3, 0.2)
    imgs = {n: FloorRenderer(floor_style(cfg.floor, n), cfg.camera).render(pose).mean(axis=2)
            for n in FLOOR_STYLES}
    # light grout: the grout pixels (the darkest in the default) are the brightest
    dark = imgs["default"] < np.percentile(imgs["default"], 2)
    assert imgs["light_grout"][dark].mean() > np.percentile(imgs["light_grout"], 90)
    assert (imgs["wide_grout"] < 150).mean() > 2.5 * (imgs["default"] < 150).mean()
    assert imgs["photo"].std() > 1.3 * imgs["default"].std()
    left, right = imgs["gradient"][:, :40].mean(), imgs["gradient"][:, -40:].mean()
    assert left > 1.3 * right
    with pytest.raises(ValueError, match="floor style"):
        floor_style(cfg.floor, "marble")


def test_record_writes_the_floor_style(tmp_path) -> None:
    out = tmp_path / "ds"
    assert main("record", [str(out), "--duration", "0.2", "--floor-style", "light_grout",
                 "--quiet"]) == 0
    meta = json.loads((out / "meta.json").read_text())
    assert tuple(meta["tileviz_config"]["floor"]["grout_rgb"]) == (228, 226, 220)


def test_the_demo_restarts_with_a_floor_style_and_back() -> None:
    s = Session(preset("default"))
    s.apply(C.Restart(1.0, 200.0, "wide_grout"))
    assert s.cfg.floor.grout_width == pytest.approx(0.05)
    s.apply(C.Restart(0.5, 300.0, "default"))
    assert s.cfg.floor == preset("default").floor.__class__(tile_size=0.5)
    assert s.cfg.vision == preset("default").vision
    with pytest.raises(ValueError, match="floor style"):
        C.Restart(1.0, 200.0, "marble")


def test_record_refuses_a_grout_floor_without_grout(tmp_path, capsys) -> None:
    """``--floor-kind grout`` over the checker style (tiles edge to edge, no grout) would draw
    a floor with no visible lattice: one line naming the problem, nothing written."""
    out = tmp_path / "ds"
    assert main("record", [str(out), "--duration", "0.2", "--floor-style", "checker",
                           "--floor-kind", "grout"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--floor-kind grout: this floor has no grout" in err[0]
    assert not out.exists()
