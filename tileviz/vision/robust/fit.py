"""The common fit of the lines' parts (residual tilt, line positions, their variances) and the
checks on the measured lines (``no lines`` .. ``foreign line``)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tileviz.vision.robust import checks, fit_kernel
from tileviz.vision.robust.checks import Refusal
from tileviz.vision.robust.crossings import crossings_agree
from tileviz.vision.robust.profiles import beside_dip
from tileviz.vision.robust.state import Line, ReadingState
from tileviz.vision.robust.statistics import list_median

__all__ = ["check_lines", "drop_stray_part", "fit_tilt", "leave_out_unlike", "part_spreads",
           "shoulder_px"]


def fit_tilt(run: ReadingState, lines: list[list[Line]]) -> float:
    """Fit one residual tilt eps for all lines (family-1 rows drift by +eps per unit of t,
    family-2 columns by -eps) and one intercept per line, weighted by part lengths; set each
    line's ``pos`` (at t = 0), ``var`` and ``infl``, and ``run.part_bound``; return eps (rad).
    A part whose own bound reaches half the period is left out of the fit, and a line of no
    other part out of ``lines``.
    Also records the tilt of each family on its own (``tilt_gap``: their difference in
    standard errors). All lines at once, compiled
    (:func:`~tileviz.vision.robust.fit_kernel.fit_arrays`)."""
    st = run.st.fit
    # a part whose own bound reaches half the tile period (one side of its dip with no depth
    # over the noise) says nothing of where its line is, modulo the period: the fit leaves it,
    # and a line with nothing else measured
    blind = {id(ln): st.part_sigmas * ln.sigma + ln.spread >= 0.5 * run.lp
             for fam in lines for ln in fam}
    for fam in lines:
        fam[:] = [ln for ln in fam if not blind[id(ln)][ln.wpart > 0].all()]
    every = lines[0] + lines[1]
    m = len(every)
    if m == 0:
        run.details["straightness_px"] = 0.0
        run.part_bound = run.part_band = run.part_t = run.part_p = np.zeros(0)
        run.part_line = np.zeros(0, np.intp)
        run.details["heading_parts"] = 0.0
        run.details["heading_se"] = math.inf
        run.details["tilt_gap"] = 0.0
        return 0.0
    spreads = part_spreads(run, lines)
    sigma = np.array([ln.sigma for ln in every])
    wpart = np.array([np.where(blind[id(ln)], 0.0, ln.wpart) for ln in every])
    tpart = np.array([ln.tpart for ln in every])
    ppart = np.array([ln.parts for ln in every])
    # what the band-shape terms (a shouldered line's reach, a band beside) add to the parts'
    # bounds, in the fit's order of parts (details heading_band, position_band: shown, not
    # allowed for by the bound checks)
    run.part_band = (spreads - np.array([ln.spread for ln in every]))[wpart > 0]
    eps, pos, var, g, d_eps, part_bound, straight, heading_se, tilt_gap = fit_kernel.fit_arrays(
        wpart, tpart, ppart, sigma, spreads, len(lines[0]), st.part_sigmas,
        st.prior_dof * st.prior_sigma**2, st.prior_dof, run.st.lines.straight_part_share,
        2.0 * run.tol_px)
    run.details["straightness_px"] = straight
    tol = run.tol_px
    if tol > 0.0:
        # a line may lie up to tol off the ideal lattice at any point: each part's position is
        # within its own bound plus tol of its ideal line (the fit is linear in them)
        part_bound = part_bound + tol
        run.details["heading_tolerance"] = tol * float(np.abs(d_eps).sum())
        tilt_gap = _tolerated_gap(lines, tilt_gap, tol)
    run.part_bound = part_bound
    run.tilt = eps
    measured = wpart > 0  # the fit's order of parts: line by line, along each line
    run.part_t, run.part_p = tpart[measured], ppart[measured]
    run.part_line = np.nonzero(measured)[0]
    run.details["heading_parts"] = float(np.dot(np.abs(d_eps), part_bound))
    run.details["heading_band"] = float(np.dot(np.abs(d_eps), run.part_band))
    for i, ln in enumerate(every):
        ln.pos = float(pos[i])
        ln.var = float(var[i])
        ln.infl = g[i]
    run.details["heading_se"] = heading_se
    run.details["tilt_gap"] = tilt_gap
    return eps


def part_spreads(run: ReadingState, lines: list[list[Line]]) -> np.ndarray:
    """The term of each part's own bound that its band's shape gives (lines of both families
    in order, PARTS; px): the spread of its 25 / 75 % midpoints; on a reading that bounds
    shoulders
    (``ReadingState.bound_shoulders``), for a line with a shoulder in every part
    (:func:`shoulder_px` above ``lines.shoulder_px``), the reach of its 25 % crossings from its
    50 % midpoint. Such a band may be the grout and something along it read as one (a cable
    touching it, a bevel's shadow): the grout, at least a quarter as dark as the band, lies
    within the band at a quarter of its depth (docs/vision.md, "The bound of a view"). A line
    among others of its family with a second band beside it (at least ``lines.beside_share``
    of its depth, apart) within the reach the lattice spacing leaves unseen
    (:func:`unseen_reach`) adds that band's distance: it may be the grout.
    A family's lone line is refused for such a band instead (``foreign_line.beside``); a band
    at the same offset beside another line of the family is the floor's own (a bevel, a double
    joint: :func:`beside_reach`). A family's lone line is bounded at least by
    :func:`lone_reach`."""
    every = lines[0] + lines[1]
    if run.bound_shoulders:
        limit = run.st.lines.shoulder_px
        wide = [shoulder_px(ln) > limit for ln in every]
        run.details["shouldered"] = float(sum(wide))
        out = np.array([ln.reach if w else ln.spread for ln, w in zip(every, wide, strict=True)])
    else:
        out = np.array([ln.spread for ln in every])
    lone = lone_reach(lines)
    if lone.size:
        out = np.maximum(out, lone)
    beside = np.array([d for k in range(2) for d in beside_reach(run, k, lines[k])])
    run.details["beside_px"] = float(beside.max()) if beside.size else 0.0
    return out + beside[:, None]


def lone_reach(lines: list[list[Line]]) -> np.ndarray:
    """How far (px, per part of each line of both families in order; empty when no family
    has a lone line) the grout may lie from where a family's lone line is read: the reach of
    the line's 25 % crossings from its 50 % midpoint less half the narrowest half-depth width
    among the other family's lines (0 for lines of a family of two or more). A lone line meets
    no spacing check: a band along the grout read with it as one line (a cable over the joint)
    moves the line's centre, while its width and contrast may still agree with the other
    family's; the grout, as wide as the other family's narrowest line at half its depth and
    wider at a quarter, lies within the band at a quarter of its depth (docs/vision.md,
    "The bound of a view"). It is at least half the line's width beyond that narrowest line's
    (its 25 % crossing lies beyond its 50 % one), so such a line's excess width is not added
    again (:func:`~tileviz.vision.robust.lattice.lattice_offsets`)."""
    if all(len(fam) != 1 for fam in lines):
        return np.zeros(0)
    rows = []
    for k, fam in enumerate(lines):
        widths = [ln.width for ln in lines[1 - k] if math.isfinite(ln.width) and ln.width > 0]
        half = 0.5 * min(widths) if widths else 0.0
        for ln in fam:
            rows.append(np.maximum(ln.reach - half, 0.0) if len(fam) == 1
                        else np.zeros_like(ln.reach))
    return np.array(rows)


def _family_tilt(fam: list[Line], sign: float) -> tuple[float, float]:
    """The tilt of one family's lines on their own (rad, each line its own intercept, weighted
    by part lengths as :func:`fit_tilt`) and how far parts each moved by 1 px can move it
    (rad per px: the sum of the magnitudes of its derivatives); (nan, 0) without a baseline."""
    num = den = sens = 0.0
    for ln in fam:
        ok = ln.wpart > 0
        if not ok.any():
            continue
        w, t, p = ln.wpart[ok], ln.tpart[ok], ln.parts[ok]
        dt = t - float(np.dot(w, t) / w.sum())
        num += sign * float(np.dot(w * dt, p - float(np.dot(w, p) / w.sum())))
        den += float(np.dot(w, dt * dt))
        sens += float(np.abs(w * dt).sum())
    if den <= 1e-9:
        return math.nan, 0.0
    return num / den, sens / den


def _tolerated_gap(lines: list[list[Line]], gap_se: float, tol: float) -> float:
    """The two families' tilts apart (``gap_se``: in standard errors) less what parts within
    ``tol`` px of their ideal lines can make of it, in the same standard errors (0 when the
    tolerance explains it all)."""
    t0, s0 = _family_tilt(lines[0], 1.0)
    t1, s1 = _family_tilt(lines[1], -1.0)
    gap = abs(t0 - t1)
    if not (math.isfinite(gap) and gap > 0.0 and gap_se > 0.0):
        return gap_se
    return max(0.0, gap - tol * (s0 + s1)) * gap_se / gap


def drop_stray_part(run: ReadingState, lines: list[list[Line]], eps: float) -> bool:
    """Leave out (``wpart`` 0, position NaN) the one part that keeps the lines from being
    straight, when it is unambiguous: exactly one part of the whole view (among those the
    straightness weighs, ``lines.straight_part_share`` of its line's longest part or more) lies
    farther than the straightness limit (``lines.straight_fraction`` x ``run.bound_px``) from
    the common fit of tilt ``eps`` (rad) and its line's other parts, which are at least
    ``lines.stray_min_rest`` (of those so weighed) and lie within ``lines.stray_share`` of that
    limit of their own mean offset from that fit; no other line has a
    part beyond the limit. A dip of the texture (a mortar joint of a brick
    photograph a few px beside the grout) measured instead of the grout in one part of a short
    line moves that part alone; the line is then measured by its other parts. True when a
    part was left out (the caller fits again; every check then applies as before). Used only
    in a second reading of a view the first refused (``ReadingState.drop_stray``). The part
    left out is kept in ``Line.dropped``: where its line is its family's only one, nothing
    else in the view says which of its parts are right (a cable along one segment of a
    checkerboard's edge moves every part of that segment alike), and the bound covers the
    part left out too (:func:`~tileviz.vision.robust.lattice.lattice_offsets`)."""
    st = run.st.lines
    limit = checks.ANGLE_STRAIGHT.limit(run)
    stray: list[tuple[Line, int]] = []
    for k, fam in enumerate(lines):
        sign = 1.0 if k == 0 else -1.0
        for ln in fam:
            ok = ln.wpart > 0
            if not ok.any():
                continue
            big = np.flatnonzero(ok & (ln.wpart >= st.straight_part_share
                                       * float(ln.wpart.max())))
            res = ln.parts[big] - (ln.pos + sign * eps * ln.tpart[big])
            if float(np.abs(res).max()) <= limit:
                continue
            found = []
            for j in range(big.size):
                rest = np.delete(np.arange(big.size), j)
                if rest.size < st.stray_min_rest:
                    continue
                # the line without part j: its parts' mean offset from the common fit
                m = float(np.average(res[rest], weights=ln.wpart[big[rest]]))
                if (abs(res[j] - m) > limit
                        and float(np.abs(res[rest] - m).max()) <= st.stray_share * limit):
                    found.append(int(big[j]))
            if len(found) != 1:
                return False
            stray.append((ln, found[0]))
    if len(stray) != 1:
        return False
    ln, i = stray[0]
    # its own bound as the fit bounds every part (the band's shape, a lone line's reach)
    row = next(j for j, other in enumerate(lines[0] + lines[1]) if other is ln)
    spread = float(part_spreads(run, lines)[row, i])
    ln.dropped = (float(ln.parts[i]), float(ln.tpart[i]),
                  run.st.fit.part_sigmas * float(ln.sigma[i]) + spread + run.tol_px)
    ln.wpart = ln.wpart.copy()
    ln.parts = ln.parts.copy()
    ln.wpart[i] = 0.0
    ln.parts[i] = math.nan
    return True


def check_lines(run: ReadingState, lines: list[list[Line]]) -> None:
    """Refuse (the first failing check, :mod:`.checks`: ``lines.found`` .. ``foreign_line.
    shoulder``) unless the lines look like one lattice's grout."""
    rec = run.record
    rec.require(checks.LINES_FOUND, run, len(lines[0]) + len(lines[1]))
    rec.require(checks.CONTRAST_DEPTH, run, run.details["depth"])
    rec.require(checks.LINES_FAMILIES, run, min(len(lines[0]), len(lines[1])))
    if run.reading.unlike:
        rec.require(checks.FOREIGN_LEFT_OUT, run, run.unlike_others)
    every = lines[0] + lines[1]
    rises = [ln.rise for ln in every if math.isfinite(ln.rise)]
    rise = list_median(rises) if rises else math.inf
    run.details["rise"] = rise
    rec.require(checks.BLUR_RISE, run, rise)
    step = max(ln.step for ln in every)
    run.details["step"] = step
    rec.require(checks.STEP_LEVELS, run, step)
    rec.require(checks.ANGLE_STRAIGHT, run, run.details["straightness_px"])
    rec.require(checks.ANGLE_PERPENDICULAR, run, run.details["tilt_gap"])
    # Grout lines of both families share one width and one colour: a line unlike the
    # others (a cable along the grout direction, a seam) is foreign.
    widths = [ln.width for ln in every if math.isfinite(ln.width)]
    run.details["width_spread"] = max(widths) / min(widths) if widths else math.inf
    run.details["contrast_spread"] = family_spread(
        lines, lambda ln: ln.contrast, lambda v: max(v) / max(min(v), 1e-9))
    if run.inverted:
        # lighter grout: the lines agree in depth over the tiles' inverted level (shade
        # steps between the tiles move it little) or over the grout's own level (light
        # falling off across the view cancels); a line unlike the others differs in both
        run.details["contrast_spread"] = min(
            run.details["contrast_spread"],
            family_spread(lines, lambda ln: ln.contrast_grout, spread))
    rec.require(checks.FOREIGN_WIDTH, run, max(widths) if widths else math.nan,
                min(widths) if widths else math.nan)
    # the floor's own variation: lines differ in contrast as much as each varies along itself
    # (measured only when the lines differ more than the setting alone allows)
    along = 1.0
    if run.details["contrast_spread"] > run.st.lines.contrast_ratio:
        along = contrast_along(every)
        run.details["contrast_along"] = along
    if not rec.check(checks.FOREIGN_CONTRAST, run, run.details["contrast_spread"],
                     along) and not (
            run.inverted and crossings_agree(run, lines)):
        raise Refusal(rec.results[-1], "foreign line")
    # one grout line is one band: a second band just beside it (a cable along the grout)
    # darkens the plateaus its position is measured against, and may be read instead of
    # it; a family's lone line is refused, a line among others bounded (part_spreads) as far
    # as the spacing would not show it (a brick photograph's mortar line beside the grout
    # all along a line that spans one tile is a second band too)
    beside = max((beside_dip(run, k, lines[k][0])[0] for k in range(2) if len(lines[k]) == 1),
                 default=0.0)
    run.details["beside"] = beside
    rec.require(checks.FOREIGN_BESIDE, run, beside)
    shoulder = max(shoulder_px(ln) for ln in every)
    run.details["shoulder_px"] = shoulder
    if not run.bound_shoulders:  # else in the parts' bounds (part_spreads)
        rec.require(checks.FOREIGN_SHOULDER, run, shoulder)


def beside_reach(run: ReadingState, k: int, fam: list[Line]) -> list[float]:
    """How far (px) a second band beside each line of family ``k`` (``fam``) may lie, as the line's
    bound must hold it (:func:`part_spreads`): the farthest sample of a dip apart from the
    line, at least ``lines.beside_share`` of its depth, within :func:`unseen_reach`, that is
    not the floor's own (a band within ``lines.beside_same_px`` of the same offset beside
    another line of the family: a joint's bevel or double line, where a cable runs along one
    line only); 0 for a family's lone line (refused for such a band,
    ``foreign_line.beside``)."""
    if len(fam) < 2:
        return [0.0] * len(fam)
    share, same = run.st.lines.beside_share, run.st.lines.beside_same_px
    found = [beside_dip(run, k, ln, reach, share)[1]
             for ln, reach in unseen_reach(run, fam)]
    out = []
    for i, offs in enumerate(found):
        own = [o for o in offs if not any(
            any(abs(o - q) <= same for q in other)
            for j, other in enumerate(found) if j != i)]
        out.append(float(max((abs(o) for o in own), default=0)))
    return out


def unseen_reach(run: ReadingState, fam: list[Line]) -> list[tuple[Line, float]]:
    """Each line of one family with how far (px) a band beside it, read instead of it, stays
    unseen by the lattice spacing (``spacing``'s limit, which the declared tolerance widens
    by 2 tol): a family's lone line, its whole measurement window (inf); a line among
    others, the limit over one less its chord's share of the family's (the family's offset is
    their chord-weighted mean, so a line read ``d`` off moves its own residual by ``d`` times
    that)."""
    if len(fam) == 1:
        return [(fam[0], math.inf)]
    limit = checks.SPACING.limit(run)
    total = sum(ln.chord for ln in fam)
    return [(ln, limit / max(1.0 - ln.chord / total, 1e-9)) for ln in fam]


def leave_out_unlike(run: ReadingState, lines: list[list[Line]]) -> None:
    """Leave out of ``lines`` (in place) the one line most unlike the others of its family
    (``Reading.unlike``): of the families with more than ``lines.unlike_others`` lines, the line
    farthest from the median of its family's other lines in log contrast plus log half-depth
    width (a line without a positive finite value the farthest). A panel's seam along a joint,
    a cable along one: the family's other lines, alike, read the lattice without it, and every
    check runs on them. Sets ``run.unlike_others`` (the other lines of that family; when no
    family has enough, of the largest, and nothing is left out: ``foreign_line.left_out``
    refuses) and ``details["left_out_family"]`` (1 or 2)."""
    need = run.st.lines.unlike_others
    best: tuple[float, int, int] | None = None  # (how unlike, family, index)
    for k, fam in enumerate(lines):
        if len(fam) <= need:
            continue
        for i, ln in enumerate(fam):
            others = fam[:i] + fam[i + 1:]
            score = (_unlike(ln.contrast, [o.contrast for o in others])
                     + _unlike(ln.width, [o.width for o in others]))
            if best is None or score > best[0]:
                best = (score, k, i)
    if best is None:
        run.unlike_others = float(max(max(len(f) for f in lines) - 1, 0))
        return
    _, k, i = best
    del lines[k][i]
    run.unlike_others = float(len(lines[k]))
    run.details["left_out_family"] = float(k + 1)


def _unlike(value: float, others: list[float]) -> float:
    """|log(value / median of the positive finite ``others``)| (inf when ``value`` is not
    positive and finite; 0 when no other is)."""
    if not (value > 0.0 and math.isfinite(value)):
        return math.inf
    kept = [o for o in others if o > 0.0 and math.isfinite(o)]
    return abs(math.log(value / list_median(kept))) if kept else 0.0


def contrast_along(lines: list[Line]) -> float:
    """How much the lines' contrast varies along themselves: the median over the lines with two
    measured parts or more (length > 0, contrast positive and finite) of max / min over their
    parts, at least 1 (1 when no line has two)."""
    ratios = []
    for ln in lines:
        c = ln.part_contrast[(ln.wpart > 0) & (ln.part_contrast > 0)
                             & np.isfinite(ln.part_contrast)]
        if c.size >= 2:
            ratios.append(float(c.max() / c.min()))
    return max(1.0, list_median(ratios)) if ratios else 1.0


def shoulder_px(line: Line) -> float:
    """The smallest, over the measured parts of ``line`` (0.0 with fewer than two), of the
    distance of its 25 / 75 % midpoints from its 50 % midpoint (px): a shoulder beside the
    band that every part shows."""
    spread = line.spread[(line.wpart > 0) & np.isfinite(line.spread)]
    return float(spread.min()) if spread.size >= 2 else 0.0


def family_spread(lines: list[list[Line]], value: Callable[[Line], float],
                  ratio: Callable[[list[float]], float]) -> float:
    """How much the lines differ in ``value`` where it tells a foreign line: the ``ratio``
    (max / min) within each family of two lines or more, and of a family's one line against
    every line of both; the largest of these (1.0 without lines). A cable or a seam runs along
    one family, unlike that family's grout lines; the two families may differ from each other
    (light falling across recessed joints shades the joints of one family more than the
    other's), so a family of two lines or more is compared with itself only."""
    every = [value(ln) for fam in lines for ln in fam]
    out = 1.0
    for fam in lines:
        if fam:
            out = max(out, ratio([value(ln) for ln in fam]) if len(fam) >= 2
                      else ratio(every))
    return out


def spread(values: list[float]) -> float:
    """max / min of positive ``values`` (inf when one is not finite: no evidence of
    agreement)."""
    if not values or not all(math.isfinite(v) for v in values):
        return math.inf
    return max(values) / max(min(values), 1e-9)
