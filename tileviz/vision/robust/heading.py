"""The first heading estimate (y3 modulo pi/2) from the gradient directions."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.robust import checks, heading_kernel
from tileviz.vision.robust.checks import Context, Record
from tileviz.vision.robust.settings import HeadingSettings
from tileviz.vision.robust.state import View

__all__ = ["first_heading", "gradient_votes",
           "lattice_headings", "lattice_power", "sharpened_headings", "smoothed_headings",
           "voters"]


def first_heading(ctx: Context, dx: np.ndarray, dy: np.ndarray, rec: Record,
                  details: dict[str, float]) -> float:
    """First y3 estimate (rad) from the gradient directions of the strongest gradients.

    Every pixel votes (not only Canny's edge pixels: on a textured surface those are mostly
    the texture's): 4 phi of its gradient, weighted by the gradient magnitude, over the
    pixels in the top ``heading.share`` of magnitudes; the peak of the smoothed histogram,
    then the weighted circular mean of the votes near the peak (report eq. 4.4 per pixel).
    Grout lines, tile-to-tile shade steps and a surface laid along the tiles all vote for
    the lattice direction (mod pi/2); isotropic texture adds a flat floor. Every other row
    and column votes: a quarter of the votes is plenty for a first estimate (the fit over
    the lattice refines it). The votes are compiled
    (:func:`~tileviz.vision.robust.heading_kernel.heading_votes`). Refuses (``no lines``,
    check ``heading.gradients``) when no gradient is non-zero; records the share of the votes
    near the peak (``orientation_share``) in ``details``."""
    st = ctx.st.heading
    q = heading_kernel.heading_magnitudes(dx, dy)
    thr = voters(q, st.share, st.min_voters)
    rec.require(checks.HEADING_GRADIENTS, ctx, thr)
    y0, share = heading_kernel.heading_votes(dx, dy, q, thr, st.bins, st.near)
    details["orientation_share"] = share
    return y0


def gradient_votes(dx: np.ndarray, dy: np.ndarray, st: HeadingSettings
                   ) -> tuple[float, float] | None:
    """The votes of :func:`first_heading` on the Scharr gradients ``dx``, ``dy`` (int16): the
    heading (rad, modulo pi/2) and the share of the votes' weight near the peak; None when no
    gradient is non-zero."""
    q = heading_kernel.heading_magnitudes(dx, dy)
    thr = voters(q, st.share, st.min_voters)
    if thr <= 0:
        return None
    return heading_kernel.heading_votes(dx, dy, q, thr, st.bins, st.near)


def smoothed_headings(view: View) -> list[tuple[float, float]]:
    """The votes of :func:`first_heading` again on the view smoothed by a Gaussian of each
    ``heading.smoothing`` std (px): (std, heading (rad, modulo pi/2)) where a gradient votes.
    Strong camera noise (and the 8 x 8 blocks of a JPEG) outvotes a thin grout line pixel by
    pixel; smoothing weakens the noise's gradients far more than the grout's edges, which span
    several pixels."""
    out = []
    for sigma in view.st.heading.smoothing:
        g = cv2.GaussianBlur(view.gray, (0, 0), sigma)
        dx = cv2.Scharr(g, cv2.CV_16S, 1, 0)
        dy = cv2.Scharr(g, cv2.CV_16S, 0, 1)
        found = gradient_votes(dx, dy, view.st.heading)
        if found is not None:
            out.append((sigma, found[0]))
    return out


def voters(q: np.ndarray, share: float, least: int) -> int:
    """The smallest squared magnitude among the top ``share`` (at least ``least``) of ``q``
    (int64): every gradient at least as strong votes
    (:func:`~tileviz.vision.robust.heading_kernel.kth_largest`, the same value as numpy's
    partition)."""
    n = q.size
    k = min(max(least, int(share * n)), n)
    thr = int(heading_kernel.kth_largest(q, k))
    if thr > 0:
        return thr
    # a noise-free view (a clean render, a drawing) is flat but for its edges: fewer than
    # ``share`` of the gradients are non-zero, and every non-zero one votes
    return 1 if int(q.max()) > 0 else 0


def lattice_power(img: np.ndarray, period: float, angles: np.ndarray, *, detrend: bool = True,
                  harmonics: int = 4) -> np.ndarray:
    """How strongly ``img`` (float32, its mean removed) repeats with ``period`` (px) along the two
    directions of each of ``angles`` (rad): the row and the column means of the image turned by
    the angle, over the central square that every turn keeps inside the view, projected on the
    first ``harmonics`` harmonics of the period (summed power of both); with ``detrend``, blind
    to a quadratic trend of the light across the square."""
    return _Turns(img, period, harmonics).power(angles, detrend)


class _Turns:
    """The row and column means of ``img`` turned by each angle asked for (see
    :func:`lattice_power`), kept per angle: both variants of the search (blind to a trend of
    the light and not) read the same turns."""

    def __init__(self, img: np.ndarray, period: float, harmonics: int) -> None:
        self.img = img
        h, w = img.shape
        side = int(min(w, h) / math.sqrt(2.0)) - 2
        self.side = side
        self.cx, self.cy = (w - 1) / 2.0, (h - 1) / 2.0
        self.x0 = (side - 1) / 2.0
        n = np.arange(side) - self.x0
        ks = np.arange(1, harmonics + 1)[:, None] * (2.0 * math.pi / period) * n[None, :]
        basis = np.concatenate([np.cos(ks), np.sin(ks)])  # (2 harmonics, side)
        # blind to a slope and a bow of the light across the square (a lighting gradient,
        # vignetting): the harmonics' part along 1, n, n^2 is removed
        q, _ = np.linalg.qr(np.stack([np.ones(side), n, n * n], axis=1))
        self.basis = {False: basis.astype(np.float32),
                      True: (basis - (basis @ q) @ q.T).astype(np.float32)}
        self.means: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def turn(self, a: float) -> tuple[np.ndarray, np.ndarray]:
        """Row and column means (float32) of the central square turned by ``a`` (rad)."""
        got = self.means.get(a)
        if got is None:
            ca, sa = math.cos(a), math.sin(a)
            cx, cy, x0 = self.cx, self.cy, self.x0
            m = np.array([[ca, -sa, cx - x0 * ca + x0 * sa], [sa, ca, cy - x0 * sa - x0 * ca]])
            turned = cv2.warpAffine(self.img, m, (self.side, self.side),
                                    flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
            got = (turned.mean(axis=1), turned.mean(axis=0))
            self.means[a] = got
        return got

    def power(self, angles: np.ndarray, detrend: bool) -> np.ndarray:
        basis = self.basis[detrend]
        out = np.empty(angles.size)
        for i, a in enumerate(angles.tolist()):
            rows, cols = self.turn(a)
            pr = basis @ rows
            pc = basis @ cols
            out[i] = float(pr @ pr) + float(pc @ pc)
        return out


def centred_gray(view: View) -> np.ndarray:
    """The view's gray image (float32) less its mean: what the periodicity searches turn."""
    img = view.gray.astype(np.float32)
    img -= float(img.mean())
    return img


def lattice_headings(view: View) -> list[float]:
    """Headings (rad, modulo pi/2) at which the view repeats most strongly with the tile
    period in both directions (:func:`lattice_power`), blind to a trend of the light and not:
    every ``heading.lattice_coarse_step`` on the image at ``heading.lattice_scale``, then every
    ``lattice_fine_step`` within ``lattice_fine_span`` of the best at full size (the
    trend-blind heading first). Used when the
    gradient directions of :func:`first_heading` lead to no lattice (texture can outvote the
    grout, blur and uneven light can hide it)."""
    st = view.st.heading
    img = centred_gray(view)
    scale = st.lattice_scale
    small = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    coarse = np.arange(-0.25 * math.pi, 0.25 * math.pi, st.lattice_coarse_step)
    turns_small = _Turns(small, scale * view.lp, st.lattice_harmonics)
    turns = _Turns(img, view.lp, st.lattice_harmonics)
    out = []
    for detrend in (True, False):
        pw = turns_small.power(coarse, detrend)
        best = float(coarse[int(np.argmax(pw))])
        span, step = st.lattice_fine_span, st.lattice_fine_step
        fine = best + np.arange(-span, span + 0.5 * step, step)
        pw = turns.power(fine, detrend)
        out.append(float(fine[int(np.argmax(pw))]))
    return out


def sharpened_headings(view: View, around: list[float]) -> list[float]:
    """The headings (rad, modulo pi/2) at which the view's grout lines are sharpest near those
    of ``around`` (the headings read so far): near each, the heading whose row and column
    means repeat most strongly with the tile period on its harmonics down to a wavelength of
    ``heading.sharpen_wavelength`` px (:func:`lattice_power`, blind to a trend of the light),
    searched every ``heading.sharpen_coarse_step`` within ``heading.sharpen_span`` of it (on
    one grid for all of them, each turn computed once), then every ``sharpen_fine_step``
    within a coarse step of the best; the ``heading.sharpen_readings`` sharpest, each once
    (``heading.same_heading``). A line a few px wide smears across its neighbouring samples a
    degree off its heading; the few harmonics that find the lattice's heading do not see that
    smear, these do (faint thin grout under camera noise, whose gradients point anywhere)."""
    st = view.st.heading
    img = centred_gray(view)
    harmonics = max(st.lattice_harmonics, int(view.lp / st.sharpen_wavelength))
    turns = _Turns(img, view.lp, harmonics)
    coarse, fine = st.sharpen_coarse_step, st.sharpen_fine_step
    reach = int(round(st.sharpen_span / coarse))
    found: list[tuple[float, float]] = []
    for y in around:
        k0 = int(round(math.remainder(y, 0.5 * math.pi) / coarse))
        grid = (np.arange(k0 - reach, k0 + reach + 1) * coarse).round(9)
        best = float(grid[int(np.argmax(turns.power(grid, True)))])
        near = (best + np.arange(-coarse, coarse + 0.5 * fine, fine)).round(9)
        pw = turns.power(near, True)
        i = int(np.argmax(pw))
        if all(abs(math.remainder(float(near[i]) - b, 0.5 * math.pi)) >= st.same_heading
               for _, b in found):
            found.append((float(pw[i]), float(near[i])))
    found.sort(key=lambda f: -f[0])
    return [b for _, b in found[: st.sharpen_readings]]
