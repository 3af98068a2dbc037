"""Whether the lines a view's edge image read are the edges between tiles of a checkerboard
(docs/vision.md, "Colour"): :func:`tile_edges`.

On a checkerboard two shades meet edge to edge, or across a thin grout band: across each line,
between two crossings, the view steps once from one tile's level to the other's. Read from its
edge image, a line is a ridge of the step's edge; where a band of a third level lies along the
edge (a thin grout), the band's far side is an edge the other way, and the line read may lie on
either edge (the edge image has a ridge on each), the band's centre (the lattice's line) between
them. So a view is read as a checkerboard that the user did not declare only when every piece of
every line it read is one step (the level on either side differs, and the view is steep the
step's way over one stretch only: not two edges with a band of a third level between) whose
steepest point and any edge the other way lie near the line read (their reach); a second
reading with the floor's tolerance widened by the largest reach then widens the first's bounds
(:func:`tileviz.vision.views.read_robust`). A grout band between two tiles of one shade is no
step; a wide one is no tile edge. A band whose far side is fainter than ``band_edge`` is not
seen: a line read along its stronger edge is then off the band's centre by half its width,
which only the fit's straightness across a crossing (where the light tile, and the stronger
edge with it, swaps sides) shows. A floor declared ``checker`` declares its tolerance instead.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import NamedTuple

import cv2
import numpy as np

from tileviz.vision.result import BAG_HORIZONTAL, BAG_VERTICAL
from tileviz.vision.robust.settings import CheckerSettings
from tileviz.vision.robust.statistics import noise_sigma

__all__ = ["Steps", "sides_alternate", "tile_edges"]


class Steps:
    """What :func:`tile_edges` found: the pieces of lines measured (between two crossings, or
    a crossing and the view's border), how many of them are not one step, and the largest
    reach of those that are (px, :func:`step_band`)."""

    def __init__(self, measured: int, failed: int, band: float = 0.0) -> None:
        self.measured = measured
        self.failed = failed
        self.band = band


def tile_edges(view: np.ndarray, segments: np.ndarray, bags: np.ndarray, lp: float,
               st: CheckerSettings) -> Steps:
    """Each line read (``segments``: (N, 4) image endpoints x1, y1, x2, y2 px; ``bags``: 1 or 2
    its family, 0 not a line) cut at its crossings with the other family's lines, each piece
    whose middle is at least ``st.min_piece`` of the period ``lp`` (px) long measured on
    ``view`` (HxW uint8, the image whose edge image was read): its profile across the line
    (mean along the piece's middle, the ends ``st.piece_margin`` of it left out by the
    crossings' corners) over ``st.reach`` of the period each side (at least ``st.min_reach``
    px), the levels either side the mean of its outer ``st.plateau`` px. A piece is one step
    when the two levels differ by ``st.step_sigmas`` of the profile's noise (the view's noise
    over the root of the piece's length) and ``st.min_step`` gray levels, its slope the step's
    way is at least ``st.single_edge`` of its steepest over one stretch only (by central
    differences: one edge, not two with a band of a third level between), and its reach
    (:func:`step_band`: the farther of its steepest point and any slope against the step
    steeper than ``st.band_edge`` of the steepest, from the line read) is at most
    ``st.max_band`` of the period. ``Steps.band``: the largest reach."""
    sigma = noise_sigma(view)
    measured = failed = 0
    band = 0.0
    for piece in _pieces(view, segments, bags, lp, st):
        measured += 1
        got = step_band(piece.profile, piece.u, piece.outer, sigma / math.sqrt(piece.n),
                        st.max_band * lp, st)
        if got is None:
            failed += 1
        else:
            band = max(band, got)
    return Steps(measured, failed, band)


def sides_alternate(view: np.ndarray, segments: np.ndarray, bags: np.ndarray, lp: float,
                    st: CheckerSettings) -> tuple[int, float]:
    """Whether the tiles on both sides of each line swap shades at its crossings, as on a
    checkerboard (docs/vision.md, "Colour"): (crossings measured, the smallest swap).

    On a checkerboard every line is the edge between two tiles of opposite shades, and at
    each crossing with a line of the other family both tiles beside it change to the other
    shade: the side that was the darker becomes the lighter. Each line read (``segments``
    (N, 4) image endpoints x1, y1, x2, y2 px; ``bags`` 1 or 2 its family, 0 not a line) is cut
    into pieces at its crossings as in :func:`tile_edges` (same settings, measured on ``view``,
    HxW uint8, the image whose edge image was read; ``lp`` the tile period, px), each side's
    level the mean of the profile's outer ``st.plateau`` px. Two pieces measured either side of
    one crossing, with levels (l0, r0) and (l1, r1), see the four tiles around it: on a
    checkerboard l0 and r1 are of one shade, r0 and l1 of the other, so each of the four pairs
    of neighbours differs the same way: r0 - l0, l1 - r1 (across the line), l1 - l0 and
    r0 - r1 (along it) all have the sign of (r0 + l1) - (l0 + r1). Each is compared with the
    least step a piece has between two tiles (``st.step_sigmas`` of the profile's noise, the
    view's noise over the root of the shorter piece's length, and at least ``st.min_step``
    gray levels): the swap is the smallest of the four, signed that way, over it; 1 or more
    where the four tiles alternate, about 0 where one side keeps its level (the edge of an
    object lying on the floor: one side the object, the other the tiles) or a piece is no step
    (a line running into the object), negative where a pair differs the wrong way. Tiles of
    one shade may differ from each other (marble, a worn floor): only the direction of each
    difference and that it stands out of the noise are asked for. With no crossing measured
    the swap is inf."""
    sigma = noise_sigma(view)
    crossings = 0
    worst = math.inf
    last: _Piece | None = None
    for piece in _pieces(view, segments, bags, lp, st):
        if last is not None and last.line == piece.line and last.cut + 1 == piece.cut:
            crossings += 1
            l0, r0 = _levels(last)
            l1, r1 = _levels(piece)
            way = math.copysign(1.0, (r0 + l1) - (l0 + r1))
            least = max(st.step_sigmas * sigma / math.sqrt(min(last.n, piece.n)), st.min_step)
            worst = min(worst, min(r0 - l0, l1 - r1, l1 - l0, r0 - r1) * way / least)
        last = piece
    return crossings, worst


class _Piece(NamedTuple):
    """A piece of line ``line`` between its cuts ``cut`` and ``cut + 1``: its mean
    ``profile`` across the line at offsets ``u`` (px, ``outer`` the plateau samples), averaged
    over ``n`` samples along it."""

    line: int
    cut: int
    profile: np.ndarray
    u: np.ndarray
    outer: np.ndarray
    n: int


def _levels(piece: _Piece) -> tuple[float, float]:
    """The levels (left, right) of a piece: the means of its outer plateau on either side."""
    prof, u, outer = piece.profile, piece.u, piece.outer
    return float(prof[outer & (u < 0)].mean()), float(prof[outer & (u > 0)].mean())


def _pieces(view: np.ndarray, segments: np.ndarray, bags: np.ndarray, lp: float,
            st: CheckerSettings) -> Iterator[_Piece]:
    """Every piece of every line (``segments`` (N, 4), ``bags`` its family, 0 not a line)
    cut at the crossings with the other family's lines whose middle is long enough and whose
    profile stays in ``view``, in order along each line (:func:`tile_edges`)."""
    keep = (bags == BAG_HORIZONTAL) | (bags == BAG_VERTICAL)
    seg, fam = segments[keep], bags[keep]
    reach = max(st.min_reach, st.reach * lp)
    u = np.arange(-reach, reach + 0.25, 0.5)
    outer = np.abs(u) >= reach - st.plateau
    src = view.astype(np.float32)
    for i in range(seg.shape[0]):
        p0, p1 = seg[i, :2], seg[i, 2:]
        length = float(np.hypot(*(p1 - p0)))
        if length <= 0.0:
            continue
        t = (p1 - p0) / length
        n = np.array([-t[1], t[0]])
        cuts = [0.0, length]
        for j in np.flatnonzero(fam != fam[i]).tolist():
            at = _crossing(p0, t, seg[j])
            if at is not None and 0.0 < at < length:
                cuts.append(at)
        cuts.sort()
        for k, (a, b) in enumerate(zip(cuts[:-1], cuts[1:], strict=True)):
            m = st.piece_margin * (b - a)
            if (b - a) - 2.0 * m < st.min_piece * lp:
                continue
            s = np.arange(a + m, b - m, 1.0)
            xs = p0[0] + s[:, None] * t[0] + u[None, :] * n[0]
            ys = p0[1] + s[:, None] * t[1] + u[None, :] * n[1]
            prof = cv2.remap(src, xs.astype(np.float32), ys.astype(np.float32),
                             cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                             borderValue=math.nan)
            if not np.isfinite(prof).all():
                continue  # the piece's profile leaves the view
            yield _Piece(i, k, prof.mean(axis=0), u, outer, int(s.size))


def _crossing(p0: np.ndarray, t: np.ndarray, other: np.ndarray) -> float | None:
    """Where (px along the line from ``p0``, direction ``t``) the line through ``other``'s
    endpoints crosses it; None when they are parallel."""
    q0, q1 = other[:2], other[2:]
    d = q1 - q0
    den = t[0] * d[1] - t[1] * d[0]
    if abs(den) < 1e-9:
        return None
    w = q0 - p0
    return float((w[0] * d[1] - w[1] * d[0]) / den)


def step_band(prof: np.ndarray, u: np.ndarray, outer: np.ndarray, noise: float,
              max_band: float, st: CheckerSettings) -> float | None:
    """A profile across a line read (levels at offsets ``u`` from the line, px, evenly
    spaced; ``outer`` the plateau samples; ``noise`` a sample's noise, gray levels) as a tile
    edge (:func:`tile_edges`): None when it is not one step between its two outer levels, or
    its reach is more than ``max_band`` px; else its reach (px): how far from the line read
    the step's edge (its steepest point) and any edge the other way (a band's far side) lie,
    the farther. The tile edge, or the centre of a band along it, lies between the two."""
    left = float(prof[outer & (u < 0)].mean())
    right = float(prof[outer & (u > 0)].mean())
    step = right - left
    if abs(step) < max(st.step_sigmas * noise, st.min_step):
        return None
    slope = np.gradient(prof, u) * math.copysign(1.0, step)
    steepest = float(slope.max())
    steep = slope >= st.single_edge * steepest
    if int(np.count_nonzero(steep[1:] & ~steep[:-1])) + int(steep[0]) != 1:
        return None
    # a central difference of two samples du apart each side: its noise is noise * sqrt(2) / 2du
    noise_slope = noise * math.sqrt(2.0) / (2.0 * float(u[1] - u[0]))
    back = -slope > max(st.band_edge * steepest, 3.0 * noise_slope)
    reach = abs(float(u[int(np.argmax(slope))]))
    if back.any():
        reach = max(reach, float(np.abs(u[back]).max()))
    return reach if reach <= max_band else None
