"""Tiled-floor views rendered independently of ``tileviz.sim.camera`` (for the vision study).

This module shares no code with the product's renderer: it samples every pixel at 3 x 3 points
(box-filter anti-aliasing) straight from the floor's definition, so the study does not tune the
extractor to the renderer's own quirks. Conventions are those of ``docs/dataset-format.md``: an
orthographic downward camera, ``ppm`` pixels per metre, image centre ``((W-1)/2, (H-1)/2)``; a
pixel ``(col, row)`` sees the floor point ``c + R(theta) a`` with ``a_forward = -(row - cy)/ppm``
and ``a_left = -(col - cx)/ppm``; grout line centres on ``x = kL`` and ``y = kL``.

Floor families (:data:`FAMILIES`), each drawn at random by :func:`draw_floor`:

- ``plain``: light tiles, dark grout 1..6 px, a little per-tile shade;
- ``light_grout``: grout lighter than the tiles;
- ``wide_grout``: grout 8..20 px wide, darker or lighter;
- ``shade_steps``: neighbouring tiles of strongly different shades (steps of up to 150 levels);
- ``photo``: real photographs on the tiles (scikit-image's CC0 ``brick``, ``grass`` and
  ``gravel`` samples; docs/vision.md), each tile a different crop and quarter turn;
- ``terrazzo``: speckled stone (chips of random size and shade);
- ``wood``: wavy grain along one tile axis, the axis alternating from tile to tile;
- ``degraded``: any surface above with heavy noise, blur, vignetting, a lighting gradient, JPEG;
- ``coarse``: thin grout (about 1 px) at 100..140 px/m;

and the floors a user declares (:data:`DECLARED_FAMILIES`: their ``FloorSpec.kind`` and
``lattice_tolerance`` are what such a floor's meta.json declares, :attr:`FloorSpec.model`):

- ``checker``: tiles of two shades (60..180 levels apart) alternating edge to edge, no grout;
  a third of them (drawn from the floor's own seed) two hues of nearly one luma (within 0..20
  levels) instead;
- ``hand_laid``: every tile laid up to 0.3..2.5 % of the tile off the lattice (its edges and the
  grout between them move; the grout 2..8 px);
- ``mosaic``: panels of 3..5 x 3..5 small tiles with seams 2..3 x the grout's width, each panel
  laid up to 1..3 % of a tile off the lattice;
- ``faint_colour``: grout of nearly the tiles' luma (within 2..6 levels) but of another hue.

Corruptions (:data:`CORRUPTIONS`): a cable, the edge of a box, a shadow edge, glare, motion blur.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from tileviz.config import FloorModel
from tileviz.testing import missing

FAMILIES = ("plain", "light_grout", "wide_grout", "shade_steps", "photo", "terrazzo", "wood",
            "degraded", "coarse")
DECLARED_FAMILIES = ("checker", "hand_laid", "mosaic", "faint_colour")
ALL_FAMILIES = FAMILIES + DECLARED_FAMILIES
CORRUPTIONS = ("cable", "box", "shadow", "glare", "motion_blur")
PHOTOS = ("brick", "grass", "gravel")
SS = 3
"""Samples per pixel side."""


@functools.cache
def photo(name: str) -> np.ndarray:
    """A photograph shipped by scikit-image (CC0), gray float32 0..1, 512 x 512."""
    try:
        import skimage.data
    except ImportError as exc:
        raise ImportError(missing("scikit-image", "the photo floors")) from exc

    img = getattr(skimage.data, name)()
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    return img.astype(np.float32) / 255.0


@dataclass
class FloorSpec:
    """One random floor and camera. Lengths in metres unless ``_px``; shades 0..255."""

    family: str
    tile_size: float
    ppm: float
    grout_px: float
    grout_shade: float
    tile_shade: float
    shade_spread: float  # per-tile shade: tile_shade +- shade_spread (uniform)
    surface: str  # flat, photo:<name>, terrazzo, wood
    surface_amp: float  # relative amplitude of the surface texture
    width: int = 320
    height: int = 240
    noise: float = 2.0
    blur: float = 0.5
    vignetting: float = 0.0
    gradient: float = 0.0  # relative lighting change across the view
    jpeg: int = 0
    seed: int = 0
    extra: dict = field(default_factory=dict)
    kind: str = "grout"  # grout, or checker (tile_shade and grout_shade alternate, no grout)
    lattice_tolerance: float = 0.0  # metres: each tile (panel) laid within this off the lattice
    panel: int = 0  # tiles per panel side (0: no panels); seams seam_px wide
    seam_px: float = 0.0
    tint: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    """RGB of the tiles and of the grout (0..255) when they differ in hue, else None."""
    second: tuple[float, float] | None = None
    """The width (px) and shade of the joints along y = kL when they differ from those along
    x = kL (a mosaic whose two families of joints differ), else None. No family draws it."""
    fill: tuple[int, float, float] | None = None
    """Every n-th joint of each family (joint index k % n == 0) filled along its centre line
    with another material: (n, the share of the joint's width filled, its shade), else None
    (dirt in a paver mosaic's joints). No family draws it. Both only on a floor laid on the
    lattice (no ``lattice_tolerance``, no ``panel``: :func:`render` raises ValueError)."""
    band_shade: float | None = None
    """On a checkerboard, the shade of a grout ``grout_px`` wide centred on the tiles' edges
    (a thin grout between marble squares), else None (``grout_px`` 0: edge to edge). No
    family draws it."""

    @property
    def model(self) -> FloorModel:
        """What a meta.json declares of this floor."""
        return FloorModel(self.kind, self.lattice_tolerance)  # type: ignore[arg-type]


def draw_floor(family: str, rng: np.random.Generator) -> FloorSpec:
    """A random floor and camera of ``family`` (see the module docstring)."""
    lp = float(rng.uniform(80.0, 240.0))  # tile period, px
    ppm = float(rng.uniform(150.0, 650.0))
    tile = lp / ppm
    dark = bool(rng.uniform() < 0.5)
    spec = FloorSpec(
        family=family, tile_size=tile, ppm=ppm, grout_px=float(rng.uniform(1.5, 6.0)),
        grout_shade=float(rng.uniform(30, 120)), tile_shade=float(rng.uniform(150, 225)),
        shade_spread=float(rng.uniform(0, 15)), surface="flat", surface_amp=0.0,
        noise=float(rng.uniform(0.5, 4.0)), blur=float(rng.uniform(0.0, 1.0)),
        vignetting=float(rng.uniform(0.0, 0.15)), seed=int(rng.integers(0, 2**31)),
    )
    if family == "light_grout":
        spec.tile_shade = float(rng.uniform(50, 150))
        spec.grout_shade = float(rng.uniform(spec.tile_shade + 50, 245))
        spec.grout_px = float(rng.uniform(1.5, 8.0))
    elif family == "wide_grout":
        spec.grout_px = float(rng.uniform(8.0, 20.0))
        if not dark:
            spec.tile_shade = float(rng.uniform(50, 140))
            spec.grout_shade = float(rng.uniform(spec.tile_shade + 50, 240))
    elif family == "shade_steps":
        spec.grout_px = float(rng.uniform(2.0, 8.0))
        if dark:
            spec.tile_shade, spec.shade_spread = 155.0, 75.0
            spec.grout_shade = float(rng.uniform(10, 50))
        else:
            spec.tile_shade, spec.shade_spread = 100.0, 75.0
            spec.grout_shade = float(rng.uniform(205, 245))
    elif family == "photo":
        spec.surface = "photo:" + PHOTOS[int(rng.integers(0, len(PHOTOS)))]
        spec.surface_amp = float(rng.uniform(0.3, 0.8))
        spec.grout_px = float(rng.uniform(2.0, 10.0))
        if not dark:
            spec.tile_shade = float(rng.uniform(80, 140))
            spec.grout_shade = float(rng.uniform(200, 245))
    elif family == "terrazzo":
        spec.surface = "terrazzo"
        spec.surface_amp = float(rng.uniform(0.2, 0.4))
        spec.tile_shade = float(rng.uniform(130, 170))
        spec.grout_shade = float(rng.uniform(15, 60))
        spec.grout_px = float(rng.uniform(1.5, 8.0))
    elif family == "wood":
        spec.surface = "wood"
        spec.surface_amp = float(rng.uniform(0.1, 0.3))
        spec.tile_shade = float(rng.uniform(120, 200))
        spec.grout_shade = float(rng.uniform(20, 70))
        spec.grout_px = float(rng.uniform(1.5, 5.0))
    elif family == "degraded":
        base = draw_floor(FAMILIES[int(rng.integers(0, 7))], rng)
        base.family = family
        base.noise = float(rng.uniform(5.0, 10.0))
        base.blur = float(rng.uniform(0.8, 1.8))
        base.vignetting = float(rng.uniform(0.15, 0.4))
        base.gradient = float(rng.uniform(0.2, 0.5))
        base.jpeg = int(rng.integers(30, 80))
        return base
    elif family == "coarse":
        ppm = float(rng.uniform(100.0, 140.0))
        spec.ppm = ppm
        spec.tile_size = float(rng.uniform(0.8, 1.6))
        spec.grout_px = float(rng.uniform(0.8, 1.5))
        spec.grout_shade = float(rng.uniform(20, 80))
    elif family == "checker":
        spec.kind = "checker"
        spec.grout_px = 0.0
        spec.tile_shade = float(rng.uniform(20, 90))
        spec.grout_shade = float(rng.uniform(spec.tile_shade + 60,
                                             min(245.0, spec.tile_shade + 180)))
        spec.shade_spread = float(rng.uniform(0, 8))
        if rng.uniform() < 0.5:  # marble-like
            spec.surface, spec.surface_amp = "terrazzo", float(rng.uniform(0.05, 0.15))
        # a coloured pair, from the floor's own seed (the family's other draws unchanged)
        own = np.random.default_rng([spec.seed, 97])
        if own.uniform() < 1.0 / 3.0:
            pale, deep = _hues(own, float(own.uniform(60, 190)), float(own.uniform(0, 20)))
            spec.tint = (tuple(deep.tolist()), tuple(pale.tolist()))
            spec.grout_shade = float(np.dot(_LUMA, pale))
            spec.tile_shade = float(np.dot(_LUMA, deep))
    elif family == "hand_laid":
        spec.grout_px = float(rng.uniform(2.0, 8.0))
        spec.lattice_tolerance = float(rng.uniform(0.003, 0.025)) * tile
        # the grout is never closed: a tile moves at most 0.4 grout widths toward its neighbour
        spec.lattice_tolerance = min(spec.lattice_tolerance, 0.4 * spec.grout_px / ppm)
    elif family == "mosaic":
        spec.grout_px = float(rng.uniform(1.5, 4.0))
        spec.panel = int(rng.integers(3, 6))
        spec.seam_px = spec.grout_px * float(rng.uniform(2.0, 3.0))
        spec.lattice_tolerance = min(float(rng.uniform(0.01, 0.03)) * tile,
                                     0.4 * spec.seam_px / ppm)
    elif family == "faint_colour":
        spec.grout_px = float(rng.uniform(2.0, 6.0))
        grey = np.array([float(rng.uniform(120, 180))] * 3)
        hued = _hue_shift(rng, grey, 25, 45)
        grout = np.clip(hued - float(rng.uniform(2, 6)) * float(rng.choice([-1, 1])), 0, 255)
        spec.tint = (tuple(grey.tolist()), tuple(grout.tolist()))
        spec.tile_shade = float(np.dot(_LUMA, grey))
        spec.grout_shade = float(np.dot(_LUMA, grout))
    elif family != "plain":
        raise ValueError(f"unknown floor family {family!r}")
    return spec


_LUMA = np.array([0.299, 0.587, 0.114])
"""The luma's weights of R, G, B."""


def banded_checker(seed: int, families: str = "one") -> FloorSpec:
    """A checkerboard (dark squares 50..110, light 160..220 levels, flat, noise 2, blur
    0.5..0.8 px, 90..200 px a tile) with a grout band 4..9 px wide centred on the edges between
    its tiles, along one family of lines (``families`` ``one``: the lines y = kL) or both
    (``both``), 2..16 levels darker than the dark squares (1..32 % of the step between the
    shades, mostly under 15 %: its far side is a faint edge). The lattice's lines are the bands'
    centres; a camera that does not see a band sees the edge where the light tile meets it,
    half its width off the line. Drawn from ``seed`` alone."""
    rng = np.random.default_rng([seed, 7103])
    spec = draw_floor("checker", rng)
    lp = float(rng.uniform(90.0, 200.0))
    ppm = float(rng.uniform(300.0, 600.0))
    dark = float(rng.uniform(50.0, 110.0))
    light = float(rng.uniform(160.0, 220.0))
    width = float(rng.uniform(4.0, 9.0))
    band = dark - float(rng.uniform(2.0, 16.0))
    spec.tile_size, spec.ppm, spec.grout_shade, spec.tile_shade = lp / ppm, ppm, dark, light
    spec.shade_spread = float(rng.uniform(0.0, 6.0))
    spec.surface, spec.surface_amp, spec.noise = "flat", 0.0, 2.0
    spec.blur = float(rng.uniform(0.5, 0.8))
    spec.vignetting = spec.gradient = 0.0
    spec.jpeg, spec.tint, spec.band_shade, spec.seed = 0, None, band, seed
    if families == "one":
        spec.grout_px, spec.second = 0.0, (width, band)
    else:
        spec.grout_px, spec.second = width, None
    return spec


def _hue_shift(rng: np.random.Generator, grey: np.ndarray, lo: float, hi: float
               ) -> np.ndarray:
    """``grey`` (RGB) moved by a random hue of no luma, ``lo``..``hi`` levels in its largest
    channel (not clipped)."""
    hue = rng.normal(0.0, 1.0, 3)
    hue -= np.dot(hue, _LUMA) / np.dot(_LUMA, _LUMA) * _LUMA  # no luma change
    hue *= float(rng.uniform(lo, hi)) / float(np.abs(hue).max())
    return grey + hue


def _hues(rng: np.random.Generator, level: float, apart: float
          ) -> tuple[np.ndarray, np.ndarray]:
    """Two colours (RGB) of a coloured checkerboard about ``level``: hues 60..120 levels apart
    in their largest channel, the second ``apart`` levels of luma darker."""
    grey = np.array([level] * 3)
    return grey, np.clip(_hue_shift(rng, grey, 60, 120) - apart, 0, 255)


def _hash(i: np.ndarray, j: np.ndarray, seed: int, salt: int) -> np.ndarray:
    """A uniform 0..1 value per tile (i, j), from integer hashing (vectorised)."""
    h = (i.astype(np.int64) * 73856093) ^ (j.astype(np.int64) * 19349663) ^ (seed * 83492791)
    h = (h ^ salt) & 0xFFFFFFFF
    h = (h * 2654435761) & 0xFFFFFFFF
    h ^= h >> 15
    h = (h * 2246822519) & 0xFFFFFFFF
    h ^= h >> 13
    return (h & 0xFFFFFF).astype(np.float64) / float(0x1000000)


def _surface(spec: FloorSpec, i: np.ndarray, j: np.ndarray, fx: np.ndarray, fy: np.ndarray
             ) -> np.ndarray:
    """Relative surface modulation (about 0) at tile-local coordinates fx, fy in [0, 1)."""
    if spec.surface == "flat":
        return np.zeros_like(fx)
    if spec.surface.startswith("photo:"):
        tex = photo(spec.surface[6:])
        n = tex.shape[0]
        # each tile: its own crop (offset) and quarter turn; the photo spans 0.6..1 tile
        scale = n * (0.6 + 0.4 * _hash(i, j, spec.seed, 7))
        turn = (4 * _hash(i, j, spec.seed, 11)).astype(np.int64)
        u, v = fx, fy
        u, v = (np.where(turn == 1, 1 - v, np.where(turn == 2, 1 - u, np.where(turn == 3, v, u))),
                np.where(turn == 1, u, np.where(turn == 2, 1 - v, np.where(turn == 3, 1 - u, v))))
        ox = _hash(i, j, spec.seed, 13) * n
        oy = _hash(i, j, spec.seed, 17) * n
        cx = ((u * scale + ox) % n).astype(np.int64)
        cy = ((v * scale + oy) % n).astype(np.int64)
        val = tex[cy, cx]
        return (val - 0.5) * 2.0 * spec.surface_amp
    if spec.surface == "terrazzo":
        # chips: a hashed grid of cells, each cell a chip of random shade and size
        cells = 9.0 + 6.0 * _hash(i, j, spec.seed, 3)
        # the chips' grid is turned by a random angle per tile (never along the grout)
        rot = 2.0 * math.pi * _hash(i, j, spec.seed, 37)
        cr, sr = np.cos(rot), np.sin(rot)
        fx, fy = fx * cr - fy * sr + 4.0, fx * sr + fy * cr + 4.0
        gi = np.floor(fx * cells)
        gj = np.floor(fy * cells)
        key_i = i * 64 + gi
        key_j = j * 64 + gj
        shade = _hash(key_i, key_j, spec.seed, 5) - 0.5
        rad = 0.25 + 0.25 * _hash(key_i, key_j, spec.seed, 9)
        cx = (gi + 0.3 + 0.4 * _hash(key_i, key_j, spec.seed, 19)) / cells
        cy = (gj + 0.3 + 0.4 * _hash(key_i, key_j, spec.seed, 23)) / cells
        inside = (np.hypot(fx - cx, fy - cy) * cells) < rad
        return np.where(inside, 2.0 * shade * spec.surface_amp, 0.0)
    if spec.surface == "wood":
        along_x = ((i + j) % 2) == 0
        a = np.where(along_x, fy, fx)
        b = np.where(along_x, fx, fy)
        freq = 6.0 + 8.0 * _hash(i, j, spec.seed, 29)
        phase = 6.28 * _hash(i, j, spec.seed, 31)
        wav = 0.08 * np.sin(2 * math.pi * (1.3 * b + phase)) + 0.04 * np.sin(
            2 * math.pi * (3.1 * b + 2 * phase))
        g = np.sin(2 * math.pi * freq * (a + wav) + phase)
        return spec.surface_amp * (0.7 * g + 0.3 * np.sin(2 * math.pi * 2.3 * freq * (a + wav)))
    raise ValueError(f"unknown surface {spec.surface!r}")


def render(spec: FloorSpec, cx: float, cy: float, theta: float,
           rng: np.random.Generator, corruption: str | None = None,
           overlay: Callable[[np.ndarray], np.ndarray] | None = None,
           motion: tuple[float, float] | None = None) -> np.ndarray:
    """The view (HxWx3 uint8 RGB) of a camera centred on floor point ``(cx, cy)`` (metres)
    with heading ``theta`` (rad), with optional ``corruption`` (one of :data:`CORRUPTIONS`),
    ``overlay`` (an object on the floor: the HxW float32 floor's shades in, the shades
    with the object out; lit and seen through the optics as the floor is) and ``motion``
    (a motion blur of a given length, px, and angle, rad: :func:`motion_blur`)."""
    w, h, ppm, L = spec.width, spec.height, spec.ppm, spec.tile_size
    sub = (np.arange(SS) + 0.5) / SS - 0.5
    u = (np.arange(w)[None, :, None, None] - (w - 1) / 2.0) + sub[None, None, None, :]
    v = (np.arange(h)[:, None, None, None] - (h - 1) / 2.0) + sub[None, None, :, None]
    a_f = -v / ppm
    a_l = -u / ppm
    ct, st = math.cos(theta), math.sin(theta)
    px = cx + a_f * ct - a_l * st
    py = cy + a_f * st + a_l * ct
    X = px / L
    Y = py / L
    i = np.floor(X)
    j = np.floor(Y)
    fx = X - i
    fy = Y - j
    i, j, fx, fy = np.broadcast_arrays(i, j, fx, fy)
    half = 0.5 * spec.grout_px / ppm / L
    if (spec.second is not None or spec.fill is not None) and (
            spec.lattice_tolerance > 0 or spec.panel):
        raise ValueError("floorgen: second and fill draw a floor laid on the lattice "
                         "(no lattice_tolerance, no panel)")
    other: tuple[np.ndarray, float] | None = None  # joints of another width and shade
    filled: tuple[np.ndarray, float] | None = None  # joints filled with another material
    if spec.lattice_tolerance > 0 or spec.panel:
        X, Y = _laid(spec, X, Y, i, j)
        i, j = np.floor(X), np.floor(Y)
        fx, fy = X - i, Y - j
        kx, ky = np.rint(X), np.rint(Y)
        seam = 0.5 * spec.seam_px / ppm / L
        hx = np.where((kx % spec.panel == 0) if spec.panel else False, seam, half)
        hy = np.where((ky % spec.panel == 0) if spec.panel else False, seam, half)
        grout = (np.abs(X - kx) < hx) | (np.abs(Y - ky) < hy)
    elif spec.second is None and spec.fill is None:
        grout = (np.minimum(fx, 1 - fx) < half) | (np.minimum(fy, 1 - fy) < half)
    else:  # the two families of joints differ, or some joints are filled
        half_y = half if spec.second is None else 0.5 * spec.second[0] / ppm / L
        ex, ey = np.abs(X - np.rint(X)), np.abs(Y - np.rint(Y))
        on_x, on_y = ex < half, ey < half_y
        grout = on_x | on_y
        if spec.second is not None:
            other = (on_y & ~on_x, spec.second[1])
        if spec.fill is not None:
            n, share, fill_shade = spec.fill
            filled = (((on_x & (np.rint(X) % n == 0) & (ex < share * half))
                       | (on_y & (np.rint(Y) % n == 0) & (ey < share * half_y))), fill_shade)
    shade0: float | np.ndarray = spec.tile_shade
    hued = grout  # where the second colour of spec.tint is (the grout, or the odd tiles)
    band_shade = spec.grout_shade
    if spec.kind == "checker":  # two shades alternate, no grout unless band_shade is given
        hued = (i + j) % 2 != 0
        shade0 = np.where(hued, spec.grout_shade, spec.tile_shade)
        if spec.band_shade is None:
            grout = np.zeros_like(grout)
        else:
            band_shade = spec.band_shade
    shade = shade0 + spec.shade_spread * (2.0 * _hash(i, j, spec.seed, 1) - 1.0)
    tile = shade * (1.0 + _surface(spec, i, j, fx, fy))
    val = np.where(grout, band_shade, tile)
    for mask, level in (m for m in (other, filled) if m is not None):
        val = np.where(mask, level, val)
    img = val.mean(axis=(2, 3)).astype(np.float32)
    cover = hued.mean(axis=(2, 3)).astype(np.float32) if spec.tint is not None else None
    if corruption is not None:
        img = corrupt(img, corruption, rng)
    if overlay is not None:
        img = overlay(img).astype(np.float32)
    # lighting: a linear gradient across the view and vignetting
    uu = (np.arange(w) - (w - 1) / 2.0)[None, :] / (0.5 * w)
    vv = (np.arange(h) - (h - 1) / 2.0)[:, None] / (0.5 * h)
    ga = rng.uniform(0, 2 * math.pi)
    light = 1.0 + 0.5 * spec.gradient * (math.cos(ga) * uu + math.sin(ga) * vv)
    light = light * (1.0 - spec.vignetting * 0.5 * (uu * uu + vv * vv))
    img = img * light.astype(np.float32)
    if spec.blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), spec.blur)
    if corruption == "motion_blur":
        img = random_motion_blur(img, rng)
    if motion is not None:
        img = motion_blur(img, *motion)
    img = img + rng.normal(0.0, spec.noise, img.shape).astype(np.float32)
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    # the light's colour cast, before the sensor clips each channel at 255: a surface brighter
    # than the sensor's range (glare, a light grout under strong light) saturates every
    # channel, as a real camera's highlights do, instead of being tinted below saturation
    tint = np.array([1.0, 0.97, 0.92]) if spec.seed % 2 else np.array([0.95, 1.0, 1.0])
    level = np.where(img > 255.0, img, out)
    if cover is not None and spec.tint is not None:  # the tiles' and the grout's hues
        if spec.blur > 0:
            cover = cv2.GaussianBlur(cover, (0, 0), spec.blur)
        t_rgb, g_rgb = np.array(spec.tint[0]), np.array(spec.tint[1])
        c = cover[..., None]
        mix = t_rgb * (1 - c) + g_rgb * c
        tint = tint * mix / np.maximum(np.dot(mix, _LUMA), 1.0)[..., None]
    rgb = np.clip(np.rint(level[..., None] * tint), 0, 255).astype(np.uint8)
    if spec.jpeg:
        ok, buf = cv2.imencode(".jpg", rgb, [cv2.IMWRITE_JPEG_QUALITY, spec.jpeg])
        if ok:
            rgb = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return rgb


def _laid(spec: FloorSpec, X: np.ndarray, Y: np.ndarray, i: np.ndarray, j: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray]:
    """Floor coordinates (tiles) in the frame of the tile (or panel of ``spec.panel`` tiles)
    that holds the point on the ideal lattice, laid off it by up to ``lattice_tolerance``: a
    point near an edge falls into its own tile's grout, so the grout between two tiles lies
    between their two displaced edges (its centre within the tolerance of the lattice)."""
    n = spec.panel or 1
    pi, pj = np.floor(i / n), np.floor(j / n)
    reach = spec.lattice_tolerance / spec.tile_size
    ox = (2.0 * _hash(pi, pj, spec.seed, 41) - 1.0) * reach
    oy = (2.0 * _hash(pi, pj, spec.seed, 43) - 1.0) * reach
    return X - ox, Y - oy


def corrupt(img: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    """``img`` (H x W shades, or H x W x C) with a corruption of ``kind`` (one of
    :data:`CORRUPTIONS`) drawn from ``rng``: a cable (a band 3-10 px wide, dark or light), the
    edge of a box, a shadow edge (a soft step darkening 35-60 %), glare (a bright blob), or,
    for ``motion_blur``, the image unchanged (the smear is applied after the optics:
    :func:`random_motion_blur`). The same draws for any number of channels."""
    h, w = img.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    ang = rng.uniform(0, math.pi)
    off = rng.uniform(-0.25, 0.25) * min(w, h)
    d = (-(xx - (w - 1) / 2) * math.sin(ang) + (yy - (h - 1) / 2) * math.cos(ang)) - off
    if img.ndim == 3:
        d = d[..., None]
        yy, xx = yy[..., None], xx[..., None]
    if kind == "cable":
        width = rng.uniform(3.0, 10.0)
        shade = rng.uniform(10, 60) if rng.uniform() < 0.7 else rng.uniform(200, 250)
        cov = np.clip(0.5 * width + 0.5 - np.abs(d), 0, 1)
        return img + cov * (shade - img)
    if kind == "box":
        cov = np.clip(d + 0.5, 0, 1)
        return img + cov * (rng.uniform(60, 200) - img)
    if kind == "shadow":
        t = np.clip(d / rng.uniform(1.0, 4.0) + 0.5, 0, 1)
        return img * (1.0 - rng.uniform(0.35, 0.6) * t)
    if kind == "glare":
        gx, gy = rng.uniform(0.25, 0.75) * w, rng.uniform(0.25, 0.75) * h
        r = rng.uniform(0.2, 0.35) * min(w, h)
        return img + 400.0 * np.exp(-((xx - gx) ** 2 + (yy - gy) ** 2) / (2 * r * r))
    if kind == "motion_blur":
        return img
    raise ValueError(f"unknown corruption {kind!r}")


def line_offset(spec: FloorSpec, cx: float, cy: float, theta: float, family: int
                ) -> tuple[tuple[float, float], float]:
    """The grout line of ``family`` (0: x = mL, 1: y = mL) nearest the view's centre: its unit
    normal ``(gu, gv)`` in image pixels (u right, v down from the centre) and its offset
    ``s`` (px), the line being ``gu u + gv v = s``."""
    lp = spec.tile_size * spec.ppm
    ct, st = math.cos(theta), math.sin(theta)
    g0, gu, gv = (cx * spec.ppm, st, -ct) if family == 0 else (cy * spec.ppm, -ct, -st)
    return (gu, gv), round(g0 / lp) * lp - g0


def band(spec: FloorSpec, normal: tuple[float, float], s: float, width: float, shade: float
         ) -> Callable[[np.ndarray], np.ndarray]:
    """An overlay for :func:`render`: a straight band (a cable) of ``width`` px and gray level
    ``shade`` along ``gu u + gv v = s`` (px, image coordinates of :func:`line_offset`),
    anti-aliased by its coverage of each pixel."""
    h, w = spec.height, spec.width
    u = (np.arange(w, dtype=np.float32) - (w - 1) / 2.0)[None, :]
    v = (np.arange(h, dtype=np.float32) - (h - 1) / 2.0)[:, None]
    d = normal[0] * u + normal[1] * v - s
    cov = np.clip(0.5 * width + 0.5 - np.abs(d), 0.0, 1.0)
    return lambda img: img + cov * (shade - img)


def random_motion_blur(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``img`` smeared by :func:`motion_blur` over 15-40 px at a random angle (``rng``)."""
    length = rng.uniform(15.0, 40.0)
    return motion_blur(img, length, rng.uniform(0, math.pi))


def motion_blur(img: np.ndarray, length: float, ang: float) -> np.ndarray:
    """``img`` smeared along a straight path of ``length`` px at angle ``ang`` (rad, from the
    image's u axis towards v): the camera moving during the exposure."""
    n = int(math.ceil(length)) | 1
    k = np.zeros((n + 2, n + 2), np.float32)
    c = (n + 1) / 2.0
    for t in np.linspace(-length / 2, length / 2, 4 * n):
        k[int(round(c + t * math.sin(ang))), int(round(c + t * math.cos(ang)))] += 1.0
    return cv2.filter2D(img, -1, k / k.sum())


def cell(x: float, spec: str) -> str:
    """``x`` formatted by ``spec`` for a Markdown table; a dash where there is no value (NaN:
    no accepted view to measure)."""
    return format(x, spec) if math.isfinite(x) else "—"


def readable(spec: FloorSpec, cx: float, cy: float, theta: float) -> bool:
    """Whether a person could read the lattice: each family's grout lines that cross the view
    at least ``grout/2 + 8`` px inside it span together at least 0.75 x the smaller side."""
    w, h, lp = spec.width, spec.height, spec.tile_size * spec.ppm
    inset = 0.5 * spec.grout_px + 8.0
    ct, st = math.cos(theta), math.sin(theta)
    for k in range(2):
        total = 0.0
        # family k: lines x = mL (k = 0) or y = mL (k = 1); a pixel's coordinate along the
        # family's world normal is linear in (u, v): X = cx/L + (-v ct + u st)/lp ...
        if k == 0:
            g0, gu, gv = cx * spec.ppm, st, -ct
        else:
            g0, gu, gv = cy * spec.ppm, -ct, -st
        # half extents of the inset rectangle
        hw, hh = 0.5 * (w - 1) - inset, 0.5 * (h - 1) - inset
        lo = g0 - abs(gu) * hw - abs(gv) * hh
        hi = g0 + abs(gu) * hw + abs(gv) * hh
        for m in range(math.ceil(lo / lp), math.floor(hi / lp) + 1):
            total += _chord(gu, gv, m * lp - g0, hw, hh)
        if total < 0.75 * min(w, h):
            return False
    return True


def _chord(gu: float, gv: float, s: float, hw: float, hh: float) -> float:
    """Length of the line gu u + gv v = s inside |u| <= hw, |v| <= hh (unit (gu, gv))."""
    tu, tv = -gv, gu
    pu, pv = gu * s, gv * s
    lo, hi = -math.inf, math.inf
    for p0, d, e in ((pu, tu, hw), (pv, tv, hh)):
        if abs(d) < 1e-12:
            if abs(p0) > e:
                return 0.0
            continue
        a, b = (-e - p0) / d, (e - p0) / d
        lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
    return max(0.0, hi - lo)


def draw_view(rng: np.random.Generator) -> tuple[float, float, float]:
    """A random camera centre (metres, within 30 m) and heading (rad)."""
    return (float(rng.uniform(-30, 30)), float(rng.uniform(-30, 30)),
            float(rng.uniform(-math.pi, math.pi)))
