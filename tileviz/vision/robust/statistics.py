"""Gray statistics of a frame (``constant image``, ``glare``) and its noise level."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.robust import checks
from tileviz.vision.robust.checks import Context, Record

__all__ = ["glare_share", "gray_statistics", "list_median", "noise_sigma"]


def gray_statistics(gray: np.ndarray, ctx: Context, rec: Record,
                    details: dict[str, float]) -> float:
    """The gray mean of ``gray`` (HxW uint8, gray levels); refuse a ``constant image`` or
    ``glare`` (checks ``constant.*``, ``glare.*`` with the limits' context ``ctx``, recorded in
    ``rec``; ``gray_range`` and ``saturated`` in ``details``)."""
    st = ctx.st.statistics
    hist = cv2.calcHist([gray], [0], None, [256], [0, 256]).ravel()
    cdf = np.cumsum(hist)
    n = float(cdf[-1])
    lo, hi, thin_lo, thin_hi = (float(v) for v in np.searchsorted(
        cdf, np.array([*st.range_quantiles, *st.thin_quantiles]) * n))
    mean = float(np.dot(hist, np.arange(256))) / n
    details["gray_range"] = hi - lo
    if not rec.check(checks.CONSTANT_RANGE, ctx, hi - lo):
        rec.require(checks.CONSTANT_THIN, ctx, thin_hi - thin_lo)
    saturated = float(hist[st.saturated_level:].sum()) / n
    details["saturated"] = saturated
    if not rec.check(checks.GLARE_SATURATED, ctx, saturated):
        rec.require(checks.GLARE_PATCHES, ctx,
                    glare_share(gray, st.glare_patch, st.saturated_level))
    return mean


def glare_share(gray: np.ndarray, patch: int, level: int = 250) -> float:
    """Share of the pixels (0..1) inside a saturated (>= ``level``) patch at least ``patch`` px
    across (an erosion of the saturated pixels by a ``patch`` x ``patch`` square). Glare
    washes out a large area, grout and texture alike; a light texture (the light stones of
    a gravel photograph, bright grass blades) saturates scattered specks between which the
    floor still shows, and they vanish under the erosion."""
    mask = cv2.compare(gray, level, cv2.CMP_GE)
    core = cv2.erode(mask, np.ones((patch, patch), np.uint8))
    return float(cv2.countNonZero(core)) / float(gray.size)


def noise_sigma(gray: np.ndarray) -> float:
    """Gaussian noise std of the image, gray levels (Immerkaer's fast estimate)."""
    # the kernel [[1, -2, 1], [-2, 4, -2], [1, -2, 1]] is [1, -2, 1] along rows then columns:
    # integer taps on 8-bit pixels, |r| <= 16 * 255 fits 16 bits and every partial sum is an
    # exact integer, so the L1 sum is the same exact integer as in float (a quarter of the
    # time of a float32 filter)
    h, w = gray.shape
    r = cv2.sepFilter2D(gray, cv2.CV_16S, _IMMERKAER, _IMMERKAER)
    return math.sqrt(math.pi / 2.0) * float(cv2.norm(r[1:-1, 1:-1], cv2.NORM_L1)) / (
        6.0 * (w - 2) * (h - 2)
    )


_IMMERKAER = np.array([1.0, -2.0, 1.0], np.float32)
"""One axis of Immerkaer's noise kernel (:func:`noise_sigma`)."""


def list_median(values: list[float]) -> float:
    """``float(np.median(values))`` of a short non-empty list, without numpy's overhead: the
    middle value, or the mean of the two middle ones; NaN when any value is NaN."""
    if any(v != v for v in values):
        return math.nan
    srt = sorted(values)
    n = len(srt)
    return srt[n // 2] if n % 2 else (srt[n // 2 - 1] + srt[n // 2]) / 2.0
