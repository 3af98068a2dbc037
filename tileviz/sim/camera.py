"""The downward camera: renders what it sees of the tiled floor at a robot pose.

Conventions (``docs/dataset-format.md``): orthographic camera with ``ppm`` pixels per metre,
optical centre on the floor ``c = (x, y) + R(theta) @ camera_offset``. A floor point at
camera-frame coordinates ``(a_forward, a_left)`` metres from ``c`` lands on pixel
``col = cx - a_left * ppm``, ``row = cy - a_forward * ppm`` with ``cx = (W - 1) / 2`` and
``cy = (H - 1) / 2``: image up is the robot's forward direction, image left the robot's left.
Grout line centres lie on ``x = kL`` and ``y = kL``.

The floor's appearance is fixed by :class:`~tileviz.config.FloorConfig` (its ``seed`` included):
a per-tile brightness (a random table over a 16 x 16 tile period, i.e. a hash of the tile indices
modulo 16), a mottled surface texture and dark stains, all fixed to the floor and computed once
per renderer. Grout lines are anti-aliased analytically (the exact coverage of each pixel's
footprint across the line, per axis), so the rendered line centres sit where the geometry says,
to a small fraction of a pixel. The camera then adds its own effects: optional faults (a cable, a
box edge, a shadow edge, glare, motion blur, a dropout), Gaussian blur, vignetting, Gaussian
noise and optional JPEG artefacts.

Pure numpy/OpenCV: this module never imports pymunk.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from tileviz.config import CameraConfig, FloorConfig
from tileviz.types import Pose

__all__ = [
    "FAULT_KINDS",
    "Fault",
    "FloorRenderer",
    "floor_point",
    "pixel_of",
    "random_camera",
    "random_floor",
]

_PERIOD_TILES = 16
"""The floor's appearance (tile brightness, texture, stains) repeats every this many tiles."""
_TEXELS_PER_TILE = 32
"""Resolution of the appearance texture, texels per tile side."""

# Fault parameters and their meaning (image frame: x = column, y = row, pixels; an ``angle`` is
# the direction of a straight edge as atan2(d_row, d_col), an ``offset`` the signed distance of
# that edge from the image centre along the normal (-sin angle, cos angle)).
_FAULT_PARAMS: dict[str, tuple[str, ...]] = {
    "cable": ("angle", "offset", "width", "gray"),
    "box": ("angle", "offset", "gray"),
    "shadow": ("angle", "offset", "strength", "softness"),
    "glare": ("x", "y", "radius", "strength"),
    "motion_blur": ("angle", "length"),
    "dropout": ("gray",),
}
FAULT_KINDS = tuple(_FAULT_PARAMS)
"""Camera faults :meth:`FloorRenderer.render` knows (docs/faults.md)."""


@dataclass(frozen=True)
class Fault:
    """A camera fault for one rendered frame.

    Kinds and parameters (pixels in the image frame; missing parameters are drawn from the
    render's ``rng``, or take a fixed default when it is None):

    - ``cable``: a dark straight band across the whole view: ``angle`` (rad), ``offset`` (px),
      ``width`` (px, default 1 cm on the floor, at least 3 px), ``gray`` (0..255, default 35).
    - ``box``: an object with a straight edge covering the half-plane beyond the edge line (its
      normal side): ``angle``, ``offset``, ``gray`` (default 150).
    - ``shadow``: the same half-plane darkened: ``strength`` (fraction of light removed, default
      0.5) with a soft edge of ``softness`` px (default 1.5).
    - ``glare``: a bright blob that saturates: centre ``x``, ``y`` (px), ``radius`` (px, default a
      quarter of the smaller image side), ``strength`` (default 1.0; 1.0 adds 400 gray levels at
      the centre).
    - ``motion_blur``: a straight blur of ``length`` px (default 25) along ``angle``.
    - ``dropout``: the camera delivers a uniform frame of ``gray`` (default 0).
    """

    kind: str
    params: Mapping[str, float] = field(default_factory=dict)


def floor_point(
    col: float, row: float, pose: Pose, camera: CameraConfig
) -> tuple[float, float]:
    """World (x, y) metres of the floor point seen at pixel (col, row) (docs/dataset-format.md)."""
    cx_px = (camera.width - 1) / 2.0
    cy_px = (camera.height - 1) / 2.0
    a_fwd = (cy_px - row) / camera.ppm
    a_left = (cx_px - col) / camera.ppm
    f, left = camera.offset
    ct, st = math.cos(pose.theta), math.sin(pose.theta)
    fx, fy = f + a_fwd, left + a_left
    return (pose.x + ct * fx - st * fy, pose.y + st * fx + ct * fy)


def pixel_of(x: float, y: float, pose: Pose, camera: CameraConfig) -> tuple[float, float]:
    """Pixel (col, row) where the world floor point (x, y) metres appears (may be outside)."""
    f, left = camera.offset
    ct, st = math.cos(pose.theta), math.sin(pose.theta)
    dx, dy = x - pose.x, y - pose.y
    a_fwd = ct * dx + st * dy - f
    a_left = -st * dx + ct * dy - left
    return (
        (camera.width - 1) / 2.0 - a_left * camera.ppm,
        (camera.height - 1) / 2.0 - a_fwd * camera.ppm,
    )


EDGE_FAULTS = ("cable", "box", "shadow")
"""Faults drawn along a straight edge (``angle``, ``offset``): objects that lie on the floor."""


def edge_to_floor(angle: float, offset: float, pose: Pose,
                  camera: CameraConfig) -> tuple[tuple[float, float], tuple[float, float]]:
    """Two world points (metres) of the fault edge (``angle`` rad, ``offset`` px, image frame as
    in :class:`Fault`) seen at ``pose``: the edge's foot from the image centre and the point one
    pixel further along it."""
    cx, cy = (camera.width - 1) / 2.0, (camera.height - 1) / 2.0
    u0, v0 = -math.sin(angle) * offset, math.cos(angle) * offset
    p = floor_point(cx + u0, cy + v0, pose, camera)
    q = floor_point(cx + u0 + math.cos(angle), cy + v0 + math.sin(angle), pose, camera)
    return p, q


def edge_in_image(p: tuple[float, float], q: tuple[float, float], pose: Pose,
                  camera: CameraConfig) -> tuple[float, float]:
    """(``angle`` rad, ``offset`` px) of the floor edge through world points ``p`` and ``q``
    seen at ``pose`` (the inverse of :func:`edge_to_floor`; the view is orthographic, so the
    edge keeps its place on the floor)."""
    cx, cy = (camera.width - 1) / 2.0, (camera.height - 1) / 2.0
    pc, pr = pixel_of(p[0], p[1], pose, camera)
    qc, qr = pixel_of(q[0], q[1], pose, camera)
    angle = math.atan2(qr - pr, qc - pc)
    offset = -math.sin(angle) * (pc - cx) + math.cos(angle) * (pr - cy)
    return angle, offset


def _periodic_smooth_noise(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    """n x n periodic Gaussian-filtered white noise (filter sigma ``scale`` texels), unit std."""
    white = rng.standard_normal((n, n))
    k = np.fft.fftfreq(n)
    k2 = k[:, None] ** 2 + k[None, :] ** 2
    smooth = np.fft.ifft2(np.fft.fft2(white) * np.exp(-2.0 * (math.pi * scale) ** 2 * k2)).real
    return smooth / max(float(smooth.std()), 1e-12)


_DATA = Path(__file__).resolve().parent / "data"


def _photo_texture(rng: np.random.Generator, k: int, r: int) -> np.ndarray:
    """A (k r) x (k r) texture of k x k tiles, each a random r x r crop of the gravel photograph
    (``data/gravel.png``, CC0) turned by a random quarter turn; zero mean."""
    img = cv2.imread(str(_DATA / "gravel.png"), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise ValueError(f"cannot read the floor photograph {_DATA / 'gravel.png'}")
    # each tile shows 0.5..1 of the photo's side
    out = np.empty((k * r, k * r), np.float64)
    n = img.shape[0]
    for ti in range(k):
        for tj in range(k):
            side = int(rng.integers(n // 2, n + 1))
            x0, y0 = (int(v) for v in rng.integers(0, n - side + 1, size=2))
            crop = cv2.resize(img[y0:y0 + side, x0:x0 + side], (r, r),
                              interpolation=cv2.INTER_AREA)
            out[ti * r:(ti + 1) * r, tj * r:(tj + 1) * r] = np.rot90(crop, int(rng.integers(4)))
    return out - out.mean()


def _appearance(floor: FloorConfig) -> np.ndarray:
    """The floor's multiplicative appearance over one period of 16 x 16 tiles, float32 texels
    (rows = y, columns = x, 32 texels a tile): tile brightness x texture x stains."""
    rng = np.random.default_rng(np.random.SeedSequence([int(floor.seed), 0x71E5]))
    k, r = _PERIOD_TILES, _TEXELS_PER_TILE
    n = k * r
    jitter = np.clip(rng.standard_normal((k, k)), -2.5, 2.5) * floor.tile_brightness_jitter
    tiles = np.repeat(np.repeat(1.0 + jitter, r, axis=0), r, axis=1)
    texture = (
        0.6 * _periodic_smooth_noise(rng, n, r / 3.0)
        + 0.6 * _periodic_smooth_noise(rng, n, r / 12.0)
        + 0.5 * _periodic_smooth_noise(rng, n, 1.0)
    )
    if floor.surface == "photo":
        texture = _photo_texture(rng, k, r)
    texture = 1.0 + floor.texture_strength * texture / texture.std()
    stains = np.ones((n, n))
    count = rng.poisson(floor.stains_per_tile * k * k)
    for _ in range(int(count)):
        cx, cy = rng.uniform(0, n, size=2)
        radius = rng.uniform(0.04, 0.18) * r
        depth = rng.uniform(0.08, 0.3)
        aspect = rng.uniform(0.5, 1.0)
        ang = rng.uniform(0, math.pi)
        half = int(math.ceil(radius * 2.5)) + 1
        ys = np.arange(int(cy) - half, int(cy) + half + 1)
        xs = np.arange(int(cx) - half, int(cx) + half + 1)
        dy = (ys - cy)[:, None]
        dx = (xs - cx)[None, :]
        u = dx * math.cos(ang) + dy * math.sin(ang)
        v = (-dx * math.sin(ang) + dy * math.cos(ang)) / aspect
        blob = depth * np.exp(-0.5 * (u * u + v * v) / (radius * radius))
        stains[np.ix_(ys % n, xs % n)] *= 1.0 - blob
    out = tiles * np.clip(texture, 0.3, 1.7) * stains
    return out.astype(np.float32)


def _layout(floor: FloorConfig) -> tuple[np.ndarray, np.ndarray] | None:
    """The offsets (tiles) of every tile, or every panel of ``panel_tiles`` x ``panel_tiles``
    tiles, off the lattice, over the 16 x 16 tile period: (x offsets, y offsets), each a
    (rows = y, columns = x) table uniform in +-``lattice_tolerance`` (at most 0.8 of the grout's
    half width, so that no tile reaches past its cell), or None for a perfect lattice. A grout
    line's centre, midway between its two tiles' edges, is then within the tolerance."""
    if floor.lattice_tolerance <= 0:
        return None
    half = 0.5 * (floor.seam_width if floor.panel_tiles else floor.grout_width)
    reach = min(floor.lattice_tolerance, 0.8 * max(half, 0.0)) / floor.tile_size
    rng = np.random.default_rng(np.random.SeedSequence([int(floor.seed), 0x1A1D]))
    k = _PERIOD_TILES
    n = floor.panel_tiles or 1
    out = []
    for _ in range(2):
        table = rng.uniform(-reach, reach, (k // n, k // n))
        out.append(np.repeat(np.repeat(table, n, axis=0), n, axis=1).astype(np.float32))
    return out[0], out[1]


class FloorRenderer:
    """Renders the downward camera's view of the tiled floor (HxWx3 uint8 RGB).

    ``floor``: the floor (tile size, grout, colours, appearance seed). ``camera``: ppm, image
    size, lever arm and the camera effects (noise, blur, vignetting, JPEG). The floor's appearance
    is computed once here; :meth:`render` then costs a few milliseconds at 320x240.
    """

    def __init__(self, floor: FloorConfig, camera: CameraConfig) -> None:
        if not isinstance(floor, FloorConfig):
            raise ValueError(f"floor must be a FloorConfig, got {type(floor).__name__}")
        if not isinstance(camera, CameraConfig):
            raise ValueError(f"camera must be a CameraConfig, got {type(camera).__name__}")
        self.floor = floor
        self.camera = camera
        w, h = int(camera.width), int(camera.height)
        self._u = (np.arange(w, dtype=np.float32) - np.float32((w - 1) / 2.0))[None, :]
        self._v = (np.arange(h, dtype=np.float32) - np.float32((h - 1) / 2.0))[:, None]
        self._appearance = _appearance(floor)
        self._tile_rgb = np.array(floor.tile_rgb, np.float32)
        self._grout_minus_tile = np.array(floor.grout_rgb, np.float32) - self._tile_rgb
        lp = floor.tile_size * camera.ppm
        self._tile_px = lp
        self._grout_half_px = 0.5 * floor.grout_width * camera.ppm
        self._seam_half_px = 0.5 * floor.seam_width * camera.ppm
        self._layout = _layout(floor)
        """Offsets of each tile (or panel) off the lattice, in tiles: (x, y) tables over the
        appearance's 16 x 16 tile period, or None for a perfect lattice."""
        self._tile2_minus_tile = np.array(floor.tile2_rgb, np.float32) - self._tile_rgb
        self._seam_minus_tile = np.array(floor.seam_rgb, np.float32) - self._tile_rgb
        r2 = self._u * self._u + self._v * self._v
        r2max = float((w - 1) ** 2 + (h - 1) ** 2) / 4.0
        self._vignette = (1.0 - camera.vignetting * r2 / max(r2max, 1.0)).astype(np.float32)
        if floor.light_gradient > 0:
            # uneven light: falling off linearly from the image's left edge to its right edge
            ramp = 1.0 - floor.light_gradient * (self._u / max(w - 1.0, 1.0) + 0.5)
            self._vignette = (self._vignette * ramp).astype(np.float32)
        vig = np.clip(self._vignette, 0.0, 1.0)
        self._vignette = np.ascontiguousarray(np.repeat(vig[..., None], 3, axis=2))
        # Noise: a fixed field of twice the image size (the same in the three channels, i.e.
        # luminance noise); each frame adds a window of it at an offset drawn from its rng.
        noise_rng = np.random.default_rng(np.random.SeedSequence([int(floor.seed), 0x401E]))
        field = (noise_rng.standard_normal((2 * h, 2 * w)) * camera.noise_sigma).astype(
            np.float32
        )
        self._noise = np.ascontiguousarray(np.repeat(field[..., None], 3, axis=2))

    # ------------------------------------------------------------------ floor
    def floor_image(self, pose: Pose) -> np.ndarray:
        """The noise-free, blur-free floor radiance seen at ``pose``: HxWx3 float32, 0..255."""
        if not isinstance(pose, Pose):
            raise ValueError(f"pose must be a Pose, got {type(pose).__name__}")
        x, y, theta = float(pose.x), float(pose.y), float(pose.theta)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(theta)):
            raise ValueError(f"pose must be finite, got {pose!r}")
        cam = self.camera
        lsize = self.floor.tile_size
        f, left = cam.offset
        ct, st = math.cos(theta), math.sin(theta)
        cxw = x + f * ct - left * st
        cyw = y + f * st + left * ct
        # World point of pixel (u, v) relative to the image centre (docs/dataset-format.md):
        # a_fwd = -v/ppm, a_left = -u/ppm, p = c + R(theta) a; in tiles X = p_x / L, Y = p_y / L.
        k = 1.0 / (cam.ppm * lsize)
        x0, y0 = cxw / lsize, cyw / lsize
        ix0, iy0 = math.floor(x0), math.floor(y0)
        fx0, fy0 = np.float32(x0 - ix0), np.float32(y0 - iy0)
        ax, bx = np.float32(st * k), np.float32(-ct * k)
        ay, by = np.float32(-ct * k), np.float32(-st * k)
        gx = fx0 + ax * self._u + bx * self._v
        gy = fy0 + ay * self._u + by * self._v
        if self.floor.kind == "checker" or self._layout is not None or self.floor.panel_tiles:
            return self._laid_floor(gx, gy, ix0, iy0, float(ax), float(bx), float(ay),
                                    float(by))
        # Grout coverage: the overlap of each pixel's footprint [d - 1/2, d + 1/2] (along the
        # axis normal to the line) with the grout band [-w/2, w/2]; the union of both families.
        cov = self._coverage(gx)
        np.maximum(cov, self._coverage(gy), out=cov)
        # Appearance texture (periodic over 16 tiles), sampled bilinearly.
        mx = self._texture_map(gx, ix0, float(ax), float(bx))
        my = self._texture_map(gy, iy0, float(ay), float(by))
        shade = cv2.remap(self._appearance, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        # colour = shade * (tile + cov * (grout - tile)), channel by channel (OpenCV, rather than
        # numpy broadcasting over a last axis of 3)
        cov *= shade
        return cv2.merge(
            [
                cv2.addWeighted(shade, float(t), cov, float(d), 0.0)
                for t, d in zip(self._tile_rgb, self._grout_minus_tile, strict=True)
            ]
        )

    def _laid_floor(self, gx: np.ndarray, gy: np.ndarray, ix0: int, iy0: int, ax: float,
                    bx: float, ay: float, by: float) -> np.ndarray:
        """:meth:`floor_image` for a checkerboard, a floor laid off the lattice (tiles or panels
        offset by up to ``lattice_tolerance``) or a mosaic of panels: ``gx``, ``gy`` the tile
        coordinates of the pixels relative to the tile (``ix0``, ``iy0``)."""
        floor = self.floor
        mx = self._texture_map(gx, ix0, ax, bx)
        my = self._texture_map(gy, iy0, ay, by)
        shade = cv2.remap(self._appearance, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        ti = np.floor(gx).astype(np.int64) + ix0  # the cell of each pixel, in tiles
        tj = np.floor(gy).astype(np.int64) + iy0
        if floor.kind == "checker":
            # each family: +-1 on alternate tiles, a linear ramp across the pixel at an edge
            sx = self._square_wave(gx, ix0)
            sy = self._square_wave(gy, iy0)
            half = 0.5 * (1.0 - sx * sy)  # 0 on the tiles of tile_rgb, 1 on those of tile2_rgb
            weight = (half * shade).astype(np.float32)
            return cv2.merge([cv2.addWeighted(shade, float(t), weight, float(d), 0.0) for t, d in
                              zip(self._tile_rgb, self._tile2_minus_tile, strict=True)])
        cov_x, seam_x = self._laid_coverage(gx, ix0, tj, 0)
        cov_y, seam_y = self._laid_coverage(gy, iy0, ti, 1)
        cov = np.maximum(cov_x, cov_y)
        seam = np.maximum(seam_x, seam_y)
        cov = np.minimum(cov, 1.0 - seam)
        cov *= shade
        seam *= shade
        return cv2.merge([
            cv2.addWeighted(cv2.addWeighted(shade, float(t), cov, float(d), 0.0), 1.0,
                            seam, float(e), 0.0)
            for t, d, e in zip(self._tile_rgb, self._grout_minus_tile, self._seam_minus_tile,
                               strict=True)])

    def _square_wave(self, g: np.ndarray, i0: int) -> np.ndarray:
        """+1 on the tiles of even index along one family's normal (``i0 + g``, tiles), -1 on
        the odd ones, ramping linearly across the one pixel that straddles an edge."""
        n = np.rint(g)
        d = (g - n) * np.float32(self._tile_px)  # signed px from the nearest edge
        parity = ((n.astype(np.int64) + i0) & 1).astype(np.float32)
        right = 1.0 - 2.0 * parity  # the sign of the tile on the positive side of that edge
        return (right * np.clip(2.0 * d, -1.0, 1.0)).astype(np.float32)

    def _laid_coverage(self, g: np.ndarray, i0: int, across: np.ndarray,
                       axis: int) -> tuple[np.ndarray, np.ndarray]:
        """Coverage of each pixel by the nearest line of one family (``g``: tiles along the
        family's normal, relative to tile ``i0``; ``across``: each pixel's cell index along the
        line): (grout, seam). The band between the two tiles
        beside that line spans from the first tile's far edge to the second's near edge, each
        tile shifted by its layout offset (``axis`` 0: x offsets, 1: y)."""
        n = np.rint(g)
        edge = n.astype(np.int64) + i0  # the line's index: between cells edge - 1 and edge
        p = _PERIOD_TILES
        panel = self.floor.panel_tiles
        if self._layout is None:
            lo_off = hi_off = np.zeros_like(g)
        else:
            table = self._layout[axis]
            row = across % p
            lo_off = table[row, (edge - 1) % p] if axis == 0 else table[(edge - 1) % p, row]
            hi_off = table[row, edge % p] if axis == 0 else table[edge % p, row]
        seam_line = (edge % panel == 0) if panel else np.zeros(g.shape, bool)
        half = np.where(seam_line, np.float32(self._seam_half_px),
                        np.float32(self._grout_half_px))
        tile_px = np.float32(self._tile_px)
        # the band [edge + lo_off - half, edge + hi_off + half] in px from the pixel's centre
        d = (g - n) * tile_px
        b_lo = lo_off * tile_px - half
        b_hi = hi_off * tile_px + half
        hi = np.minimum(d + np.float32(0.5), b_hi)
        lo = np.maximum(d - np.float32(0.5), b_lo)
        cov = np.clip(hi - lo, 0.0, 1.0).astype(np.float32)
        seam = np.where(seam_line, cov, np.float32(0.0)).astype(np.float32)
        return np.where(seam_line, np.float32(0.0), cov).astype(np.float32), seam

    def _texture_map(self, g: np.ndarray, i0: int, a: float, b: float) -> np.ndarray:
        """Texel coordinates of the appearance texture for tile coordinates ``i0 + g`` (g affine
        in the pixel offsets: ``g = g0 + a u + b v``), shifted by whole periods into the
        texture; wrapped pixel by pixel only when the view spans more than one period (OpenCV's
        remap is slow for coordinates far outside its source)."""
        tpt = float(_TEXELS_PER_TILE)
        n = float(_PERIOD_TILES * _TEXELS_PER_TILE)
        g0 = float(g[0, 0]) - a * float(self._u[0, 0]) - b * float(self._v[0, 0])
        u0, u1 = float(self._u[0, 0]), float(self._u[0, -1])
        v0, v1 = float(self._v[0, 0]), float(self._v[-1, 0])
        lo = g0 + min(a * u0, a * u1) + min(b * v0, b * v1)
        hi = g0 + max(a * u0, a * u1) + max(b * v0, b * v1)
        base = (i0 % _PERIOD_TILES) * tpt - 0.5
        shift = math.floor((base + lo * tpt) / n) * n
        m = g * np.float32(tpt)
        m += np.float32(base - shift)
        if base + hi * tpt - shift >= n - 1.0:
            m -= np.float32(n) * np.floor(m * np.float32(1.0 / n))
        return m

    def _coverage(self, g: np.ndarray) -> np.ndarray:
        """Fraction of each pixel covered by the nearest grout line of one family (``g`` in tiles
        along that family's normal)."""
        d = np.abs(g - np.rint(g))
        d *= np.float32(self._tile_px)
        hw = np.float32(self._grout_half_px)
        hi = np.minimum(d + np.float32(0.5), hw)
        lo = np.maximum(d - np.float32(0.5), -hw)
        hi -= lo
        return np.clip(hi, 0.0, 1.0, out=hi)

    # ------------------------------------------------------------------ render
    def render(
        self,
        pose: Pose,
        rng: np.random.Generator | None = None,
        faults: Iterable[Fault | tuple[str, Mapping[str, float]]] | None = None,
    ) -> np.ndarray:
        """The camera image at ``pose``: HxWx3 uint8 RGB.

        ``rng``: draws the image noise (and any fault parameter left unspecified); None renders
        without noise, deterministically. ``faults``: :class:`Fault` objects or ``(kind, params)``
        pairs (``tileviz.sim.source`` passes pairs), applied in order.
        """
        cam = self.camera
        specs = self._resolve_faults(faults, rng)
        for kind, p in specs:
            if kind == "dropout":
                return np.full((cam.height, cam.width, 3), int(round(p["gray"])), np.uint8)
        img = self.floor_image(pose)
        blur_faults = []
        for kind, p in specs:
            if kind == "motion_blur":
                blur_faults.append(p)
            else:
                self._apply_scene_fault(img, kind, p)
        for p in blur_faults:
            img = cv2.filter2D(img, -1, _line_kernel(p["angle"], p["length"]))
        if cam.blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), cam.blur_sigma)
        if cam.vignetting > 0 or self.floor.light_gradient > 0:
            img = cv2.multiply(img, self._vignette)
        if rng is not None and cam.noise_sigma > 0:
            h, w = cam.height, cam.width
            oy = int(rng.integers(0, h + 1))
            ox = int(rng.integers(0, w + 1))
            img = cv2.add(img, self._noise[oy : oy + h, ox : ox + w])
        # saturate to 0..255 and round (convertScaleAbs rounds and saturates |x|; x >= 0 here)
        out = cv2.convertScaleAbs(cv2.max(img, 0.0))
        if cam.jpeg_quality > 0:
            ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(cam.jpeg_quality)])
            if ok:
                out = cv2.imdecode(buf, cv2.IMREAD_COLOR)  # channel order unchanged: RGB stays RGB
        return out

    # ------------------------------------------------------------------ faults
    def resolve_faults(
        self,
        faults: Iterable[Fault | tuple[str, Mapping[str, float]]] | None,
        rng: np.random.Generator | None,
    ) -> list[tuple[str, dict[str, float]]]:
        """The faults validated, every parameter filled in (drawn from ``rng`` where missing,
        fixed defaults when it is None): ``(kind, params)`` pairs :meth:`render` takes as they
        are. Raises ValueError naming a bad fault or parameter."""
        return self._resolve_faults(faults, rng)

    def _resolve_faults(
        self,
        faults: Iterable[Fault | tuple[str, Mapping[str, float]]] | None,
        rng: np.random.Generator | None,
    ) -> list[tuple[str, dict[str, float]]]:
        """Validate the faults and fill in their missing parameters."""
        if faults is None:
            return []
        out = []
        cam = self.camera
        side = float(min(cam.width, cam.height))
        for item in faults:
            if isinstance(item, Fault):
                kind, params = item.kind, dict(item.params)
            else:
                try:
                    kind, raw = item
                    params = dict(raw)
                except (TypeError, ValueError):
                    raise ValueError(
                        f"a camera fault must be a Fault or a (kind, params) pair, got {item!r}"
                    ) from None
            if kind not in _FAULT_PARAMS:
                raise ValueError(f"unknown camera fault {kind!r} (choose from {FAULT_KINDS})")
            allowed = _FAULT_PARAMS[kind]
            for name, value in params.items():
                if name not in allowed:
                    raise ValueError(f"unknown parameter {name!r} for camera fault {kind!r}")
                if not isinstance(value, (int, float)) or not math.isfinite(value):
                    raise ValueError(f"{kind} {name} must be a finite number, got {value!r}")

            def draw(name: str, lo: float, hi: float, fixed: float, p: dict = params) -> None:
                if name not in p:
                    p[name] = float(rng.uniform(lo, hi)) if rng is not None else fixed

            if kind in ("cable", "box", "shadow", "motion_blur"):
                draw("angle", 0.0, math.pi, 0.4)
            if kind in ("cable", "box", "shadow"):
                draw("offset", -0.25 * side, 0.25 * side, 0.1 * side)
            if kind == "cable":
                draw("width", max(3.0, 0.01 * cam.ppm), max(3.0, 0.01 * cam.ppm),
                     max(3.0, 0.01 * cam.ppm))
                draw("gray", 35.0, 35.0, 35.0)
            elif kind == "box":
                draw("gray", 150.0, 150.0, 150.0)
            elif kind == "shadow":
                draw("strength", 0.5, 0.5, 0.5)
                draw("softness", 1.5, 1.5, 1.5)
            elif kind == "glare":
                draw("x", 0.25 * cam.width, 0.75 * cam.width, 0.5 * cam.width)
                draw("y", 0.25 * cam.height, 0.75 * cam.height, 0.5 * cam.height)
                draw("radius", 0.25 * side, 0.25 * side, 0.25 * side)
                draw("strength", 1.0, 1.0, 1.0)
            elif kind == "motion_blur":
                draw("length", 25.0, 25.0, 25.0)
            elif kind == "dropout":
                draw("gray", 0.0, 0.0, 0.0)
            for name in ("width", "radius", "length", "softness"):
                if name in params and params[name] < 0:
                    raise ValueError(f"{kind} {name} must be >= 0, got {params[name]!r}")
            out.append((kind, params))
        return out

    def _signed_distance(self, angle: float, offset: float) -> np.ndarray:
        """HxW float32: signed distance (px) of each pixel from the edge line (angle, offset)."""
        nx, ny = np.float32(-math.sin(angle)), np.float32(math.cos(angle))
        return nx * self._u + ny * self._v - np.float32(offset)

    def _apply_scene_fault(self, img: np.ndarray, kind: str, p: dict[str, float]) -> None:
        """Draw a fault into the scene radiance ``img`` (HxWx3 float32), in place."""
        if kind == "cable":
            d = np.abs(self._signed_distance(p["angle"], p["offset"]))
            hw = 0.5 * p["width"]
            cov = np.clip(np.minimum(d + 0.5, hw) - np.maximum(d - 0.5, -hw), 0.0, 1.0)
            img += cov[..., None] * (np.float32(p["gray"]) - img)
        elif kind == "box":
            d = self._signed_distance(p["angle"], p["offset"])
            cov = np.clip(d + 0.5, 0.0, 1.0)[..., None]
            img += cov * (np.float32(p["gray"]) * np.array([1.0, 0.8, 0.55], np.float32) - img)
        elif kind == "shadow":
            d = self._signed_distance(p["angle"], p["offset"])
            soft = max(p["softness"], 1e-3)
            t = np.clip(d / np.float32(soft) + 0.5, 0.0, 1.0)
            img *= (1.0 - np.float32(p["strength"]) * t)[..., None]
        elif kind == "glare":
            du = self._u - np.float32(p["x"] - (self.camera.width - 1) / 2.0)
            dv = self._v - np.float32(p["y"] - (self.camera.height - 1) / 2.0)
            r = max(p["radius"], 1e-3)
            blob = np.exp((du * du + dv * dv) * np.float32(-0.5 / (r * r)))
            img += (np.float32(400.0 * p["strength"]) * blob)[..., None]


def _line_kernel(angle: float, length: float) -> np.ndarray:
    """A normalised straight motion-blur kernel of ``length`` px along ``angle`` (rad)."""
    n = max(1, int(math.ceil(length)))
    size = n + 3 if n % 2 == 0 else n + 2  # odd: the kernel is centred on a pixel
    k = np.zeros((size, size), np.float32)
    c = (size - 1) / 2.0
    dx, dy = math.cos(angle), math.sin(angle)
    for t in np.linspace(-length / 2.0, length / 2.0, 4 * n + 1):
        x, y = c + t * dx, c + t * dy
        x0, y0 = int(math.floor(x)), int(math.floor(y))
        fx, fy = x - x0, y - y0
        for yy, xx, w in (
            (y0, x0, (1 - fx) * (1 - fy)),
            (y0, x0 + 1, fx * (1 - fy)),
            (y0 + 1, x0, (1 - fx) * fy),
            (y0 + 1, x0 + 1, fx * fy),
        ):
            if 0 <= yy < size and 0 <= xx < size:
                k[yy, xx] += w
    return k / k.sum()


def random_floor(rng: np.random.Generator) -> FloorConfig:
    """A random floor for studies and tests: tile size 0.166..1 m, grout 3..15 mm (at most a
    fifth of the tile), bright tiles and darker grout of random tints, per-tile brightness
    jitter 0..0.1, texture 0..0.12, 0..1 stains per tile, a random appearance seed."""
    tile = float(rng.uniform(0.166, 1.0))
    grout = float(min(rng.uniform(0.003, 0.015), 0.2 * tile))
    base = rng.uniform(150, 230)
    tile_rgb = tuple(int(round(base * t)) for t in rng.uniform(0.85, 1.0, size=3))
    g = rng.uniform(40, 130)
    grout_rgb = tuple(int(round(g * t)) for t in rng.uniform(0.9, 1.0, size=3))
    return FloorConfig(
        tile_size=tile,
        grout_width=grout,
        tile_rgb=tile_rgb,  # type: ignore[arg-type]
        grout_rgb=grout_rgb,  # type: ignore[arg-type]
        tile_brightness_jitter=float(rng.uniform(0.0, 0.1)),
        texture_strength=float(rng.uniform(0.0, 0.12)),
        stains_per_tile=float(rng.uniform(0.0, 1.0)),
        seed=int(rng.integers(0, 2**31)),
    )


def random_camera(rng: np.random.Generator) -> CameraConfig:
    """A random camera for studies and tests: 100..700 px/m, 320x240 or 256x384, lever arm
    0.3 m, noise 0..8 gray levels, blur 0..1.5 px, vignetting 0..0.3, and JPEG (quality
    40..95) one time in three."""
    w, h = ((320, 240), (256, 384))[int(rng.integers(0, 2))]
    return CameraConfig(
        ppm=float(rng.uniform(100.0, 700.0)),
        width=w,
        height=h,
        offset=(0.3, 0.0),
        noise_sigma=float(rng.uniform(0.0, 8.0)),
        blur_sigma=float(rng.uniform(0.0, 1.5)),
        vignetting=float(rng.uniform(0.0, 0.3)),
        jpeg_quality=int(rng.integers(40, 96)) if rng.uniform() < 1 / 3 else 0,
    )
