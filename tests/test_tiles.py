"""The observation model and the corrected equivalence (docs/method.md), shown on rendered views.

The views are made by a small exact rasterizer of the grout-line centres written here from the
conventions of docs/dataset-format.md (lines on x = kL and y = kL; image up = robot forward, image
left = robot left; pixel (row, col) sees the floor point c + R(theta) @ (a_forward, a_left) with
a_left = (cx - col) / ppm, a_forward = (cy - row) / ppm). It returns, for every pixel, the
distance of that floor point to the nearest line: two poses give the same view iff these maps
agree, and the binary "on a grout line" image follows.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from tileviz.config import CameraConfig, FloorConfig
from tileviz.core.tiles import (
    camera_centre,
    equivalence_residuals,
    equivalent_parameters,
    equivalent_pose,
    equivalent_poses,
    observe,
    quarter_turn,
    quarter_turns,
)
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Observation, Pose

FAST = settings(max_examples=100, deadline=None)

L = 0.2
PPM = 200.0
W, H = 80, 60  # a 0.4 m x 0.3 m view: both line families always cross it
GROUT = 0.01

coord = st.floats(-5.0, 5.0)
heading = st.floats(-10.0, 10.0)
offsets = st.sampled_from([(0.0, 0.0), (0.3, 0.0), (0.875, 0.0), (0.25, -0.1), (-0.2, 0.15)])


def _line_distance(pose: Pose, offset: tuple[float, float]) -> np.ndarray:
    """Per pixel, the distance (m) from the floor point it sees to the nearest grout line."""
    cx, cy = camera_centre(pose, offset)
    col, row = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    a_left = ((W - 1) / 2 - col) / PPM
    a_fwd = ((H - 1) / 2 - row) / PPM
    ct, st_ = math.cos(pose.theta), math.sin(pose.theta)
    px = cx + ct * a_fwd - st_ * a_left
    py = cy + st_ * a_fwd + ct * a_left
    dx = np.abs(px - L * np.round(px / L))
    dy = np.abs(py - L * np.round(py / L))
    return np.minimum(dx, dy)


def _view(pose: Pose, offset: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """The binary grout image (True on a line)."""
    return _line_distance(pose, offset) <= GROUT / 2


def _same_view(p: Pose, q: Pose, offset: tuple[float, float]) -> bool:
    d1 = _line_distance(p, offset)
    d2 = _line_distance(q, offset)
    # pixels within 1e-9 m of a grout edge may flip on rounding: require none of them to differ
    edge = np.abs(d1 - GROUT / 2) < 1e-9
    return bool(np.allclose(d1, d2, atol=1e-9) and np.array_equal(_view(p, offset)[~edge],
                                                                   _view(q, offset)[~edge]))


def _differs(p: Pose, q: Pose, offset: tuple[float, float]) -> int:
    """How many pixels of the binary views differ."""
    return int(np.count_nonzero(_view(p, offset) != _view(q, offset)))


def _circ(a: float, b: float, period: float) -> float:
    return abs(math.remainder(a - b, period))


# --- the observation ----------------------------------------------------------------------------


@FAST
@given(coord, coord, heading, offsets)
def test_observe_is_in_range_and_satisfies_the_design_relation(x, y, th, offset) -> None:
    pose = Pose(x, y, th)
    y1, y2, y3 = observe(pose, L, offset)
    assert 0.0 <= y1 < L and 0.0 <= y2 < L and -math.pi / 4 <= y3 < math.pi / 4
    m = quarter_turns(th)
    cx, cy = camera_centre(pose, offset)
    u1, u2 = quarter_turn(m, y1, y2)  # c == R(m pi/2) y (mod L)
    assert _circ(u1, cx, L) < 1e-9 and _circ(u2, cy, L) < 1e-9
    assert _circ(y3 + m * math.pi / 2, th, 2 * math.pi) < 1e-9


def test_camera_centre_follows_the_lever_arm() -> None:
    # heading north (pi/2): forward is +y, left is -x
    cx, cy = camera_centre(Pose(1.0, 2.0, math.pi / 2), (0.3, 0.1))
    assert cx == pytest.approx(0.9) and cy == pytest.approx(2.3)


def test_observe_a_quarter_turn_example() -> None:
    # camera centre (0.05, 0.13) on L = 0.2 tiles, heading 100 deg (m = 1):
    # (y1, y2) = R(-pi/2) c mod L = (c_y, -c_x) mod L = (0.13, 0.15), y3 = 10 deg
    y1, y2, y3 = observe(Pose(0.05, 0.13, math.radians(100)), L, (0.0, 0.0))
    assert (y1, y2) == pytest.approx((0.13, 0.15))
    assert y3 == pytest.approx(math.radians(10))


# --- the corrected equivalence, on rendered views -----------------------------------------------


@FAST
@given(coord, coord, heading, offsets, st.integers(0, 3), st.integers(-3, 3), st.integers(-3, 3))
def test_equivalent_poses_render_the_same_view(x, y, th, offset, m, kx, ky) -> None:
    pose = Pose(x, y, th)
    other = equivalent_pose(pose, m, L, offset, (kx, ky))
    assert _same_view(pose, other, offset)
    a = observe(pose, L, offset)
    b = observe(other, L, offset)
    assert _circ(a[0], b[0], L) < 1e-9 and _circ(a[1], b[1], L) < 1e-9
    assert a[2] == pytest.approx(b[2], abs=1e-9)
    if m:  # a true quarter/half turn: a different heading
        assert _circ(other.theta, th, 2 * math.pi) > 1.0


@FAST
@given(st.floats(0, L), st.floats(0, L), st.floats(-math.pi / 4, math.pi / 4))
def test_equivalent_parameters_describe_the_same_view(y1, y2, y3) -> None:
    # a parameter vector is a camera pose up to the lattice: c = (z1, z2), theta = z3
    base = Pose(y1, y2, y3)
    zs = equivalent_parameters((y1, y2, y3), L)
    assert len(zs) == 4
    for z in zs:
        assert _same_view(base, Pose(*z), (0.0, 0.0))
        assert 0.0 <= z[0] < L and 0.0 <= z[1] < L


@FAST
@given(st.floats(0, L), st.floats(0, L), st.floats(-math.pi / 4, math.pi / 4))
def test_the_original_theorem_1_pairs_give_different_views(y1, y2, y3) -> None:
    """Report eq. 3.9: y ~ z if (z1, z2) = (y1, y2), z3 = y3 + pi (a half turn as identity), or
    (z1, z2) = (y2, y1), z3 = y3 + pi/2 (a swap without the sign change). Both views differ from
    y's unless c sits on a symmetric spot (a line or a tile's mid-line), excluded here."""
    away = 0.02 * L

    def off_symmetric(v: float) -> bool:
        return min(_circ(v, 0.0, L / 2), L / 2 - _circ(v, 0.0, L / 2)) > away

    base = Pose(y1, y2, y3)
    # half turn treated as identity: same (y1, y2), heading + pi; the truth is (-y1, -y2)
    assume(off_symmetric(y1) or off_symmetric(y2))
    assert _differs(base, Pose(y1, y2, y3 + math.pi), (0.0, 0.0)) > 20
    assert _same_view(base, Pose(-y1, -y2, y3 + math.pi), (0.0, 0.0))
    # quarter turn with a plain swap: (y2, y1); the truth is R(pi/2) y = (-y2, y1)
    assume(off_symmetric(y2))
    assert _differs(base, Pose(y2, y1, y3 + math.pi / 2), (0.0, 0.0)) > 20
    assert _same_view(base, Pose(-y2, y1, y3 + math.pi / 2), (0.0, 0.0))


def test_the_original_theorem_fails_on_a_concrete_robot_pose() -> None:
    """The robot at (1.23, -0.41) heading 30 deg, camera 0.3 m ahead: turning the camera a quarter
    turn about the lattice with the plain swap the report uses gives another view; the corrected
    form gives the same view (and the same observation)."""
    offset = (0.3, 0.0)
    pose = Pose(1.23, -0.41, math.radians(30))
    cx, cy = camera_centre(pose, offset)
    th = pose.theta + math.pi / 2
    robot_at = lambda ax, ay: Pose(ax - 0.3 * math.cos(th), ay - 0.3 * math.sin(th), th)  # noqa: E731
    wrong = robot_at(cy, cx)
    right = robot_at(-cy, cx)
    assert _differs(pose, wrong, offset) > 100
    assert _same_view(pose, right, offset)
    assert observe(right, L, offset) == pytest.approx(observe(pose, L, offset), abs=1e-9)
    assert observe(wrong, L, offset) != pytest.approx(observe(pose, L, offset), abs=1e-3)
    assert right.as_tuple() == pytest.approx(equivalent_pose(pose, 1, L, offset).as_tuple())


def test_equivalent_poses_lists_the_four_turns() -> None:
    pose = Pose(0.3, 0.7, 0.2)
    poses = equivalent_poses(pose, L, (0.3, 0.0))
    assert [round(p.theta - pose.theta, 12) for p in poses] == [
        round(m * math.pi / 2, 12) for m in range(4)
    ]
    assert poses[0] == pytest.approx(pose)
    for p in poses:
        assert _same_view(pose, p, (0.3, 0.0))


# --- the same with the simulator's renderer -----------------------------------------------------

_PLAIN_FLOOR = FloorConfig(tile_size=L, grout_width=0.012, tile_brightness_jitter=0.0,
                           texture_strength=0.0, stains_per_tile=0.0)
"""A floor without appearance marks (they would break the symmetry the theorem is about)."""


def _renderer(offset: tuple[float, float]) -> FloorRenderer:
    cam = CameraConfig(ppm=PPM, width=W, height=H, offset=offset, noise_sigma=0.0,
                       blur_sigma=0.0, vignetting=0.0)
    return FloorRenderer(_PLAIN_FLOOR, cam)


@settings(max_examples=40, deadline=None)
@given(coord, coord, heading, offsets, st.integers(1, 3), st.integers(-2, 2), st.integers(-2, 2))
def test_renderer_equivalent_poses_give_the_same_image(x, y, th, offset, m, kx, ky) -> None:
    """FloorRenderer (noise, blur, vignetting off; anti-aliased lines in float32): a pose and its
    quarter-turned equivalent render the same image, up to one gray level of float32 rounding."""
    r = _renderer(offset)
    pose = Pose(x, y, th)
    a = r.render(pose).astype(int)
    b = r.render(equivalent_pose(pose, m, L, offset, (kx, ky))).astype(int)
    assert np.abs(a - b).max() <= 1


@pytest.mark.parametrize("pose", [Pose(1.23, -0.41, math.radians(30)), Pose(-2.0, 0.77, 2.5),
                                  Pose(0.31, 0.05, -1.2)])
def test_renderer_shows_the_original_theorem_is_wrong(pose) -> None:
    offset = (0.3, 0.0)
    r = _renderer(offset)
    base = r.render(pose).astype(int)
    cx, cy = camera_centre(pose, offset)

    def robot_at(ax: float, ay: float, th: float) -> Pose:
        return Pose(ax - 0.3 * math.cos(th), ay - 0.3 * math.sin(th), th)

    quarter = pose.theta + math.pi / 2
    half = pose.theta + math.pi
    # corrected: R(pi/2) c = (-c_y, c_x) and R(pi) c = -c give the same image
    assert np.abs(r.render(robot_at(-cy, cx, quarter)).astype(int) - base).max() <= 1
    assert np.abs(r.render(robot_at(-cx, -cy, half)).astype(int) - base).max() <= 1
    # the report's: a plain swap (c_y, c_x) for a quarter turn, the same c for a half turn
    for wrong in (robot_at(cy, cx, quarter), robot_at(cx, cy, half)):
        diff = np.abs(r.render(wrong).astype(int) - base)
        assert np.count_nonzero(diff > 50) > 100


# --- residuals for the --output-file CSV --------------------------------------------------------


@FAST
@given(coord, coord, heading, offsets)
def test_equivalence_residuals_one_triple_vanishes_for_a_right_observation(x, y, th, offset):
    pose = Pose(x, y, th)
    y1, y2, y3 = observe(pose, L, offset)
    r = equivalence_residuals(pose, Observation(y1, y2, y3, 0.0, 0.0), L, offset)
    assert len(r) == 6 and all(-1.0 <= v <= 1.0 for v in r)
    m = quarter_turns(th)
    zero, other = (r[:3], r[3:]) if m in (0, 2) else (r[3:], r[:3])
    assert max(abs(v) for v in zero) < 1e-9
    # r3 = sin(theta - y3), r6 = cos(theta - y3): the report's own heading terms
    assert r[2] == pytest.approx(math.sin(th - y3), abs=1e-12)
    assert r[5] == pytest.approx(math.cos(th - y3), abs=1e-12)
    assert abs(other[2]) == pytest.approx(1.0, abs=1e-9)  # the other family's heading term


def test_residuals_with_the_original_signs_do_not_vanish() -> None:
    # heading 100 deg (m = 1): the corrected swapped triple vanishes; the original's swapped
    # triple, sin(pi (c_x - y2) / L), sin(pi (c_y - y1) / L), does not
    pose = Pose(0.05, 0.13, math.radians(100))
    y1, y2, y3 = observe(pose, L, (0.0, 0.0))
    r = equivalence_residuals(pose, Observation(y1, y2, y3, 0.0, 0.0), L, (0.0, 0.0))
    assert max(abs(v) for v in r[3:]) < 1e-12
    old = (math.sin(math.pi * (pose.x - y2) / L), math.sin(math.pi * (pose.y - y1) / L))
    assert max(abs(v) for v in old) > 0.5


def test_residuals_pick_the_nearest_branch_of_each_family() -> None:
    # heading 180 deg + 5 deg (m = 2): the direct triple uses u = R(-pi) c = -c
    pose = Pose(0.07, 0.11, math.pi + 0.0873)
    y1, y2, y3 = observe(pose, L, (0.0, 0.0))
    r = equivalence_residuals(pose, Observation(y1, y2, y3, 0.0, 0.0), L, (0.0, 0.0))
    assert max(abs(v) for v in r[:3]) < 1e-12
    wrong = equivalence_residuals(
        pose, Observation(y1 + 0.03, y2, y3, 0.0, 0.0), L, (0.0, 0.0)
    )
    assert abs(wrong[0]) == pytest.approx(math.sin(math.pi * 0.03 / L), abs=1e-9)
