"""The common fit of the lines' parts (residual tilt, line positions, their variances) and the
checks on the measured lines (``no lines`` .. ``foreign line``)."""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.robust.state import Fail, Line, RobustRun

__all__ = ["check_lines", "fit_tilt"]


def fit_tilt(run: RobustRun, lines: list[list[Line]]) -> float:
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
    run.details["straightness_px"] = worst
    # The fit is linear in the part positions: d eps / d p_i = sign w_i (t_i - tb) / dall,
    # d pos / d p_i = w_i / sum(w) [its own line] - sign tb d eps / d p_i. With every part
    # within its own bound b_i, eps and pos are within sum |d / d p_i| b_i.
    infl = [(ln, sign, tb, ln.wpart > 0) for ln, sign, tb, _ in stats]
    d_eps = np.concatenate(
        [sign * ln.wpart[ok] * (ln.tpart[ok] - tb) / max(dall, 1e-9)
         for ln, sign, tb, ok in infl]) if infl else np.zeros(0)
    run.part_bound = np.concatenate(
        [run.st.part_sigmas * ln.sigma[ok] + ln.spread[ok] for ln, _, _, ok in infl]
    ) if infl else np.zeros(0)
    start = 0
    for ln, sign, tb, ok in infl:
        g = -sign * tb * d_eps
        w = ln.wpart[ok]
        g[start : start + w.size] += w / w.sum()
        ln.infl = g
        start += w.size
    run.details["heading_parts"] = float(np.dot(np.abs(d_eps), run.part_bound))
    # Scatter of the parts about the fit, per unit of part length (px^2 px), with a weak
    # prior so that a fit with few degrees of freedom is not trusted blindly.
    st = run.st
    dof = max(nobs - (len(stats) + 1), 0)
    sigma2 = (ss + st.prior_dof * st.prior_sigma**2) / (dof + st.prior_dof)
    var_eps = sigma2 / dall if dall > 1e-9 else math.inf
    for ln, _, tb, _ in stats:
        ln.var = sigma2 / float(ln.wpart.sum()) + tb * tb * var_eps
    run.details["heading_se"] = math.sqrt(var_eps)
    # the two families must be perpendicular: their own tilts agree within their errors
    if den[0] > 1e-9 and den[1] > 1e-9:
        gap = abs(num[0] / den[0] - num[1] / den[1])
        run.details["tilt_gap"] = gap / math.sqrt(sigma2 / den[0] + sigma2 / den[1])
    else:
        run.details["tilt_gap"] = 0.0
    return eps


def check_lines(run: RobustRun, lines: list[list[Line]]) -> None:
    """Refuse (the first failing check) unless the lines look like one lattice's grout."""
    st = run.st
    if not lines[0] and not lines[1]:
        raise Fail("no lines")
    if run.details["depth"] < st.min_depth:
        raise Fail("low contrast")
    if not lines[0] or not lines[1]:
        raise Fail("one family")
    every = lines[0] + lines[1]
    rises = [ln.rise for ln in every if math.isfinite(ln.rise)]
    rise = float(np.median(rises)) if rises else math.inf
    run.details["rise"] = rise
    if not rise <= st.max_rise:
        raise Fail("blurred")
    step = max(ln.step for ln in every)
    run.details["step"] = step
    if step > st.max_step:
        raise Fail("step edge")
    if (
        run.details["straightness_px"] > st.straight_fraction * run.bound_px
        or run.details["tilt_gap"] > st.sigmas
    ):
        raise Fail("inconsistent angle")
    # Grout lines of both families share one width and one colour: a line unlike the
    # others (a cable along the grout direction, a seam) is foreign.
    widths = [ln.width for ln in every if math.isfinite(ln.width)]
    run.details["width_spread"] = max(widths) / min(widths) if widths else math.inf
    contrasts = [ln.contrast for ln in every]
    run.details["contrast_spread"] = max(contrasts) / max(min(contrasts), 1e-9)
    if run.inverted:
        # lighter grout: the lines agree in depth over the tiles' inverted level (shade
        # steps between the tiles move it little) or over the grout's own level (light
        # falling off across the view cancels); a line unlike the others differs in both
        run.details["contrast_spread"] = min(
            run.details["contrast_spread"], spread([ln.contrast_grout for ln in every]))
    if (
        not widths
        or max(widths) > st.width_ratio * min(widths) + st.width_slack
        or run.details["contrast_spread"] > st.contrast_ratio
    ):
        raise Fail("foreign line")


def spread(values: list[float]) -> float:
    """max / min of positive ``values`` (inf when one is not finite: no evidence of
    agreement)."""
    if not values or not all(math.isfinite(v) for v in values):
        return math.inf
    return max(values) / max(min(values), 1e-9)
