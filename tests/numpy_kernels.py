"""numpy references of the robust extractor's compiled heading, fit, lattice and foreign-edge
kernels (:mod:`tileviz.vision.robust.heading_kernel`, :mod:`~tileviz.vision.robust.fit_kernel`,
:mod:`~tileviz.vision.robust.lattice_kernel`, :mod:`~tileviz.vision.robust.foreign_kernel`): the
same computations written with numpy, operation for operation, which the tests compare with the
kernels bit for bit (``tests/test_vision_speed_paths.py``). The package itself runs the kernels
only."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tileviz.vision.robust import heading_kernel
from tileviz.vision.robust.heading import voters


def angles(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """atan2(y, x) within 3e-4 rad (never both 0), as
    :func:`~tileviz.vision.robust.heading_kernel._angle` computes it: an odd polynomial of
    min / max on the octant, then the octant."""
    ax = np.abs(x)
    ay = np.abs(y)
    a = np.minimum(ax, ay) / np.maximum(ax, ay)
    z = a * a
    c0, c1, c2 = heading_kernel.ATAN
    r = ((c0 * z + c1) * z + c2) * z * a + a
    r = np.where(ay > ax, 0.5 * math.pi - r, r)
    r = np.where(x < 0.0, math.pi - r, r)
    return np.where(y < 0.0, -r, r)


def heading_votes_numpy(dx: np.ndarray, dy: np.ndarray, share: float, nb: int,
                        near_peak: float, least: int) -> tuple[bool, float, float]:
    """The votes of :func:`first_heading` from the Scharr gradients ``dx``, ``dy`` (int16) of
    every other row and column: whether any gradient is non-zero; the heading (rad, modulo
    pi / 2); the share of the votes' weight near the histogram's peak.

    The squared magnitude q = gx^2 + gy^2 and the doubled-angle vector (c2, s2) = (gx^2 -
    gy^2, 2 gx gy) are exact integers, so is 4 phi's vector (c2^2 - s2^2, 2 c2 s2) (length
    q^2): the pixels in the top ``share`` of q vote with weight sqrt(q) in ``nb`` bins of
    4 phi = atan2 of that vector; the peak of the 3-bin smoothed histogram; the votes within
    ``near_peak`` of it are averaged as vectors (weight x
    unit vector, each its integer vector / q^1.5). Sums run in pixel order (row by row), one
    term after the other."""
    gx = dx[::2, ::2].astype(np.int64).ravel()
    gy = dy[::2, ::2].astype(np.int64).ravel()
    q = gx * gx + gy * gy
    thr = voters(q, share, least)
    if thr <= 0:
        return False, 0.0, 0.0
    sel = np.flatnonzero(q >= thr)
    gx, gy, qs = gx[sel], gy[sel], q[sel]
    c2 = gx * gx - gy * gy
    s2 = 2 * gx * gy
    cc = (c2 * c2 - s2 * s2).astype(np.float64)
    ss = (2 * c2 * s2).astype(np.float64)
    qf = qs.astype(np.float64)
    g = np.sqrt(qf)
    r = qf * g
    theta = angles(ss, cc)
    vc = cc / r
    vs = ss / r
    b = ((theta + math.pi) * (nb / (2.0 * math.pi))).astype(np.intp) % nb
    hist = np.bincount(b, weights=g, minlength=nb)
    smooth = (hist + np.roll(hist, 1)) + np.roll(hist, -1)
    peak = (int(np.argmax(smooth)) + 0.5) * (2.0 * math.pi / nb) - math.pi
    d = theta - peak
    d = np.where(d > math.pi, d - 2.0 * math.pi, np.where(d < -math.pi, d + 2.0 * math.pi, d))
    near = np.abs(d) < near_peak

    def total(a: np.ndarray) -> float:
        # one term after the other, from 0.0 (as the compiled loop adds)
        return float(np.cumsum(np.concatenate(([0.0], a)))[-1])

    sw = total(g)
    return (True, math.atan2(total(vs[near]), total(vc[near])) / 4.0,
            total(g[near]) / max(sw, 1e-9))



def fit_arrays_numpy(
    wp: np.ndarray, tp: np.ndarray, pp: np.ndarray, sig: np.ndarray, spr: np.ndarray, n0: int,
    part_sigmas: float, prior: float, prior_dof: float, big_share: float, explained: float
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, float,
           float]:
    """The fit of :func:`fit_tilt` on the (lines, PARTS) arrays of the parts' lengths ``wp``
    (0: not measured, weighing nothing), tangent coordinates ``tp``, positions ``pp``,
    standard errors ``sig`` and spreads ``spr`` (the first ``n0`` lines of family 1): eps
    (rad); each line's pos and var; its influence row ``g`` (d pos / d every measured part);
    d eps / d every measured part; every measured part's own bound (``part_sigmas`` sigma +
    spread); the straightness (px), the heading's standard error and the tilt gap. ``prior``
    is ``prior_dof`` x the prior sigma squared; the variances from the residuals beyond
    ``explained`` px, the gap from the whole residuals. :func:`~tileviz.vision.robust.fit_kernel.
    fit_arrays` is the same computation compiled (bit-identical)."""
    m = wp.shape[0]
    ok = wp > 0
    w = np.where(ok, wp, 0.0)
    t = np.where(ok, tp, 0.0)
    p = np.where(ok, pp, 0.0)
    sign = np.ones(m)
    sign[n0:] = -1.0
    sw = w.sum(axis=1)
    tb = (w * t).sum(axis=1) / sw
    pb = (w * p).sum(axis=1) / sw
    dt = np.where(ok, t - tb[:, None], 0.0)
    num_l = sign * (w * dt * (p - pb[:, None])).sum(axis=1)
    den_l = (w * dt * dt).sum(axis=1)
    first = np.arange(m) < n0
    num = (float(num_l[first].sum()), float(num_l[~first].sum()))
    den = (float(den_l[first].sum()), float(den_l[~first].sum()))
    dall = den[0] + den[1]
    eps = (num[0] + num[1]) / dall if dall > 1e-9 else 0.0
    pos = pb - sign * eps * tb
    res = np.where(ok, p - (pos[:, None] + sign[:, None] * eps * t), 0.0)
    ss = float((w * res * res).sum())
    res_u = np.maximum(np.abs(res) - explained, 0.0)
    ss_u = float((w * res_u * res_u).sum())
    nobs = int(ok.sum())
    big = ok & (wp >= big_share * wp.max(axis=1)[:, None])
    straight = float(np.abs(res[big]).max()) if big.any() else 0.0
    # The fit is linear in the part positions: d eps / d p_i = sign w_i (t_i - tb) / dall,
    # d pos / d p_i = w_i / sum(w) [its own line] - sign tb d eps / d p_i. With every part
    # within its own bound b_i, eps and pos are within sum |d / d p_i| b_i. (Parts in the
    # order of the lines, then of their parts; only the measured ones.)
    d_eps = (sign[:, None] * w * dt)[ok] / max(dall, 1e-9)
    part_bound = (part_sigmas * sig + spr)[ok]
    g = -(sign * tb)[:, None] * d_eps[None, :]
    own = np.repeat(np.arange(m), ok.sum(axis=1))
    g[own, np.arange(own.size)] += (w / sw[:, None])[ok]
    # Scatter of the parts about the fit, per unit of part length (px^2 px), with a weak
    # prior so that a fit with few degrees of freedom is not trusted blindly.
    dof = max(nobs - (m + 1), 0)
    sigma2 = (ss + prior) / (dof + prior_dof)
    sigma2_u = (ss_u + prior) / (dof + prior_dof)
    var_eps = sigma2_u / dall if dall > 1e-9 else math.inf
    var = sigma2_u / sw + tb * tb * var_eps
    # the two families must be perpendicular: their own tilts agree within their errors
    gap = 0.0
    if den[0] > 1e-9 and den[1] > 1e-9:
        gap = abs(num[0] / den[0] - num[1] / den[1])
        gap = gap / math.sqrt(sigma2 / den[0] + sigma2 / den[1])
    return eps, pos, var, g, d_eps, part_bound, straight, math.sqrt(var_eps), gap



def missing_line_numpy(n0: float, n1: float, hyp: float, ref: float, lp: float, reach: float,
                       margin: int, width: int, height: int, min_chord: float,
                       found: np.ndarray, peak: np.ndarray, fam: np.ndarray, k: int, pad: int,
                       centre: float, near: float, found_share: float) -> bool:
    """Whether a line of family ``k`` that the lattice predicts at the signed offsets ``ref + j
    lp`` (px; ``(n0, n1)`` the family's unit normal, ``hyp`` its ``math.hypot``) within
    ``reach`` of the centre is missing: visible along at least ``min_chord`` of the longest
    chord at the offset and ``margin`` px each side of it, neither a line ``found`` (offsets,
    px) within a quarter of the period nor a dip of the family (``peak``, ``fam``: the
    projection's dips, padded by ``pad``; ``centre`` the warp centre's profile coordinate)
    within ``near`` px. :func:`~tileviz.vision.robust.lattice_kernel.missing_line` is the same
    computation compiled (bit-identical)."""
    j0 = math.floor((-reach - ref) / lp)
    j1 = math.ceil((reach - ref) / lp)
    s = ref + np.arange(j0, j1 + 1) * lp
    # the longest chord of a direction through a rectangle passes through its centre
    ch = chords((n0, n1), np.concatenate(([0.0], s - margin, s, s + margin)), width, height,
                hyp)
    need = min_chord * ch[0]
    visible = (ch[1:].reshape(3, -1) >= need).all(axis=0)
    dips = -(peak[fam == k] - pad - centre).astype(np.float64)
    for sj in s[visible].tolist():
        if found.size == 0 or float(np.min(np.abs(found - sj))) > found_share * lp:
            if dips.size and float(np.min(np.abs(dips - sj))) <= near:
                continue
            return True
    return False


def chords(n: tuple[float, float], s: np.ndarray, width: int, height: int,
           hyp: float | None = None) -> np.ndarray:
    """The length (px) inside the image of each line ``n . (p - centre) = s`` (n a unit normal
    in pixel coordinates, ``s`` an array of offsets, px); 0 where it misses the image. The
    same clipping as :func:`clip_line`, for many parallel lines at once. ``hyp``: the
    normal's ``math.hypot`` when the caller has it."""
    cxp, cyp = (width - 1) / 2.0, (height - 1) / 2.0
    tx, ty = -n[1], n[0]
    lo = np.full(s.shape, -np.inf)
    hi = np.full(s.shape, np.inf)
    for p0, d, size in ((cxp + s * n[0], tx, width), (cyp + s * n[1], ty, height)):
        if abs(d) < 1e-12:
            hi = np.where((p0 >= -0.5) & (p0 <= size - 0.5), hi, -np.inf)
            continue
        a = (-0.5 - p0) / d
        b = (size - 0.5 - p0) / d
        lo = np.maximum(lo, np.minimum(a, b))
        hi = np.minimum(hi, np.maximum(a, b))
    span = hi - lo
    return np.where(span > 0, span, 0.0) * (math.hypot(tx, ty) if hyp is None else hyp)



def edge_shares_numpy(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, seg: np.ndarray,
                      cos_tol: float) -> np.ndarray:
    """:func:`edge_share` on the gradients ``dx``, ``dy`` and edge pixels ``edges`` (HxW),
    with the tolerance's cosine ``cos_tol``: the share of each edge's points (1 px apart)
    that :func:`oriented_points` sees with its normal; 0 for an edge under 1 px."""
    out = np.zeros(len(seg))
    for i, (x1, y1, x2, y2) in enumerate(seg[:, :4].tolist()):
        ln = math.hypot(x2 - x1, y2 - y1)
        if ln < 1.0:
            continue
        t = np.arange(0.0, ln + 0.5, 1.0) / ln
        xs = np.rint(x1 + t * (x2 - x1)).astype(np.intp)
        ys = np.rint(y1 + t * (y2 - y1)).astype(np.intp)
        hit = oriented_points(dx, dy, edges, xs, ys, -(y2 - y1) / ln, (x2 - x1) / ln, cos_tol)
        out[i] = float(hit.mean())
    return out


def oriented_points(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, xs: np.ndarray,
                    ys: np.ndarray, nx: float, ny: float, cos_tol: float) -> np.ndarray:
    """:func:`oriented_hits` on the gradients ``dx``, ``dy`` and edge pixels ``edges`` (HxW),
    with the tolerance's cosine ``cos_tol``."""
    h, w = edges.shape
    # the 3 x 3 neighbours of every pixel at once (rows: the 9 offsets), as flat indices
    xx = np.clip(xs[None, :] + _NX[:, None], 0, w - 1)
    yy = np.clip(ys[None, :] + _NY[:, None], 0, h - 1)
    flat = yy * w + xx
    gx = dx.ravel()[flat].astype(np.float64)
    gy = dy.ravel()[flat].astype(np.float64)
    g = np.hypot(gx, gy)
    along = np.abs(gx * nx + gy * ny) >= cos_tol * g
    return ((edges.ravel()[flat] > 0) & along & (g > 0)).any(axis=0)


_NX = np.array([-1, -1, -1, 0, 0, 0, 1, 1, 1], np.intp)


_NY = np.array([-1, 0, 1, -1, 0, 1, -1, 0, 1], np.intp)


def end_steps_numpy(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, px: float, py: float,
                    ux: float, uy: float, band: float, n00: float, n01: float, n10: float,
                    n11: float, sh0: float, sh1: float, lp: float, cos_tol: float,
                    inside_steps: int, far_steps: int, seen_share: float
                    ) -> tuple[int, np.ndarray, np.ndarray, int, int, int, bool, int, float]:
    """The steps of :func:`ends` from a straight edge's end (px, py) along the unit vector
    (ux, uy), 1 px apart, to the border of the view (``edges``: the edge pixels, HxW; ``dx``,
    ``dy``: the gradients), and where they meet the grout bands (half-width ``band``, px; the
    families' unit normals (n00, n01), (n10, n11) and offsets sh0, sh1, px, so that a line
    lies where ``n . (p - centre) + sh`` is a multiple of the period ``lp``, px).

    Returns (done, xs, ys, i0, i1, i2, far, k, dmin): ``done`` (1) when the border of the view
    comes before any band, or at least 4 steps lead to the first band and at most half of them
    see the edge (:func:`oriented_hits` with tolerance cosine ``cos_tol``); else the steps
    (xs, ys, pixels), the first step in a band ``i0``, the first after it out of the bands
    ``i1``, the first in a band again ``i2`` (the number of steps when none), whether at
    least 6 steps lie between and at least half of them see the edge (``far``), the family
    ``k`` whose lines come nearest in ``i0..i1`` and that distance ``dmin`` (px)."""
    h, w = edges.shape
    empty = np.zeros(0, np.intp)
    # the steps to the border: t = 1 .. tmax, inside [-0.5, W - 0.5) x [-0.5, H - 0.5)
    lim = []
    for p, d, size in ((px, ux, w), (py, uy, h)):
        if d > 1e-12:
            lim.append((size - 0.5 - p) / d)
        elif d < -1e-12:
            lim.append((-0.5 - p) / d)
    tmax = int(math.floor(min(lim) - 1e-9)) if lim else 0
    if tmax < 1:
        return 1, empty, empty, 0, 0, 0, False, 0, 0.0
    t = np.arange(1.0, tmax + 1.0)
    xs = np.rint(px + t * ux).astype(np.intp)
    ys = np.rint(py + t * uy).astype(np.intp)
    keep = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
    xs, ys = xs[keep], ys[keep]
    m = int(xs.size)
    if m == 0:
        return 1, empty, empty, 0, 0, 0, False, 0, 0.0
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    # distance of each step to the nearest line of each family (px), from the offsets
    dk = []
    for n0, n1, sh in ((n00, n01, sh0), (n10, n11, sh1)):
        o = n0 * (xs - cx) + n1 * (ys - cy) + sh
        dk.append(np.abs(o - lp * np.rint(o / lp)))
    inb = np.minimum(dk[0], dk[1]) < band
    i0 = int(np.argmax(inb)) if inb.any() else m
    if i0 == m:
        return 1, xs, ys, i0, m, m, False, 0, 0.0  # the border comes first
    hit = _oriented(dx, dy, edges, -uy, ux, cos_tol)
    if i0 >= inside_steps and int(hit(xs[:i0], ys[:i0]).sum()) <= seen_share * i0:
        return 1, xs, ys, i0, m, m, False, 0, 0.0  # it ends inside the tile
    out = np.flatnonzero(~inb[i0:])
    i1 = i0 + int(out[0]) if out.size else m
    back = np.flatnonzero(inb[i1:])
    i2 = i1 + int(back[0]) if back.size else m
    n2 = i2 - i1
    far = n2 >= far_steps and int(hit(xs[i1:i2], ys[i1:i2]).sum()) >= seen_share * n2
    k = 0 if float(dk[0][i0:i1].min()) <= float(dk[1][i0:i1].min()) else 1
    return 0, xs, ys, i0, i1, i2, far, k, float(dk[k][i0:i1].min())


def _oriented(dx: np.ndarray, dy: np.ndarray, edges: np.ndarray, nx: float, ny: float,
              cos_tol: float) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """:func:`oriented_hits` on the given gradients and edge pixels, for the unit normal
    (nx, ny) (tolerance cosine ``cos_tol``)."""

    def hit(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return oriented_points(dx, dy, edges, xs, ys, nx, ny, cos_tol)

    return hit



def stretch_range_numpy(lv: np.ndarray, idx: np.ndarray, u: np.ndarray, clear: int,
                        stretches: int) -> float:
    """The largest range of 19 consecutive gray levels ``lv`` (at the samples ``idx[1:-1]``,
    indices into the positions ``u`` along a line, px, one interval in view, at least 19
    levels) among the stretches that keep ``clear`` samples clear of the crossing's own
    samples -9..9 about u = 0; NaN when fewer than ``stretches`` stretches are clear."""
    win = np.lib.stride_tricks.sliding_window_view(lv, 19)
    first = idx[1 : 1 + win.shape[0]]
    zero = int(np.argmin(np.abs(u)))
    lim = 9 + clear
    far = (first + 18 < zero - lim) | (first > zero + lim)
    if int(far.sum()) < stretches:
        return math.nan
    return float((win.max(axis=1) - win.min(axis=1))[far].max())

