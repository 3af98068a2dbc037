"""The robust extractor: sub-pixel lattice parameters, and a refusal when the view is doubtful.

How it measures (vectorised numpy/OpenCV; timings in ``bench/bench_vision.py``):

1. Gray statistics: a constant image, or one with many saturated pixels (glare), is refused.
2. Scharr gradients and Canny edges; the heading modulo pi/2 from the edge pixels' gradient
   directions (a weighted histogram of 4 phi, its peak, then the weighted circular mean of the
   pixels near the peak: the report's (cos 4a, sin 4a) of eq. 4.4 applied per pixel).
3. One affine warp turns the image by that heading so that family-1 grout lines become rows and
   family-2 lines columns (:func:`~tileviz.vision.geometry.family_normals`). Row (column) means
   are the gray profile across every line of a family, averaged over the whole line.
4. Dips of a profile are the line candidates. Each is then measured in four equal parts of the
   stretch of its line that every sample of its window sees (sums from the integral image of
   the warp, so that the samples of a part all average the same stretch of floor): its
   position is the centroid of the darkness ``1 - profile / level``, with a plateau level of
   its own on each side (a brighter tile on one side does not pull it), re-centred three
   times; its depth, contrast (depth / level), half-depth width, 20-80 % edge rise and the step
   between its two sides are measured too. Dips much wider than the strong ones (a shadow, a
   stain) are not lines.
5. A least-squares fit over every line's part positions gives the residual tilt of the warp
   (one slope shared by all lines, one intercept per line): the heading correction, each
   line's offset at the image centre, and standard errors from the scatter of the parts. A
   large correction redoes the warp.
6. Checks, in order; the first that fails is the ``reason``:
   ``constant image``, ``glare``, ``no lines``, ``low contrast``, ``one family``, ``blurred``
   (edges too soft), ``step edge`` (a line with a different level on each side),
   ``inconsistent angle`` (a line not straight, or the two families not perpendicular within
   their errors), ``foreign line`` (a line unlike the others in width or contrast: grout lines
   share both), ``inconsistent spacing`` (line offsets not multiples of L apart, or a
   well-visible lattice line missing), ``too few segments`` (too little line length per
   family), ``imprecise`` (the fit's own standard errors, times 4, exceed the bounds), then
   ``foreign line`` / ``step edge`` again for a long straight edge that is not on the lattice
   (a cable; a box or shadow edge), found by a probabilistic Hough transform on the Canny edges
   that the predicted grout lines do not explain.

Known limit: a straight dark object lying exactly along the grout direction (within about
0.2 deg), as wide and as dark as the grout, with no real grout line of that family in view,
cannot be told from grout by a single image; the fault study shows how rare that is.

The observation carries the declared bounds (``VisionConfig.position_error_px / ppm`` and
``VisionConfig.heading_error``). The consistency checks work at the smaller of those bounds and
the check scales of :class:`RobustSettings` (2 px, 0.02 rad): the defaults of the declared
bounds (3 px, 0.025 rad) keep a margin over the largest errors the accuracy study saw among
accepted frames (``bench/accuracy_study.py``), and a tighter declared bound tightens the checks.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import cv2
import numpy as np

from tileviz.config import CameraConfig, VisionConfig
from tileviz.types import Observation
from tileviz.vision import draw
from tileviz.vision.geometry import QUARTER, family_normals
from tileviz.vision.result import BAG_HORIZONTAL, BAG_VERTICAL, VisionResult

__all__ = ["RobustSettings", "clip_line", "extract_robust", "normalise"]

PARTS = 4
"""Each line is measured in this many parts along its length."""


@dataclass(frozen=True)
class RobustSettings:
    """Thresholds of the robust extractor (gray levels 0..255, pixels, radians)."""

    min_range: float = 6.0
    """Gray range (2nd to 98th percentile) below which the image is ``constant image``."""
    glare_fraction: float = 0.04
    """Fraction of pixels >= 250 above which the frame is refused as ``glare``."""
    min_depth: float = 15.0
    """Weakest grout dip trusted, gray levels (``low contrast`` when the deepest is weaker)."""
    rel_depth: float = 0.3
    """A dip counts as a line when at least this fraction of the deepest dip."""
    max_rise: float = 3.0
    """Median 20-80 % edge rise of the lines above which the view is ``blurred``, px."""
    max_step: float = 0.85
    """|level left - level right| / brighter level above which a line is a ``step edge``."""
    spacing_fraction: float = 0.5
    """A line may sit at most this fraction of the declared position bound off the lattice."""
    straight_fraction: float = 1.0
    """A line's parts may sit at most this fraction of the position bound off the common fit."""
    min_chord: float = 0.35
    """A lattice line is expected (``inconsistent spacing`` when missing) where its chord is at
    least this fraction of the longest chord in the view."""
    min_evidence: float = 0.5
    """Total line length per family, as a fraction of the smaller image side."""
    width_ratio: float = 1.5
    """Lines may differ in half-depth width at most by this factor (+ ``width_slack`` px)."""
    width_slack: float = 1.0
    contrast_ratio: float = 1.7
    """Lines may differ in contrast (depth / level) at most by this factor."""
    foreign_length: float = 0.3
    """Straight edges off the lattice longer than this fraction of the smaller side refuse."""
    foreign_contrast: float = 0.35
    """Edges weaker than this fraction of the grout's depth (a step of that many gray levels)
    are not searched for foreign objects."""
    heading_share: float = 0.2
    """Share of the pixels (the strongest gradients) that vote for the heading."""
    refine_tilt: float = 0.012
    """Heading correction (rad) above which the warp is redone."""
    check_position_px: float = 2.0
    """Scale of the position consistency checks, px: they use the smaller of this and the
    declared ``VisionConfig.position_error_px``."""
    check_heading: float = 0.02
    """Scale of the heading check, rad (the smaller of this and ``heading_error``)."""
    min_part: float = 20.0
    """Shortest stretch of a line measured on its own (a part), px."""
    sigmas: float = 4.0
    """The fit's own standard errors times this must stay within the declared bounds."""
    prior_sigma: float = 1.5
    """Prior scatter of a part's centroid at unit part length, px sqrt(px) (0.15 px for a
    100 px part), weighing ``prior_dof`` degrees of freedom."""
    prior_dof: float = 2.0
    floor_px: float = 0.1
    """Smallest position bound of a view, px (with ``floor_width`` x the grout's half-depth
    width and ``floor_rise`` x its edge rise added)."""
    floor_width: float = 0.02
    asym_factor: float = 1.5
    asym_step: float = 0.2
    """A line's asymmetry counts fully from this step between its sides on (proportionally
    below)."""
    """Weight in the position bound of the largest disagreement between a part's centroid and
    the midpoint of its half-depth edges (an asymmetric dip), px per px."""
    floor_rise: float = 0.05
    floor_rad: float = 0.0005
    """Smallest heading bound of a view, rad."""
    heading_sigmas: float = 6.0
    """The heading bound is this many standard errors of the fitted tilt (plus ``floor_rad``):
    the tilt's error has heavier tails than the positions' (bench/vision_study.py)."""
    """Smallest heading bound of a view, rad."""


DEFAULT_SETTINGS = RobustSettings()


def normalise(y1: float, y2: float, y3: float, tile_size: float) -> tuple[float, float, float]:
    """The same observation with y3 in [-pi/4, pi/4) and y1, y2 in [0, L) (design.md).

    Turning y3 by -m pi/2 turns (y1, y2) by R(-m pi/2): R((m0 + m) pi/2) (y1', y2') must equal
    R(m0 pi/2) (y1, y2)."""
    m = math.floor((y3 + 0.25 * math.pi) / QUARTER)
    y3n = y3 - m * QUARTER
    if y3n >= 0.25 * math.pi:
        y3n -= QUARTER
        m += 1
    elif y3n < -0.25 * math.pi:
        y3n += QUARTER
        m -= 1
    a, b = ((y1, y2), (y2, -y1), (-y1, -y2), (-y2, y1))[m & 3]
    a %= tile_size
    b %= tile_size
    return (0.0 if a >= tile_size else a, 0.0 if b >= tile_size else b, y3n)


def clip_line(
    n: tuple[float, float], s: float, width: int, height: int
) -> tuple[float, float, float, float] | None:
    """The part inside the image of the line ``n . (p - centre) = s`` (n a unit normal in pixel
    coordinates, s in px) as endpoints (x1, y1, x2, y2), or None when it misses the image.
    The image spans [-0.5, W - 0.5] x [-0.5, H - 0.5] (pixel centres at integers)."""
    cxp, cyp = (width - 1) / 2.0, (height - 1) / 2.0
    tx, ty = -n[1], n[0]
    px, py = cxp + s * n[0], cyp + s * n[1]
    lo, hi = -math.inf, math.inf
    for p0, d, size in ((px, tx, width), (py, ty, height)):
        if abs(d) < 1e-12:
            if not -0.5 <= p0 <= size - 0.5:
                return None
            continue
        a = (-0.5 - p0) / d
        b = (size - 0.5 - p0) / d
        lo = max(lo, min(a, b))
        hi = min(hi, max(a, b))
    if hi - lo <= 0:
        return None
    return (px + lo * tx, py + lo * ty, px + hi * tx, py + hi * ty)


@dataclass
class _Line:
    """A grout line candidate of one family, measured on the warped image.

    Positions are profile coordinates (row for family 1, column for family 2) in the warp
    frame; tangent coordinates t are along the line, relative to the warp centre."""

    depth: float
    width: float  # half-depth width, median over the parts, px
    rise: float  # 20-80 % edge rise, median over the parts, px
    step: float  # |level left - level right| / brighter level
    contrast: float  # depth / brighter plateau level (vignetting and shading cancel)
    chord: float  # line length in the view, px
    parts: np.ndarray  # (PARTS,) centroid in each part (NaN when not measured)
    tpart: np.ndarray  # (PARTS,) mean tangent coordinate of each part
    asym: float  # largest |half-depth midpoint - centroid| over the parts, px
    wpart: np.ndarray  # (PARTS,) length of each part (0 when not measured)
    pos: float = math.nan  # at tangent coordinate 0, after the common tilt fit
    var: float = math.inf  # variance of pos from the fit's scatter, px^2


class _Fail(Exception):
    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def extract_robust(
    gray: np.ndarray,
    *,
    camera: CameraConfig,
    tile_size: float,
    vision: VisionConfig,
    keep_stages: bool = False,
    image: np.ndarray | None = None,
    timings: dict[str, float] | None = None,
    settings: RobustSettings = DEFAULT_SETTINGS,
) -> VisionResult:
    """Run the robust extractor on ``gray`` (HxW uint8); see the module docstring.

    ``image`` (the RGB input) is only used for the overlays when ``keep_stages``; ``timings``
    (ms) may already hold the gray conversion's time."""
    tm = {} if timings is None else timings
    run = _Run(gray, camera, tile_size, vision, settings, tm)
    reason = "ok"
    # missing data is NaN throughout (profiles beyond the view, unmeasured parts): arithmetic
    # on it is expected and its warnings are noise
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        try:
            run.execute()
        except _Fail as f:
            reason = f.reason
    t0 = time.perf_counter()
    res = run.result(reason)
    tm["result"] = (time.perf_counter() - t0) * 1e3
    if keep_stages:
        t1 = time.perf_counter()
        stages = run.stages(image, res)
        tm["stages"] = (time.perf_counter() - t1) * 1e3
        res = replace(res, stages=stages)
    return res


class _Run:
    """One frame through the robust extractor (keeps intermediate arrays for the stages)."""

    def __init__(
        self,
        gray: np.ndarray,
        camera: CameraConfig,
        tile_size: float,
        vision: VisionConfig,
        settings: RobustSettings,
        timings: dict[str, float],
    ) -> None:
        self.gray = gray
        self.vision = vision
        self.st = settings
        self.tm = timings
        self.h, self.w = gray.shape
        self.side = float(min(self.h, self.w))
        self.ppm = float(camera.ppm)
        self.tile_size = float(tile_size)
        self.lp = self.tile_size * self.ppm  # tile period, px
        # the consistency checks work at the smaller of the declared bounds and the check
        # scales (the declared bounds keep a margin over the errors the checks let through)
        self.bound_px = min(float(vision.position_error_px), settings.check_position_px)
        self.bound_rad = min(float(vision.heading_error), settings.check_heading)
        self.mean = 0.0
        self.edges: np.ndarray | None = None
        self.free_edges: np.ndarray | None = None
        self.warped: np.ndarray | None = None
        self.centre = (0.0, 0.0)  # warp centre (X0, Y0)
        self.lines: list[list[_Line]] = [[], []]
        self.y3: float | None = None
        self.y: tuple[float, float, float] | None = None
        self.foreign: np.ndarray = np.zeros((0, 4))
        self.details: dict[str, float] = {}
        # grey-closing window of the profile baseline (wider than any grout dip) and the
        # half-size of the window each dip is measured in, samples (px)
        # (up to a third of the tile period: a grout band up to ~20 px wide on any floor whose
        # tiles span 80 px or more)
        self.closing = 2 * int(round(min(max(8.0, 0.17 * self.lp), 30.0))) + 1
        # half-size of the window each dip is measured in: 20 samples suit grout up to ~9 px
        # wide; a wider band measures again with a window up to closing + 8 (see execute)
        self.window = min(20, self.closing + 8)
        self.inverted = False  # grout lighter than the tiles: the gray levels are inverted

    def _lap(self, name: str, t0: float) -> float:
        t = time.perf_counter()
        self.tm[name] = self.tm.get(name, 0.0) + (t - t0) * 1e3
        return t

    # ------------------------------------------------------------------ pipeline
    def execute(self) -> None:
        """Run every step; raises _Fail with the reason of the first failed check."""
        t = time.perf_counter()
        self._statistics()
        t = self._lap("statistics", t)
        dx = cv2.Scharr(self.gray, cv2.CV_16S, 1, 0)
        dy = cv2.Scharr(self.gray, cv2.CV_16S, 0, 1)
        self._dxy = (dx, dy)
        self._noise_sigma()
        t = self._lap("edges", t)
        y3 = self._heading(dx, dy)
        t = self._lap("heading", t)
        for attempt in range(3):
            lines = self._select(self._measure(y3, attempt))
            # a window too narrow for the grout (a wide band): measure again with a wider one
            width = self.details.get("width", math.nan) if lines[0] or lines[1] else math.nan
            need = self.closing + 8
            if math.isfinite(width):
                need = min(int(math.ceil(1.5 * width + 12.0)), need)
            if need > self.window:
                self.window = need
                lines = self._select(self._measure(y3, attempt + 1))
            tilt = self._fit(lines)
            t = self._lap("profiles", t)
            y3 += tilt
            if abs(tilt) <= self.st.refine_tilt or attempt == 2:
                break
        self.lines = lines
        self.y3 = y3
        self._check_lines(lines)
        t = self._lap("checks", t)
        self._lattice(lines, y3)
        t = self._lap("lattice", t)
        self._foreign()
        self._lap("foreign", t)

    def _statistics(self) -> None:
        st = self.st
        hist = cv2.calcHist([self.gray], [0], None, [256], [0, 256]).ravel()
        cdf = np.cumsum(hist)
        n = float(cdf[-1])
        lo = float(np.searchsorted(cdf, 0.02 * n))
        hi = float(np.searchsorted(cdf, 0.98 * n))
        self.mean = float(np.dot(hist, np.arange(256))) / n
        self.details["gray_range"] = hi - lo
        if hi - lo < st.min_range:
            raise _Fail("constant image")
        saturated = float(hist[250:].sum()) / n
        self.details["saturated"] = saturated
        if saturated > st.glare_fraction:
            raise _Fail("glare")

    def _noise_sigma(self) -> float:
        """Gaussian noise std of the image, gray levels (Immerkaer's fast estimate)."""
        k = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
        # integer kernel on 8-bit pixels: |r| <= 16 * 255 fits 16 bits exactly, and the L1 sum
        # is the same exact integer as in float (half the time of a float32 filter)
        r = cv2.filter2D(self.gray, cv2.CV_16S, k)
        sigma = math.sqrt(math.pi / 2.0) * float(cv2.norm(r[1:-1, 1:-1], cv2.NORM_L1)) / (
            6.0 * (self.w - 2) * (self.h - 2)
        )
        self.details["noise_sigma"] = sigma
        return sigma

    def _heading(self, dx: np.ndarray, dy: np.ndarray) -> float:
        """First y3 estimate (rad) from the gradient directions of the strongest gradients.

        Every pixel votes (not only Canny's edge pixels: on a textured surface those are mostly
        the texture's): 4 phi of its gradient, weighted by the gradient magnitude, over the
        pixels in the top ``heading_share`` of magnitudes; the peak of the smoothed histogram,
        then the weighted circular mean of the votes near the peak (report eq. 4.4 per pixel).
        Grout lines, tile-to-tile shade steps and a surface laid along the tiles all vote for
        the lattice direction (mod pi/2); isotropic texture adds a flat floor."""
        # (2 phi) as the angle of (gx^2 - gy^2, 2 gx gy), and |g|^2 its length
        # every other row and column: a quarter of the votes is plenty for a first estimate
        # (the fit over the lattice refines it)
        fx = dx[::2, ::2].astype(np.float32)
        fy = dy[::2, ::2].astype(np.float32)
        c2 = cv2.subtract(cv2.multiply(fx, fx), cv2.multiply(fy, fy))
        s2 = cv2.multiply(fx, fy, scale=2.0)
        mag2, ang2 = cv2.cartToPolar(c2, s2)  # |g|^2, 2 phi in [0, 2 pi)
        m = mag2.ravel()
        n = m.size
        k = max(20, int(self.st.heading_share * n))
        thr = float(np.partition(m, n - k)[n - k])
        if thr <= 0.0:
            raise _Fail("no lines")
        sel = np.flatnonzero(m >= thr)
        wgt = np.sqrt(m[sel])  # |g|
        ang = np.remainder(2.0 * ang2.ravel()[sel], 2.0 * math.pi) - math.pi  # 4 phi - pi
        nb = 90
        b = ((ang + math.pi) * (nb / (2.0 * math.pi))).astype(np.int32) % nb
        hist = np.bincount(b, weights=wgt, minlength=nb)
        smooth = (hist + np.concatenate((hist[-1:], hist[:-1]))
                  + np.concatenate((hist[1:], hist[:1])))
        peak = (int(np.argmax(smooth)) + 0.5) * (2.0 * math.pi / nb) - math.pi
        near = np.abs(np.remainder(ang - peak + math.pi, 2.0 * math.pi) - math.pi) < 0.35
        wn = wgt[near]
        an = ang[near] + math.pi
        self.details["orientation_share"] = float(wn.sum() / max(float(wgt.sum()), 1e-9))
        # gradient directions are normal to the lines: 4 (a + pi/2) = 4 a (mod 2 pi)
        return math.atan2(float(np.dot(wn, np.sin(an))), float(np.dot(wn, np.cos(an)))) / 4.0

    def _light_grout(self, warped: np.ndarray, size: tuple[int, int],
                     cs: tuple[float, float]) -> bool:
        """Whether the grout is lighter than the tiles: the family profiles (row and column
        means of the warped image, offsets from the mean) hold stronger narrow peaks (above a
        grey opening) than narrow dips (below a grey closing), summed over both families."""
        wo, ho = size
        c, s = cs
        kern = np.ones((1, self.closing), np.uint8)
        score = 0.0
        for k, axis in ((0, 1), (1, 0)):
            n = ho if k == 0 else wo
            q = np.arange(n) - ((n - 1) / 2.0)
            lo, hi = self._spans(q, c, s, along_rows=k == 0)
            length = np.maximum(hi - lo, 0.0)
            ok = length >= max(8.0, 0.15 * float(length.max()))
            if int(ok.sum()) < 8:
                continue
            sums = cv2.reduce(warped, axis, cv2.REDUCE_SUM, dtype=cv2.CV_64F).ravel()
            prof = (sums[ok] / length[ok]).astype(np.float32)[None, :]
            # beyond the view: the median level (the tiles'), so that a stretch of tile or a
            # line cut by the border is neither a peak nor a dip
            mid = float(np.median(prof))
            bd = {"borderType": cv2.BORDER_CONSTANT, "borderValue": mid}
            close = cv2.erode(cv2.dilate(prof, kern, **bd), kern, **bd)
            opening = cv2.dilate(cv2.erode(prof, kern, **bd), kern, **bd)
            score += float((prof - opening).max()) - float((close - prof).max())
        return score > 0.0

    def _measure(self, y3: float, attempt: int = 1) -> list[list[_Line]]:
        """Warp the image by y3 and measure the dips of both families (on the first attempt,
        also decide the grout's polarity)."""
        c, s = math.cos(y3), math.sin(y3)
        w, h = self.w, self.h
        wo = int(math.ceil(w * abs(c) + h * abs(s))) + 2
        ho = int(math.ceil(w * abs(s) + h * abs(c))) + 2
        x0, y0 = (wo - 1) / 2.0, (ho - 1) / 2.0
        cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
        # dst (X, Y) -> src: p = centre + (X - X0) (c, s) + (Y - Y0) (-s, c), so that rows follow
        # family-1 lines (s1 = -(Y - Y0)) and columns family-2 lines (s2 = -(X - X0)).
        m = np.array([[c, -s, cx - x0 * c + y0 * s], [s, c, cy - x0 * s - y0 * c]])
        src = self.gray.astype(np.float32)
        src -= np.float32(self.mean)  # outside the view reads 0, i.e. the mean level
        warped = cv2.warpAffine(
            src,
            m,
            (wo, ho),
            flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0,
        )
        if attempt == 0 and self._light_grout(warped, (wo, ho), (c, s)):
            # lighter grout: measure the inverted image (255 - gray), whose offset from its
            # mean is -warped; every later step then sees dark lines on brighter tiles
            self.inverted = True
            self.mean = 255.0 - self.mean
        if self.inverted:
            cv2.multiply(warped, -1.0, dst=warped)
        self.warped = warped
        self.centre = (x0, y0)
        # integral image: the sum over any stretch of any row or column in four look-ups
        integ = cv2.integral(warped, sdepth=cv2.CV_64F)
        sums = (integ[1:, -1] - integ[:-1, -1], integ[-1, 1:] - integ[-1, :-1])
        spans = (
            self._spans(np.arange(ho) - y0, c, s, along_rows=True),
            self._spans(np.arange(wo) - x0, c, s, along_rows=False),
        )
        return self._dips(integ, sums, spans)

    def _spans(
        self, q: np.ndarray, c: float, s: float, *, along_rows: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """The in-view stretch [lo, hi] of each warped row (``along_rows``) or column at offset
        ``q`` from the warp centre, in the tangent coordinate u (relative to the centre); empty
        where hi <= lo."""
        cx, cy = (self.w - 1) / 2.0, (self.h - 1) / 2.0
        lo = np.full(q.shape, -np.inf)
        hi = np.full(q.shape, np.inf)
        # src col = cx + a u + b q, row = cy + e u + f q
        a, b, e, f = (c, -s, s, c) if along_rows else (-s, c, c, s)
        for coef, base, size in ((a, cx + b * q, self.w), (e, cy + f * q, self.h)):
            if abs(coef) < 1e-12:
                lo = np.where((base >= -0.5) & (base <= size - 0.5), lo, np.inf)
                continue
            u1 = (-0.5 - base) / coef
            u2 = (size - 0.5 - base) / coef
            lo = np.maximum(lo, np.minimum(u1, u2))
            hi = np.minimum(hi, np.maximum(u1, u2))
        return lo, hi

    def _dips(
        self,
        integ: np.ndarray,
        sums: tuple[np.ndarray, np.ndarray],
        spans: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    ) -> list[list[_Line]]:
        """The lines of both families. Dips are found in each family's whole profile (row or
        column means of the warped image); each dip is then measured in PARTS equal stretches
        of the part of its line that every sample of its window sees (so all samples of a part
        average the same stretch of floor), from the integral image ``integ``. Every dip of both
        families is measured at once (vectorised)."""
        r = self.window
        mean = self.mean
        size = max(sums[0].size, sums[1].size) + 2 * r
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
            with np.errstate(invalid="ignore", divide="ignore"):
                prof[k, r : r + n] = np.where(valid, sums[k] / length + mean, np.nan)
        # baseline: a grey closing (max then min filter, along each row) removes dips narrower
        # than its window
        missing = np.isnan(prof)
        filled = np.where(missing, mean, prof).astype(np.float32)
        kern = np.ones((1, self.closing), np.uint8)
        base = cv2.erode(
            cv2.dilate(filled, kern, borderType=cv2.BORDER_REPLICATE),
            kern,
            borderType=cv2.BORDER_REPLICATE,
        )
        dark = base - prof  # NaN where no data
        peaks: list[tuple[int, int]] = []
        for k in range(2):
            ok = ~missing[k]
            if int(ok.sum()) < 8:
                continue
            diffs = np.abs(np.diff(prof[k][ok]))
            kth = diffs.size // 2
            sig = 1.4826 * float(np.partition(diffs, kth)[kth]) / math.sqrt(2.0)
            self.details["profile_noise"] = max(self.details.get("profile_noise", 0.0), sig)
            thr = max(0.5 * self.st.min_depth, 5.0 * sig)
            dk = np.where(ok, dark[k], -np.inf)
            above = dk > thr
            if not above.any():
                continue
            edges = np.diff(above.astype(np.int8), prepend=0, append=0)
            starts = np.flatnonzero(edges == 1)
            ends = np.flatnonzero(edges == -1)
            for a, b in zip(starts, ends, strict=True):
                peaks.append((k, a + int(np.argmax(dk[a:b]))))
        if not peaks:
            return [[], []]
        fam = np.array([k for k, _ in peaks])
        pk = np.array([p for _, p in peaks])
        m = pk.size
        jj = np.arange(-r, r + 1)
        jf = jj.astype(np.float64)
        cols = pk[:, None] + jj[None, :]
        # the whole profile: depth, half-depth crossings, width, window and plateau levels
        p0 = prof[fam[:, None], cols]
        d0 = dark[fam[:, None], cols]
        near = np.nan_to_num(d0[:, r - 2 : r + 3], nan=-np.inf)
        depth = near.max(axis=1)
        hl, hr = _crossings(d0, jf, np.argmax(near, axis=1) - 2, 0.5 * depth)
        c0 = 0.5 * (hl + hr)
        half = 1.5 * (hr - hl) + 1.5
        lev_l, lev_r = _plateaus(p0, jf, c0, half)
        # the parts: PARTS equal stretches of the window's common in-view stretch
        # (over the samples a part's centroid and plateaus use: c0 +- (half + 4))
        used = np.abs(jf[None, :] - np.nan_to_num(c0)[:, None]) <= (
            np.nan_to_num(half)[:, None] + 5.0
        )
        u_lo = np.where(used, lo[fam[:, None], cols], -np.inf).max(axis=1) + 1.0
        u_hi = np.where(used, hi[fam[:, None], cols], np.inf).min(axis=1) - 1.0
        step = (u_hi - u_lo) / PARTS
        usable = np.isfinite(c0) & (step >= self.st.min_part / 2.0)
        x0, y0 = self.centre
        along = np.where(fam == 0, x0, y0)  # warp coordinate of u = 0
        with np.errstate(invalid="ignore"):
            edges_u = u_lo[:, None] + step[:, None] * np.arange(PARTS + 1)[None, :]
            idx = np.ceil(along[:, None] + edges_u)
        idx = np.where(usable[:, None], idx, 0.0).astype(np.intp)
        count = np.diff(idx, axis=1)  # samples in each part, (m, PARTS)
        tpart = 0.5 * (idx[:, :-1] + idx[:, 1:] - 1) - along[:, None]
        line = np.clip(cols - r, 0, integ.shape[0] + integ.shape[1])  # warp row / column
        a = idx[:, None, :-1]  # (m, 1, PARTS)
        b = idx[:, None, 1:]
        q = line[:, :, None]  # (m, W, 1)
        fam1 = (fam == 0)[:, None, None]
        hmax, wmax = integ.shape[0] - 1, integ.shape[1] - 1
        qr = np.minimum(q, hmax - 1)
        qc = np.minimum(q, wmax - 1)
        ar, br = np.minimum(a, wmax), np.minimum(b, wmax)
        ac, bc = np.minimum(a, hmax), np.minimum(b, hmax)
        part_sum = np.where(
            fam1,
            integ[qr + 1, br] - integ[qr, br] - integ[qr + 1, ar] + integ[qr, ar],
            integ[bc, qc + 1] - integ[bc, qc] - integ[ac, qc + 1] + integ[ac, qc],
        )  # (m, W, PARTS)
        with np.errstate(invalid="ignore", divide="ignore"):
            pp = part_sum / count[:, None, :] + mean
        pp = np.where(usable[:, None, None] & ~np.isnan(p0)[:, :, None], pp, np.nan)
        pp = pp.transpose(0, 2, 1).reshape(m * PARTS, -1)  # row i * PARTS + j
        cj = np.repeat(c0, PARTS)
        hj = np.repeat(half, PARTS)
        ll, lr = _plateaus(pp, jf, cj, hj)
        lev = ll[:, None] + (lr - ll)[:, None] * np.clip(jf[None, :] - cj[:, None] + 0.5, 0, 1)
        dp = lev - pp
        nearp = np.nan_to_num(dp[:, r - 3 : r + 4], nan=-np.inf)
        dpk = nearp.max(axis=1)
        jp = np.argmax(nearp, axis=1) - 3
        lv = np.concatenate([0.5 * dpk, 0.2 * dpk, 0.8 * dpk])
        xl, xr = _crossings(np.tile(dp, (3, 1)), jf, np.tile(jp, 3), lv)
        nr = dp.shape[0]
        width = (xr[:nr] - xl[:nr]).reshape(m, PARTS)
        rise = (0.5 * ((xl[2 * nr :] - xl[nr : 2 * nr]) + (xr[nr : 2 * nr] - xr[2 * nr :])))
        rise = rise.reshape(m, PARTS)
        inside = (cj - hj - 4.0 >= -r) & (cj + hj + 4.0 <= r)
        cen = _centroid(pp, jf, cj, hj, ll, lr)
        cen = np.where(inside & (np.abs(cen - cj) <= hj), cen, np.nan).reshape(m, PARTS)
        # the same position from the dip's half-depth edges: a symmetric dip gives the
        # centroid; a step or shadow inside the window pulls the two apart
        mid = (0.5 * (xl[:nr] + xr[:nr])).reshape(m, PARTS)
        with np.errstate(invalid="ignore"):
            asym = np.nanmax(np.where(np.isfinite(cen) & np.isfinite(mid), np.abs(mid - cen),
                                      0.0), axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            wmed = _nanmedian(width.T)
            rmed = _nanmedian(rise.T)
            cmed = _nanmedian((dpk / np.maximum(ll, lr)).reshape(m, PARTS).T)
        lo_lev = np.minimum(lev_l, lev_r)
        hi_lev = np.maximum(lev_l, lev_r)
        stepr = (hi_lev - lo_lev) / np.maximum(hi_lev, 1e-9)
        out: list[list[_Line]] = [[], []]
        for i in range(m):
            ok = np.isfinite(cen[i])
            if not usable[i] or not ok.any():
                continue
            out[int(fam[i])].append(
                _Line(
                    depth=float(depth[i]),
                    width=float(wmed[i]),
                    rise=float(rmed[i]),
                    step=float(stepr[i]),
                    contrast=float(cmed[i]),
                    chord=float(total[fam[i], pk[i]]),
                    parts=pk[i] - r + cen[i],
                    asym=float(asym[i]),
                    tpart=tpart[i],
                    wpart=np.where(ok, count[i], 0).astype(np.float64),
                )
            )
        return out

    def _select(self, lines: list[list[_Line]]) -> list[list[_Line]]:
        """Keep the dips that look like grout lines: deep enough against the deepest, and not
        much wider than the strong ones (a broad shadow or stain is not a line)."""
        every = lines[0] + lines[1]
        if not every:
            return [[], []]
        deepest = max(ln.depth for ln in every)
        wref = float(np.median([ln.width for ln in every if ln.depth >= 0.5 * deepest]))
        self.details["depth"] = deepest
        self.details["width"] = wref
        return [
            [
                ln
                for ln in fam
                if ln.depth >= self.st.rel_depth * deepest and ln.width <= 2.0 * wref + 2.0
            ]
            for fam in lines
        ]

    def _fit(self, lines: list[list[_Line]]) -> float:
        """Fit one residual tilt eps for all lines (family-1 rows drift by +eps per unit of t,
        family-2 columns by -eps) and one intercept per line, weighted by part lengths; set each
        line's ``pos`` (at t = 0) and ``var``; return eps (rad). Also records the tilt of each
        family on its own (``tilt_gap``: their difference in standard errors)."""
        num = [0.0, 0.0]
        den = [0.0, 0.0]
        stats = []
        for k, (fam, sign) in enumerate(((lines[0], 1.0), (lines[1], -1.0))):
            for ln in fam:
                ok = ln.wpart > 0
                w = ln.wpart[ok]
                t = ln.tpart[ok]
                p = ln.parts[ok]
                tb = float(np.dot(w, t) / w.sum())
                pb = float(np.dot(w, p) / w.sum())
                num[k] += sign * float(np.dot(w, (t - tb) * (p - pb)))
                den[k] += float(np.dot(w, (t - tb) ** 2))
                stats.append((ln, sign, tb, pb))
        dall = den[0] + den[1]
        eps = (num[0] + num[1]) / dall if dall > 1e-9 else 0.0
        worst = 0.0
        ss = 0.0
        nobs = 0
        for ln, sign, tb, pb in stats:
            ln.pos = pb - sign * eps * tb
            ok = ln.wpart > 0
            res = ln.parts[ok] - (ln.pos + sign * eps * ln.tpart[ok])
            ss += float(np.dot(ln.wpart[ok], res * res))
            nobs += int(ok.sum())
            big = ln.wpart[ok] >= 0.25 * ln.wpart.max()
            if big.any():
                worst = max(worst, float(np.abs(res[big]).max()))
        self.details["straightness_px"] = worst
        # Scatter of the parts about the fit, per unit of part length (px^2 px), with a weak
        # prior so that a fit with few degrees of freedom is not trusted blindly.
        st = self.st
        dof = max(nobs - (len(stats) + 1), 0)
        sigma2 = (ss + st.prior_dof * st.prior_sigma**2) / (dof + st.prior_dof)
        var_eps = sigma2 / dall if dall > 1e-9 else math.inf
        for ln, _, tb, _ in stats:
            ln.var = sigma2 / float(ln.wpart.sum()) + tb * tb * var_eps
        self.details["heading_se"] = math.sqrt(var_eps)
        # the two families must be perpendicular: their own tilts agree within their errors
        if den[0] > 1e-9 and den[1] > 1e-9:
            gap = abs(num[0] / den[0] - num[1] / den[1])
            self.details["tilt_gap"] = gap / math.sqrt(sigma2 / den[0] + sigma2 / den[1])
        else:
            self.details["tilt_gap"] = 0.0
        return eps

    def _check_lines(self, lines: list[list[_Line]]) -> None:
        st = self.st
        if not lines[0] and not lines[1]:
            raise _Fail("no lines")
        if self.details["depth"] < st.min_depth:
            raise _Fail("low contrast")
        if not lines[0] or not lines[1]:
            raise _Fail("one family")
        every = lines[0] + lines[1]
        rises = [ln.rise for ln in every if math.isfinite(ln.rise)]
        rise = float(np.median(rises)) if rises else math.inf
        self.details["rise"] = rise
        if not rise <= st.max_rise:
            raise _Fail("blurred")
        step = max(ln.step for ln in every)
        self.details["step"] = step
        if step > st.max_step:
            raise _Fail("step edge")
        if (
            self.details["straightness_px"] > st.straight_fraction * self.bound_px
            or self.details["tilt_gap"] > st.sigmas
        ):
            raise _Fail("inconsistent angle")
        # Grout lines of both families share one width and one colour: a line unlike the
        # others (a cable along the grout direction, a seam) is foreign.
        widths = [ln.width for ln in every if math.isfinite(ln.width)]
        contrasts = [ln.contrast for ln in every]
        self.details["width_spread"] = max(widths) / min(widths) if widths else math.inf
        self.details["contrast_spread"] = max(contrasts) / max(min(contrasts), 1e-9)
        if (
            not widths
            or max(widths) > st.width_ratio * min(widths) + st.width_slack
            or self.details["contrast_spread"] > st.contrast_ratio
        ):
            raise _Fail("foreign line")

    def _lattice(self, lines: list[list[_Line]], y3: float) -> None:
        """Offsets modulo L per family, the spacing checks, and the observation."""
        st = self.st
        x0, y0 = self.centre
        lp = self.lp
        ys: list[float] = []
        worst = 0.0
        se = 0.0
        for k, fam in enumerate(lines):
            # signed offsets s_k (px) at the image centre: s1 = -(Y - Y0), s2 = -(X - X0)
            s_arr = np.array([-(ln.pos - (y0 if k == 0 else x0)) for ln in fam])
            w_arr = np.array([ln.chord for ln in fam])
            ang = s_arr * (2.0 * math.pi / lp)
            ref = math.atan2(float(np.dot(w_arr, np.sin(ang))), float(np.dot(w_arr, np.cos(ang))))
            ref *= lp / (2.0 * math.pi)
            res = np.remainder(s_arr - ref + 0.5 * lp, lp) - 0.5 * lp
            ref += float(np.dot(w_arr, res) / w_arr.sum())
            res = np.remainder(s_arr - ref + 0.5 * lp, lp) - 0.5 * lp
            worst = max(worst, float(np.abs(res).max()))
            var = np.array([ln.var for ln in fam])
            se = max(se, math.sqrt(float(np.dot(w_arr * w_arr, var))) / float(w_arr.sum()))
            ys.append(-ref / self.ppm)  # eq. 4.6 corrected: y_k = -s_k mod L
            self._missing_lines(k, ref, s_arr, y3)
        self.details["spacing_residual_px"] = worst
        if worst > st.spacing_fraction * self.bound_px:
            raise _Fail("inconsistent spacing")
        for fam in lines:
            if sum(ln.chord for ln in fam) < st.min_evidence * self.side:
                raise _Fail("too few segments")
        self.details["position_se_px"] = se
        pos_px, head = self._frame_bound(se)
        self.details["bound_px"] = pos_px
        self.details["bound_rad"] = head
        if pos_px > self.vision.position_error_px or head > self.vision.heading_error:
            raise _Fail("imprecise")
        self.y = normalise(ys[0], ys[1], y3, self.tile_size)

    def _frame_bound(self, se: float) -> tuple[float, float]:
        """This view's error bound (px, rad) from its own evidence (docs/vision.md, "The
        bound of a view"): ``sigmas`` standard errors of the fit (the scatter of every line's
        parts about one straight lattice), plus the largest deviations the fit could not
        explain (a line off the lattice spacing, half the worst part off its line), plus a
        floor for what the scatter cannot show (interpolation, a band's width under uneven
        light, blur)."""
        st = self.st
        d = self.details
        # a step between the two sides of a line (a shadow or a box edge near it, a shade step)
        # inside the centroid's window pulls the centroid off the half-depth midpoint; without
        # a step the difference is only the crossings' noise
        d["asymmetry_px"] = max(ln.asym * min(1.0, ln.step / st.asym_step)
                                for fam in self.lines for ln in fam)
        pos = (st.sigmas * se + d["spacing_residual_px"] + 0.5 * d["straightness_px"]
               + st.asym_factor * d["asymmetry_px"]
               + st.floor_px + st.floor_width * d["width"] + st.floor_rise * d["rise"])
        head = st.heading_sigmas * d["heading_se"] + st.floor_rad
        return pos, head

    def _missing_lines(self, k: int, ref: float, found: np.ndarray, y3: float) -> None:
        """Refuse when the lattice predicts a well-visible line of family k that was not found
        (the signed offsets ``ref + j L ppm``, px)."""
        n = family_normals(y3)[k]
        reach = 0.5 * math.hypot(self.w, self.h)
        # a dip is measured over its window and 4 plateau samples on each side
        margin = math.ceil(1.5 * self.details["width"] + 1.5) + 5

        def chord(s: float) -> float:
            e = clip_line(n, s, self.w, self.h)
            return 0.0 if e is None else math.hypot(e[2] - e[0], e[3] - e[1])

        # the longest chord of a direction through a rectangle passes through its centre
        need = self.st.min_chord * chord(0.0)
        j0 = math.floor((-reach - ref) / self.lp)
        j1 = math.ceil((reach - ref) / self.lp)
        for j in range(j0, j1 + 1):
            s = ref + j * self.lp
            if min(chord(s - margin), chord(s), chord(s + margin)) < need:
                continue
            if found.size == 0 or float(np.min(np.abs(found - s))) > 0.25 * self.lp:
                raise _Fail("inconsistent spacing")

    def _foreign(self) -> None:
        """Refuse when a long straight edge is not explained by the predicted grout lines."""
        assert self.y is not None
        # Edges at least ``foreign_contrast`` of the grout's own contrast (in gray levels: a
        # texture's fine edges are not objects) and above the noise. Scharr answers 16 x a unit
        # step; its noise is about 15.4 sigma per component.
        dx, dy = self._dxy
        high = max(240.0, 6.0 * 15.4 * self.details["noise_sigma"],
                   16.0 * self.st.foreign_contrast * self.details["depth"])
        self.edges = cv2.Canny(dx, dy, 0.5 * high, high, L2gradient=True)
        free = self.edges.copy()
        wmax = max(ln.width for fam in self.lines for ln in fam)
        thick = int(math.ceil(wmax + 2.0 * max(2.0, 0.5 * wmax) + 2.0))
        _draw_lattice_mask(free, self.y, self.ppm, self.tile_size, thick)
        self.free_edges = free
        minlen = max(25.0, self.st.foreign_length * self.side)
        seg = cv2.HoughLinesP(
            free, 1.0, math.pi / 180.0, int(0.5 * minlen), minLineLength=minlen, maxLineGap=3.0
        )
        if seg is None:
            return
        seg = np.asarray(seg, np.float64).reshape(-1, 4)
        self.foreign = seg
        self.details["foreign_segments"] = float(len(seg))
        raise _Fail(self._classify_edge(seg))

    def _classify_edge(self, seg: np.ndarray) -> str:
        """``step edge`` when the longest foreign segment separates two different levels (a box,
        a shadow), ``foreign line`` when it is a dark or bright ridge with the same level on
        both sides (a cable): the gray profile across it, median along it, from -16 to 16 px."""
        lengths = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
        x1, y1, x2, y2 = seg[int(np.argmax(lengths))]
        ln = max(math.hypot(x2 - x1, y2 - y1), 1e-9)
        nx, ny = -(y2 - y1) / ln, (x2 - x1) / ln
        ts = np.linspace(0.1, 0.9, 9)
        offs = np.arange(-16.0, 17.0, 2.0)
        px = x1 + ts[None, :] * (x2 - x1) + offs[:, None] * nx
        py = y1 + ts[None, :] * (y2 - y1) + offs[:, None] * ny
        xs = np.clip(np.round(px), 0, self.w - 1).astype(int)
        ys = np.clip(np.round(py), 0, self.h - 1).astype(int)
        prof = np.median(self.gray[ys, xs].astype(np.float64), axis=1)
        a, b = prof[0], prof[-1]
        ridge = max(min(a, b) - prof.min(), prof.max() - max(a, b))
        return "step edge" if abs(a - b) > ridge else "foreign line"

    # ------------------------------------------------------------------ output
    def result(self, reason: str) -> VisionResult:
        """The VisionResult of this run (segments = the measured lines, clipped to the view)."""
        segs: list[tuple[float, float, float, float]] = []
        bags: list[int] = []
        offsets: list[float] = []
        if self.y3 is not None:
            normals = family_normals(self.y3)
            x0, y0 = self.centre
            for k, fam in enumerate(self.lines):
                for ln in fam:
                    if not math.isfinite(ln.pos):
                        continue
                    s_px = -(ln.pos - (y0 if k == 0 else x0))
                    seg = clip_line(normals[k], s_px, self.w, self.h)
                    if seg is None:
                        continue
                    segs.append(seg)
                    bags.append(BAG_HORIZONTAL if k == 0 else BAG_VERTICAL)
                    offsets.append(s_px / self.ppm)
        seg_arr = np.array(segs, np.float64).reshape(-1, 4)
        ang = np.arctan2(seg_arr[:, 3] - seg_arr[:, 1], seg_arr[:, 2] - seg_arr[:, 0])
        dis = np.stack([np.cos(4.0 * ang), np.sin(4.0 * ang)], axis=1).reshape(-1, 2)
        med = None if self.y3 is None else (math.cos(4.0 * self.y3), math.sin(4.0 * self.y3))
        obs = None
        if reason == "ok" and self.y is not None:
            obs = Observation(
                y1=self.y[0],
                y2=self.y[1],
                y3=self.y[2],
                position_error=self.details["bound_px"] / self.ppm,
                heading_error=self.details["bound_rad"],
            )
        return VisionResult(
            observation=obs,
            accepted=obs is not None,
            reason="ok" if obs is not None else ("no lines" if reason == "ok" else reason),
            extractor="robust",
            segments=seg_arr,
            angles=ang,
            bags=np.array(bags, np.int8),
            disambiguation=dis,
            offsets=np.array(offsets, np.float64),
            median=med,
            timings=self.tm,
            details=self.details,
        )

    def stages(self, image: np.ndarray | None, res: VisionResult) -> dict[str, np.ndarray]:
        """Stage images (HxWx3 uint8 RGB): input, gray, edges, warped (the view turned by the
        heading: grout lines along rows and columns), lines (by bag), distances (each line's
        signed offset from the centre), lattice (the lines the observation predicts), foreign
        (unexplained edges and the straight ones among them), disambiguation ((cos 4a, sin 4a)
        of the lines and the heading)."""
        rgb = draw.to_rgb(self.gray if image is None else image)
        out: dict[str, np.ndarray] = {"input": rgb, "gray": draw.to_rgb(self.gray)}
        if self.edges is not None:
            out["edges"] = draw.to_rgb(self.edges)
        if self.warped is not None:
            wv = cv2.normalize(self.warped, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
            out["warped"] = draw.to_rgb(cv2.resize(wv, (self.w, self.h)))
        out["lines"] = draw.draw_segments(rgb.copy(), res.segments, res.bags)
        out["distances"] = draw.draw_offsets(
            draw.draw_segments(rgb.copy(), res.segments, res.bags, thickness=1), res.bags,
            res.offsets, self.y3, ppm=self.ppm,
        )
        if self.y is not None:
            out["lattice"] = draw.draw_lattice(
                rgb.copy(), self.y, ppm=self.ppm, tile_size=self.tile_size
            )
        if self.free_edges is not None:
            out["foreign"] = draw.draw_segments(draw.to_rgb(self.free_edges), self.foreign, None)
        out["disambiguation"] = draw.disambiguation_plot(
            res.disambiguation, res.bags, res.median, size=int(self.side)
        )
        return out


def _nanmedian(a: np.ndarray) -> np.ndarray:
    """Median over axis 0 of the finite entries of a small (k, m) array (NaN if none)."""
    srt = np.sort(np.where(np.isfinite(a), a, np.inf), axis=0)
    cnt = np.isfinite(a).sum(axis=0)
    lo = np.clip((cnt - 1) // 2, 0, a.shape[0] - 1)
    hi = np.clip(cnt // 2, 0, a.shape[0] - 1)
    cols = np.arange(a.shape[1])
    out = 0.5 * (srt[lo, cols] + srt[hi, cols])
    return np.where(cnt > 0, out, np.nan)


def _crossings(
    d: np.ndarray, j: np.ndarray, jp: np.ndarray, level: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where each row of ``d`` (darkness over sample offsets ``j``) first falls below ``level``
    on the left and on the right of its peak ``jp``, interpolated linearly; NaN when it does
    not (or runs into missing data first)."""
    lv = level[:, None]
    below = ~(d >= lv)  # NaN counts as below: such a crossing interpolates to NaN
    jr = j[None, :]
    pk = jp[:, None].astype(np.float64)
    big = float(j[-1]) + 1.0
    jl = np.where(below & (jr < pk), jr, -big).max(axis=1)
    jrt = np.where(below & (jr > pk), jr, big).min(axis=1)
    ok = (jl > -big) & (jrt < big)
    r = (j.size - 1) // 2
    il = np.clip(jl + r, 0, j.size - 2).astype(np.intp)
    ir = np.clip(jrt + r, 1, j.size - 1).astype(np.intp)
    rows = np.arange(d.shape[0])
    dl0, dl1 = d[rows, il], d[rows, il + 1]
    dr0, dr1 = d[rows, ir], d[rows, ir - 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        xl = jl + (lv[:, 0] - dl0) / (dl1 - dl0)
        xr = jrt - (lv[:, 0] - dr0) / (dr1 - dr0)
    return np.where(ok, xl, np.nan), np.where(ok, xr, np.nan)


def _plateaus(
    p: np.ndarray, j: np.ndarray, c: np.ndarray, half: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Mean level of each row of ``p`` (sample offsets ``j``) over the 4 samples just outside
    its window [c - half, c + half], on the left and on the right (NaN if none)."""
    cl = (c - half)[:, None]
    cr = (c + half)[:, None]
    jr = j[None, :]
    ok = ~np.isnan(p)
    ml = (jr < cl) & (jr >= cl - 4.0) & ok
    mr = (jr > cr) & (jr <= cr + 4.0) & ok
    pz = np.where(ok, p, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        left = (pz * ml).sum(axis=1) / ml.sum(axis=1)
        right = (pz * mr).sum(axis=1) / mr.sum(axis=1)
    return left, right


def _centroid(
    p: np.ndarray,
    j: np.ndarray,
    c: np.ndarray,
    half: np.ndarray,
    lev_l: np.ndarray,
    lev_r: np.ndarray,
    iterations: int = 3,
) -> np.ndarray:
    """Centroid of each row's darkness ``1 - p / level`` over [c - half, c + half] (sample
    offsets ``j``), the level stepping from ``lev_l`` to ``lev_r`` at the current centre; each
    sample weighs by its overlap with the window; re-centred ``iterations`` times. NaN where
    the window holds missing data or no darkness."""
    jr = j[None, :]
    ll = lev_l[:, None]
    lr = lev_r[:, None]
    h = half[:, None]
    cc = c.copy()
    for _ in range(iterations):
        ccol = cc[:, None]
        w = np.clip(np.minimum(jr + 0.5, ccol + h) - np.maximum(jr - 0.5, ccol - h), 0.0, 1.0)
        lev = ll + (lr - ll) * np.clip(jr - ccol + 0.5, 0.0, 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            q = (1.0 - p / lev) * w
            q = np.where(w > 0, q, 0.0)  # NaN inside the window stays NaN
            tot = q.sum(axis=1)
            cc = np.where(tot > 0, (q * jr).sum(axis=1) / tot, np.nan)
    return cc


def _draw_lattice_mask(
    img: np.ndarray, y: tuple[float, float, float], ppm: float, tile_size: float, thick: int
) -> None:
    """Blacken (in place) bands of ``thick`` px around every grout line ``y`` predicts."""
    h, w = img.shape
    n1, n2 = family_normals(y[2])
    lp = tile_size * ppm
    reach = 0.5 * math.hypot(w, h) + thick
    for n, yk in ((n1, y[0]), (n2, y[1])):
        j0 = math.floor((-reach + yk * ppm) / lp)
        j1 = math.ceil((reach + yk * ppm) / lp)
        for j in range(j0, j1 + 1):
            # clipped to the image grown by ``thick`` on every side: a line just outside the
            # view still masks the part of its band inside it
            e = clip_line(n, j * lp - yk * ppm, w + 2 * thick, h + 2 * thick)
            if e is None:
                continue
            a = (int(round(e[0])) - thick, int(round(e[1])) - thick)
            b = (int(round(e[2])) - thick, int(round(e[3])) - thick)
            cv2.line(img, a, b, 0, thick)
