"""The lattice's periodicity at the line selection: weak dips off the tile period are texture.

A grout line runs through the whole view and its family repeats with the tile period; the
mortar of a brick photograph, a plank's edge or a stone's vein lies inside one tile, at no
fixed place in the period, and is seen along part of its line only. Each family's phase (the
offset, modulo the period, where its grout lines lie) is the one that the most evidence agrees
on: every dip votes with its depth times the length over which it was measured (its parts'
lengths), for the phase of every dip within ``selection.phase_tolerance`` of it. A dip off that
phase is dropped only when it is weak beside the lattice's lines (``selection.weak_share``): a
strong line off the period (a cable along the grout direction, a second lattice) is kept, so
that the checks refuse the view as before (``foreign line``, ``inconsistent spacing``).
"""

from __future__ import annotations

import numpy as np

from tileviz.vision.robust.settings import SelectionSettings
from tileviz.vision.robust.state import Line, ReadingState

__all__ = ["like", "on_lattice"]

def on_lattice(run: ReadingState, lines: list[list[Line]]) -> list[list[Line]]:
    """``lines`` (per family) without the weak dips off each family's phase (see the module
    docstring)."""
    st = run.st.selection
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
        near = np.abs(d - lp * np.rint(d / lp)) <= st.phase_tolerance * lp
        votes = near @ weight
        member = near[int(np.argmax(votes))]
        strongest = float(weight[member].max())
        keep = member | (weight >= st.weak_share * strongest) | (
            ((wp > 0).sum(axis=1) >= st.like_parts)
            & np.array([like(ln, template[1 - k], st) for ln in fam]))
        out.append([ln for ln, kept in zip(fam, keep.tolist(), strict=True) if kept])
    return out


def like(line: Line, grout: Line | None, st: SelectionSettings) -> bool:
    """Whether ``line`` looks like the grout line ``grout`` of the other family: at least
    ``st.like_depth`` of its depth, and its half-depth width within ``st.like_width`` x
    (``st.like_slack`` px) of it either way (a brick photograph's mortar lines, as deep as
    low-contrast grout, are narrower)."""
    if grout is None:
        return False
    w, g = line.width, grout.width
    return bool(line.depth >= st.like_depth * grout.depth
                and w <= st.like_width * g + st.like_slack
                and g <= st.like_width * w + st.like_slack)
