"""The lattice: line offsets modulo L, the spacing checks and the observation; geometry helpers
(:func:`normalise`, :func:`clip_line`)."""

from __future__ import annotations

import math

import numpy as np

from tileviz.vision.geometry import QUARTER, family_normals
from tileviz.vision.robust import checks, lattice_kernel
from tileviz.vision.robust.bound import frame_bound, part_floor
from tileviz.vision.robust.feasible_kernel import relaxed_ranges
from tileviz.vision.robust.state import Line, ReadingState
from tileviz.vision.robust.statistics import list_median

__all__ = ["clip_line", "feasible_terms", "lattice_offsets", "measured_period",
           "missing_lines", "normalise"]


def normalise(y1: float, y2: float, y3: float, tile_size: float) -> tuple[float, float, float]:
    """The same observation with y3 in [-pi/4, pi/4) and y1, y2 in [0, L) (docs/method.md).

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


def lattice_offsets(run: ReadingState, lines: list[list[Line]], y3: float) -> None:
    """Offsets modulo L per family, the spacing checks, the bound and the observation
    (checks ``spacing.missing`` .. ``bound.heading``)."""
    x0, y0 = run.centre
    lp = run.lp
    ys: list[float] = []
    refs: list[float] = []
    terms: list[float] = []  # each family's parts' term of the bound (px)
    worst = 0.0
    se = 0.0
    # a line wider than the view's narrowest may be the grout and something beside it (a
    # cable along its edge) read as one band: its midpoint may be off by half the excess
    narrowest = min((ln.width for fam in lines for ln in fam if math.isfinite(ln.width)),
                    default=math.nan)
    run.details["width_excess_px"] = 0.0
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
        # ref moves with the lines' offsets s = -(pos - centre), weighted by their chords
        # (the chord-weighted influence rows added one after the other)
        g = np.add.accumulate(w_arr[:, None] * np.array([ln.infl for ln in fam]),
                              axis=0)[-1] / w_arr.sum()
        parts_k = float(np.dot(np.abs(g), run.part_bound))
        if len(fam) == 1 and fam[0].dropped is not None:
            # a lone line read without a stray part: the part left out may be the right one
            # (no other line of the family says which), so the term reaches it too, carried
            # to the view's centre with the tilt's error (its parts' term)
            p, t, b = fam[0].dropped
            sign = 1.0 if k == 0 else -1.0
            parts_k = max(parts_k, abs(p - (fam[0].pos + sign * run.tilt * t)) + b
                          + abs(t) * run.details["heading_parts"])
        terms.append(parts_k)
        run.details["position_parts"] = max(run.details.get("position_parts", 0.0),
                                             parts_k)
        run.details["position_band"] = max(run.details.get("position_band", 0.0),
                                            float(np.dot(np.abs(g), run.part_band)))
        if run.tol_px > 0.0:  # the part of it that the floor's lattice tolerance makes
            run.details["position_tolerance"] = max(
                run.details.get("position_tolerance", 0.0),
                run.tol_px * float(np.abs(g).sum()))
        # (a family's lone line: its parts' bounds hold its band's reach instead, at least
        # half its excess width, fit.lone_reach)
        excess = np.array([max(ln.width - narrowest, 0.0)
                           if math.isfinite(ln.width) and len(fam) > 1 else 0.0 for ln in fam])
        run.details["width_excess_px"] = max(run.details["width_excess_px"],
                                             0.5 * float(np.dot(w_arr, excess) / w_arr.sum()))
        var = np.array([ln.var for ln in fam])
        se = max(se, math.sqrt(float(np.dot(w_arr * w_arr, var))) / float(w_arr.sum()))
        refs.append(ref)
        ys.append(-ref / run.ppm)  # eq. 4.6 corrected: y_k = -s_k mod L
        measured_period(run, s_arr, ref)
        missing_lines(run, k, ref, s_arr, y3)
    run.details["spacing_residual_px"] = worst
    run.offsets = (refs[0], refs[1])
    rec = run.record
    rec.require(checks.SPACING, run, worst)
    for k, fam in enumerate(lines):
        rec.require(checks.EVIDENCE, run, sum(ln.chord for ln in fam), subject=FAMILY[k])
    run.details["position_se_px"] = se
    feasible_terms(run, lines, refs, terms)
    d = run.details
    # the view declares the bound from the set the parts allow (one line may be wrong); it is
    # precise enough when that bound and the one from the fit's sums are both within the limit
    d["bound_px"], d["bound_rad"] = frame_bound(run, se, d["position_parts"],
                                                d["heading_parts"])
    pos_fit, head_fit = frame_bound(run, se, d["position_fit"], d["heading_fit"])
    # what the tolerance adds to the bound: its part of the parts' term, and at most tol to
    # the scatter's standard error (fit.sigmas of them) and to half a width's excess. What the
    # band-shape terms add (a shouldered line, a band beside a line; details position_band,
    # heading_band) is not allowed for: a view that needs them beyond the limit is refused
    # (a motion-blurred checkerboard read 8 degrees off its heading declared 0.18 rad, 32 px,
    # and lay 61 px off; another read 10 degrees off, whose parts' set allowed 0.13 rad of its
    # 0.36 from the fit's sums: the set's tight parts were blurred alike)
    rec.require(checks.BOUND_POSITION, run, max(pos_fit, d["bound_px"]),
                d.get("position_tolerance", 0.0) + (run.st.fit.sigmas + 1.0) * run.tol_px)
    # each heading bound within the limit beyond what the tolerance adds to it (the fit's sum:
    # heading_tolerance; the set's reach: heading_tolerance_set)
    fit_share = d.get("heading_tolerance", 0.0)
    declared = d["bound_rad"]
    beyond = max(head_fit - fit_share, declared - d.get("heading_tolerance_set", fit_share))
    head = max(head_fit, declared)
    rec.require(checks.BOUND_HEADING, run, head,
                head - beyond if math.isfinite(head) else fit_share)
    run.y = normalise(ys[0], ys[1], y3, run.tile_size)


def feasible_terms(run: ReadingState, lines: list[list[Line]], refs: list[float],
                   terms: list[float]) -> None:
    """Replace the parts' terms of the bound (``position_parts``, ``heading_parts``) by the
    distance from the estimate to the far ends of the lattices that the parts of every line
    but one allow, each part within its own bound (docs/vision.md, "The bound of a view";
    :func:`~tileviz.vision.robust.feasible_kernel.relaxed_ranges`): one line whose parts lie
    beyond their bounds (a joint farther off than the tolerance, a cable lying on it) cannot
    move the set off the truth, though it moves the fit, so the set may reach farther than
    the fit's terms. ``refs`` are the families' offsets (px, the estimate, as ``s`` in
    :func:`lattice_offsets`) and ``terms`` their parts' terms from the fit (px); each part
    belongs to the ideal line nearest its own line's offset. Where the parts' own bounds allow
    no lattice with any one line left out, each part is allowed its bound plus the view's floor
    (:func:`~tileviz.vision.robust.bound.part_floor`: what no part's bound shows, the warp's
    interpolation, the pixel grid), as the bound allows the whole view. ``details
    ["feasible"]``: 1 when the parts of every line but one allow a lattice, 0.5 when they do
    with the floor, 0 when they do not, NaN when the tilt is unbounded or a part's input is not
    finite (for 0 and NaN the terms stay the fit's). A family whose offset is free with its
    lone line left out takes the larger of the set's reach (any other line wrong) and its fit's
    term (that line wrong within its band's reach)."""
    every = lines[0] + lines[1]
    line = run.part_line
    fam = (line >= len(lines[0])).astype(np.intp)
    sign = np.where(fam == 0, 1.0, -1.0)
    centre = np.where(fam == 0, run.centre[1], run.centre[0])
    # a part's line, at the signed offset s = -(pos - centre), is the ideal line n periods
    # from its family's offset o: the part says -o + sign t eps = p - centre + n L ppm
    s_line = -(np.array([ln.pos for ln in every])[line] - centre)
    n = np.rint((s_line - np.asarray(refs)[fam]) / run.lp)
    a, q = sign * run.part_t, run.part_p - centre + n * run.lp
    b = run.part_bound
    status, ranges, opened = relaxed_ranges(a, q, b, fam, line)
    floored = status == 1
    if floored:
        b = b + part_floor(run)
        status, ranges, opened = relaxed_ranges(a, q, b, fam, line)
    d = run.details
    d["feasible"] = (0.5 if floored else 1.0) if status == 0 else 0.0 if status == 1 else math.nan
    # the fit's own terms, shown beside the ones the bound takes
    d["position_fit"] = max(terms)
    d["heading_fit"] = d["heading_parts"]
    if status != 0:
        return
    eps = run.tilt
    d["heading_parts"] = _reach(eps, ranges[0])
    if run.tol_px > 0.0:
        # what the floor's tolerance adds to the set's heading reach: the same set with every
        # part's bound less the tolerance (none left: as to the fit's sum)
        status0, ranges0, _ = relaxed_ranges(a, q, b - run.tol_px, fam, line)
        if status0 == 0:
            d["heading_tolerance_set"] = d["heading_parts"] - _reach(eps, ranges0[0])
    # a family's lone line left out leaves its offset free: the set bounds it with any other
    # line wrong, the fit's term (the line's band's reach in its parts' bounds) with that one
    reach = [_reach(refs[k], ranges[1 + k]) for k in range(2)]
    d["position_parts"] = max(
        terms[k] if not math.isfinite(r) else max(terms[k], r) if opened[k] else r
        for k, r in enumerate(reach))



def _reach(x: float, row: np.ndarray) -> float:
    """The distance from ``x`` to the farther end of the range ``row`` (lower, upper)."""
    return float(max(x - row[0], row[1] - x))

def measured_period(run: ReadingState, s: np.ndarray, ref: float) -> None:
    """The tile period that one family's lines show (signed offsets ``s``, px, about the
    family's phase ``ref``), over the declared one (``tile_size`` x ``ppm``): the slope of a
    least-squares line through the offsets against their lattice indices, when they span at
    least one period; kept in ``details["period_ratio"]`` (with ``period_span``, the indices
    spanned) when it spans more periods than the family read before. Lines a period apart
    are read 2 % of a period closer or farther when ``ppm`` or ``tile_size`` is 2 % off;
    such a view is refused (``inconsistent spacing``) or, with one line per family in view,
    cannot show it: the ratio over many frames can (:class:`tileviz.summary.RunTally`)."""
    lp = run.lp
    n = np.rint((s - ref) / lp)
    span = float(n.max() - n.min()) if n.size else 0.0
    if span < 1.0 or span <= run.details.get("period_span", 0.0):
        return
    dn = n - n.mean()
    run.details["period_ratio"] = float(np.dot(dn, s - s.mean()) / np.dot(dn, dn)) / lp
    run.details["period_span"] = span


def missing_lines(run: ReadingState, k: int, ref: float, found: np.ndarray, y3: float) -> None:
    """Refuse when the lattice predicts a well-visible line of family k that was not found
    (the signed offsets ``ref + j L ppm``, px) and the family's profile shows no dip there
    either (within half the grout's width + 1.5 px of it): a grout line as light as the
    tiles beside it, or cut short by the border, may give no line yet be seen
    (compiled: :func:`~tileviz.vision.robust.lattice_kernel.missing_line`)."""
    n = family_normals(y3)[k]
    reach = 0.5 * math.hypot(run.w, run.h)
    # the grout's width; a family measured in a window of its own (profiles.wide_family) has
    # wider grout than the other: its own lines' median width when wider
    width = run.details["width"]
    if run.family_window[k] and run.lines[k]:
        width = max(width, list_median([ln.width for ln in run.lines[k]]))
    # a dip is measured over its window and 4 plateau samples on each side
    margin = math.ceil(1.5 * width + 1.5) + 5
    # the family's dips (the deepest sample of each, px offsets as ``s``): a grout line
    # between two tiles of nearly its own shade (lighter grout beside light tiles) may be
    # too shallow for a line, or too near the border of the view to be measured in parts,
    # yet shows as a dip where the lattice puts it
    proj = run.projection
    if proj is None:
        peak, fam, pad = _NO_DIPS, _NO_DIPS, 0
    else:
        peak, fam, pad = proj.peak, proj.fam, proj.pad
    centre = run.centre[1] if k == 0 else run.centre[0]
    # a line may lie up to twice the lattice tolerance from where the others put it
    near = 0.5 * width + 1.5 + 2.0 * run.tol_px
    missing = lattice_kernel.missing_line(
        n[0], n[1], math.hypot(-n[1], n[0]), ref, run.lp, reach, margin, run.w, run.h,
        run.st.lattice.min_chord, found, peak, fam, k, pad, centre, near,
        run.st.lattice.found_share)
    run.record.require(checks.SPACING_MISSING, run, 1.0 if missing else 0.0, subject=FAMILY[k])


_NO_DIPS = np.zeros(0, np.intp)

FAMILY = ("family 1", "family 2")
"""How a per-family check names its family (family 1 gives y1, family 2 y2)."""


