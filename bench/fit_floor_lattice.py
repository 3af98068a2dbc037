"""Fit the ideal square lattice to an image of a tiled floor and measure how far its lines depart.

    python bench/fit_floor_lattice.py fit IMAGE (--tiles N | --period P) [--grout dark|light|edge]
                                      [--wrap] [--mask MASK] [--pieces 16] [--affine fixed|free]
                                      [--meta META.json] [--tile-size L] [--view-period V]
    python bench/fit_floor_lattice.py compare FLOORS_DIR [--only ID,...]

``fit`` prints one entry of a real-floor ``floors.json`` (the schema ``bench/real_floors.py``
reads): the lattice fits per family, ``tile_to_photo_affine``, ``lattice_residual_rms_px`` and
``lattice_residual_max_px``; ``--meta`` is a JSON object of the descriptive fields (``id``,
``file``, ``kind``, ``notes``, ``source``, ``tile_size_m``, ``view_period_px``) copied into the
entry. ``compare`` refits every floor of ``FLOORS_DIR/floors.json`` from its recorded grout kind,
period, wrap and valid mask, and prints the recorded period, phases and largest departure next to
the refitted ones.

Conventions. Image pixels are (col, row), pixel centres at integer coordinates, rows downward.
Floor coordinates are in tiles (u, v), grout line centres at integer u and v, v upward:
``tile_to_photo_affine`` A (2 x 3) maps (u, v, 1) to (col, row). The *vertical* family is the
lines of constant u (near-constant column: col = phase + k * period + tilt * row); the
*horizontal* family the lines of constant v (row = phase + m * period + tilt * col, m = -v).
All lengths are image pixels; ``depth_gray`` is in grey levels (0..255). A family's
``residuals`` are ``[k, t, r, inlier]`` per piece: line index k (the line at phase + k * period),
the piece's centre t along the line, its departure r from the fitted line, and whether the fit
kept it. ``lattice_fit`` says which fit (fixed or free) the affine and ``lattice_residual_*``
come from.

Method.
1. A signal in which a line is a ridge: the grey level negated (``dark`` grout), the grey level
   (``light`` grout), or the grey level's derivative across the family, in magnitude, after a
   Gaussian blur of 1 px (``edge``: a checkerboard, whose lattice is the edges between tiles).
2. Coarse phase per family: the signal's mean along the family (the column or row profile), less
   its moving average over one period, sampled at phase + k * period; the phase (0.05 px grid)
   that maximises the mean. Without ``--tiles`` the period is searched as well (within 3 %).
3. Each line is cut into ``--pieces`` pieces along its length; a piece's profile across the line
   is the signal's mean over the piece, in a window of half-width ``max(3 w, P / 8)`` (w the grout
   width of the mean profile, at most P / 3) centred on the line's ideal position. Its centre is
   the midpoint of the two half-depth crossings on either side of the profile's peak (linear
   interpolation), the depth measured from the median of each side's outer fifth. A piece is
   not measured where a crossing is missing, where its depth is under a quarter of the family's
   median depth, or (``--mask``) where under 90 % of its window is floor.
4. Fits, by least squares on the piece centres, with outliers (departures beyond 4 robust
   standard deviations of the residuals, 1.4826 MAD, and beyond 1 px) dropped and refitted
   until none remains: *fixed*: phase per family, the period given by ``--tiles`` (size / N,
   a seamless texture) or one period common to both families, no tilt; *free*: phase, period
   and tilt per family. The residuals of the pieces from the fitted lattice are the floor's
   lattice departure: rms and max over the inliers, per family; the entry's
   ``lattice_residual_*`` are the larger of the two families' figures for the fit the affine
   is built from (``--affine``: fixed by default with ``--tiles``, free otherwise).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

FAMILIES = ("vertical", "horizontal")
GROUT = ("dark", "light", "edge")
OUTLIER_SIGMAS = 4.0
OUTLIER_FLOOR_PX = 1.0
MIN_DEPTH_FRACTION = 0.25
MIN_VALID_FRACTION = 0.9
PERIOD_SEARCH = 0.03


class FitError(Exception):
    """The image cannot be fitted (a one-line reason)."""


@dataclass
class Piece:
    """One piece of one line: line index k, position along the line t (px), measured centre
    across the line x (px), depth (grey levels), width (px)."""

    k: int
    t: float
    x: float
    depth: float
    width: float


def family_signal(gray: np.ndarray, family: str, grout: str) -> tuple[np.ndarray, np.ndarray]:
    """The signal in which the family's lines are ridges along columns, and the grey image in the
    same orientation (the horizontal family is transposed: its lines become columns)."""
    g = gray if family == "vertical" else gray.T
    g = np.ascontiguousarray(g)
    if grout == "dark":
        return -g, g
    if grout == "light":
        return g.copy(), g
    blurred = cv2.GaussianBlur(g, (0, 0), 1.0)
    return np.abs(np.gradient(blurred, axis=1)), g


def masked_profile(sig: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """The mean of each column over the rows where ``mask`` is set (all rows without a mask)."""
    if mask is None:
        return sig.mean(axis=0)
    w = mask.astype(np.float64)
    n = w.sum(axis=0)
    out = np.full(sig.shape[1], np.nan)
    ok = n > 0
    out[ok] = (sig * w).sum(axis=0)[ok] / n[ok]
    return out


def coarse_phase(profile: np.ndarray, period: float, search_period: bool,
                 wrap: bool) -> tuple[float, float]:
    """The phase (px, in [0, period)) and period maximising the detrended profile's mean at
    phase + k * period."""
    p = profile.copy()
    good = np.isfinite(p)
    if good.sum() < period:
        raise FitError("too little floor in the image for one period")
    p[~good] = np.nanmean(p)
    box = max(3, int(round(period)) | 1)
    padded = np.pad(p, box // 2, mode="wrap" if wrap else "reflect")
    trend = np.convolve(padded, np.full(box, 1.0 / box), mode="valid")
    d = p - trend
    d[~good] = 0.0
    periods = (np.linspace(period * (1 - PERIOD_SEARCH), period * (1 + PERIOD_SEARCH), 121)
               if search_period else np.array([period]))
    n = p.size
    best = (-np.inf, 0.0, period)
    for per in periods:
        phases = np.arange(0.0, per, 0.05)
        ks = np.arange(0, int(n / per) + 1)
        pos = phases[:, None] + per * ks[None, :]
        inside = pos <= n - 1
        vals = np.interp(np.where(inside, pos, 0.0), np.arange(n), d)
        score = (vals * inside).sum(axis=1) / np.maximum(inside.sum(axis=1), 1)
        i = int(np.argmax(score))
        if score[i] > best[0]:
            best = (float(score[i]), float(phases[i]), float(per))
    return best[1], best[2]


def crossing(p: np.ndarray, i: int, level: float, step: int) -> float | None:
    """Where ``p`` first falls below ``level`` walking from index ``i`` by ``step`` (linear
    interpolation, fractional index), or None."""
    j = i
    while 0 <= j + step < p.size:
        if p[j + step] < level:
            a, b = float(p[j]), float(p[j + step])
            return j + step * (a - level) / (a - b) if a > b else None
        j += step
    return None


def measure_piece(prof: np.ndarray, gprof: np.ndarray, c0: int, centre: float,
                  grout: str) -> tuple[float, float, float] | None:
    """A piece's line centre (px), depth (grey levels) and width (px) from its profile across
    the line (``prof``: the signal, ``gprof``: the grey level; column ``c0`` first), or None."""
    n = prof.size
    q = max(2, n // 5)
    lo = int(math.floor(centre - c0 - n / 4))
    hi = int(math.ceil(centre - c0 + n / 4))
    lo, hi = max(lo, 1), min(hi, n - 2)
    if hi <= lo:
        return None
    i = lo + int(np.argmax(prof[lo:hi + 1]))
    base_l = float(np.median(prof[:q]))
    base_r = float(np.median(prof[-q:]))
    if prof[i] <= max(base_l, base_r):
        return None
    xl = crossing(prof, i, (prof[i] + base_l) / 2.0, -1)
    xr = crossing(prof, i, (prof[i] + base_r) / 2.0, +1)
    if xl is None or xr is None:
        return None
    if grout == "edge":
        depth = abs(float(np.median(gprof[:q])) - float(np.median(gprof[-q:])))
    else:
        depth = abs(float(prof[i]) - (base_l + base_r) / 2.0)
    return c0 + (xl + xr) / 2.0, depth, xr - xl


def measure_family(sig: np.ndarray, g: np.ndarray, mask: np.ndarray | None, phase: float,
                   period: float, halfwidth: float, pieces: int, grout: str) -> list[Piece]:
    """The pieces of every line of the family whose window lies inside the image."""
    h, w = sig.shape
    out: list[Piece] = []
    k_lo = int(math.ceil((halfwidth - phase) / period))
    k_hi = int(math.floor((w - 1 - halfwidth - phase) / period))
    edges = np.linspace(0, h, pieces + 1).round().astype(int)
    for k in range(k_lo, k_hi + 1):
        x0 = phase + k * period
        c0 = int(math.floor(x0 - halfwidth))
        c1 = int(math.ceil(x0 + halfwidth))
        if c0 < 0 or c1 > w - 1:
            continue
        for j in range(pieces):
            r0, r1 = edges[j], edges[j + 1]
            block = sig[r0:r1, c0:c1 + 1]
            gblock = g[r0:r1, c0:c1 + 1]
            if mask is not None:
                m = mask[r0:r1, c0:c1 + 1]
                if m.mean() < MIN_VALID_FRACTION:
                    continue
                rows = m.all(axis=1)
                if not rows.any():
                    continue
                block, gblock = block[rows], gblock[rows]
            got = measure_piece(block.mean(axis=0), gblock.mean(axis=0), c0, x0, grout)
            if got is not None:
                out.append(Piece(k, (r0 + r1 - 1) / 2.0, got[0], got[1], got[2]))
    if out:
        med = float(np.median([p.depth for p in out]))
        out = [p for p in out if p.depth >= MIN_DEPTH_FRACTION * med]
    return out


def robust_fit(design: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares ``design @ beta = x`` dropping outliers (beyond 4 robust sigmas and 1 px)
    until none remains: (beta, inlier mask)."""
    inl = np.ones(x.size, bool)
    for _ in range(20):
        beta, *_ = np.linalg.lstsq(design[inl], x[inl], rcond=None)
        r = x - design @ beta
        med = float(np.median(r[inl]))
        sigma = 1.4826 * float(np.median(np.abs(r[inl] - med)))
        new = np.abs(r - med) <= max(OUTLIER_SIGMAS * sigma, OUTLIER_FLOOR_PX)
        if np.array_equal(new, inl) or new.sum() < design.shape[1] + 1:
            break
        inl = new
    beta, *_ = np.linalg.lstsq(design[inl], x[inl], rcond=None)
    return beta, inl


def family_report(pcs: list[Piece], phase: float, period: float, tilt: float,
                  inl: np.ndarray, residuals: bool) -> dict:
    """The floors.json record of one family's fit."""
    k = np.array([p.k for p in pcs], float)
    t = np.array([p.t for p in pcs])
    x = np.array([p.x for p in pcs])
    r = x - (phase + k * period + tilt * t)
    ri = r[inl]
    offsets = [abs(float(ri[k[inl] == kk].mean())) for kk in np.unique(k[inl])]
    rep: dict = {
        "phase_px": float(phase), "period_px": float(period), "tilt": float(tilt),
        "points": int(inl.sum()), "outliers": int((~inl).sum()),
        "rms_px": float(np.sqrt(np.mean(ri ** 2))), "max_px": float(np.abs(ri).max()),
        "line_offset_max_px": float(max(offsets)),
        "grout_width_px": float(np.median([p.width for p in pcs])),
        "depth_gray": float(np.median([p.depth for p in pcs])),
    }
    if residuals:
        rep["residuals"] = [[int(p.k), float(p.t), round(float(rr), 3), bool(ok)]
                            for p, rr, ok in zip(pcs, r, inl, strict=True)]
    return rep


def fit_lattice(bgr: np.ndarray, period: float, seamless: bool, grout: str, wrap: bool,
                mask: np.ndarray | None, pieces: int) -> dict:
    """Both families' fixed and free fits (see the module docstring)."""
    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float64)
    sigs, coarse, measured = {}, {}, {}
    for fam in FAMILIES:
        sig, g = family_signal(gray, fam, grout)
        m = None if mask is None else (mask if fam == "vertical" else mask.T)
        sigs[fam] = (sig, g, m)
        coarse[fam] = coarse_phase(masked_profile(sig, m), period, not seamless, wrap)
    per0 = period if seamless else float(np.mean([coarse[f][1] for f in FAMILIES]))
    for fam in FAMILIES:
        sig, g, m = sigs[fam]
        phase = coarse[fam][0]
        halfwidth = per0 / 8.0
        for _ in range(2):
            pcs = measure_family(sig, g, m, phase, per0, halfwidth, pieces, grout)
            if len(pcs) < 4:
                raise FitError(f"{fam} lines: too few pieces of grout found ({len(pcs)}): "
                               "check --grout and the period")
            width = float(np.median([p.width for p in pcs]))
            halfwidth = float(np.clip(3.0 * width, per0 / 8.0, per0 / 3.0))
            x = np.array([p.x - p.k * per0 for p in pcs])
            phase = float(np.median(x))
        measured[fam] = measure_family(sig, g, m, phase, per0, halfwidth, pieces, grout)
    # fixed: a phase per family, one period (given, or common to both families), no tilt
    rows = []
    for i, fam in enumerate(FAMILIES):
        for p in measured[fam]:
            rows.append([1.0 - i, float(i), p.k, p.x])
    arr = np.array(rows)
    if seamless:
        design = arr[:, :2]
        target = arr[:, 3] - arr[:, 2] * period
        beta, inl = robust_fit(design, target)
        phases, per_fixed = beta, period
    else:
        beta, inl = robust_fit(arr[:, :3], arr[:, 3])
        phases, per_fixed = beta[:2], float(beta[2])
    n_v = len(measured["vertical"])
    fixed = {fam: family_report(measured[fam], float(phases[i]), per_fixed, 0.0,
                                inl[:n_v] if i == 0 else inl[n_v:], True)
             for i, fam in enumerate(FAMILIES)}
    free = {}
    for fam in FAMILIES:
        pcs = measured[fam]
        design = np.array([[1.0, p.k, p.t] for p in pcs])
        b, fi = robust_fit(design, np.array([p.x for p in pcs]))
        free[fam] = family_report(pcs, float(b[0]), float(b[1]), float(b[2]), fi, False)
    return {"lattice_fixed": fixed, "lattice_free": free}


def affine_from(fits: dict) -> list[list[float]]:
    """The tile-to-pixel affine of a fit: (u, v) is where vertical line u (col = p_v + u P_v +
    a row) meets horizontal line -v (row = p_h - v P_h + b col)."""
    fv, fh = fits["vertical"], fits["horizontal"]
    a, b = fv["tilt"], fh["tilt"]
    minv = np.linalg.inv(np.array([[1.0, -a], [-b, 1.0]]))
    lin = minv @ np.array([[fv["period_px"], 0.0], [0.0, -fh["period_px"]]])
    off = minv @ np.array([fv["phase_px"], fh["phase_px"]])
    return [[float(lin[0, 0]), float(lin[0, 1]), float(off[0])],
            [float(lin[1, 0]), float(lin[1, 1]), float(off[1])]]


def read_image(path: Path) -> np.ndarray:
    if not path.is_file():
        raise FitError(f"no image file {path}")
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise FitError(f"cannot read image {path}")
    return bgr


def read_mask(path: Path | None, shape: tuple[int, int]) -> np.ndarray | None:
    if path is None:
        return None
    if not path.is_file():
        raise FitError(f"no mask file {path}")
    m = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if m is None:
        raise FitError(f"cannot read mask {path}")
    if m.shape != shape:
        raise FitError(f"mask {path} is {m.shape[1]}x{m.shape[0]}, the image "
                       f"{shape[1]}x{shape[0]}")
    return m > 127


def entry(image: Path, bgr: np.ndarray, tiles: int | None, period: float | None, grout: str,
          wrap: bool, mask_path: Path | None, pieces: int, affine: str | None,
          meta: dict) -> dict:
    """One floors.json entry for ``image``."""
    h, w = bgr.shape[:2]
    if tiles is not None:
        if tiles <= 0:
            raise FitError("--tiles must be positive")
        if h != w:
            raise FitError(f"--tiles needs a square seamless image; {image} is {w}x{h}")
        period = w / tiles
    if period is None or period <= 4:
        raise FitError("give --tiles N or --period P (P > 4 px)")
    mask = read_mask(mask_path, (h, w))
    fits = fit_lattice(bgr, period, tiles is not None, grout, wrap, mask, pieces)
    use = affine or ("fixed" if tiles is not None else "free")
    chosen = fits["lattice_fixed" if use == "fixed" else "lattice_free"]
    out: dict = {
        "id": meta.get("id", image.stem), "file": meta.get("file", image.name),
        "kind": meta.get("kind", ""), "notes": meta.get("notes", ""),
        "source": meta.get("source", {}),
        "size_px": [w, h], "seamless_tiles_per_side": tiles or 0,
        "period_px": float(chosen["vertical"]["period_px"]), "grout": grout, "wrap": wrap,
        "valid_mask": mask_path.name if mask_path else None, "rectification": None,
    }
    out.update(fits)
    out["tile_to_photo_affine"] = affine_from(chosen)
    out["tile_size_m"] = meta.get("tile_size_m", 0.3)
    out["view_period_px"] = meta.get("view_period_px", 107.0)
    out["lattice_residual_rms_px"] = max(chosen[f]["rms_px"] for f in FAMILIES)
    out["lattice_residual_max_px"] = max(chosen[f]["max_px"] for f in FAMILIES)
    out["lattice_fit"] = use
    return out


def wrapped(d: float, period: float) -> float:
    return (d + period / 2.0) % period - period / 2.0


def compare(folder: Path, only: set[str] | None) -> None:
    """Refit every floor of ``folder/floors.json`` and print recorded vs refitted figures."""
    index = folder / "floors.json"
    if not index.is_file():
        raise FitError(f"{index} not found")
    doc = json.loads(index.read_text(encoding="utf-8"))
    print("| floor | grout | period px (recorded / refit) "
          "| phase v, h px (recorded; refit - recorded) "
          "| departure rms px (recorded / refit) | max px (recorded / refit) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for f in doc["floors"]:
        if only and f["id"] not in only:
            continue
        bgr = read_image(folder / f["file"])
        tiles = f.get("seamless_tiles_per_side") or None
        rec_fixed = f.get("lattice_fixed") or {}
        ts = {r[1] for fam in rec_fixed.values() for r in fam.get("residuals", [])}
        pieces = len(ts) if tiles and ts else 16
        mask = folder / f["valid_mask"] if f.get("valid_mask") else None
        got = entry(folder / f["file"], bgr, tiles, None if tiles else float(f["period_px"]),
                    f["grout"], bool(f["wrap"]), mask, pieces, "fixed", {})
        a_rec, a_fit = f["tile_to_photo_affine"], got["tile_to_photo_affine"]
        per_rec, per_fit = float(a_rec[0][0]), float(a_fit[0][0])
        dv = wrapped(a_fit[0][2] - a_rec[0][2], per_rec)
        dh = wrapped(a_fit[1][2] - a_rec[1][2], per_rec)
        print(f"| {f['id']} | {f['grout']} | {per_rec:.2f} / {per_fit:.2f} "
              f"| {a_rec[0][2] % per_rec:.2f}, {a_rec[1][2] % per_rec:.2f}; "
              f"{dv:+.2f}, {dh:+.2f} "
              f"| {f['lattice_residual_rms_px']:.2f} / {got['lattice_residual_rms_px']:.2f} "
              f"| {f['lattice_residual_max_px']:.2f} / {got['lattice_residual_max_px']:.2f} |",
              flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("fit", help="fit one image and print its floors.json entry")
    f.add_argument("image", type=Path)
    g = f.add_mutually_exclusive_group(required=True)
    g.add_argument("--tiles", type=int, help="tiles per side of a square seamless texture")
    g.add_argument("--period", type=float, help="approximate tile period (px)")
    f.add_argument("--grout", choices=GROUT, default="dark")
    f.add_argument("--wrap", action="store_true", help="the image is a seamless texture")
    f.add_argument("--mask", type=Path, help="valid-pixel mask (white = floor)")
    f.add_argument("--pieces", type=int, default=16, help="pieces per line (default 16)")
    f.add_argument("--affine", choices=("fixed", "free"),
                   help="the fit the affine is built from (default: fixed with --tiles)")
    f.add_argument("--meta", type=Path, help="JSON object of descriptive fields to copy")
    f.add_argument("--tile-size", type=float, help="tile size to declare (m)")
    f.add_argument("--view-period", type=float, help="view pixels per tile")
    c = sub.add_parser("compare", help="refit the floors of FLOORS_DIR/floors.json")
    c.add_argument("folder", type=Path)
    c.add_argument("--only", help="comma-separated floor ids")
    args = ap.parse_args(argv)
    try:
        if args.cmd == "compare":
            compare(args.folder, set(args.only.split(",")) if args.only else None)
            return 0
        if args.pieces < 2:
            raise FitError("--pieces must be at least 2")
        meta: dict = {}
        if args.meta is not None:
            try:
                meta = json.loads(args.meta.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise FitError(f"cannot read --meta {args.meta}: {exc}") from exc
            if not isinstance(meta, dict):
                raise FitError(f"--meta {args.meta} is not a JSON object")
        if args.tile_size is not None:
            meta["tile_size_m"] = args.tile_size
        if args.view_period is not None:
            meta["view_period_px"] = args.view_period
        out = entry(args.image, read_image(args.image), args.tiles, args.period, args.grout,
                    args.wrap, args.mask, args.pieces, args.affine, meta)
        print(json.dumps(out, indent=1))
    except FitError as exc:
        print(f"fit_floor_lattice: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
