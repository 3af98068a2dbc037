"""A real camera in the simulator: a tilted pinhole camera with OpenCV's lens distortion.

:func:`mounted_camera` builds the ``camera_model`` block (``docs/dataset-format.md``) of a camera
mounted above the robot, looking down with a small tilt; :func:`webcam_model` is the ``webcam``
preset (640x480, a wide webcam lens, tilted 3 and 2 degrees) placed so that it sees the whole
orthographic view of a :class:`~tileviz.config.CameraConfig`. :class:`LensRenderer` draws what
that camera sees: every raw pixel's floor point is found once (through the distortion and the
floor homography), the floor is rendered orthographically at a finer scale around the raw
footprint by :class:`~tileviz.sim.camera.FloorRenderer`, and each frame is resampled to the raw
pixels before the camera's own blur, vignetting and noise.

Frames: robot frame (forward, left, up), metres; raw pixels (column, row). Pure numpy/OpenCV.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import cv2
import numpy as np

from tileviz.config import CameraConfig, FloorConfig
from tileviz.datasets.camera_model import CameraModel
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose

__all__ = ["LENSES", "LensRenderer", "mounted_camera", "webcam_model"]

LENSES = ("webcam",)
"""Lens presets ``record --lens`` knows."""

WEBCAM_DIST = (-0.21, 0.08, 0.0012, -0.0009, -0.012)
"""A wide webcam lens (k1, k2, p1, p2, k3): barrel distortion, a slightly decentred lens."""
WEBCAM_FOCAL = 560.0
"""Focal length of the webcam preset at 640x480, pixels (a 60 degree horizontal view)."""
SUPERSAMPLE = 1.5
"""The orthographic floor is rendered at this many pixels per raw pixel (finest place)."""


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def mounted_camera(*, raw_size: tuple[int, int], focal: float, dist: tuple[float, ...],
                   target: tuple[float, float], height: float, pitch: float, roll: float,
                   reprojection_error_px: float | None = None) -> CameraModel:
    """The camera model of a pinhole camera ``height`` metres above the floor whose optical axis
    meets the floor at ``target`` (forward, left; metres, robot frame), tilted by ``pitch``
    (about the image's horizontal axis) and ``roll`` (about its vertical axis), radians, from
    straight down with image up = forward; principal point at the raw image's centre."""
    w, h = raw_size
    k = np.array([[focal, 0.0, (w - 1) / 2.0], [0.0, focal, (h - 1) / 2.0], [0.0, 0.0, 1.0]])
    # columns: the camera's x (image right), y (image down), z (optical axis) in the robot frame
    down = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]).T
    r = down @ _rot(0, pitch) @ _rot(1, roll)
    z = r[:, 2]
    t = -height / z[2]
    centre = np.array([target[0], target[1], 0.0]) - t * z
    m = r.T
    g = k @ np.column_stack([m[:, 0], m[:, 1], -m @ centre])
    hom = np.linalg.inv(g)
    hom /= hom[2, 2]
    return CameraModel(
        raw_width=w, raw_height=h,
        camera_matrix=tuple(tuple(float(e) for e in row) for row in k),
        dist_coeffs=tuple(float(e) for e in dist),
        floor_homography=tuple(tuple(float(e) for e in row) for row in hom),
        reprojection_error_px=reprojection_error_px,
    )


def webcam_model(camera: CameraConfig, *, pitch_deg: float = 3.0, roll_deg: float = -2.0,
                 margin: float = 0.08) -> CameraModel:
    """The ``webcam`` preset for ``camera``'s orthographic view: 640x480 (480x640 for a portrait
    view), focal 560 px, :data:`WEBCAM_DIST`, tilted ``pitch_deg`` / ``roll_deg``, aimed at the
    view's centre and raised until the view's border stays ``margin`` (a fraction of the raw
    size) inside the raw image."""
    raw = (480, 640) if camera.height > camera.width else (640, 480)
    half = np.array([camera.width, camera.height], float) / (2.0 * camera.ppm)
    corners = np.array([(camera.offset[0] + sf * half[1], camera.offset[1] + sl * half[0])
                        for sf in (-1, 0, 1) for sl in (-1, 0, 1)])
    lo = np.array([margin * raw[0], margin * raw[1]])
    hi = np.array([(1 - margin) * (raw[0] - 1), (1 - margin) * (raw[1] - 1)])
    height = 0.05
    for _ in range(200):
        model = mounted_camera(raw_size=raw, focal=WEBCAM_FOCAL, dist=WEBCAM_DIST,
                               target=camera.offset, height=height,
                               pitch=math.radians(pitch_deg), roll=math.radians(roll_deg))
        px, seen = model.floor_to_raw(corners)
        if seen.all() and (px >= lo).all() and (px <= hi).all():
            return model
        height *= 1.05
    raise ValueError("no camera height sees the whole view")


class LensRenderer:
    """Renders the raw images of a real camera (``model``) over the floor, with ``camera``'s
    blur, vignetting and noise (its ppm, size and lever arm describe the rectified view, not
    these images). Same ``render(pose, rng, faults)`` as :class:`FloorRenderer`; camera faults
    are not drawn through a lens (ValueError)."""

    def __init__(self, floor: FloorConfig, camera: CameraConfig, model: CameraModel) -> None:
        self.model = model
        self.camera = camera
        w, h = model.raw_width, model.raw_height
        cols, rows = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        floor_pts = model.raw_to_floor(np.c_[cols.ravel(), rows.ravel()]).reshape(h, w, 2)
        step = min(float(np.hypot(*np.diff(floor_pts, axis=a).reshape(-1, 2).T).min())
                   for a in (0, 1))
        ppm = SUPERSAMPLE / max(step, 1e-9)
        lo, hi = floor_pts.reshape(-1, 2).min(0), floor_pts.reshape(-1, 2).max(0)
        iw = int(math.ceil((hi[1] - lo[1]) * ppm)) + 3
        ih = int(math.ceil((hi[0] - lo[0]) * ppm)) + 3
        if max(iw, ih) > 8192:
            raise ValueError("the camera sees too much floor to render (> 8192 px a side)")
        centre = (float(lo[0] + hi[0]) / 2.0, float(lo[1] + hi[1]) / 2.0)
        inner = replace(camera, ppm=ppm, width=max(iw, 16), height=max(ih, 16), offset=centre,
                        noise_sigma=0.0, blur_sigma=0.0, vignetting=0.0, jpeg_quality=0)
        self._inner = FloorRenderer(floor, inner)
        # raw pixel -> inner orthographic pixel (dataset-format.md image axes)
        mx = (inner.width - 1) / 2.0 - (floor_pts[..., 1] - centre[1]) * ppm
        my = (inner.height - 1) / 2.0 - (floor_pts[..., 0] - centre[0]) * ppm
        self._map1, self._map2 = cv2.convertMaps(mx.astype(np.float32), my.astype(np.float32),
                                                 cv2.CV_16SC2)
        self._pre_blur = 0.5 * SUPERSAMPLE  # anti-aliasing before the resampling, inner px
        u = np.arange(w, dtype=np.float32) - (w - 1) / 2.0
        v = np.arange(h, dtype=np.float32) - (h - 1) / 2.0
        r2 = u[None, :] ** 2 + v[:, None] ** 2
        vig = np.clip(1.0 - camera.vignetting * r2 / max(float(r2.max()), 1.0), 0.0, 1.0)
        self._vignette = np.ascontiguousarray(np.repeat(vig[..., None], 3, axis=2),
                                              dtype=np.float32)
        noise_rng = np.random.default_rng(np.random.SeedSequence([int(floor.seed), 0x1E45]))
        field = (noise_rng.standard_normal((2 * h, 2 * w)) * camera.noise_sigma)
        self._noise = np.ascontiguousarray(np.repeat(field[..., None], 3, axis=2),
                                           dtype=np.float32)

    def render(self, pose: Pose, rng: np.random.Generator | None = None,
               faults: Any = None) -> np.ndarray:
        """The raw camera image at ``pose``: raw_height x raw_width x 3 uint8 RGB."""
        if faults:
            raise ValueError("camera faults are not drawn through a lens model")
        img = self._inner.floor_image(pose)
        img = cv2.GaussianBlur(img, (0, 0), self._pre_blur)
        img = cv2.remap(img, self._map1, self._map2, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE)
        cam = self.camera
        if cam.blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), cam.blur_sigma)
        if cam.vignetting > 0:
            img = cv2.multiply(img, self._vignette)
        if rng is not None and cam.noise_sigma > 0:
            h, w = self.model.raw_height, self.model.raw_width
            oy, ox = int(rng.integers(0, h + 1)), int(rng.integers(0, w + 1))
            img = cv2.add(img, self._noise[oy:oy + h, ox:ox + w])
        return cv2.convertScaleAbs(cv2.max(img, 0.0))
