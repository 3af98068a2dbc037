"""The common fit of the lines' parts, compiled with numba (:func:`fit_arrays`), with the
conventions of :mod:`~tileviz.vision.robust.kernel` (numpy's order of operations and of its
sums, its NaN propagation and error model). A view has a dozen lines of four parts: one
compiled pass instead of some forty numpy calls on arrays that small.
``tests/test_vision_speed_paths.py`` checks it bit for bit against a numpy reference
(``tests/numpy_kernels.py``) on random fits.
"""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust.kernel import _max, _rowsum, compiled

__all__ = ["fit_arrays"]


@compiled
def fit_arrays(
    wp: np.ndarray, tp: np.ndarray, pp: np.ndarray, sig: np.ndarray, spr: np.ndarray, n0: int,
    part_sigmas: float, prior: float, prior_dof: float, big_share: float, explained: float
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, float,
           float]:
    """The fit of :func:`~tileviz.vision.robust.fit.fit_tilt` on the (lines, PARTS) arrays of
    the parts' lengths ``wp`` (0: not measured, weighing nothing), tangent coordinates ``tp``,
    positions ``pp``, standard errors ``sig`` and spreads ``spr`` (the first ``n0`` lines of
    family 1): eps (rad); each line's pos and var; its influence row ``g`` (d pos / d every
    measured part); d eps / d every measured part; every measured part's own bound
    (``part_sigmas`` sigma + spread); the straightness (px: the largest residual of the parts
    ``big_share`` of their line's longest or more), the heading's standard error and the tilt gap
    (the two families' own tilts apart, in standard errors). ``prior`` is ``prior_dof`` x the
    prior sigma squared. The lines' variances and the heading's standard error come from the
    residuals beyond ``explained`` px (what the floor's lattice tolerance explains of a part
    off its line: it is in every part's bound already); the tilt gap from the whole residuals.

    The fit is linear in the part positions: d eps / d p_i = sign w_i (t_i - tb) / sum, d pos
    / d p_i = w_i / sum(w) [its own line] - sign tb d eps / d p_i; with every part within its
    own bound b_i, eps and pos are within sum |d / d p_i| b_i. The scatter of the parts about
    the fit, per unit of part length, carries a weak prior so that a fit with few degrees of
    freedom is not trusted blindly."""
    m, parts = wp.shape
    w = np.empty((m, parts))
    t = np.empty((m, parts))
    p = np.empty((m, parts))
    ok = np.empty((m, parts), np.bool_)
    nok = 0
    for i in range(m):
        for j in range(parts):
            o = wp[i, j] > 0
            ok[i, j] = o
            w[i, j] = wp[i, j] if o else 0.0
            t[i, j] = tp[i, j] if o else 0.0
            p[i, j] = pp[i, j] if o else 0.0
            nok += 1 if o else 0
    sign = np.empty(m)
    sw = np.empty(m)
    tb = np.empty(m)
    pb = np.empty(m)
    num_l = np.empty(m)
    den_l = np.empty(m)
    dt = np.empty((m, parts))
    buf = np.empty(parts)
    for i in range(m):
        sign[i] = 1.0 if i < n0 else -1.0
        sw[i] = _rowsum(w[i])
        for j in range(parts):
            buf[j] = w[i, j] * t[i, j]
        tb[i] = _rowsum(buf) / sw[i]
        for j in range(parts):
            buf[j] = w[i, j] * p[i, j]
        pb[i] = _rowsum(buf) / sw[i]
        for j in range(parts):
            dt[i, j] = t[i, j] - tb[i] if ok[i, j] else 0.0
        for j in range(parts):
            buf[j] = w[i, j] * dt[i, j] * (p[i, j] - pb[i])
        num_l[i] = sign[i] * _rowsum(buf)
        for j in range(parts):
            buf[j] = w[i, j] * dt[i, j] * dt[i, j]
        den_l[i] = _rowsum(buf)
    num0 = _rowsum(num_l[:n0])
    num1 = _rowsum(num_l[n0:])
    den0 = _rowsum(den_l[:n0])
    den1 = _rowsum(den_l[n0:])
    dall = den0 + den1
    eps = (num0 + num1) / dall if dall > 1e-9 else 0.0
    pos = np.empty(m)
    flat = np.empty(m * parts)
    flat_u = np.empty(m * parts)
    nobs = 0
    straight = -math.inf
    anybig = False
    dmax = 1e-9 if 1e-9 > dall else dall  # Python's max(dall, 1e-9)
    d_eps = np.empty(nok)
    part_bound = np.empty(nok)
    own = np.empty(nok, np.intp)
    k = 0
    for i in range(m):
        se = sign[i] * eps
        pos[i] = pb[i] - se * tb[i]
        wmax = wp[i, 0]
        for j in range(1, parts):
            wmax = _max(wmax, wp[i, j])
        for j in range(parts):
            r = p[i, j] - (pos[i] + se * t[i, j]) if ok[i, j] else 0.0
            flat[i * parts + j] = w[i, j] * r * r
            ru = _max(abs(r) - explained, 0.0)
            flat_u[i * parts + j] = w[i, j] * ru * ru
            if ok[i, j]:
                nobs += 1
                if wp[i, j] >= big_share * wmax:
                    straight = _max(straight, abs(r))
                    anybig = True
                d_eps[k] = sign[i] * w[i, j] * dt[i, j] / dmax
                part_bound[k] = part_sigmas * sig[i, j] + spr[i, j]
                own[k] = i
                k += 1
    ss = _rowsum(flat)
    ss_u = _rowsum(flat_u)
    g = np.empty((m, nok))
    for i in range(m):
        a = -(sign[i] * tb[i])
        for c in range(nok):
            g[i, c] = a * d_eps[c]
    k = 0
    for i in range(m):
        for j in range(parts):
            if ok[i, j]:
                g[i, k] += w[i, j] / sw[i]
                k += 1
    dof = nobs - (m + 1)
    dof = dof if dof > 0 else 0
    sigma2 = (ss + prior) / (dof + prior_dof)
    sigma2_u = (ss_u + prior) / (dof + prior_dof)
    var_eps = sigma2_u / dall if dall > 1e-9 else math.inf
    var = np.empty(m)
    for i in range(m):
        var[i] = sigma2_u / sw[i] + tb[i] * tb[i] * var_eps
    gap = 0.0
    if den0 > 1e-9 and den1 > 1e-9:
        gap = abs(num0 / den0 - num1 / den1)
        gap = gap / math.sqrt(sigma2 / den0 + sigma2 / den1)
    return (eps, pos, var, g, d_eps, part_bound, straight if anybig else 0.0,
            math.sqrt(var_eps), gap)
