"""The 3-D scene: the floor looks like the simulated floor, the camera footprint is where the camera
looks, the interval sets are drawn from a fixed pool of nodes, layers hide."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from tileviz.app.scene import (
    TRAIL_WIDTH,
    SceneView,
    floor_texture,
    grid_colour,
    ribbon_centreline,
    tile_grid,
    yaw_wxyz,
)
from tileviz.config import CameraConfig, FloorConfig, preset
from tileviz.sim.camera import FloorRenderer, floor_point
from tileviz.types import Box, BoxSet, Pose


@pytest.fixture(scope="module")
def server():
    import viser

    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()


def test_floor_texture_is_the_simulated_floor_north_up_from_row_0_south():
    floor = FloorConfig(tile_size=1.0, grout_width=0.03)
    half = 3.0
    tex = floor_texture(floor, half, max_pixels=600)
    n = tex.shape[0]
    assert tex.shape == (n, n, 3) and tex.dtype == np.uint8
    ppm = n / (2 * half)

    def pixel(x: float, y: float) -> tuple[int, int]:
        """(row, col) of world (x, y): column grows east, row grows north."""
        return (int(round(y * ppm + (n - 1) / 2)), int(round(x * ppm + (n - 1) / 2)))

    # grout lines on x = kL and y = kL are dark, tile centres are light
    for k in (-2, -1, 0, 1, 2):
        r, c = pixel(k * 1.0, 0.5)
        r2, c2 = pixel(k * 1.0 + 0.5, 0.5)
        assert tex[r, c].mean() < tex[r2, c2].mean() - 40
        r, c = pixel(0.5, k * 1.0)
        r2, c2 = pixel(0.5, k * 1.0 + 0.5)
        assert tex[r, c].mean() < tex[r2, c2].mean() - 40
    # and every texel is what the simulator's camera sees there (same stains and brightness):
    # a 41x41 camera heading north at (x, y) sees the texture patch, rows flipped (image up =
    # north, texture row 0 = south)
    cam = CameraConfig(ppm=ppm, width=41, height=41, offset=(0.0, 0.0), noise_sigma=0.0,
                       blur_sigma=0.0, vignetting=0.0)
    renderer = FloorRenderer(floor, cam)
    for x, y in ((0.37, -1.21), (-2.2, 1.9), (1.45, 0.05)):
        r, c = pixel(x, y)
        cx, cy = (c - (n - 1) / 2) / ppm, (r - (n - 1) / 2) / ppm
        view = np.clip(renderer.floor_image(Pose(cx, cy, math.pi / 2)), 0, 255)
        patch = tex[r - 20: r + 21, c - 20: c + 21][::-1].astype(float)
        assert np.abs(patch - view).max() <= 1.0


def test_camera_footprint_is_the_image_outline_on_the_floor(server):
    cfg = preset("default")
    view = SceneView(server.scene, pool=4)
    view.set_world(cfg, path=[(0.0, 0.0), (1.0, 1.0)], waypoints=[(1.0, 1.0)],
                   setpoint_kind="lissajous")
    seg = np.asarray(view.footprint.points, float)  # robot frame (x forward, y left)
    corners = {tuple(np.round(p[:2], 6)) for p in seg[:, 0]}
    cam = cfg.camera
    robot = Pose(0.0, 0.0, 0.0)  # robot frame = world frame
    want = {tuple(np.round(floor_point(c, r, robot, cam), 6))
            for c in (-0.5, cam.width - 0.5) for r in (-0.5, cam.height - 0.5)}
    assert corners == want


def test_the_tile_grid_draws_the_grout_lines_across_the_room(server):
    cfg = preset("default")
    half, size = cfg.sim.room_half_size, cfg.floor.tile_size
    seg = tile_grid(size, half, 0.002)
    n = len(seg) // 2
    ks = np.arange(-half, half + size / 2, size)
    assert np.allclose(seg[:n, 0, 0], ks) and np.allclose(seg[:n, 1, 0], ks)  # x = kL
    assert np.allclose(seg[:n, :, 1], [-half, half])  # ... across the room
    assert np.allclose(seg[n:, 0, 1], ks) and np.allclose(seg[n:, :, 0], [-half, half])
    assert np.allclose(seg[:, :, 2], 0.002)
    # a tile size that does not divide the room: the lines inside it only
    odd = tile_grid(0.7, 2.0, 0.0)
    assert np.allclose(odd[: len(odd) // 2, 0, 0], [-1.4, -0.7, 0.0, 0.7, 1.4])
    # drawn as one node in the grout colour, or in the tile colour when the grout is the lighter
    view = SceneView(server.scene, pool=1)
    view.set_world(cfg, path=[(0.0, 0.0), (1.0, 1.0)], waypoints=[(1.0, 1.0)],
                   setpoint_kind="lissajous")
    assert np.allclose(view.grid.points, seg)
    assert grid_colour(cfg.floor) == cfg.floor.grout_rgb
    light = FloorConfig(tile_rgb=(96, 92, 86), grout_rgb=(228, 226, 220))
    assert grid_colour(light) == (96, 92, 86)


TRUTH = Pose(1.0, 2.0, 0.5)


def record(updated: BoxSet, predicted: BoxSet | None = None) -> SimpleNamespace:
    return SimpleNamespace(truth=TRUTH, predicted=predicted or updated, updated=updated,
                           setpoint=(3.0, -1.0))


def test_interval_sets_use_a_fixed_pool_of_nodes(server):
    view = SceneView(server.scene, pool=4)
    view.apply_layers({"boxes": True, "prediction": True, "wedge": True}, force=True)
    nodes_before = len(server.scene._handle_from_node_name)
    three = BoxSet((Box(0, 1, 0, 1, 0, 0.1), Box(2, 2.5, 0, 1, 0, 0.1), Box(4, 5, 4, 6, 0, 0.1)))
    empty_trail = np.full((3, 2), np.nan)
    view.show(record(three), empty_trail, empty_trail)
    boxes, _ = view.sets["boxes"]
    assert [b.visible for b in boxes] == [True, True, True, False]
    assert tuple(boxes[1].position[:2]) == (2.25, 0.5)
    assert tuple(boxes[2].dimensions[:2]) == (1.0, 2.0)
    six = BoxSet(tuple(Box(i, i + 0.5, 0, 1, 0, 0.1) for i in range(6)))
    view.show(record(six), empty_trail, empty_trail)
    assert all(b.visible for b in boxes)
    last = boxes[3]  # the pool's last node shows the hull of the boxes that did not fit
    assert tuple(last.position[:2]) == (4.25, 0.5) and tuple(last.dimensions[:2]) == (2.5, 1.0)
    view.show(record(BoxSet((Box(0, 1, 0, 1, 0, 0.1),))), empty_trail, empty_trail)
    assert [b.visible for b in boxes] == [True, False, False, False]
    for _ in range(20):
        view.show(record(three), np.random.rand(50, 2), np.random.rand(50, 2))
    assert len(server.scene._handle_from_node_name) == nodes_before  # nothing new per frame
    # the robot and the pink truth arrow stand on the true pose
    assert tuple(view.robot.position) == (1.0, 2.0, 0.0)
    assert np.allclose(view.truth.wxyz, yaw_wxyz(0.5))
    assert tuple(view.setpoint.position[:2]) == (3.0, -1.0)


def test_heading_wedge_spans_the_heading_interval(server):
    view = SceneView(server.scene, pool=2)
    hull = Box(0.0, 0.2, 1.0, 1.2, 0.3, 0.9)
    trail = np.zeros((2, 2))
    view.show(record(BoxSet((hull,))), trail, trail)
    v = np.asarray(view.wedge.vertices, float)
    assert np.allclose(v[0, :2], (0.1, 1.1), atol=1e-6)
    angles = np.arctan2(v[1:, 1] - 1.1, v[1:, 0] - 0.1)
    assert math.isclose(angles.min(), 0.3, abs_tol=1e-5)
    assert math.isclose(angles.max(), 0.9, abs_tol=1e-5)


def test_hidden_layers_stay_hidden(server):
    view = SceneView(server.scene, pool=3)
    view.apply_layers({"boxes": False, "robot": False, "trails": True}, force=True)
    trail = np.zeros((2, 2))
    view.show(record(BoxSet((Box(0, 1, 0, 1, 0, 0.1),))), trail, trail)
    boxes, outline = view.sets["boxes"]
    assert not any(b.visible for b in boxes) and not outline.visible
    assert not view.body.visible and not any(w.visible for w in view.wheels)
    view.apply_layers({"boxes": True, "robot": True, "trails": True})
    view.show(record(BoxSet((Box(0, 1, 0, 1, 0, 0.1),))), trail, trail)
    assert boxes[0].visible and outline.visible and view.body.visible


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    """z of the cross product of two vectors' (x, y) parts."""
    return float(a[0] * b[1] - a[1] * b[0])


def test_trails_follow_the_past_positions(server):
    view = SceneView(server.scene, pool=1)
    truth = np.array([[0.0, 0.0], [1.0, 0.0], [np.nan, np.nan], [1.0, 1.0], [2.0, 1.0]])
    est = truth + 0.01
    view.show(record(BoxSet((Box(0, 1, 0, 1, 0, 0.1),))), truth, est)
    v = np.asarray(view.trail_truth.vertices, float)
    seg = ribbon_centreline(v)
    want = np.array([[[0.0, 0.0], [1.0, 0.0]], [[1.0, 1.0], [2.0, 1.0]]])
    drawn = np.array([s[:, :2] for s in seg if not np.allclose(s[0], s[1])])
    assert np.allclose(drawn, want, atol=1e-6)  # NaN breaks the line
    # each drawn segment is a flat quad TRAIL_WIDTH wide across its direction, facing up
    quads = v.reshape(-1, 4, 3)
    drawn_quads = [q for q, (a, b) in zip(quads, seg, strict=True) if not np.allclose(a, b)]
    for q in drawn_quads:
        assert np.hypot(*(q[3, :2] - q[0, :2])) == pytest.approx(TRAIL_WIDTH, abs=1e-6)
        assert _cross(q[1] - q[0], q[2] - q[0]) > 0  # counter-clockwise seen from above
    # the unused quads have no area (nothing drawn), and the head follows the newest segments
    areas = [abs(_cross(q[1] - q[0], q[2] - q[0])) for q in quads]
    assert sum(a > 0 for a in areas) == 2
    head = ribbon_centreline(view.head_truth.vertices)
    assert np.allclose([s[:, :2] for s in head if not np.allclose(s[0], s[1])], want, atol=1e-6)


def test_box_outlines_draw_the_shown_boxes_edges_only(server):
    view = SceneView(server.scene, pool=8)
    trail = np.zeros((2, 2))
    two = BoxSet((Box(0.0, 0.1, 0.0, 0.1, 0, 0.1), Box(1.0, 1.2, 1.0, 1.1, 0, 0.1)))
    view.show(record(two), trail, trail)
    _, outline = view.sets["boxes"]
    seg = np.asarray(outline.points, float)
    assert seg.shape == (8, 2, 3)  # 4 edges a box shown, not 4 x the pool
    corners = {tuple(np.round(p[:2], 6)) for p in seg.reshape(-1, 3)}
    assert corners == {(0.0, 0.0), (0.1, 0.0), (0.1, 0.1), (0.0, 0.1),
                       (1.0, 1.0), (1.2, 1.0), (1.2, 1.1), (1.0, 1.1)}


def test_a_click_ray_meets_the_floor_where_the_target_goes():
    from tileviz.app.gui import floor_point as hit

    assert hit((0.0, 0.0, 2.0), (1.0, 0.0, -1.0)) == pytest.approx((2.0, 0.0))
    assert hit((1.0, -1.0, 5.0), (0.0, 0.6, -0.8)) == pytest.approx((1.0, 2.75))
    assert hit((0.0, 0.0, 2.0), (1.0, 0.0, 0.2)) is None  # looking up: no floor
    assert hit((0.0, 0.0, -1.0), (0.0, 0.0, -1.0)) is None  # below the floor
    assert hit((0.0, 0.0, 2.0), (float("nan"), 0.0, -1.0)) is None


def test_mcl_particles_are_drawn_when_given_and_the_layer_is_on(server):
    from tileviz.app.history import ParticleView

    view = SceneView(server.scene, pool=1, particles=50)
    view.apply_layers({"particles": True}, force=True)
    pts = np.column_stack([np.linspace(0, 1, 40), np.linspace(2, 3, 40), np.zeros(40)])
    mcl = ParticleView(pts.astype(np.float32), np.array([0.5, 2.5, 0.0]),
                       np.zeros((65, 2), np.float32), True)
    trail = np.zeros((2, 2))
    view.show(record(BoxSet((Box(0, 1, 0, 1, 0, 0.1),))), trail, trail, mcl=mcl)
    drawn = np.asarray(view.particles.points, float)
    assert view.particles.visible and drawn.shape == (50, 3)
    assert np.allclose(drawn[:40, :2], pts[:, :2], atol=1e-6)
    assert np.allclose(drawn[40:, :2], (0.5, 2.5))  # the unused points sit on the mean
    view.show(record(BoxSet((Box(0, 1, 0, 1, 0, 0.1),))), trail, trail, mcl=None)
    assert not view.particles.visible and not view.ellipse.visible
    view.apply_layers({"particles": False})
    view.show(record(BoxSet((Box(0, 1, 0, 1, 0, 0.1),))), trail, trail, mcl=mcl)
    assert not view.particles.visible
