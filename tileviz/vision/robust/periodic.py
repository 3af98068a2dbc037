"""The lattice's periodicity at the line selection: weak dips off the tile period are texture.

A grout line runs through the whole view and its family repeats with the tile period; the
mortar of a brick photograph, a plank's edge or a stone's vein lies inside one tile, at no
fixed place in the period, and is seen along part of its line only. Each family's phase (the
offset, modulo the period, where its grout lines lie) is the one that the most evidence agrees
on: every dip votes with its depth times the length over which it was measured (its parts'
lengths), for the phase of every dip within :data:`PHASE_TOLERANCE` of it. A dip off that
phase is dropped only when it is weak beside the lattice's lines (:data:`WEAK_SHARE`): a
strong line off the period (a cable along the grout direction, a second lattice) is kept, so
that the checks refuse the view as before (``foreign line``, ``inconsistent spacing``).
"""

from __future__ import annotations

import numpy as np

from tileviz.vision.robust.state import Line, RobustRun

__all__ = ["LIKE_DEPTH", "LIKE_WIDTH", "PHASE_TOLERANCE", "WEAK_SHARE", "like", "on_lattice"]

PHASE_TOLERANCE = 0.04
"""A dip is on a phase when within this fraction of the tile period of it (modulo the period);
a dip kept a little off (more than the spacing check allows) is refused there."""
WEAK_SHARE = 0.5
"""A dip off the phase is dropped when its evidence (depth x measured length) is under this
share of the strongest line on the phase, unless it runs along its whole line (measured in
three parts or more) and looks like the other family's grout (:func:`like`): a grout line
beside a bright cable, three times as deep, that took the phase."""
LIKE_DEPTH = 0.8
"""A dip as deep as this share of the other family's deepest is as deep as the grout."""
LIKE_WIDTH = 1.3
"""A dip whose half-depth width is within this factor (+ 1 px) of the other family's deepest
dip's is as wide as the grout."""


def on_lattice(run: RobustRun, lines: list[list[Line]]) -> list[list[Line]]:
    """``lines`` (per family) without the weak dips off each family's phase (see the module
    docstring)."""
    lp = run.lp
    out: list[list[Line]] = []
    # each family's deepest dip: the template of a grout line for the other family
    template = [max(fam, key=lambda ln: ln.depth) if fam else None for fam in lines]
    for k, fam in enumerate(lines):
        if len(fam) < 2:
            out.append(fam)
            continue
        wp = np.array([ln.wpart for ln in fam])
        parts = np.array([ln.parts for ln in fam])
        measured = wp.sum(axis=1)
        # the line's place: its parts' length-weighted mean (a residual tilt moves the parts
        # of one line by about the same amount as those of the others)
        # (np.nansum's sum, without its copy and its checks: NaN terms are 0.0)
        x = parts * wp
        x = np.where((wp > 0) & (x == x), x, 0.0)
        pos = x.sum(axis=1) / np.maximum(measured, 1e-9)
        weight = np.array([ln.depth for ln in fam]) * measured
        d = pos[:, None] - pos[None, :]
        near = np.abs(d - lp * np.rint(d / lp)) <= PHASE_TOLERANCE * lp
        votes = near @ weight
        member = near[int(np.argmax(votes))]
        strongest = float(weight[member].max())
        keep = member | (weight >= WEAK_SHARE * strongest) | (
            ((wp > 0).sum(axis=1) >= 3) & np.array([like(ln, template[1 - k]) for ln in fam]))
        out.append([ln for ln, kept in zip(fam, keep.tolist(), strict=True) if kept])
    return out


def like(line: Line, grout: Line | None) -> bool:
    """Whether ``line`` looks like the grout line ``grout`` of the other family: at least
    :data:`LIKE_DEPTH` of its depth, and its half-depth width within ``LIKE_WIDTH`` x (1 px
    slack) of it either way (a brick photograph's mortar lines, as deep as low-contrast
    grout, are narrower)."""
    if grout is None:
        return False
    w, g = line.width, grout.width
    return bool(line.depth >= LIKE_DEPTH * grout.depth
                and w <= LIKE_WIDTH * g + 1.0 and g <= LIKE_WIDTH * w + 1.0)
