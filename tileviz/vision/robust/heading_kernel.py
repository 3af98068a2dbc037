"""The first heading's votes, compiled with numba (:func:`heading_magnitudes`,
:func:`kth_largest`, :func:`heading_votes`), with the conventions of the profile kernels
(:mod:`~tileviz.vision.robust.kernel`: numpy's error model, cached next to this module).
``tests/test_vision_speed_paths.py`` checks them bit for bit against a numpy reference
(``tests/numpy_kernels.py``) on random gradients.
"""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust.kernel import compiled

__all__ = ["ATAN", "heading_magnitudes", "heading_votes", "kth_largest"]

ATAN = (-0.0464964749, 0.15931422, -0.327622764)
"""Coefficients of :func:`_angle`'s polynomial (z = a^2): atan(a) ~ a + a z (c2 + z (c1 + z c0))."""


@compiled
def _angle(y: float, x: float) -> float:
    """atan2(y, x) within 3e-4 rad (not both 0): an odd polynomial of min / max on the octant
    (:func:`~tileviz.vision.robust.heading.angles` is the same computation in numpy)."""
    ax = abs(x)
    ay = abs(y)
    a = min(ax, ay) / max(ax, ay)
    z = a * a
    r = ((ATAN[0] * z + ATAN[1]) * z + ATAN[2]) * z * a + a
    # selections rather than branches (the signs of a texture's gradients are a coin toss)
    r = 0.5 * math.pi - r if ay > ax else r
    r = math.pi - r if x < 0.0 else r
    return -r if y < 0.0 else r


@compiled
def heading_magnitudes(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """gx^2 + gy^2 (int64) of every other row and column of the Scharr gradients ``dx``,
    ``dy`` (int16), row by row."""
    h, w = dx.shape
    q = np.empty(((h + 1) // 2) * ((w + 1) // 2), np.int64)
    i = 0
    for y in range(0, h, 2):
        for x in range(0, w, 2):
            gx = np.int64(dx[y, x])
            gy = np.int64(dy[y, x])
            q[i] = gx * gx + gy * gy
            i += 1
    return q


@compiled
def kth_largest(q: np.ndarray, k: int) -> int:
    """The ``k``-th largest value of ``q`` (int64, >= 0; 1 <= ``k`` <= its size), exactly
    ``np.partition(q, q.size - k)[q.size - k]``: a radix selection, 12 bits a pass from the
    top (a histogram of the values that share the bits found so far picks the next 12)."""
    mx = np.int64(0)
    for v in q:
        if v > mx:
            mx = v
    shift = 0
    while (mx >> shift) >= 4096:
        shift += 1
    hist = np.zeros(4096, np.int64)
    for v in q:
        hist[v >> shift] += 1
    prefix = np.int64(0)
    need = k
    while True:
        b = 4095
        while hist[b] < need:
            need -= hist[b]
            b -= 1
        prefix += b  # the value's bits above ``shift``
        if shift == 0:
            return int(prefix)
        low = max(shift - 12, 0)
        hist[:] = 0
        base = prefix << (shift - low)
        for v in q:
            if (v >> shift) == prefix:
                hist[(v >> low) - base] += 1
        prefix = base
        shift = low


@compiled
def heading_votes(dx: np.ndarray, dy: np.ndarray, q: np.ndarray, thr: int, nb: int,
                  near_peak: float) -> tuple[float, float]:
    """The votes of :func:`~tileviz.vision.robust.heading.first_heading` from the Scharr
    gradients ``dx``, ``dy`` (int16) of every other row and column, given their squared
    magnitudes ``q`` (:func:`heading_magnitudes`) and the threshold ``thr`` (> 0) of the
    voters: the heading (rad, modulo pi / 2) and the share of the votes' weight near the
    histogram's peak.

    The squared magnitude q = gx^2 + gy^2 and the doubled-angle vector (c2, s2) = (gx^2 - gy^2, 2 gx
    gy) are exact integers, so is 4 phi's vector (c2^2 - s2^2, 2 c2 s2) (length q^2): the pixels
    with q >= ``thr`` vote with weight sqrt(q) in ``nb`` bins of 4 phi = atan2 of that vector
    (:func:`_angle`); the peak of the 3-bin smoothed histogram; the votes within ``near_peak`` (rad,
    of 4 phi) of it are averaged as vectors (weight x unit vector, each its integer vector / q^1.5).
    Sums run in pixel order (row by row), one term after the other."""
    h, w = dx.shape
    n = 0
    for v in q:
        if v >= thr:
            n += 1
    # the voters first (pixel order), then their votes in a loop of their own: the pixel
    # loop's unpredictable branch no longer stalls the votes' divisions (the same operations
    # in the same order as before)
    gxs = np.empty(n, np.int64)
    gys = np.empty(n, np.int64)
    qs = np.empty(n, np.int64)
    fx = dx.ravel()
    fy = dy.ravel()
    m = 0
    i = 0
    for y in range(0, h, 2):
        row = y * w
        for x in range(0, w, 2):
            if q[i] >= thr:
                gxs[m] = fx[row + x]
                gys[m] = fy[row + x]
                qs[m] = q[i]
                m += 1
            i += 1
    theta = np.empty(n)
    wgt = np.empty(n)
    vc = np.empty(n)
    vs = np.empty(n)
    for j in range(n):
        gx = gxs[j]
        gy = gys[j]
        c2 = gx * gx - gy * gy
        s2 = 2 * gx * gy
        cc = float(c2 * c2 - s2 * s2)
        ss = float(2 * c2 * s2)
        qf = float(qs[j])
        g = math.sqrt(qf)
        r = qf * g
        theta[j] = _angle(ss, cc)
        wgt[j] = g
        vc[j] = cc / r
        vs[j] = ss / r
    hist = np.zeros(nb)
    scale = nb / (2.0 * math.pi)
    for j in range(m):
        b = int((theta[j] + math.pi) * scale) % nb
        hist[b] += wgt[j]
    best = -1.0
    at = 0
    for b in range(nb):
        v = (hist[b] + hist[(b - 1) % nb]) + hist[(b + 1) % nb]
        if v > best:
            best = v
            at = b
    peak = (at + 0.5) * (2.0 * math.pi / nb) - math.pi
    sw = 0.0
    swn = 0.0
    sc = 0.0
    sn = 0.0
    for j in range(m):
        sw += wgt[j]
        d = theta[j] - peak
        d = d - 2.0 * math.pi if d > math.pi else (d + 2.0 * math.pi if d < -math.pi else d)
        # adding +0.0 leaves a sum that starts at +0.0 as it was: no branch on the vote
        near = abs(d) < near_peak
        swn += wgt[j] if near else 0.0
        sc += vc[j] if near else 0.0
        sn += vs[j] if near else 0.0
    return math.atan2(sn, sc) / 4.0, swn / max(sw, 1e-9)
