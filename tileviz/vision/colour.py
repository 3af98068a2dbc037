"""Other gray images of a view for the robust extractor to read when the luma (OpenCV's RGB to
gray) shows no grout: colour projections, the edge image and the joints image (docs/vision.md,
"Colour").

Grout may differ from its tiles more in hue than in brightness (reddish grout on brown tiles):
the luma then shows dips of a few gray levels, under the camera's noise, while one channel or
the difference of two shows them clearly. Each projection is a fixed integer combination of the
channels, computed in integer arithmetic (the same pixels on every machine):

- ``red``, ``green``, ``blue``: one channel;
- ``red-green``, ``green-blue``, ``red-blue``: ``(a - b + 256) // 2``, 0..255 (half the
  difference, centred on 128).

The edge image (``edges``, :func:`edge_image`) shows a checkerboard's lattice: tiles of two
shades meet edge to edge, no grout, and the lattice is the edges between them, which the
gradient's magnitude draws as thin light lines on dark tiles, read as lighter grout. On a floor
declared ``checker`` the edge images are read instead of the luma and the projections (a dip of
the luma there is no line of the floor): the luma's and each projection's that differs from it,
strongest edges first (:func:`edges_and_strength`: two tiles of one luma and two hues show
their edges in a difference of channels only). On a grout floor the
edge image's ridge is the grout's centre only while its two edges are alike (a motion blur that
smears one edge more than the other moves it off the centre, beyond what the reading's bound
can see), so it is not read there.

The joints image (:func:`joints_image`) shows joints of either polarity: how far each pixel lies
from the tiles' level around it, whichever the sign. Dark grout filled with light dirt along
part of its joints (a paver mosaic), or lighter along one edge and darker along the other, is
one light band there, centred on the joint. It is read on a grout floor last, after every
image above refused the view, and only when the luma did not show the lattice
(:data:`RETRY_REASONS`) or saw a second dip beside a line
(:func:`tileviz.vision.views.read_robust`). Grout 0.29 of the period
wide or wider fills half the median's square: the median is then no longer the tiles' level.

The projections are tried in that order, after the luma, each only when it differs from the
luma (:data:`SAME_AS_LUMA`: a projection that is nearly the luma again, a channel of a gray
floor under a tinted light, shows nothing new); the first whose reading the extractor accepts is
the view's (:func:`tileviz.vision.extract`; its ``details["projection"]`` is then the
projection's number in that order, from 1). Each is read by the same checks and
declares its own bound from its own evidence, as the luma's reading does: a projection changes
which pixels are darker, not what the checks require of them.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

__all__ = ["EDGE_BLUR", "EDGE_QUANTILE", "JOINT_MAX_SIDE", "JOINT_WINDOW", "PROJECTIONS",
           "RETRY_REASONS", "SAME_AS_LUMA", "correlation", "edge_image", "edges_and_strength",
           "joints_image", "project"]

EDGE_BLUR = 1.0
"""Gaussian std (px) of the blur before the edge image's gradient."""
EDGE_QUANTILE = 0.995
"""The edge image maps this quantile of the gradient magnitude to 255."""
JOINT_WINDOW = 1.0
"""The side of the square over which :func:`joints_image` takes the tiles' level (the median),
as a share of the tile period: such a square holds one crossing of two joints, a small share
of it (under half while the grout is narrower than 0.29 of the period), the tiles the rest."""
JOINT_MAX_SIDE = 255
"""The largest side of that square, px: OpenCV's median of 8-bit pixels over a wider square is
some 15 times slower (a period over 255 px: grout under 0.29 of this side still holds)."""


def _channel(k: int) -> Callable[[np.ndarray], np.ndarray]:
    return lambda rgb: np.ascontiguousarray(rgb[..., k])


def _difference(a: int, b: int) -> Callable[[np.ndarray], np.ndarray]:
    def f(rgb: np.ndarray) -> np.ndarray:
        d = rgb[..., a].astype(np.int16) - rgb[..., b].astype(np.int16) + 256
        return (d // 2).astype(np.uint8)

    return f


def edge_image(gray: np.ndarray) -> np.ndarray:
    """The edge image of ``gray`` (HxW uint8): the L1 magnitude of the Scharr gradient after a
    Gaussian blur of :data:`EDGE_BLUR` px, scaled so that its :data:`EDGE_QUANTILE` quantile is
    255 (integer arithmetic after the blur), HxW uint8."""
    return edges_and_strength(gray)[0]


def edges_and_strength(gray: np.ndarray) -> tuple[np.ndarray, float]:
    """:func:`edge_image` of ``gray`` and how strong its edges are: the gradient magnitude's
    :data:`EDGE_QUANTILE` quantile (gray levels per px, times the Scharr kernel's gain of 32;
    an integer, the same on every machine). A checkerboard's two shades meet along its
    strongest edges; a projection in which the two shades are alike shows the noise and the
    texture alone."""
    g = cv2.GaussianBlur(gray, (0, 0), EDGE_BLUR)
    m = (np.abs(cv2.Scharr(g, cv2.CV_16S, 1, 0).astype(np.int32))
         + np.abs(cv2.Scharr(g, cv2.CV_16S, 0, 1).astype(np.int32)))
    flat = np.sort(m, axis=None)
    hi = max(1, int(flat[min(flat.size - 1, int(EDGE_QUANTILE * flat.size))]))
    return np.minimum(255, m * 255 // hi).astype(np.uint8), float(hi)


def joints_image(gray: np.ndarray, period_px: float) -> np.ndarray:
    """The joints image of ``gray`` (HxW uint8; ``period_px`` the tile period, px): each
    pixel's absolute difference from the median of ``gray`` over a square :data:`JOINT_WINDOW`
    x the period wide (odd, 3 to :data:`JOINT_MAX_SIDE` px), HxW uint8, gray levels. A joint
    darker or lighter than its tiles, or both along its length, is a light band on dark tiles;
    a texture's noise is folded to its magnitude as well (the reading's noise is measured on
    this image)."""
    side = min(max(3, int(JOINT_WINDOW * period_px) | 1), JOINT_MAX_SIDE)
    return cv2.absdiff(gray, cv2.medianBlur(gray, side))


PROJECTIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "red": _channel(0), "green": _channel(1), "blue": _channel(2),
    "red-green": _difference(0, 1), "green-blue": _difference(1, 2),
    "red-blue": _difference(0, 2),
}
"""The projections after the luma, in the order they are tried: name -> HxWx3 (or x4) uint8
RGB(A) to HxW uint8."""

RETRY_REASONS = frozenset({"constant image", "no lines", "low contrast", "one family",
                           "too few segments", "inconsistent spacing", "imprecise",
                           "inconsistent angle"})
"""Refusals of the luma's reading after which the projections are tried: the grout did not
show, not all of it (a predicted line missing), or too faintly for straight lines and a tight
bound (``inconsistent angle``, ``imprecise``: another image may show it clearly); a refusal for
what the view shows, a foreign line, a step edge, blur or glare, is final."""


SAME_AS_LUMA = 0.95
"""A projection whose correlation with the luma is at least this (in magnitude) shows nothing
the luma did not: it is not read (a second reading of the same pixels would only be a second
chance for a view the luma refused)."""


def correlation(a: np.ndarray, b: np.ndarray, step: int = 2) -> float:
    """The correlation of two HxW uint8 images over every ``step``-th row and column, from
    exact integer sums (the same value on every machine); 1.0 when either is constant."""
    x = a[::step, ::step].astype(np.int64).ravel()
    y = b[::step, ::step].astype(np.int64).ravel()
    n = x.size
    sx, sy = int(x.sum()), int(y.sum())
    sxx, syy, sxy = int(np.dot(x, x)), int(np.dot(y, y)), int(np.dot(x, y))
    vx, vy = n * sxx - sx * sx, n * syy - sy * sy
    if vx <= 0 or vy <= 0:
        return 1.0
    return float(n * sxy - sx * sy) / float(np.sqrt(float(vx)) * np.sqrt(float(vy)))


def project(rgb: np.ndarray, name: str) -> np.ndarray:
    """The projection ``name`` (:data:`PROJECTIONS`) of ``rgb`` (HxWx3 or HxWx4 uint8),
    HxW uint8; KeyError on an unknown name."""
    return PROJECTIONS[name](rgb)
