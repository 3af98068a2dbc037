"""The 3-D scene of the live server: floor, robot, camera footprint, interval boxes, trails.

World frame (``docs/dataset-format.md``): metres, x east, y north, z up (viser's default up
direction). Every node is made once, with a fixed name, and then updated in place: a fixed pool
of box nodes for the interval sets (unused ones hidden), fixed-size ribbon meshes for the trails,
line-segment nodes for the outlines, a fixed-size mesh for the heading wedge. Nothing is created
per frame.

The long polylines (trails, path, waypoint loop) are flat ribbon meshes, one quad a segment, not
viser line segments: the browser draws a line-segment node as one instance a segment, and without
a GPU (software WebGL) every instance costs it on every frame, while a mesh is one draw whatever
its length (docs/demo.md, "Without a GPU"). Line segments remain for the few short outlines
(footprint, arrows, box outlines: as many segments as boxes shown).

Layers (drawing heights, metres): floor texture z = 0 (off by default: see
:func:`tile_grid`), tile grid 0.002, path 0.004, trails 0.006,
camera footprint 0.008, robot up to ~0.2, MCL particles 0.25, interval boxes above the robot at
0.26-0.28 (the boxes of a localized robot are centimetres wide and would hide under its body),
heading wedge 0.29, true pose arrow 0.31.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from tileviz.config import CameraConfig, Config, FloorConfig
from tileviz.types import Box, BoxSet, Pose

if TYPE_CHECKING:
    from viser import (
        BoxHandle,
        ImageHandle,
        LineSegmentsHandle,
        MeshHandle,
        SceneApi,
        SceneNodeHandle,
    )

    from tileviz.app.history import ParticleView
    from tileviz.pipeline import FrameRecord

__all__ = ["COLOURS", "SceneView", "floor_texture", "grid_colour", "ribbon_centreline",
           "tile_grid", "yaw_wxyz"]

COLOURS: dict[str, tuple[int, int, int]] = {
    "truth": (255, 64, 160),  # pink
    "prediction": (40, 190, 70),  # green
    "boxes": (30, 100, 240),  # blue
    "setpoint": (230, 30, 30),  # red
    "path": (200, 90, 90),
    "waypoints": (240, 140, 20),
    "estimate": (30, 100, 240),
    "robot": (120, 124, 135),
    "wheel": (40, 40, 44),
    "camera": (250, 200, 40),
    "particles": (255, 140, 0),  # orange: the MCL baseline
}
"""RGB colour of each drawn quantity."""

TRAIL_SEGMENTS = 1000
"""Segments in each trail (the last TRAIL_SEGMENTS + 1 frames up to the shown one)."""
TRAIL_WIDTH = 0.02
"""Width of the trail ribbons, metres."""
PATH_WIDTH = 0.015
"""Width of the path and waypoint-loop ribbons, metres."""
TRAIL_HEAD = 64
"""Segments of the trails' heads: the newest frames, re-sent with every frame shown, while the
long trails are re-sent only now and then (``show(..., full=True)``)."""
WEDGE_STEPS = 48
"""Arc steps of the heading wedge."""
Z_BOX = 0.26
Z_MCL = 0.25
Z_WEDGE = 0.29
Z_TRUTH = 0.31
TEXTURE_PIXELS = 1024
"""Largest side of the floor texture (the ``floor`` layer, off by default), pixels: a 1 m tile of
the default room gets 85 texture pixels, grout lines included. Without a GPU the texture costs
by the view's pixels it covers more than by its size (docs/demo.md, "Without a GPU")."""
PATH_KINDS = ("lissajous", "dataset")
"""Setpoint kinds (``set_world``) whose path is drawn: the Lissajous lap, a dataset's true path."""


def yaw_wxyz(theta: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of a rotation by ``theta`` rad about +z."""
    return (math.cos(theta / 2.0), 0.0, 0.0, math.sin(theta / 2.0))


def floor_texture(floor: FloorConfig, half_size: float,
                  max_pixels: int = TEXTURE_PIXELS) -> np.ndarray:
    """The simulated floor over [-half_size, half_size]^2 metres as an NxNx3 uint8 RGB image, drawn
    by the simulator's own :class:`tileviz.sim.camera.FloorRenderer` (same tiles, grout, tile
    brightness, texture and stains; no camera noise).

    Row 0 is the south edge (y = -half_size) and column 0 the west edge: the row order viser's
    ``add_image`` maps onto +y."""
    from tileviz.sim.camera import FloorRenderer

    if not math.isfinite(half_size) or half_size <= 0:
        raise ValueError(f"floor half size must be a finite number > 0, got {half_size!r}")
    ppm = min(max_pixels / (2.0 * half_size), 256.0)
    n = max(16, int(round(2.0 * half_size * ppm)))
    ppm = n / (2.0 * half_size)
    cam = CameraConfig(ppm=ppm, width=n, height=n, offset=(0.0, 0.0), noise_sigma=0.0,
                       blur_sigma=0.0, vignetting=0.0, jpeg_quality=0)
    # A camera at the origin heading north sees north up and east right (docs/dataset-format.md).
    north_up = FloorRenderer(floor, cam).floor_image(Pose(0.0, 0.0, math.pi / 2))
    return np.clip(north_up[::-1], 0, 255).astype(np.uint8)


def tile_grid(tile_size: float, half_size: float, z: float) -> np.ndarray:
    """The grout lines' centre lines x = kL and y = kL (L = ``tile_size``) across the room
    [-half_size, half_size]^2 at height z, metres: segments (n, 2, 3), the lines of constant x
    first. A few dozen line segments, cheap for the browser to draw, where a full-room floor (a
    texture, or viser's grid shader) fills every pixel of the view (docs/demo.md, "Without a
    GPU")."""
    k = np.arange(math.ceil(-half_size / tile_size - 1e-9),
                  math.floor(half_size / tile_size + 1e-9) + 1)
    c = k * tile_size
    seg = np.zeros((2 * len(c), 2, 3), np.float32)
    seg[: len(c), :, 0] = c[:, None]
    seg[: len(c), 0, 1], seg[: len(c), 1, 1] = -half_size, half_size
    seg[len(c):, :, 1] = c[:, None]
    seg[len(c):, 0, 0], seg[len(c):, 1, 0] = -half_size, half_size
    seg[:, :, 2] = z
    return seg


def grid_colour(floor: FloorConfig) -> tuple[int, int, int]:
    """The tile grid's colour: the darker of the floor's grout and tile colours (the grid is
    drawn on the page's light background, where light grout would not show)."""
    r, g, b = min((floor.grout_rgb, floor.tile_rgb), key=lambda c: sum(c))
    return (int(r), int(g), int(b))


def _box_outline(b: Box, z: float) -> np.ndarray:
    """The 4 edges of a box's (x, y) rectangle at height z: (4, 2, 3)."""
    c = np.array([[b.x_lo, b.y_lo], [b.x_hi, b.y_lo], [b.x_hi, b.y_hi], [b.x_lo, b.y_hi]])
    seg = np.zeros((4, 2, 3), np.float32)
    seg[:, 0, :2] = c
    seg[:, 1, :2] = np.roll(c, -1, axis=0)
    seg[:, :, 2] = z
    return seg


def _polyline_segments(points: np.ndarray, n: int, z: float) -> np.ndarray:
    """``points`` (M, 2) as n segments (n, 2, 3) joining consecutive points; NaN points break the
    line; unused segments collapse onto the last point (or the origin)."""
    seg = np.zeros((n, 2, 3), np.float32)
    seg[:, :, 2] = z
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    good = np.asarray(np.isfinite(pts).all(axis=1))
    if good.any():
        seg[:, :, :2] = pts[good][-1]
    if len(pts) >= 2:
        a, b = pts[:-1], pts[1:]
        ok = good[:-1] & good[1:]
        a, b = a[ok][-n:], b[ok][-n:]
        seg[: len(a), 0, :2] = a
        seg[: len(a), 1, :2] = b
    return seg


def _quad_faces(n: int) -> np.ndarray:
    """Faces of :func:`_ribbon`'s n quads: (2n, 3) vertex indices, counter-clockwise seen from
    above (+z), so the ribbon's front faces up."""
    q = 4 * np.arange(n, dtype=np.uint32)[:, None]
    return np.concatenate([q + np.array([0, 1, 2], np.uint32), q + np.array([0, 2, 3], np.uint32)])


def _ribbon(seg: np.ndarray, width: float) -> np.ndarray:
    """Segments (n, 2, 3) as n flat quads of ``width`` metres, one a segment: vertices (4n, 3),
    segment k's quad at rows 4k..4k+3 (start right, end right, end left, start left of its
    direction; faces :func:`_quad_faces`). A segment of zero length is a quad of zero area."""
    a, b = seg[:, 0, :], seg[:, 1, :]
    d = (b - a)[:, :2].astype(np.float64)
    norm = np.hypot(d[:, 0], d[:, 1])
    left = np.zeros_like(a)
    ok = norm > 0
    left[ok, 0] = -d[ok, 1] / norm[ok] * (width / 2.0)
    left[ok, 1] = d[ok, 0] / norm[ok] * (width / 2.0)
    return np.stack([a - left, b - left, b + left, a + left], axis=1).reshape(-1, 3).astype(
        np.float32)


def ribbon_centreline(vertices: np.ndarray) -> np.ndarray:
    """The segments (n, 2, 3) a :func:`_ribbon` mesh's vertices (4n, 3) draw (its centre line)."""
    q = np.asarray(vertices, np.float64).reshape(-1, 4, 3)
    return np.stack([(q[:, 0] + q[:, 3]) / 2.0, (q[:, 1] + q[:, 2]) / 2.0], axis=1)


class SceneView:
    """Owns the scene nodes and updates them from frame records.

    ``scene``: a viser ``SceneApi`` (``server.scene``). ``pool``: box nodes per interval set.
    ``particles``: points of the MCL baseline's cloud.
    """

    def __init__(self, scene: SceneApi, *, pool: int = 16, particles: int = 1000) -> None:
        self.scene = scene
        self.pool = int(pool)
        self.n_particles = int(particles)
        self.layers: dict[str, bool] = {}
        self._world_key: object = None
        self._floor_key: object = None
        self._nodes: dict[str, list[SceneNodeHandle]] = {}
        self._build_dynamic()

    # ------------------------------------------------------------------ building
    def _layer(self, name: str, *handles: SceneNodeHandle) -> None:
        self._nodes.setdefault(name, []).extend(handles)

    def _build_dynamic(self) -> None:
        s = self.scene
        # robot: a frame at the true pose, parts in the robot frame (x forward, y left)
        self.robot = s.add_frame("/robot", show_axes=False)
        self.body = s.add_box("/robot/body", color=COLOURS["robot"], dimensions=(0.5, 0.32, 0.1),
                              position=(0.0, 0.0, 0.09), opacity=0.75)
        side = (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0)  # axis along robot y
        self.wheels = [
            s.add_cylinder(f"/robot/wheel_{k}", radius=0.08, height=0.04, color=COLOURS["wheel"],
                           wxyz=side, position=(0.0, sgn * 0.2, 0.08))
            for k, sgn in (("left", 1.0), ("right", -1.0))
        ]
        nose = np.array([[[0.0, 0.0, 0.15], [0.32, 0.0, 0.15]],
                         [[0.32, 0.0, 0.15], [0.24, 0.06, 0.15]],
                         [[0.32, 0.0, 0.15], [0.24, -0.06, 0.15]]], np.float32)
        self.nose = s.add_line_segments("/robot/heading", nose, (30, 30, 30), thickness=3.0,
                                        thickness_units="screen")
        self.camera_mount = s.add_box("/robot/camera", color=COLOURS["camera"],
                                      dimensions=(0.05, 0.05, 0.05), position=(0.3, 0.0, 0.2))
        self.footprint = s.add_line_segments("/robot/footprint", np.zeros((4, 2, 3), np.float32),
                                             COLOURS["camera"], thickness=2.0,
                                             thickness_units="screen")
        self._layer("robot", self.body, *self.wheels, self.nose, self.camera_mount)
        self._layer("footprint", self.footprint)

        # the true pose (pink arrow), separate from the robot so it stays when the robot is hidden
        arrow = np.array([[[-0.1, 0.0, 0.0], [0.45, 0.0, 0.0]],
                          [[0.45, 0.0, 0.0], [0.33, 0.08, 0.0]],
                          [[0.45, 0.0, 0.0], [0.33, -0.08, 0.0]]], np.float32)
        self.truth = s.add_line_segments("/truth", arrow, COLOURS["truth"], thickness=4.0,
                                         thickness_units="screen", position=(0.0, 0.0, Z_TRUTH))
        self._layer("truth", self.truth)

        # interval sets: a fixed pool of translucent boxes + one outline node per set
        self.sets: dict[str, tuple[list[BoxHandle], LineSegmentsHandle]] = {}
        for name, opacity in (("prediction", 0.18), ("boxes", 0.4)):
            boxes = [
                s.add_box(f"/intervals/{name}/{i}", color=COLOURS[name],
                          dimensions=(0.01, 0.01, 0.01), opacity=opacity, visible=False,
                          cast_shadow=False, receive_shadow=False)
                for i in range(self.pool)
            ]
            outline = s.add_line_segments(
                f"/intervals/{name}_outline", np.zeros((4 * self.pool, 2, 3), np.float32),
                COLOURS[name], thickness=2.0, thickness_units="screen")
            self.sets[name] = (boxes, outline)
            self._layer(name, *boxes, outline)

        # heading interval wedge: a fan around the estimate's centre
        k = WEDGE_STEPS
        faces = np.array([[0, i + 1, i + 2] for i in range(k)], np.uint32)
        self.wedge = s.add_mesh_simple("/intervals/wedge", np.zeros((k + 2, 3), np.float32),
                                       faces, color=COLOURS["boxes"], opacity=0.3, side="double",
                                       cast_shadow=False, receive_shadow=False)
        self._layer("wedge", self.wedge)

        self.setpoint = s.add_icosphere("/setpoint", radius=0.07, color=COLOURS["setpoint"],
                                        position=(0.0, 0.0, 0.07))
        self._layer("setpoint", self.setpoint)

        def trail(name: str, n: int, colour: str) -> MeshHandle:
            return s.add_mesh_simple(name, np.zeros((4 * n, 3), np.float32), _quad_faces(n),
                                     color=COLOURS[colour], cast_shadow=False,
                                     receive_shadow=False)

        self.trail_truth = trail("/trails/truth", TRAIL_SEGMENTS, "truth")
        self.trail_est = trail("/trails/estimate", TRAIL_SEGMENTS, "estimate")
        self.head_truth = trail("/trails/truth_head", TRAIL_HEAD, "truth")
        self.head_est = trail("/trails/estimate_head", TRAIL_HEAD, "estimate")
        self._layer("trails", self.trail_truth, self.trail_est, self.head_truth, self.head_est)
        # the MCL baseline: its particles (orange points) and its 95 % confidence ellipse
        self.particles = s.add_point_cloud(
            "/mcl/particles", np.zeros((self.n_particles, 3), np.float32), COLOURS["particles"],
            point_size=0.025, point_shape="circle", precision="float32", point_shading="flat",
            visible=False)
        self.ellipse = s.add_line_segments("/mcl/ellipse", np.zeros((64, 2, 3), np.float32),
                                           COLOURS["particles"], thickness=2.0,
                                           thickness_units="screen", visible=False)
        self._mcl_nodes = (self.particles, self.ellipse)
        self.floor: ImageHandle | None = None
        self.grid: LineSegmentsHandle | None = None
        self.path: MeshHandle | None = None
        self.waypoints: MeshHandle | None = None
        self._setpoint_kind = "lissajous"
        self._unknown: set[str] = set()
        """Layers hidden on the shown frame because it does not know their value (a dataset
        frame has no setpoint, may have no true pose)."""

    def set_world(self, cfg: Config, *, path: Sequence[tuple[float, float]],
                  waypoints: Sequence[tuple[float, float]], setpoint_kind: str,
                  closed: bool = True) -> None:
        """(Re)draw the static layers: the floor (only when the floor or the room changed), the
        path (a loop when ``closed``: the Lissajous lap; else a dataset's true path; drawn for the
        :data:`PATH_KINDS`) and the waypoint loop, and the camera footprint for ``cfg.camera``."""
        half = float(cfg.sim.room_half_size)
        floor_key = (cfg.floor, half)
        s = self.scene
        if floor_key != self._floor_key:
            tex = floor_texture(cfg.floor, half)
            self.floor = s.add_image("/floor", tex, 2 * half, 2 * half, format="jpeg",
                                     jpeg_quality=90, position=(0.0, 0.0, 0.0),
                                     cast_shadow=False, receive_shadow=0.3)
            self.grid = s.add_line_segments(
                "/grid", tile_grid(cfg.floor.tile_size, half, 0.002), grid_colour(cfg.floor),
                thickness=1.5, thickness_units="screen")
            self._nodes["floor"] = [self.floor]
            self._nodes["grid"] = [self.grid]
            self._floor_key = floor_key
        pts = (np.asarray(list(path) + (list(path[:1]) if closed else []), np.float64)
               if path else np.zeros((0, 2)))
        self.path = self._polyline_mesh("/path", pts, 0.004, COLOURS["path"])
        wp = np.asarray(list(waypoints) + list(waypoints[:1]), np.float64)
        self.waypoints = self._polyline_mesh("/waypoints", wp, 0.005, COLOURS["waypoints"])
        self._setpoint_kind = setpoint_kind
        cam = cfg.camera
        fw, lw = cam.height / cam.ppm, cam.width / cam.ppm  # forward and left extents, m
        f0, l0 = cam.offset
        self.footprint.points = _box_outline(
            Box(f0 - fw / 2, f0 + fw / 2, l0 - lw / 2, l0 + lw / 2, 0.0, 0.0), 0.008)
        self.camera_mount.position = (f0, l0, 0.2)
        for w, sgn in zip(self.wheels, (1.0, -1.0), strict=True):
            w.position = (0.0, sgn * cfg.sim.wheel_base / 2, 0.08)
        self.body.dimensions = (0.5, max(cfg.sim.wheel_base - 0.08, 0.1), 0.1)
        self.apply_layers(self.layers, force=True)

    def _polyline_mesh(self, name: str, pts: np.ndarray, z: float,
                       colour: tuple[int, int, int]) -> MeshHandle:
        """A static polyline through ``pts`` (M, 2) as a ribbon mesh at height z."""
        n = max(len(pts) - 1, 1)
        return self.scene.add_mesh_simple(
            name, _ribbon(_polyline_segments(pts, n, z), PATH_WIDTH), _quad_faces(n),
            color=colour, cast_shadow=False, receive_shadow=False)

    # ------------------------------------------------------------------ layers
    def apply_layers(self, layers: dict[str, bool], force: bool = False) -> None:
        """Show or hide whole layers (``force``: re-send every layer's state)."""
        for name, on in layers.items():
            if not force and self.layers.get(name) == on:
                continue
            if name in self.sets:
                boxes, outline = self.sets[name]
                outline.visible = on
                if not on:
                    for b in boxes:
                        b.visible = False  # shown again box by box by the next show()
            elif name == "path":
                if self.path is not None:
                    self.path.visible = on and self._setpoint_kind in PATH_KINDS
                if self.waypoints is not None:
                    self.waypoints.visible = on and self._setpoint_kind == "waypoints"
            else:
                for h in self._nodes.get(name, []):
                    h.visible = on and name not in self._unknown
        self.layers = dict(layers)

    def _set_known(self, name: str, known: bool) -> None:
        """Hide layer ``name`` while the shown frame does not know its value; show it again
        (if the layer is on) when it does."""
        if known == (name not in self._unknown):
            return
        if known:
            self._unknown.discard(name)
        else:
            self._unknown.add(name)
        for h in self._nodes.get(name, []):
            h.visible = known and self.layers.get(name, True)

    # ------------------------------------------------------------------ per frame
    def show(self, rec: FrameRecord, trail_truth: np.ndarray, trail_est: np.ndarray, *,
             full: bool = True, mcl: ParticleView | None = None) -> None:
        """Update every dynamic node from the record ``rec`` (a FrameRecord) and the trails:
        (K, 2) arrays of past (x, y) up to this frame, NaN where unknown. The long trails are
        re-sent only when ``full`` (their newest part is always drawn by the trail heads).
        ``mcl``: the frame's :class:`tileviz.app.history.ParticleView` (None: no cloud)."""
        self._show_mcl(mcl)
        truth: Pose | None = rec.truth
        self._set_known("truth", truth is not None)
        self._set_known("setpoint", rec.setpoint is not None)
        if truth is not None:
            self.robot.position = (truth.x, truth.y, 0.0)
            self.robot.wxyz = yaw_wxyz(truth.theta)
            self.truth.position = (truth.x, truth.y, Z_TRUTH)
            self.truth.wxyz = yaw_wxyz(truth.theta)
        elif (hull := rec.updated.hull()) is not None:  # no true pose (a dataset): the robot
            cx, cy, ct = hull.centre  # at the estimate
            self.robot.position = (cx, cy, 0.0)
            self.robot.wxyz = yaw_wxyz(ct)
        if self.layers.get("prediction", True):
            self._show_set("prediction", rec.predicted)
        if self.layers.get("boxes", True):
            self._show_set("boxes", rec.updated)
        if self.layers.get("wedge", True):
            self._show_wedge(rec.updated.hull())
        if rec.setpoint is not None:
            self.setpoint.position = (rec.setpoint[0], rec.setpoint[1], 0.07)
        if self.layers.get("trails", True):
            w = TRAIL_WIDTH
            if full:
                self.trail_truth.vertices = _ribbon(
                    _polyline_segments(trail_truth, TRAIL_SEGMENTS, 0.006), w)
                self.trail_est.vertices = _ribbon(
                    _polyline_segments(trail_est, TRAIL_SEGMENTS, 0.007), w)
            self.head_truth.vertices = _ribbon(
                _polyline_segments(trail_truth[-TRAIL_HEAD - 1:], TRAIL_HEAD, 0.006), w)
            self.head_est.vertices = _ribbon(
                _polyline_segments(trail_est[-TRAIL_HEAD - 1:], TRAIL_HEAD, 0.007), w)

    def _show_mcl(self, mcl: ParticleView | None) -> None:
        on = mcl is not None and self.layers.get("particles", True)
        if mcl is not None and on:
            pts = np.zeros((self.n_particles, 3), np.float32)
            n = min(len(mcl.particles), self.n_particles)
            pts[:n, :2] = mcl.particles[:n, :2]
            pts[n:, :2] = mcl.mean[:2]
            pts[:, 2] = Z_MCL
            self.particles.points = pts
            self.ellipse.points = _polyline_segments(mcl.ellipse, 64, Z_MCL + 0.001)
        for node in self._mcl_nodes:
            node.visible = on

    def _show_set(self, name: str, boxset: BoxSet) -> None:
        boxes, outline = self.sets[name]
        items = list(boxset.boxes)
        if len(items) > self.pool:
            rest = BoxSet(tuple(items[self.pool - 1:])).hull()
            items = items[: self.pool - 1] + ([rest] if rest is not None else [])
        z = Z_BOX + (0.01 if name == "boxes" else 0.0)
        seg = np.zeros((4 * self.pool, 2, 3), np.float32)
        for i, node in enumerate(boxes):
            if i < len(items):
                b = items[i]
                wx, wy = max(b.x_hi - b.x_lo, 1e-4), max(b.y_hi - b.y_lo, 1e-4)
                node.dimensions = (wx, wy, 0.008)
                node.position = (0.5 * (b.x_lo + b.x_hi), 0.5 * (b.y_lo + b.y_hi), z)
                node.visible = True
                seg[4 * i: 4 * i + 4] = _box_outline(b, z + 0.005)
            else:
                node.visible = False
        # only the shown boxes' edges: the browser draws every segment sent, used or not
        outline.points = seg[: 4 * max(len(items), 1)]

    def _show_wedge(self, hull: Box | None) -> None:
        k = WEDGE_STEPS
        v = np.zeros((k + 2, 3), np.float32)
        if hull is not None:
            cx, cy, _ = hull.centre
            lo, hi = hull.t_lo, hull.t_hi
            if hi - lo >= 2.0 * math.pi:
                lo, hi = 0.0, 2.0 * math.pi
            a = np.linspace(lo, hi, k + 1)
            r = 0.6
            v[0] = (cx, cy, Z_WEDGE)
            v[1:, 0] = cx + r * np.cos(a)
            v[1:, 1] = cy + r * np.sin(a)
            v[1:, 2] = Z_WEDGE
        self.wedge.vertices = v
