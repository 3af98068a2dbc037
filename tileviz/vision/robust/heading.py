"""The first heading estimate (y3 modulo pi/2) from the gradient directions."""

from __future__ import annotations

import math

import cv2
import numpy as np

from tileviz.vision.robust.state import Fail, RobustRun

__all__ = ["first_heading"]


def first_heading(run: RobustRun, dx: np.ndarray, dy: np.ndarray) -> float:
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
    k = max(20, int(run.st.heading_share * n))
    thr = float(np.partition(m, n - k)[n - k])
    if thr <= 0.0:
        raise Fail("no lines")
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
    run.details["orientation_share"] = float(wn.sum() / max(float(wgt.sum()), 1e-9))
    # gradient directions are normal to the lines: 4 (a + pi/2) = 4 a (mod 2 pi)
    return math.atan2(float(np.dot(wn, np.sin(an))), float(np.dot(wn, np.cos(an)))) / 4.0
