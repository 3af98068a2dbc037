"""The projection of a view by a heading: the warp that turns the grout lines into rows and
columns, the in-view stretch of each, the grout's polarity, both family profiles and their dips
(:class:`Projection`), which :mod:`.profiles` then measures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from tileviz.vision.robust import kernel, projection_kernel
from tileviz.vision.robust.state import RobustRun

__all__ = ["Projection", "fill_ends", "grout_score_numpy", "light_grout", "profile_arrays_numpy",
           "profile_dips_numpy", "profiles", "project", "view_spans"]


def light_grout(run: RobustRun, sums: tuple[np.ndarray, np.ndarray],
                spans: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
                ) -> bool:
    """Whether the grout is lighter than the tiles: the family profiles (row and column
    means of the warped image, offsets from the mean) hold stronger narrow peaks (above a
    grey opening) than narrow dips (below a grey closing), summed over both families.
    ``sums``: the warped image's row and column sums (from its integral image); ``spans``:
    the in-view stretch of every row and column (:func:`view_spans`).
    :func:`~tileviz.vision.robust.projection_kernel.grout_score` computes a family's term
    compiled (bit-identical)."""
    term = projection_kernel.grout_score if kernel.AVAILABLE else grout_score_numpy
    score = 0.0
    for k in range(2):
        lo, hi = spans[k]
        used, value = term(sums[k], np.maximum(hi - lo, 0.0), run.closing)
        if used:
            score += value
    return score > 0.0


def grout_score_numpy(sums: np.ndarray, length: np.ndarray, closing: int) -> tuple[bool, float]:
    """One family's term of :func:`light_grout`: whether the family has 8 rows long enough
    (at least 8 px and 15 % of the longest), and then the highest narrow peak of its profile
    (``sums / length`` over those rows, float32) above a grey opening minus the deepest
    narrow dip below a grey closing, both ``closing`` samples wide. :func:`~tileviz.vision.
    robust.projection_kernel.grout_score` is the same computation compiled (bit-identical)."""
    ok = length >= max(8.0, 0.15 * float(length.max()))
    if int(ok.sum()) < 8:
        return False, 0.0
    prof = (sums[ok] / length[ok]).astype(np.float32)[None, :]
    # beyond the view: the median level (the tiles'), so that a stretch of tile or a line cut
    # by the border is neither a peak nor a dip
    mid = float(np.median(prof))
    kern = np.ones((1, closing), np.uint8)
    bt = cv2.BORDER_CONSTANT
    close = cv2.erode(cv2.dilate(prof, kern, borderType=bt, borderValue=mid), kern,
                      borderType=bt, borderValue=mid)
    opening = cv2.dilate(cv2.erode(prof, kern, borderType=bt, borderValue=mid), kern,
                         borderType=bt, borderValue=mid)
    return True, float((prof - opening).max()) - float((close - prof).max())


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


def project(run: RobustRun, y3: float, attempt: int) -> Projection:
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
    if kernel.AVAILABLE:
        spans = (projection_kernel.view_spans(ho, y0, c, s, w, h, True),
                 projection_kernel.view_spans(wo, x0, c, s, w, h, False))
    else:
        spans = (
            view_spans(run, np.arange(ho) - y0, c, s, along_rows=True),
            view_spans(run, np.arange(wo) - x0, c, s, along_rows=False),
        )
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


def view_spans(
    run: RobustRun, q: np.ndarray, c: float, s: float, *, along_rows: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The in-view stretch [lo, hi] of each warped row (``along_rows``) or column at offset
    ``q`` from the warp centre, in the tangent coordinate u (relative to the centre); empty
    where hi <= lo. :func:`~tileviz.vision.robust.projection_kernel.view_spans` is the same
    computation compiled (bit-identical)."""
    cx, cy = (run.w - 1) / 2.0, (run.h - 1) / 2.0
    lo = np.full(q.shape, -np.inf)
    hi = np.full(q.shape, np.inf)
    # src col = cx + a u + b q, row = cy + e u + f q
    a, b, e, f = (c, -s, s, c) if along_rows else (-s, c, c, s)
    for coef, base, size in ((a, cx + b * q, run.w), (e, cy + f * q, run.h)):
        if abs(coef) < 1e-12:
            lo = np.where((base >= -0.5) & (base <= size - 0.5), lo, np.inf)
            continue
        u1 = (-0.5 - base) / coef
        u2 = (size - 0.5 - base) / coef
        lo = np.maximum(lo, np.minimum(u1, u2))
        hi = np.minimum(hi, np.maximum(u1, u2))
    return lo, hi


def profiles(
    run: RobustRun,
    y3: float,
    integ: np.ndarray,
    sums: tuple[np.ndarray, np.ndarray],
    spans: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
) -> Projection:
    """Both family profiles (row and column means of the warped image: ``sums`` over the
    in-view ``spans``), their baselines and their dips."""
    r = run.closing + 8  # the widest window (see execute)
    mean = run.mean
    build = projection_kernel.profile_arrays if kernel.AVAILABLE else profile_arrays_numpy
    prof, lo, hi, total = build(sums[0], sums[1], spans[0][0], spans[0][1], spans[1][0],
                                spans[1][1], r, mean)
    dips_of = projection_kernel.profile_dips if kernel.AVAILABLE else profile_dips_numpy
    dark, noise, fam, peak = dips_of(prof, mean, run.closing, run.st.min_depth)
    for sig in noise.tolist():
        if math.isfinite(sig):
            run.details["profile_noise"] = max(run.details.get("profile_noise", 0.0), sig)
    return Projection(
        y3=y3, integ=integ, pad=r, prof=prof, dark=dark, lo=lo, hi=hi, total=total,
        fam=fam, peak=peak,
    )


def profile_arrays_numpy(
    sums0: np.ndarray, sums1: np.ndarray, lo0: np.ndarray, hi0: np.ndarray, lo1: np.ndarray,
    hi1: np.ndarray, r: int, mean: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The (2, size) arrays of a :class:`Projection` (family k in row k, samples shifted by
    ``r``): the profile (``sums`` / in-view length + ``mean``, NaN beyond the data and where a
    row or column is shorter than 8 px or 15 % of the family's longest), the in-view spans
    ``lo``, ``hi`` (inf, -inf beyond the data) and their length. :func:`~tileviz.vision.
    robust.projection_kernel.profile_arrays` is the same computation compiled (bit-identical)."""
    sums = (sums0, sums1)
    spans = ((lo0, hi0), (lo1, hi1))
    size = max(sums0.size, sums1.size) + 2 * r
    # family k in row k; columns shifted by r; missing data NaN
    prof = np.full((2, size), np.nan)
    lo = np.full((2, size), np.inf)
    hi = np.full((2, size), -np.inf)
    total = np.zeros((2, size))
    for k in range(2):
        n = sums[k].size
        lo[k, r : r + n], hi[k, r : r + n] = spans[k]
        length = np.maximum(hi[k, r : r + n] - lo[k, r : r + n], 0.0)
        total[k, r : r + n] = length
        valid = length >= max(8.0, 0.15 * float(length.max()))
        with np.errstate(invalid="ignore", divide="ignore"):  # length 0: not valid, NaN
            prof[k, r : r + n] = np.where(valid, sums[k] / length + mean, np.nan)
    return prof, lo, hi, total


def profile_dips_numpy(
    prof: np.ndarray, mean: float, closing: int, min_depth: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The dips of both family profiles (rows of ``prof``, NaN where there is no data): the
    darkness ``dark`` below a grey closing of ``closing`` samples (max then min filter along
    each row, removing dips narrower than its window; missing data read as the nearest valid
    sample of its row, :func:`fill_ends`), each family's profile noise (robust std of its
    sample-to-sample steps; NaN when the family has fewer than 8 samples), and the dips:
    the deepest sample of every run of samples darker than 5 x the noise (at least
    ``min_depth`` / 2), as (family, padded index) arrays. :func:`~tileviz.vision.robust.
    projection_kernel.profile_dips` is the same computation compiled (bit-identical)."""
    missing = np.isnan(prof)
    filled = fill_ends(prof, mean).astype(np.float32)
    kern = np.ones((1, closing), np.uint8)
    base = cv2.erode(
        cv2.dilate(filled, kern, borderType=cv2.BORDER_REPLICATE),
        kern,
        borderType=cv2.BORDER_REPLICATE,
    )
    dark = base - prof  # NaN where no data
    noise = np.full(prof.shape[0], np.nan)
    peaks: list[tuple[int, int]] = []
    for k in range(prof.shape[0]):
        ok = ~missing[k]
        if int(ok.sum()) < 8:
            continue
        diffs = np.abs(np.diff(prof[k][ok]))
        kth = diffs.size // 2
        sig = 1.4826 * float(np.partition(diffs, kth)[kth]) / math.sqrt(2.0)
        noise[k] = sig
        thr = max(0.5 * min_depth, 5.0 * sig)
        dk = np.where(ok, dark[k], -np.inf)
        above = dk > thr
        if not above.any():
            continue
        edges = np.diff(above.astype(np.int8), prepend=0, append=0)
        starts = np.flatnonzero(edges == 1)
        ends = np.flatnonzero(edges == -1)
        for s0, s1 in zip(starts.tolist(), ends.tolist(), strict=True):
            peaks.append((k, s0 + int(np.argmax(dk[s0:s1]))))
    return (dark, noise, np.array([k for k, _ in peaks], np.intp),
            np.array([p for _, p in peaks], np.intp))


def fill_ends(prof: np.ndarray, mean: float) -> np.ndarray:
    """``prof`` (rows of samples, NaN where missing) with each missing sample replaced by the
    nearest valid sample of its row before it, or else after it (``mean`` in a row with none):
    a row's valid data is one stretch, so its ends are replicated outward. A level beyond the
    view unlike the tiles at its border (the image mean next to a dark tile) would make a
    dip of that tile's border, or hide a grout line's edge next to it."""
    out = prof.copy()
    for k in range(prof.shape[0]):
        ok = np.flatnonzero(~np.isnan(prof[k]))
        if ok.size == 0:
            out[k] = mean
            continue
        idx = np.clip(np.searchsorted(ok, np.arange(prof.shape[1]), side="right") - 1, 0,
                      ok.size - 1)
        out[k] = prof[k, ok[idx]]
    return out
