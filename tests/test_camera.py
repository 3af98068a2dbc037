"""The downward camera: conventions of docs/dataset-format.md, sub-pixel line placement, the floor's
appearance fixed to the floor, camera effects, faults, and no pymunk."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.config import CameraConfig, FloorConfig
from tileviz.sim.camera import FAULT_KINDS, Fault, FloorRenderer, floor_point, pixel_of
from tileviz.types import Pose

PLAIN_FLOOR = FloorConfig(
    tile_size=1.0,
    grout_width=0.02,
    tile_brightness_jitter=0.0,
    texture_strength=0.0,
    stains_per_tile=0.0,
)
CLEAN_CAMERA = CameraConfig(
    ppm=200.0, width=320, height=240, offset=(0.3, 0.0), noise_sigma=0.0, blur_sigma=0.0,
    vignetting=0.0,
)


def _gray(img: np.ndarray) -> np.ndarray:
    return img.astype(np.float64).mean(axis=2)


def _dip_centre(profile: np.ndarray) -> float:
    """Sub-pixel centre of the single dark dip in a 1-D profile (centroid of the darkness)."""
    dark = profile.max() - profile
    dark[dark < 0.02 * dark.max()] = 0.0
    idx = np.arange(profile.size)
    return float((idx * dark).sum() / dark.sum())


def test_image_axes_follow_dataset_format() -> None:
    """Heading east: a grout line 0.1 m ahead of the camera centre is a row above the centre,
    one 0.15 m to the robot's left is a column left of the centre."""
    r = FloorRenderer(PLAIN_FLOOR, CLEAN_CAMERA)
    cx, cy = (CLEAN_CAMERA.width - 1) / 2.0, (CLEAN_CAMERA.height - 1) / 2.0
    img = _gray(r.render(Pose(2.6, 2.85, 0.0)))  # camera centre (2.9, 2.85)
    # x = 3: 0.1 m forward -> row cy - 20; y = 3: 0.15 m to the left -> column cx - 30
    col_profile = img[:, 40]  # a column far from the y = 3 line
    row_profile = img[200, :]  # a row far from the x = 3 line
    assert _dip_centre(col_profile) == pytest.approx(cy - 0.1 * 200.0, abs=0.05)
    assert _dip_centre(row_profile) == pytest.approx(cx - 0.15 * 200.0, abs=0.05)


def test_heading_north_turns_the_view() -> None:
    """Heading north: forward is +y, the robot's left is -x (west)."""
    r = FloorRenderer(PLAIN_FLOOR, CLEAN_CAMERA)
    # camera centre = (x, y) + R(pi/2) (0.3, 0) = (x, y + 0.3) = (3.1, 2.95)
    img = _gray(r.render(Pose(3.1, 2.65, math.pi / 2)))
    cx, cy = (CLEAN_CAMERA.width - 1) / 2.0, (CLEAN_CAMERA.height - 1) / 2.0
    # y = 3 is 0.05 m ahead: row cy - 10. x = 3 is 0.1 m to the west = to the left: col cx - 20
    assert _dip_centre(img[:, 40]) == pytest.approx(cy - 10.0, abs=0.05)
    assert _dip_centre(img[200, :]) == pytest.approx(cx - 20.0, abs=0.05)


@settings(max_examples=25, deadline=None)
@given(
    x=st.floats(-20, 20),
    y=st.floats(-20, 20),
    theta=st.floats(-4, 4),
    fwd=st.floats(-0.25, 0.25),
    left=st.floats(-0.3, 0.3),
)
def test_rendered_line_sits_at_its_projected_pixel(
    x: float, y: float, theta: float, fwd: float, left: float
) -> None:
    """For any pose, a grout line's centre in the image is within 0.05 px of the pixel that
    ``pixel_of`` projects it to (measured across the line, away from crossings)."""
    r = FloorRenderer(PLAIN_FLOOR, CLEAN_CAMERA)
    pose = Pose(x, y, theta)
    img = _gray(r.render(pose))
    # the floor point seen at (col0, row0) and the nearest line x = kL through it
    col0, row0 = 160.0 + left * 200.0, 120.0 - fwd * 200.0
    px, py = floor_point(col0, row0, pose, CLEAN_CAMERA)
    k = round(px)
    # the line x = k crosses the image: its pixels p(t) = pixel_of(k, py + t)
    a = np.array(pixel_of(k, py, pose, CLEAN_CAMERA))
    b = np.array(pixel_of(k, py + 0.1, pose, CLEAN_CAMERA))
    tangent = (b - a) / np.linalg.norm(b - a)
    normal = np.array([-tangent[1], tangent[0]])
    # stay inside the image, and away from the other family's lines (y = jL)
    if not (20 <= a[0] <= 299 and 20 <= a[1] <= 219):
        return
    if abs(py - round(py)) < 0.08:
        return
    offsets = np.arange(-12.0, 12.0, 0.25)
    pts = a[None, :] + offsets[:, None] * normal[None, :]
    vals = cv2.remap(
        img.astype(np.float32),
        pts[:, 0].astype(np.float32).reshape(1, -1),
        pts[:, 1].astype(np.float32).reshape(1, -1),
        cv2.INTER_LINEAR,
    ).ravel()
    centre = np.interp(_dip_centre(vals.astype(np.float64)), np.arange(offsets.size), offsets)
    assert abs(centre) < 0.08


@settings(max_examples=50, deadline=None)
@given(
    x=st.floats(-50, 50), y=st.floats(-50, 50), theta=st.floats(-10, 10),
    col=st.floats(-10, 330), row=st.floats(-10, 250),
)
def test_pixel_of_inverts_floor_point(x: float, y: float, theta: float, col: float,
                                      row: float) -> None:
    pose = Pose(x, y, theta)
    wx, wy = floor_point(col, row, pose, CLEAN_CAMERA)
    c2, r2 = pixel_of(wx, wy, pose, CLEAN_CAMERA)
    assert c2 == pytest.approx(col, abs=1e-6)
    assert r2 == pytest.approx(row, abs=1e-6)


def test_floor_appearance_is_fixed_to_the_floor() -> None:
    """Moving the camera by a whole number of pixels shifts the image by exactly that: tile
    brightness, texture and stains belong to the floor, not to the camera."""
    floor = FloorConfig(tile_size=0.5, stains_per_tile=2.0, texture_strength=0.1)
    r = FloorRenderer(floor, CLEAN_CAMERA)
    a = _gray(r.render(Pose(1.234, 0.567, 0.0)))
    b = _gray(r.render(Pose(1.234 + 7 / 200.0, 0.567, 0.0)))  # 7 px forward: content moves down
    assert np.abs(a[:-7, :] - b[7:, :]).max() <= 1.0
    c = _gray(r.render(Pose(1.234, 0.567 + 5 / 200.0, 0.0)))  # 5 px left: content moves right
    assert np.abs(a[:, :-5] - c[:, 5:]).max() <= 1.0


def test_floor_seed_changes_the_appearance_not_the_lines() -> None:
    r1 = FloorRenderer(FloorConfig(seed=1), CLEAN_CAMERA)
    r2 = FloorRenderer(FloorConfig(seed=2), CLEAN_CAMERA)
    pose = Pose(0.2, 0.3, 0.4)
    a, b = _gray(r1.render(pose)), _gray(r2.render(pose))
    assert np.abs(a - b).mean() > 2.0
    # the grout (darkest pixels) is at the same place
    assert np.mean((a < 120) == (b < 120)) > 0.995


def test_render_is_deterministic_and_noise_follows_the_rng() -> None:
    cam = replace(CLEAN_CAMERA, noise_sigma=4.0)
    r = FloorRenderer(FloorConfig(), cam)
    pose = Pose(0.0, 0.0, 0.3)
    assert np.array_equal(r.render(pose), r.render(pose))
    n1 = r.render(pose, np.random.default_rng(3))
    n2 = r.render(pose, np.random.default_rng(3))
    n3 = r.render(pose, np.random.default_rng(4))
    assert np.array_equal(n1, n2)
    assert not np.array_equal(n1, n3)
    diff = n1.astype(np.float64) - r.render(pose).astype(np.float64)
    assert 3.0 < diff.std() < 5.0  # noise_sigma = 4 gray levels (clipping aside)


def test_output_format_and_camera_effects() -> None:
    pose = Pose(0.1, 0.2, 0.3)
    cam = replace(CLEAN_CAMERA, width=200, height=120)
    img = FloorRenderer(FloorConfig(), cam).render(pose)
    assert img.shape == (120, 200, 3) and img.dtype == np.uint8
    # vignetting darkens the corners
    plain = _gray(FloorRenderer(PLAIN_FLOOR, CLEAN_CAMERA).render(pose))
    vig = _gray(FloorRenderer(PLAIN_FLOOR, replace(CLEAN_CAMERA, vignetting=0.3)).render(pose))
    assert vig[:10, :10].mean() < 0.8 * plain[:10, :10].mean()
    assert vig[115:125, 155:165].mean() == pytest.approx(plain[115:125, 155:165].mean(), rel=0.02)
    # blur softens the grout's edges, keeps the mean
    blur = _gray(FloorRenderer(PLAIN_FLOOR, replace(CLEAN_CAMERA, blur_sigma=2.0)).render(pose))
    assert np.abs(np.diff(blur, axis=1)).max() < 0.5 * np.abs(np.diff(plain, axis=1)).max()
    assert blur.mean() == pytest.approx(plain.mean(), rel=0.01)
    # JPEG artefacts: close to the original, not equal
    jpg = FloorRenderer(FloorConfig(), replace(CLEAN_CAMERA, jpeg_quality=30)).render(pose)
    orig = FloorRenderer(FloorConfig(), CLEAN_CAMERA).render(pose)
    err = np.abs(jpg.astype(int) - orig.astype(int))
    assert 0 < err.mean() < 6


def test_renderer_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="floor"):
        FloorRenderer("floor", CLEAN_CAMERA)  # type: ignore[arg-type]
    r = FloorRenderer(FloorConfig(), CLEAN_CAMERA)
    with pytest.raises(ValueError, match="finite"):
        r.render(Pose(float("nan"), 0.0, 0.0))
    with pytest.raises(ValueError, match="unknown camera fault"):
        r.render(Pose(0, 0, 0), faults=[("smoke", {})])
    with pytest.raises(ValueError, match="unknown parameter"):
        r.render(Pose(0, 0, 0), faults=[("glare", {"colour": 1.0})])
    with pytest.raises(ValueError, match="finite"):
        r.render(Pose(0, 0, 0), faults=[Fault("cable", {"width": float("inf")})])
    with pytest.raises(ValueError, match="pair"):
        r.render(Pose(0, 0, 0), faults=["cable"])


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_every_fault_changes_the_view_deterministically(kind: str) -> None:
    r = FloorRenderer(FloorConfig(), CLEAN_CAMERA)
    pose = Pose(0.4, -0.2, 0.7)
    clean = r.render(pose)
    a = r.render(pose, np.random.default_rng(1), faults=[(kind, {})])
    b = r.render(pose, np.random.default_rng(1), faults=[Fault(kind)])
    assert np.array_equal(a, b)
    changed = np.abs(a.astype(int) - clean.astype(int)).max(axis=2) > 20
    assert changed.mean() > 0.01


def test_fault_geometry() -> None:
    r = FloorRenderer(PLAIN_FLOOR, CLEAN_CAMERA)
    pose = Pose(0.43, 0.41, 0.0)  # no grout line near the image centre
    base = _gray(r.render(pose))
    # a horizontal cable 30 px below the centre: normal (-sin 0, cos 0) = (0, 1) = down
    cab = _gray(r.render(pose, faults=[Fault("cable", {"angle": 0.0, "offset": 30.0,
                                                        "width": 6.0, "gray": 20.0})]))
    row = 119.5 + 30.0
    assert cab[int(row), 100] < 40 and abs(cab[int(row) - 8, 100] - base[int(row) - 8, 100]) < 1
    # a shadow darkens the half-plane beyond its edge by its strength
    sh = _gray(r.render(pose, faults=[Fault("shadow", {"angle": math.pi / 2, "offset": 0.0,
                                                        "strength": 0.5})]))
    # angle pi/2: the edge is vertical; normal (-1, 0): the shadow is on the left
    assert sh[60, 20] == pytest.approx(0.5 * base[60, 20], abs=2)
    assert sh[60, 300] == pytest.approx(base[60, 300], abs=1)
    glare = r.render(pose, faults=[Fault("glare", {"x": 160, "y": 120, "radius": 30})])
    assert glare[120, 160].min() == 255 and _gray(glare)[5, 5] == pytest.approx(base[5, 5],
                                                                                  abs=1)
    drop = r.render(pose, faults=[Fault("dropout", {"gray": 7})])
    assert (drop == 7).all()


def test_camera_module_does_not_import_pymunk() -> None:
    code = (
        "import sys; import tileviz.sim.camera, tileviz.vision; "
        "assert 'pymunk' not in sys.modules, 'pymunk imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=_repo())


def _repo() -> str:
    import pathlib

    return str(pathlib.Path(__file__).resolve().parents[1])


@pytest.mark.parametrize("m", [1, 2, 3])
def test_quarter_turned_pose_sees_the_same_floor(m: int) -> None:
    """docs/method.md's corrected equivalence, checked on rendered images (plain floor, no noise):
    the pose whose camera centre is R(m pi/2) c (plus a lattice shift) with heading
    theta + m pi/2 sees exactly the same image. The original report's Theorem 1 pairs a quarter
    turn with a plain swap (c_y, c_x) and treats a half turn as the identity: those poses see
    a different image."""
    r = FloorRenderer(PLAIN_FLOOR, CLEAN_CAMERA)
    pose = Pose(0.23, 0.71, 0.4)
    f, left = CLEAN_CAMERA.offset

    def pose_for(cx: float, cy: float, theta: float) -> Pose:
        ct, st_ = math.cos(theta), math.sin(theta)
        return Pose(cx - (f * ct - left * st_), cy - (f * st_ + left * ct), theta)

    c = (pose.x + f * math.cos(pose.theta), pose.y + f * math.sin(pose.theta))
    turned = {1: (-c[1], c[0]), 2: (-c[0], -c[1]), 3: (c[1], -c[0])}[m]
    theta = pose.theta + m * math.pi / 2
    same = pose_for(turned[0] + 3.0, turned[1] - 2.0, theta)
    base = _gray(r.render(pose))
    assert np.abs(_gray(r.render(same)) - base).max() <= 1.0
    # the report's version: a swap without the sign (m odd), the identity for a half turn
    wrong_c = (c[1], c[0]) if m % 2 else c
    wrong = pose_for(wrong_c[0] + 3.0, wrong_c[1] - 2.0, theta)
    assert np.abs(_gray(r.render(wrong)) - base).max() > 50.0
