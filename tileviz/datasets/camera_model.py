"""A real, calibrated downward camera: the ``camera_model`` block of meta.json and the
rectification of its images to the orthographic view (``docs/dataset-format.md``).

Frames and units: a raw pixel ``(u, v)`` is a column and a row of a stored (distorted) image; an
undistorted pixel is the same ray in the ideal pinhole image with ``camera_matrix``; a floor point
``(forward, left)`` is in metres in the robot frame, from the robot point. The rectified view is
the orthographic image of ``image_width`` x ``image_height`` pixels at ``ppm`` pixels a metre
centred on ``camera_offset`` (image up = forward, image left = left).

:class:`Rectifier` computes its remap tables once; each frame then costs one ``cv2.remap``: of
the gray image for vision (:meth:`Rectifier.gray`, one channel), of the colour image only where
it is shown (:meth:`Rectifier.__call__`).
:func:`view_margin` says how much the rectification may move a grout line in the rectified view,
the amount the declared view bound grows by (``docs/dataset-format.md``, "Rectification and the
view bound"). No viser, no pymunk here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

__all__ = [
    "DIST_LENGTHS",
    "REPROJECTION_FACTOR",
    "RESAMPLING_PX",
    "CameraModel",
    "CameraModelError",
    "Rectifier",
    "view_margin",
]

DIST_LENGTHS = (4, 5, 8, 12, 14)
"""How many distortion coefficients OpenCV's models take."""
RESAMPLING_PX = 0.5
"""Bound on how far bilinear resampling moves a grout line's centre, in raw pixels (a line is
drawn from the raw samples either side of each rectified pixel's source point)."""
REPROJECTION_FACTOR = 3.0
"""The calibration's systematic error is taken as at most this many times its RMS reprojection
error (the RMS is a mean; three of it covers the worst corners of a good calibration)."""
TABLE_STEP = 1.0 / 256.0
"""The gray view's remap tables hold source points rounded to this many raw pixels (a sample
moves by at most half of it). Bilinear interpolation of 8-bit gray levels at such points is
exact in single precision (every product and sum fits in 24 bits), so OpenCV's float remap
(4.11 or later) gives the same pixels with or without fused multiply-add and at any vector
width: on every machine."""
MAX_MAGNITUDE = 1e9
"""Largest magnitude of a number in the block (as for the rest of meta.json)."""


class CameraModelError(ValueError):
    """A ``camera_model`` block that does not follow the format; the message names the key."""


def _matrix(v: Any, key: str, where: str) -> np.ndarray:
    ok = (isinstance(v, list) and len(v) == 3 and all(
        isinstance(r, list) and len(r) == 3 and all(
            not isinstance(e, bool) and isinstance(e, int | float) and math.isfinite(e)
            and abs(e) <= MAX_MAGNITUDE for e in r) for r in v))
    if not ok:
        raise CameraModelError(f"{where}: camera_model.{key} must be a 3x3 list of finite "
                               f"numbers, got {v!r}")
    return np.array(v, dtype=np.float64)


@dataclass(frozen=True)
class CameraModel:
    """The ``camera_model`` block (pixels, metres; see the module docstring for the frames)."""

    raw_width: int
    raw_height: int
    camera_matrix: tuple[tuple[float, ...], ...]
    """Pinhole intrinsics of the stored images ``[[fx, 0, u0], [0, fy, v0], [0, 0, 1]]``, px."""
    dist_coeffs: tuple[float, ...]
    """OpenCV's distortion coefficients in OpenCV's order (4, 5, 8, 12 or 14 of them)."""
    floor_homography: tuple[tuple[float, ...], ...]
    """Undistorted pixel ``(u, v, 1)`` -> ``(forward, left, 1)`` up to scale, metres."""
    reprojection_error_px: float | None = None
    """The calibration's RMS reprojection error, px (None: not given)."""

    @classmethod
    def from_json(cls, d: Any, where: str = "meta.json") -> CameraModel:
        """Validate and parse the block; CameraModelError names the key."""
        if not isinstance(d, dict):
            raise CameraModelError(f"{where}: camera_model must be a JSON object, got {d!r}")
        missing = [k for k in ("raw_width", "raw_height", "camera_matrix", "dist_coeffs",
                               "floor_homography") if k not in d]
        if missing:
            raise CameraModelError(f"{where}: camera_model: missing key(s) {', '.join(missing)}")
        for key in ("raw_width", "raw_height"):
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise CameraModelError(f"{where}: camera_model.{key} must be an integer > 0, "
                                       f"got {v!r}")
        k = _matrix(d["camera_matrix"], "camera_matrix", where)
        if not (k[0, 0] > 0 and k[1, 1] > 0 and k[0, 1] == 0 and k[1, 0] == 0
                and (k[2] == (0, 0, 1)).all()):
            raise CameraModelError(
                f"{where}: camera_model.camera_matrix must be [[fx, 0, u0], [0, fy, v0], "
                f"[0, 0, 1]] with fx, fy > 0, got {d['camera_matrix']!r}")
        dist = d["dist_coeffs"]
        if not (isinstance(dist, list) and len(dist) in DIST_LENGTHS and all(
                not isinstance(e, bool) and isinstance(e, int | float) and math.isfinite(e)
                and abs(e) <= MAX_MAGNITUDE for e in dist)):
            raise CameraModelError(f"{where}: camera_model.dist_coeffs must be a list of 4, 5, "
                                   f"8, 12 or 14 finite numbers, got {dist!r}")
        h = _matrix(d["floor_homography"], "floor_homography", where)
        det = float(np.linalg.det(h / np.abs(h).max())) if np.abs(h).max() > 0 else 0.0
        if abs(det) < 1e-12:
            raise CameraModelError(f"{where}: camera_model.floor_homography is singular")
        p0 = h @ np.array([k[0, 2], k[1, 2], 1.0])
        if abs(p0[2]) < 1e-12 * np.abs(p0).max():
            raise CameraModelError(f"{where}: camera_model.floor_homography: the principal "
                                   "point does not see the floor (its ray is parallel to it)")
        rep = d.get("reprojection_error_px")
        if rep is not None and (isinstance(rep, bool) or not isinstance(rep, int | float)
                                or not math.isfinite(rep) or not 0 <= rep <= MAX_MAGNITUDE):
            raise CameraModelError(f"{where}: camera_model.reprojection_error_px must be a "
                                   f"finite number >= 0, got {rep!r}")
        return cls(
            raw_width=d["raw_width"],
            raw_height=d["raw_height"],
            camera_matrix=tuple(tuple(float(e) for e in r) for r in k),
            dist_coeffs=tuple(float(e) for e in dist),
            floor_homography=tuple(tuple(float(e) for e in r) for r in h),
            reprojection_error_px=None if rep is None else float(rep),
        )

    def to_json(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "raw_width": self.raw_width,
            "raw_height": self.raw_height,
            "camera_matrix": [list(r) for r in self.camera_matrix],
            "dist_coeffs": list(self.dist_coeffs),
            "floor_homography": [list(r) for r in self.floor_homography],
        }
        if self.reprojection_error_px is not None:
            d["reprojection_error_px"] = self.reprojection_error_px
        return d

    @property
    def k(self) -> np.ndarray:
        """The camera matrix, 3x3 float64."""
        return np.array(self.camera_matrix, dtype=np.float64)

    @property
    def dist(self) -> np.ndarray:
        """The distortion coefficients, float64."""
        return np.array(self.dist_coeffs, dtype=np.float64)

    @property
    def h(self) -> np.ndarray:
        """The floor homography, 3x3 float64."""
        return np.array(self.floor_homography, dtype=np.float64)

    def raw_to_floor(self, pixels: np.ndarray) -> np.ndarray:
        """Floor points (N, 2) (forward, left), metres, robot frame, of raw pixels (N, 2)."""
        pts = np.asarray(pixels, np.float64).reshape(-1, 1, 2)
        und = cv2.undistortPoints(pts, self.k, self.dist, None, None, self.k, _UNDISTORT_CRITERIA)
        q = np.c_[und.reshape(-1, 2), np.ones(len(pts))] @ self.h.T
        return q[:, :2] / q[:, 2:3]

    def floor_to_raw(self, floor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw pixels (N, 2) of floor points (N, 2) (forward, left, metres, robot frame), and
        whether each is seen: in front of the camera, within the field of view where the
        distortion model holds, and inside the raw image."""
        f = np.asarray(floor, np.float64).reshape(-1, 2)
        g = np.linalg.inv(self.h)
        q = np.c_[f, np.ones(len(f))] @ g.T
        k = self.k
        ref = np.sign((self.h @ np.array([k[0, 2], k[1, 2], 1.0]))[2])
        front = np.sign(q[:, 2]) == ref
        w = np.where(front, q[:, 2], 1.0)
        und = q[:, :2] / w[:, None]
        norm = np.c_[(und[:, 0] - k[0, 2]) / k[0, 0], (und[:, 1] - k[1, 2]) / k[1, 1]]
        inside_fov = np.hypot(norm[:, 0], norm[:, 1]) <= self._max_radius()
        norm = np.where((front & inside_fov)[:, None], norm, 0.0)
        obj = np.c_[norm, np.ones(len(norm))]
        raw, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), k, self.dist)
        raw = raw.reshape(-1, 2)
        inside = ((raw[:, 0] >= 0) & (raw[:, 0] <= self.raw_width - 1)
                  & (raw[:, 1] >= 0) & (raw[:, 1] <= self.raw_height - 1))
        return raw, front & inside_fov & inside

    def _max_radius(self) -> float:
        """The largest normalised radius a raw pixel of the image undistorts to, plus 5 % (the
        distortion polynomial folds back beyond the field of view it was fitted in)."""
        w, h = self.raw_width - 1, self.raw_height - 1
        border = np.array([(0, 0), (w, 0), (0, h), (w, h), (w / 2, 0), (w / 2, h), (0, h / 2),
                           (w, h / 2)], np.float64).reshape(-1, 1, 2)
        und = cv2.undistortPoints(border, self.k, self.dist, None, None, None,
                                  _UNDISTORT_CRITERIA)
        return 1.05 * float(np.hypot(und[..., 0], und[..., 1]).max())


_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)


def rectified_floor_points(ppm: float, width: int, height: int,
                           camera_offset: tuple[float, float]) -> np.ndarray:
    """(height, width, 2) floor points (forward, left), metres, robot frame, that the rectified
    pixels show (``docs/dataset-format.md``, image axes)."""
    cols = np.arange(width, dtype=np.float64)
    rows = np.arange(height, dtype=np.float64)
    a_left = ((width - 1) / 2.0 - cols) / ppm
    a_fwd = ((height - 1) / 2.0 - rows) / ppm
    out = np.empty((height, width, 2))
    out[..., 0] = camera_offset[0] + a_fwd[:, None]
    out[..., 1] = camera_offset[1] + a_left[None, :]
    return out


class Rectifier:
    """Turns a stored raw image into the orthographic view (``width`` x ``height`` pixels at
    ``ppm`` px/m centred on ``camera_offset``, metres, robot frame).

    The remap tables are computed here, once. :meth:`gray` is the view vision reads: the raw
    image's gray levels (as :func:`tileviz.vision.to_gray` converts them) sampled bilinearly,
    one channel. Calling the rectifier on a colour image gives the colour view, for display
    only: its gray conversion may differ from :meth:`gray` by rounding (one gray level).
    Rectified pixels the camera does not see are invalid (``valid`` False there): they are
    filled with the mean level (colour) of the valid ones, a flat area without edges, so they
    carry no evidence of a grout line.
    """

    def __init__(self, model: CameraModel, *, ppm: float, width: int, height: int,
                 camera_offset: tuple[float, float]) -> None:
        self.model = model
        self.width, self.height = int(width), int(height)
        floor = rectified_floor_points(ppm, self.width, self.height, camera_offset)
        raw, seen = model.floor_to_raw(floor.reshape(-1, 2))
        raw = raw.reshape(self.height, self.width, 2)
        self.valid = seen.reshape(self.height, self.width)
        raw[~self.valid] = -10.0  # outside: the border value, then filled
        self.scale = _max_scale(raw.astype(np.float32), self.valid)
        """The largest number of rectified pixels one raw pixel spans (over the valid view)."""
        table = (np.round(raw / TABLE_STEP) * TABLE_STEP).astype(np.float32)
        # one float table per coordinate: OpenCV's fastest bilinear remap of one 8-bit channel
        self.map_x = np.ascontiguousarray(table[..., 0])
        """(height, width) float32: the raw column each rectified pixel samples, on the
        :data:`TABLE_STEP` grid (-10 where invalid)."""
        self.map_y = np.ascontiguousarray(table[..., 1])
        """(height, width) float32: the raw row each rectified pixel samples (as ``map_x``)."""
        self._fixed: tuple[np.ndarray, np.ndarray] | None = None  # colour: made on first use
        invalid = np.flatnonzero(~self.valid)
        self._invalid = invalid if invalid.size else None
        self._valid_u8 = self.valid.astype(np.uint8)
        self.seen_fraction = float(self.valid.mean())

    def _check(self, image: np.ndarray) -> None:
        h, w = image.shape[:2]
        if (w, h) != (self.model.raw_width, self.model.raw_height):
            raise ValueError(f"raw image is {w}x{h}, camera_model says "
                             f"{self.model.raw_width}x{self.model.raw_height}")

    def gray(self, image: np.ndarray) -> np.ndarray:
        """The rectified gray view (height x width uint8), the pixels vision reads, of a raw
        uint8 image of ``raw_width`` x ``raw_height``: HxW gray, or HxWx3 RGB / HxWx4 RGBA
        converted first as :func:`tileviz.vision.to_gray` does. ValueError names a wrong size."""
        self._check(image)
        if image.ndim == 3 and image.shape[2] == 1:
            image = image[..., 0]
        if image.ndim == 3:
            code = cv2.COLOR_RGB2GRAY if image.shape[2] == 3 else cv2.COLOR_RGBA2GRAY
            image = cv2.cvtColor(np.ascontiguousarray(image), code)
        out = cv2.remap(image, self.map_x, self.map_y, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT)
        return self._fill(out)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """The rectified view (height x width, same channels and dtype) of a raw image of
        ``raw_width`` x ``raw_height``, for display (a gray image: :meth:`gray`); ValueError
        names a wrong size."""
        if image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 1):
            return self.gray(image)
        self._check(image)
        if self._fixed is None:  # fixed-point tables: OpenCV's faster path for colour
            self._fixed = cv2.convertMaps(self.map_x, self.map_y, cv2.CV_16SC2)
        out = cv2.remap(image, self._fixed[0], self._fixed[1], cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT)
        return self._fill(out)

    def _fill(self, out: np.ndarray) -> np.ndarray:
        if self._invalid is not None:
            mean = cv2.mean(out, mask=self._valid_u8)
            c = 1 if out.ndim == 2 else out.shape[2]
            out.reshape(-1, c)[self._invalid] = mean[:c]
        return out


def _max_scale(raw: np.ndarray, valid: np.ndarray) -> float:
    """max over valid pixels of 1 / (smallest singular value of d(raw)/d(rectified))."""
    if not valid.any():
        return 1.0
    du_c = np.gradient(raw[..., 0], axis=1)
    du_r = np.gradient(raw[..., 0], axis=0)
    dv_c = np.gradient(raw[..., 1], axis=1)
    dv_r = np.gradient(raw[..., 1], axis=0)
    # singular values of [[du_c, du_r], [dv_c, dv_r]]
    a = du_c * du_c + dv_c * dv_c
    b = du_c * du_r + dv_c * dv_r
    c = du_r * du_r + dv_r * dv_r
    smin2 = 0.5 * (a + c - np.sqrt((a - c) ** 2 + 4 * b * b))
    inner = valid.copy()
    inner[[0, -1], :] = False
    inner[:, [0, -1]] = False
    inner &= np.roll(valid, 1, 0) & np.roll(valid, -1, 0) & np.roll(valid, 1, 1) & np.roll(
        valid, -1, 1)
    if not inner.any():
        inner = valid
    smin = np.sqrt(np.maximum(smin2[inner], 1e-12))
    return float(1.0 / smin.min())


def view_margin(model: CameraModel, rectifier: Rectifier) -> tuple[float, float]:
    """How far the rectification may move what the extractor measures: ``(px, rad)``, rectified
    pixels on y1, y2 and radians on y3; the declared view bound grows by these.

    ``px = scale * (RESAMPLING_PX + REPROJECTION_FACTOR * reprojection_error_px)``: the
    resampling and the calibration error, both in raw pixels, times the most rectified pixels a
    raw pixel spans. ``rad = 2 px / min(width, height)``: a displacement field within ``px`` of
    zero over the view's inscribed circle turns a line by at most that."""
    rep = model.reprojection_error_px or 0.0
    px = rectifier.scale * (RESAMPLING_PX + REPROJECTION_FACTOR * rep)
    rad = 2.0 * px / min(rectifier.width, rectifier.height)
    return px, rad
