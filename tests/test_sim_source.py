"""SimSource: the frame contract, reproducibility, and the commands the app loop sends between
frames (setpoints, kidnap, reset, noise, faults)."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

from tileviz.config import Config, NoiseConfig, preset
from tileviz.sim.sensors import prediction_encloses
from tileviz.sim.source import BlankRenderer, SimSource
from tileviz.types import FrameInput, Pose


class RecordingRenderer:
    """A fake camera that remembers the poses and faults it was asked to render."""

    def __init__(self) -> None:
        self.calls: list[tuple[Pose, object]] = []

    def render(self, pose: Pose, rng: np.random.Generator | None = None,
               faults: object = None) -> np.ndarray:
        self.calls.append((pose, faults))
        return np.zeros((8, 8, 3), np.uint8)


def _cfg(seed: int = 4, **sim: object) -> Config:
    cfg = preset("default")
    return replace(cfg, sim=replace(cfg.sim, seed=seed, **sim))


def _src(cfg: Config | None = None) -> SimSource:
    cfg = cfg or _cfg()
    return SimSource(cfg, renderer=BlankRenderer(cfg.camera.width, cfg.camera.height))


def _take(src: SimSource, n: int) -> list[FrameInput]:
    return list(itertools.islice(src, n))


def _take_steps(src: SimSource, n: int) -> list[tuple[FrameInput, object, tuple[str, ...]]]:
    """n frames, each with its true motion (StepTruth) and the faults active on it."""
    return [(f, src.last_step, src.last_faults) for f in itertools.islice(src, n)]


def _key(f: FrameInput) -> tuple:
    return (f.index, f.t, f.truth, f.odometry, f.compass, f.setpoint)


def _inside(a: FrameInput, b: FrameInput, noise: NoiseConfig) -> bool:
    return prediction_encloses(a.truth.as_tuple(), b.truth.as_tuple(), a.odometry,
                               noise.speed_error, noise.yaw_rate_error)


def test_frames_follow_the_dataset_contract() -> None:
    cam = RecordingRenderer()
    cfg = _cfg()
    src = SimSource(cfg, renderer=cam)
    frames = _take(src, 50)
    for k, f in enumerate(frames):
        assert f.index == k and f.t == pytest.approx(k * cfg.sim.dt)
        assert cam.calls[k][0] == f.truth  # image k is taken at pose k
        assert f.odometry is not None and f.odometry.dt == (k + 1) * cfg.sim.dt - k * cfg.sim.dt
    for a, b in itertools.pairwise(frames):
        assert _inside(a, b, cfg.noise)  # odometry k: the motion from pose k to pose k+1
    assert src.pose == src.last_step.end  # the world waits at pose 50
    # the true start lies within the declared initial error, and not exactly on it
    x0 = frames[0].truth.as_tuple()
    err = [abs(a - b) for a, b in zip(x0, cfg.sim.initial_pose, strict=True)]
    assert all(e <= b for e, b in zip(err, cfg.sim.initial_pose_error, strict=True))
    assert max(err) > 0


def test_the_same_seed_gives_the_same_run_and_another_seed_another() -> None:
    a = [_key(f) for f in _take(_src(_cfg(9)), 200)]
    b = [_key(f) for f in _take(_src(_cfg(9)), 200)]
    c = [_key(f) for f in _take(_src(_cfg(10)), 200)]
    assert a == b
    assert a != c


def test_reset_replays_the_run_exactly() -> None:
    src = _src()
    first = [_key(f) for f in _take(src, 100)]
    src.kidnap(3.0, 3.0, 1.0)
    src.inject("slip")
    _take(src, 20)
    src.reset()
    assert [_key(f) for f in _take(src, 100)] == first
    src.reset(seed=77)
    assert [_key(f) for f in _take(src, 100)] != first
    assert src.cfg.sim.seed == 77


def test_kidnap_teleports_and_the_odometry_does_not_know() -> None:
    src = _src()
    before = _take(src, 30)
    src.kidnap(2.5, -1.0, 0.3)
    labelled = _take_steps(src, 40)
    assert [faults for _, _, faults in labelled[:2]] == [("kidnap",), ()]
    after = [f for f, _, _ in labelled]
    assert after[0].truth == Pose(2.5, -1.0, 0.3)
    assert after[0].index == before[-1].index + 1
    assert not _inside(before[-1], after[0], src.cfg.noise)  # the jump is not in the odometry
    assert after[0].compass == pytest.approx(0.3, abs=src.cfg.noise.compass_error)
    # then it drives on normally, back toward the setpoint
    assert all(_inside(a, b, src.cfg.noise) for a, b in itertools.pairwise(after))
    sp = after[-1].setpoint
    assert math.dist(after[-1].truth.as_tuple()[:2], sp) < math.dist((2.5, -1.0), sp)


def test_setpoint_commands_act_between_frames() -> None:
    src = _src()
    a, w = src.cfg.sim.lissajous_amplitude, src.cfg.sim.lissajous_omega

    def lissajous(t: float) -> tuple[float, float]:
        ph = w * t + math.pi / 2
        return (a * math.cos(ph), a * math.sin(2 * ph))

    for f in _take(src, 20):
        assert f.setpoint == pytest.approx(lissajous(f.t))
    src.set_manual_target(1.5, 2.0)
    nxt = _take(src, 1)[0]
    assert nxt.setpoint == (1.5, 2.0)
    frames = _take(src, 600)
    assert math.dist(frames[-1].truth.as_tuple()[:2], (1.5, 2.0)) < 0.05
    src.set_waypoints([(0.0, 0.0), (-1.0, 0.0)])
    seen = {f.setpoint for f in _take(src, 800)}
    assert seen == {(0.0, 0.0), (-1.0, 0.0)}
    src.set_setpoint("lissajous")
    f = _take(src, 1)[0]
    assert f.setpoint == pytest.approx(lissajous(f.t))


def test_set_noise_changes_the_readings_from_the_next_frame() -> None:
    src = _src()
    _take(src, 10)
    src.set_noise(NoiseConfig(speed_error=0.0, yaw_rate_error=0.0, compass_error=0.0))
    for f, step, _ in _take_steps(src, 50):
        assert f.odometry.speed == step.speed and f.odometry.yaw_rate == step.yaw_rate
    assert src.cfg.noise.speed_error == 0.0


def test_slip_breaks_the_odometry_bound_for_its_window_only() -> None:
    src = _src()
    noise = src.cfg.noise
    _take(src, 60)  # get moving
    src.inject("slip", frames=10)
    window = _take_steps(src, 30)
    for i, (f, step, faults) in enumerate(window):
        off_v = abs(f.odometry.speed - step.speed)
        off_w = abs(f.odometry.yaw_rate - step.yaw_rate)
        if i < 10:
            assert faults == ("slip",)
            assert off_v > noise.speed_error and off_w > noise.yaw_rate_error
        else:
            assert faults == ()
            assert off_v <= noise.speed_error and off_w <= noise.yaw_rate_error
    frames = [f for f, _, _ in window]
    inside = [_inside(a, b, noise) for a, b in itertools.pairwise(frames)]
    assert not any(inside[:10]) and all(inside[10:])


def test_odometry_outliers_hit_exactly_the_injected_frames() -> None:
    src = _src()
    noise = src.cfg.noise
    _take(src, 40)
    src.inject("odometry_outlier", frames=3, speed=0.4, yaw_rate=0.3)
    offs = [(abs(f.odometry.speed - step.speed), abs(f.odometry.yaw_rate - step.yaw_rate))
            for f, step, _ in _take_steps(src, 10)]
    for i, (dv, dw) in enumerate(offs):
        if i < 3:
            assert 0.4 - noise.speed_error <= dv <= 0.4 + noise.speed_error
            assert 0.3 - noise.yaw_rate_error <= dw <= 0.3 + noise.yaw_rate_error
        else:
            assert dv <= noise.speed_error and dw <= noise.yaw_rate_error


def test_camera_faults_go_to_the_renderer_for_their_frames() -> None:
    cam = RecordingRenderer()
    src = SimSource(_cfg(), renderer=cam)
    _take(src, 2)
    src.inject("dropout", frames=3)
    src.inject("glare", frames=1, strength=0.8)
    _take(src, 5)
    faults = [c[1] for c in cam.calls]
    assert faults[:2] == [None, None]
    assert faults[2] == [("dropout", {}), ("glare", {"strength": 0.8})]
    assert faults[3] == faults[4] == [("dropout", {})]
    assert faults[5:] == [None, None]


def test_bad_commands_raise_one_clear_error() -> None:
    src = _src()
    with pytest.raises(ValueError, match="kidnap x"):
        src.kidnap(math.nan, 0.0, 0.0)
    with pytest.raises(ValueError, match="setpoint"):
        src.set_setpoint("spiral")
    with pytest.raises(ValueError, match="waypoint 1 y"):
        src.set_waypoints([(0.0, 0.0), (1.0, math.inf)])
    with pytest.raises(ValueError, match="at least one"):
        src.set_waypoints([])
    with pytest.raises(ValueError, match="frames"):
        src.inject("slip", frames=0)
    with pytest.raises(ValueError, match="unknown parameter"):
        src.inject("slip", speeed=1.0)
    with pytest.raises(ValueError, match="slip speed"):
        src.inject("slip", speed=-1.0)
    with pytest.raises(ValueError, match="unknown fault 'earthquake'"):
        src.inject("earthquake")
    with pytest.raises(ValueError, match="kidnap needs theta"):
        src.inject("kidnap", x=0.0, y=0.0)
    with pytest.raises(ValueError, match="seed"):
        src.reset(seed=-1)
    with pytest.raises(ValueError, match="noise"):
        src.set_noise({"speed_error": 1.0})  # type: ignore[arg-type]
    # the source keeps working after refused commands
    assert len(_take(src, 3)) == 3


def test_default_renderer_draws_the_floor_at_the_true_pose() -> None:
    cfg = _cfg()
    src = SimSource(cfg)
    frames = _take(src, 30)
    img = frames[0].image
    assert img.shape == (cfg.camera.height, cfg.camera.width, 3) and img.dtype == np.uint8
    assert img.std() > 1.0  # not blank
    assert not np.array_equal(frames[0].image, frames[-1].image)  # it moved
    # the image is the floor at the true pose (same render without noise, same pose)
    quiet = replace(cfg, camera=replace(cfg.camera, noise_sigma=0.0))
    src = SimSource(quiet)
    f = next(src)
    assert np.array_equal(f.image, src.renderer.render(f.truth))
    # a camera dropout of 3 frames: uniform frames, then the floor again
    src.inject("dropout", frames=3)
    drop = _take(src, 4)
    assert all(fr.image.std() == 0 for fr in drop[:3]) and drop[3].image.std() > 1.0
    with pytest.raises(ValueError, match="glare"):
        src.inject("glare", radius=-5.0)
    assert next(src).image.std() > 1.0  # refused at injection, the run goes on


class SpyRenderer:
    """The real floor renderer, remembering the poses and faults it was asked to draw."""

    def __init__(self, cfg: Config) -> None:
        from tileviz.sim.camera import FloorRenderer

        self.inner = FloorRenderer(cfg.floor, cfg.camera)
        self.calls: list[tuple[Pose, object]] = []

    def resolve_faults(self, faults: object, rng: np.random.Generator | None) -> object:
        return self.inner.resolve_faults(faults, rng)  # type: ignore[arg-type]

    def render(self, pose: Pose, rng: np.random.Generator | None = None,
               faults: object = None) -> np.ndarray:
        self.calls.append((pose, faults))
        return self.inner.render(pose, rng=rng, faults=faults)  # type: ignore[arg-type]


@pytest.mark.parametrize("kind", ["cable", "box", "shadow"])
def test_an_edge_fault_lies_still_on_the_floor_while_the_robot_moves(kind: str) -> None:
    """A cable (box edge, shadow edge) lasting many frames is drawn once, where it is, and then
    stays at the same place on the floor: its image position follows the robot's motion, its
    other parameters do not change."""
    from tileviz.sim.camera import edge_to_floor

    cfg = _cfg()
    cam = SpyRenderer(cfg)
    src = SimSource(cfg, renderer=cam)
    _take(src, 5)
    src.inject(kind, frames=30)
    _take(src, 31)
    drawn = [(pose, faults[0][1]) for pose, faults in cam.calls[5:35]]
    assert cam.calls[35][1] is None  # over after 30 frames
    first_pose, first = drawn[0]
    assert set(first) >= {"angle", "offset"}  # drawn once, all of them
    p0, q0 = edge_to_floor(first["angle"], first["offset"], first_pose, cfg.camera)
    nx, ny = -(q0[1] - p0[1]), q0[0] - p0[0]
    norm = math.hypot(nx, ny)
    for pose, params in drawn:
        assert {k: v for k, v in params.items() if k not in ("angle", "offset")} == \
            {k: v for k, v in first.items() if k not in ("angle", "offset")}
        p, q = edge_to_floor(params["angle"], params["offset"], pose, cfg.camera)
        # both points of the edge seen at this frame lie on the first frame's floor line
        for x, y in (p, q):
            assert abs(((x - p0[0]) * nx + (y - p0[1]) * ny) / norm) < 1e-9
    moved = math.hypot(drawn[-1][0].x - first_pose.x, drawn[-1][0].y - first_pose.y)
    assert moved > 0.05  # the robot did move: the edge moved across the image
    assert abs(drawn[-1][1]["offset"] - first["offset"]) + \
        abs(drawn[-1][1]["angle"] - first["angle"]) > 1e-3


def test_a_glare_or_blur_keeps_its_drawn_parameters_for_its_frames() -> None:
    cfg = _cfg()
    cam = SpyRenderer(cfg)
    src = SimSource(cfg, renderer=cam)
    src.inject("glare", frames=4)
    src.inject("motion_blur", frames=4, length=12.0)
    _take(src, 4)
    glares = [f[0][1] for _, f in cam.calls]
    blurs = [f[1][1] for _, f in cam.calls]
    assert all(g == glares[0] for g in glares) and {"x", "y", "radius"} <= set(glares[0])
    assert all(b == blurs[0] for b in blurs) and blurs[0]["length"] == 12.0
