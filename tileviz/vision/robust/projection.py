"""The projection of a view by a heading: the warp that turns the grout lines into rows and
columns, the in-view stretch of each, the grout's polarity, both family profiles and their dips
(:class:`Projection`), which :mod:`.profiles` then measures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from tileviz.vision.robust import checks, projection_kernel
from tileviz.vision.robust.state import ReadingState

__all__ = ["Projection", "light_grout", "profiles", "project"]


def light_grout(run: ReadingState, sums: tuple[np.ndarray, np.ndarray],
                spans: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
                ) -> bool:
    """Whether the grout is lighter than the tiles: the family profiles (row and column
    means of the warped image, offsets from the mean) hold stronger narrow peaks (above a
    grey opening) than narrow dips (below a grey closing), summed over both families.
    ``sums``: the warped image's row and column sums (from its integral image); ``spans``:
    the in-view stretch of every row and column (:func:`view_spans`).
    :func:`~tileviz.vision.robust.projection_kernel.grout_score` computes a family's term
    compiled (bit-identical)."""
    st = run.st.profiles
    score = 0.0
    for k in range(2):
        lo, hi = spans[k]
        used, value = projection_kernel.grout_score(sums[k], np.maximum(hi - lo, 0.0),
                                                    run.closing, st.min_row, st.min_row_share,
                                                    st.min_rows)
        if used:
            score += value
    return score > 0.0


@dataclass
class Projection:
    """The view warped by one heading ``y3`` and its two family profiles (row and column
    means), with the dips found in them. The profile arrays are (2, size): family k in row k,
    profile samples shifted by ``pad`` (the widest window a dip is ever measured in), NaN
    (``prof``, ``dark``) or empty spans (``lo`` = inf, ``hi`` = -inf) beyond the data."""

    y3: float
    integ: np.ndarray  # integral image of the warped view (CV_64F)
    pad: int
    prof: np.ndarray  # mean gray level of each row / column
    dark: np.ndarray  # grey closing of the profile minus the profile
    lo: np.ndarray  # in-view stretch of each row / column, tangent coordinate (px)
    hi: np.ndarray
    total: np.ndarray  # its length (px)
    fam: np.ndarray  # (m,) family of each dip
    peak: np.ndarray  # (m,) its deepest sample (padded index)


def project(run: ReadingState, y3: float, attempt: int) -> Projection:
    """Warp the image by y3 (on the first attempt, also decide the grout's polarity), and find
    the dips of both family profiles."""
    c, s = math.cos(y3), math.sin(y3)
    w, h = run.w, run.h
    wo = int(math.ceil(w * abs(c) + h * abs(s))) + 2
    ho = int(math.ceil(w * abs(s) + h * abs(c))) + 2
    x0, y0 = (wo - 1) / 2.0, (ho - 1) / 2.0
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    # dst (X, Y) -> src: p = centre + (X - X0) (c, s) + (Y - Y0) (-s, c), so that rows follow
    # family-1 lines (s1 = -(Y - Y0)) and columns family-2 lines (s2 = -(X - X0)).
    m = np.array([[c, -s, cx - x0 * c + y0 * s], [s, c, cy - x0 * s - y0 * c]])
    src = run.gray.astype(np.float32)
    # outside the view reads 0, i.e. the mean level; an inverted view's ``run.mean`` is the
    # inverted image's mean (255 - the gray mean), so the gray mean is 255 - run.mean: the
    # profile levels are then 255 - gray on every attempt, not only on the first
    src -= np.float32(255.0 - run.mean if run.inverted else run.mean)
    warped = cv2.warpAffine(
        src,
        m,
        (wo, ho),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    spans = (projection_kernel.view_spans(ho, y0, c, s, w, h, True),
             projection_kernel.view_spans(wo, x0, c, s, w, h, False))
    # integral image: the sum over any stretch of any row or column in four look-ups
    integ = cv2.integral(warped, sdepth=cv2.CV_64F)
    sums = (integ[1:, -1] - integ[:-1, -1], integ[-1, 1:] - integ[-1, :-1])
    if attempt == 0 and (light_grout(run, sums, spans) if run.force_inverted is None
                         else run.force_inverted):
        # lighter grout: measure the inverted image (255 - gray), whose offset from its
        # mean is -warped; every later step then sees dark lines on brighter tiles
        run.inverted = True
        run.mean = 255.0 - run.mean
    if run.inverted:
        cv2.multiply(warped, -1.0, dst=warped)
        # the integral of -warped: the same additions with every sign turned, exactly (+ 0.0
        # turns the zeros that the negation signed back to +0.0, as the integral gives them)
        np.negative(integ, out=integ)
        integ += 0.0
        sums = (integ[1:, -1] - integ[:-1, -1], integ[-1, 1:] - integ[-1, :-1])
    run.warped = warped
    run.centre = (x0, y0)
    return profiles(run, y3, integ, sums, spans)


def profiles(
    run: ReadingState,
    y3: float,
    integ: np.ndarray,
    sums: tuple[np.ndarray, np.ndarray],
    spans: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
) -> Projection:
    """Both family profiles (row and column means of the warped image: ``sums`` over the
    in-view ``spans``), their baselines and their dips."""
    st = run.st.profiles
    r = run.widest
    mean = run.mean
    prof, lo, hi, total = projection_kernel.profile_arrays(
        sums[0], sums[1], spans[0][0], spans[0][1], spans[1][0], spans[1][1], r, mean,
        st.min_row, st.min_row_share)
    dark, noise, fam, peak = projection_kernel.profile_dips(
        prof, mean, run.closing, checks.CONTRAST_DEPTH.limit(run), st.min_rows, st.dip_noise)
    for sig in noise.tolist():
        if math.isfinite(sig):
            run.details["profile_noise"] = max(run.details.get("profile_noise", 0.0), sig)
    return Projection(
        y3=y3, integ=integ, pad=r, prof=prof, dark=dark, lo=lo, hi=hi, total=total,
        fam=fam, peak=peak,
    )


