"""The robust extractor's shortcuts change nothing: reusing one heading's warp and profiles when
a wide grout band asks for a wider window, and measuring in parts only the dips that can be
kept as lines, give the same result, field for field, as the full computation; the compiled
part measurement and projection (:mod:`tileviz.vision.robust.kernel`,
:mod:`tileviz.vision.robust.projection_kernel`) give numpy's bits."""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests import numpy_kernels as nk
from tests import numpy_profiles as npf
from tileviz.config import FLOOR_STYLES, VisionConfig, floor_style, preset
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision import extract
from tileviz.vision.robust import (
    DEFAULT_SETTINGS,
    dip_kernel,
    fit_kernel,
    heading_kernel,
    kernel,
    lattice,
    lattice_kernel,
    profiles,
    projection_kernel,
    readings,
)

ROBUST = VisionConfig(extractor="robust")


def _same(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)  # type: ignore[union-attr]
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True
    return a == b


@pytest.mark.parametrize("preset_name", ["default", "seed"])
@pytest.mark.parametrize("style", list(FLOOR_STYLES))
def test_the_shortcuts_give_the_full_computation(
    monkeypatch: pytest.MonkeyPatch, preset_name: str, style: str
) -> None:
    cfg = preset(preset_name)
    floor = floor_style(cfg.floor, style)
    r = FloorRenderer(floor, cfg.camera)
    rng = np.random.default_rng(5)
    images = [r.render(Pose(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4)), rng)
              for _ in range(3)]

    def run_all() -> list:
        return [extract(img, camera=cfg.camera, tile_size=floor.tile_size, vision=ROBUST,
                        floor=floor.model) for img in images]

    fast = run_all()
    full_measure = profiles.measure

    def measure_fully(run: object, y3: float, attempt: int = 1) -> list:
        return full_measure(run, y3, attempt, reuse=False, every=True)  # type: ignore[arg-type]

    monkeypatch.setattr(readings, "measure", measure_fully)
    full = run_all()
    assert any(res.accepted for res in fast)
    for a, b in zip(fast, full, strict=True):
        for f in fields(a):
            if f.name != "timings":
                assert _same(getattr(a, f.name), getattr(b, f.name)), (style, f.name)


def _floor_views(n: int) -> list[tuple[np.ndarray, object, float]]:
    """``n`` clean views of every floor family of ``tileviz/testing/floorgen.py``."""
    from tileviz.config import CameraConfig
    from tileviz.testing import floorgen

    out = []
    for fam in floorgen.FAMILIES:
        for i in range(n):
            rng = np.random.default_rng([i, 31, len(fam)])
            spec = floorgen.draw_floor(fam, rng)
            img = floorgen.render(spec, *floorgen.draw_view(rng), rng)
            cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height,
                               offset=(0.0, 0.0))
            out.append((img, cam, spec.tile_size))
    return out


def _bits(a: np.ndarray) -> bytes:
    """The array's bytes, every NaN as numpy's own (0 / 0 and math.nan differ in sign)."""
    a = np.array(a, np.float64)
    a[np.isnan(a)] = np.nan
    return a.tobytes()


PROJECTION_KERNELS = ("grout_score", "profile_dips", "view_spans", "profile_arrays")
DIP_KERNELS = ("dip_rows", "part_summary", "part_layout", "dip_recentre")


def test_the_compiled_part_measurement_is_the_numpy_one_bit_for_bit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Every part profile the extractor measures on every floor family gives the same bits
    (the profile from the integral image; its width, rise, contrast, centroid, midpoints,
    standard error) from the compiled kernels as from the numpy computation, so do every
    family's light-grout score, every profile's darkness, noise and dips, every dip's
    measurement on its whole profile, where its parts lie and whether it is moved onto its
    centre, and the profiles and in-view spans of every warp (the numpy references:
    ``tests/numpy_profiles.py``)."""
    views = _floor_views(2)
    names = ("part_rows", "part_profiles", "grout_score", "profile_dips", "dip_rows",
             "view_spans", "profile_arrays", "part_summary", "part_layout", "dip_recentre")
    home = {name: projection_kernel if name in PROJECTION_KERNELS
            else dip_kernel if name in DIP_KERNELS else kernel for name in names}
    compiled = {name: getattr(home[name], name) for name in names}
    seen: dict[str, list[tuple]] = {name: [] for name in names}

    def recorder(name: str) -> object:
        def record(*args: object) -> object:
            seen[name].append(args)
            return compiled[name](*args)
        return record

    for name in names:
        monkeypatch.setattr(home[name], name, recorder(name))
    fast = [extract(img, camera=cam, tile_size=ts, vision=ROBUST) for img, cam, ts in views]
    assert sum(res.accepted for res in fast) >= len(views) // 2
    assert sum(int(args[0].shape[0]) for args in seen["part_rows"]) > 100
    for args in seen["part_rows"]:
        for a, b in zip(compiled["part_rows"](*args), npf.part_rows_numpy(*args),
                        strict=True):
            assert _bits(a) == _bits(b)
    assert len(seen["part_profiles"]) == len(seen["part_rows"])
    for flat, stride, *rest in seen["part_profiles"]:
        integ = flat.reshape(-1, stride)
        assert _bits(compiled["part_profiles"](flat, stride, *rest)) == _bits(
            npf.part_profiles_numpy(integ, *rest))
    assert sum(compiled["grout_score"](*args)[0] for args in seen["grout_score"]) >= len(views)
    for args in seen["grout_score"]:
        used, value = compiled["grout_score"](*args)
        used_np, value_np = npf.grout_score_numpy(*args)
        assert used == used_np and (not used or value.hex() == value_np.hex())
    assert len(seen["profile_dips"]) >= len(views)
    for args in seen["profile_dips"]:
        for a, b in zip(compiled["profile_dips"](*args), npf.profile_dips_numpy(*args),
                        strict=True):
            assert a.dtype == b.dtype and _bits(a) == _bits(b)
    assert sum(int(args[4].size) for args in seen["dip_rows"]) > 100
    for args in seen["dip_rows"]:
        for a, b in zip(compiled["dip_rows"](*args), npf.dip_rows_numpy(*args),
                        strict=True):
            assert a.shape == b.shape and _bits(a) == _bits(b)
    assert len(seen["part_summary"]) == len(seen["part_rows"])
    for args in seen["part_summary"]:
        for a, b in zip(compiled["part_summary"](*args), npf.part_summary_numpy(*args),
                        strict=True):
            assert a.shape == b.shape and _bits(a) == _bits(b)
    assert len(seen["part_layout"]) == len(seen["part_rows"])
    for args in seen["part_layout"]:
        for a, b in zip(compiled["part_layout"](*args), npf.part_layout_numpy(*args),
                        strict=True):
            assert a.dtype == b.dtype and a.shape == b.shape and _bits(a) == _bits(b)
    assert len(seen["dip_recentre"]) >= len(views)
    assert any(compiled["dip_recentre"](*args)[1] for args in seen["dip_recentre"])
    for args in seen["dip_recentre"]:
        (peak, moved), (peak_np, moved_np) = (compiled["dip_recentre"](*args),
                                              npf.dip_recentre_numpy(*args))
        assert moved == moved_np and np.array_equal(peak, peak_np)
    assert len(seen["profile_arrays"]) >= len(views)
    for args in seen["profile_arrays"]:
        for a, b in zip(compiled["profile_arrays"](*args), npf.profile_arrays_numpy(*args),
                        strict=True):
            assert a.shape == b.shape and _bits(a) == _bits(b)
    assert len(seen["view_spans"]) >= 2 * len(views)
    for n, off, c, s, w, h, along in seen["view_spans"]:
        ref = npf.view_spans(w, h, np.arange(n) - off, c, s, along_rows=along)
        for a, b in zip(compiled["view_spans"](n, off, c, s, w, h, along), ref, strict=True):
            assert _bits(a) == _bits(b)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), r=st.sampled_from([12, 20, 37, 69]),
       nan_share=st.sampled_from([0.0, 0.05, 0.3]))
def test_the_compiled_part_measurement_matches_numpy_on_any_profile(
    seed: int, r: int, nan_share: float
) -> None:
    """Random dips (any depth, width, offset, plateau step, noise, missing samples, windows
    up to the widest): the compiled kernel and numpy agree bit for bit."""
    rng = np.random.default_rng(seed)
    rows = 12
    jf = np.arange(-r, r + 1, dtype=np.float64)
    cj = rng.uniform(-4.0, 4.0, rows)
    hj = rng.uniform(1.5, 0.6 * r, rows)
    wid = rng.uniform(0.5, 8.0, rows)[:, None]
    step = rng.uniform(-40.0, 40.0, rows)[:, None]
    pp = (120.0 + step * (jf[None, :] > cj[:, None])
          - rng.uniform(0.0, 80.0, rows)[:, None]
          * np.exp(-0.5 * ((jf[None, :] - cj[:, None]) / wid) ** 2)
          + rng.normal(0.0, rng.uniform(0.0, 6.0), (rows, jf.size)))
    pp[rng.random(pp.shape) < nan_share] = np.nan
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        fast = kernel.part_rows(pp, jf, cj, hj, r)
        ref = npf.part_rows_numpy(pp, jf, cj, hj, r)
    for a, b in zip(fast, ref, strict=True):
        assert _bits(a) == _bits(b)


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 120),
       closing=st.sampled_from([17, 35, 61]))
def test_the_compiled_light_grout_score_matches_numpy_on_any_profile(
    seed: int, n: int, closing: int
) -> None:
    """Random family sums and row lengths (some rows too short to count): the compiled
    light-grout term and numpy / OpenCV's agree bit for bit."""
    rng = np.random.default_rng(seed)
    sums = rng.normal(0.0, 3000.0, n)
    length = rng.uniform(0.0, 300.0, n)
    used, value = projection_kernel.grout_score(sums, length, closing, 8.0, 0.15, 8)
    used_np, value_np = npf.grout_score_numpy(sums, length, closing, 8.0, 0.15, 8)
    assert used == used_np
    assert not used or value.hex() == value_np.hex()


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), h=st.integers(1, 60), w=st.integers(1, 80),
       angle=st.floats(-1.0, 1.0), zero_share=st.sampled_from([0.0, 0.5, 1.0]))
def test_the_compiled_heading_votes_match_numpy_on_any_gradients(
    seed: int, h: int, w: int, angle: float, zero_share: float
) -> None:
    """Random gradients (a dominant direction plus noise, any size, up to all zero): the
    compiled first heading and numpy's agree bit for bit (the heading, the share near the
    peak, and "no lines" when every gradient is zero), and the heading is the dominant
    direction's when the gradients are noise-free."""
    from tileviz.vision.robust import heading

    rng = np.random.default_rng(seed)
    mag = rng.uniform(0.0, 4000.0, (h, w))
    phi = angle + np.where(rng.random((h, w)) < 0.3, rng.uniform(-np.pi, np.pi, (h, w)), 0.0)
    mag[rng.random((h, w)) < zero_share] = 0.0
    dx = np.rint(mag * np.cos(phi)).astype(np.int16)
    dy = np.rint(mag * np.sin(phi)).astype(np.int16)
    hst = DEFAULT_SETTINGS.heading
    ref = nk.heading_votes_numpy(dx, dy, 0.2, hst.bins, hst.near, hst.min_voters)
    q = heading_kernel.heading_magnitudes(dx, dy)
    thr = heading.voters(q, 0.2, hst.min_voters)
    assert (thr > 0) == ref[0]
    if thr > 0:
        y0, share = heading_kernel.heading_votes(dx, dy, q, thr, hst.bins, hst.near)
        assert y0.hex() == ref[1].hex() and share.hex() == ref[2].hex()
    clean_dx = np.full((40, 40), int(round(3000 * np.cos(angle))), np.int16)
    clean_dy = np.full((40, 40), int(round(3000 * np.sin(angle))), np.int16)
    found, y_clean, _ = nk.heading_votes_numpy(clean_dx, clean_dy, 0.2, hst.bins, hst.near,
                                               hst.min_voters)
    if found:
        # gradient directions are normal to the lines; y3 is modulo pi / 2
        want = np.arctan2(float(clean_dy[0, 0]), float(clean_dx[0, 0]))
        assert abs(np.remainder(y_clean - want + np.pi / 4, np.pi / 2) - np.pi / 4) < 1e-9


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 3000), bits=st.integers(1, 62),
       zero_share=st.sampled_from([0.0, 0.5, 0.95]), share=st.floats(0.0, 1.0))
def test_the_compiled_voters_threshold_is_numpys_partition(
    seed: int, n: int, bits: int, zero_share: float, share: float
) -> None:
    """The first heading's voters: the compiled k-th largest squared magnitude is numpy's
    partition's, on any values (a few bits up to 62, mostly zero or not) and any share."""
    rng = np.random.default_rng(seed)
    q = rng.integers(0, 2**bits, n).astype(np.int64)
    q[rng.random(n) < zero_share] = 0
    k = min(max(20, int(share * n)), n)
    assert heading_kernel.kth_largest(q, k) == int(np.partition(q, n - k)[n - k])


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), rows=st.integers(1, 20), cols=st.integers(1, 20),
       missing=st.floats(0.0, 0.9), fractional=st.booleans())
def test_the_foreign_edge_medians_are_numpys(
    seed: int, rows: int, cols: int, missing: float, fractional: bool
) -> None:
    """The foreign-edge search's medians (the grout's levels, median of 3 neighbours; the
    levels beside an edge, the median of each row's seen samples) are numpy's bit for bit, on
    gray levels with and without fractions and any share of unseen (NaN) samples."""
    from tileviz.vision.robust import grout_levels

    rng = np.random.default_rng(seed)
    v = rng.integers(0, 256, (rows, cols)).astype(np.float64)
    if fractional:
        v += rng.random((rows, cols))
    v[rng.random((rows, cols)) < missing] = np.nan
    count = np.isfinite(v).sum(axis=1)
    seen = count >= 1
    if seen.any():
        want = np.nanmedian(v[seen], axis=1)
        assert want.tobytes() == grout_levels.row_medians(v[seen], count[seen]).tobytes()
    line = v[0][np.isfinite(v[0])]
    if line.size >= 3:
        want3 = np.median(np.stack([line[:-2], line[1:-1], line[2:]]), axis=0)
        assert want3.tobytes() == grout_levels.neighbour_medians(line).tobytes()


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), y3=st.one_of(st.just(0.0), st.floats(-0.79, 0.79)),
       size=st.sampled_from([(320, 240), (640, 480), (100, 300)]), lp=st.floats(15.0, 400.0),
       drop=st.integers(0, 3), k=st.integers(0, 1))
def test_the_compiled_missing_line_check_matches_numpy_on_any_lattice(
    seed: int, y3: float, size: tuple[int, int], lp: float, drop: int, k: int
) -> None:
    """Random lattices (any heading, including one along the pixel axes, any period, lines
    found near the predicted ones or not, dips of both families here and there): the compiled
    missing-line check decides as numpy's does; with every predicted line found it finds none
    missing."""
    rng = np.random.default_rng(seed)
    w, h = size
    n = ((np.sin(y3), -np.cos(y3)), (-np.cos(y3), -np.sin(y3)))[k]
    ref = float(rng.uniform(-lp, lp))
    reach = 0.5 * float(np.hypot(w, h))
    every = ref + np.arange(-int(reach / lp) - 2, int(reach / lp) + 3) * lp
    found = every + rng.normal(0.0, 0.1 * lp, every.size)
    found = np.delete(found, rng.permutation(found.size)[:drop])
    peak = rng.integers(0, 800, int(rng.integers(0, 12))).astype(np.intp)
    fam = rng.integers(0, 2, peak.size).astype(np.intp)
    args = (float(n[0]), float(n[1]), float(np.hypot(-n[1], n[0])), ref, lp, reach,
            int(rng.integers(5, 40)), w, h, float(rng.uniform(0.2, 0.9)))
    tail = (peak, fam, k, int(rng.integers(0, 40)), float(rng.uniform(0.0, 400.0)),
            float(rng.uniform(1.0, 10.0)), 0.25)
    for got in (found, every, np.zeros(0)):
        assert lattice_kernel.missing_line(*args, got, *tail) == nk.missing_line_numpy(
            *args, got, *tail)
    assert not nk.missing_line_numpy(*args, every, *tail)


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), m=st.integers(1, 20), unmeasured=st.floats(0.0, 0.6),
       tilt=st.floats(-0.05, 0.05), explained=st.one_of(st.just(0.0), st.floats(0.0, 1.0)))
def test_the_compiled_fit_matches_numpy_on_any_parts(
    seed: int, m: int, unmeasured: float, tilt: float, explained: float
) -> None:
    """Random lines of four parts (any number of each family, some parts not measured, up to
    whole lines): the compiled common fit gives numpy's bits (tilt, positions, variances,
    influences, the parts' bounds, straightness, heading error, tilt gap), whatever share of
    the residuals the floor's tolerance explains; parts drawn on straight lines with one
    common tilt give that tilt back."""
    rng = np.random.default_rng(seed)
    n0 = int(rng.integers(0, m + 1))
    wp = np.where(rng.random((m, 4)) < unmeasured, 0.0, rng.integers(3, 200, (m, 4)) * 1.0)
    tp = rng.normal(0.0, 80.0, (m, 4))
    sign = np.where(np.arange(m) < n0, 1.0, -1.0)[:, None]
    straight = rng.uniform(-300.0, 300.0, (m, 1)) + sign * tilt * tp
    pp = np.where(wp > 0, straight + rng.normal(0.0, 0.3, (m, 4)), np.nan)
    sig = np.where(wp > 0, rng.random((m, 4)), 0.0)
    spr = np.where(wp > 0, rng.random((m, 4)), 0.0)
    args = (wp, tp, pp, sig, spr, n0, 4.0, 4.5, 2.0, 0.25, explained)
    with np.errstate(invalid="ignore", divide="ignore"):
        ref = nk.fit_arrays_numpy(*args)
    got = fit_kernel.fit_arrays(*args)
    assert all(_bits(a) == _bits(b) for a, b in zip(got, ref, strict=True))
    # residuals the floor's tolerance explains whole leave the prior's scatter alone
    nobs, m_fit = int((wp > 0).sum()), int(((wp > 0).sum(axis=1) > 0).sum())
    dall = float(sum((w * (t - np.dot(w, t) / w.sum()) ** 2).sum()
                     for w, t in ((wp[i][wp[i] > 0], tp[i][wp[i] > 0]) for i in range(m))
                     if w.size))
    if m_fit == m and dall > 1e-6:
        prior_only = math.sqrt(4.5 / (max(nobs - (m + 1), 0) + 2.0) / dall)
        heading_se = fit_kernel.fit_arrays(*args[:-1], 1e9)[7]
        assert heading_se == pytest.approx(prior_only, rel=1e-9)
    exact = np.where(wp > 0, straight, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        eps = nk.fit_arrays_numpy(wp, tp, exact, sig, spr, n0, 4.0, 4.5, 2.0, 0.25, 0.0)[0]
    if ((wp > 0).sum(axis=1) >= 2).all():  # every line measured in two parts or more
        assert abs(eps - tilt) < 1e-6


@settings(max_examples=100, deadline=None)
@given(y3=st.one_of(st.just(0.0), st.just(np.pi / 2), st.floats(-3.2, 3.2)),
       offsets=st.lists(st.floats(-500.0, 500.0), max_size=12),
       size=st.sampled_from([(320, 240), (64, 480), (7, 5)]), k=st.integers(0, 1))
def test_the_compiled_clipping_matches_clip_line(
    y3: float, offsets: list[float], size: tuple[int, int], k: int
) -> None:
    """Any heading (along the pixel axes too) and offsets within and beyond the view: the
    compiled clipping gives clip_line's endpoints bit for bit, and misses where it does."""
    n = ((np.sin(y3), -np.cos(y3)), (-np.cos(y3), -np.sin(y3)))[k]
    n = (float(n[0]), float(n[1]))
    out, hit = lattice_kernel.clip_lines(n[0], n[1], np.array(offsets, np.float64), *size)
    for i, s in enumerate(offsets):
        seg = lattice.clip_line(n, s, *size)
        assert hit[i] == (seg is not None)
        if seg is not None:
            assert _bits(out[i]) == _bits(np.array(seg))


def _edge_view(rng: np.random.Generator, h: int, w: int, share: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random gradients (int16, some zero) and edge pixels (uint8, 0 or 255) of an h x w view."""
    dx = rng.integers(-400, 401, (h, w)).astype(np.int16)
    dy = rng.integers(-400, 401, (h, w)).astype(np.int16)
    dx[rng.random((h, w)) < 0.1] = 0
    dy[rng.random((h, w)) < 0.1] = 0
    edges = np.where(rng.random((h, w)) < share, 255, 0).astype(np.uint8)
    return dx, dy, edges


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), size=st.sampled_from([(240, 320), (31, 17)]),
       share=st.sampled_from([0.0, 0.2, 0.7]), count=st.integers(0, 12))
def test_the_compiled_edge_shares_match_numpy(
    seed: int, size: tuple[int, int], share: float, count: int
) -> None:
    """Random straight edges (some under 1 px, some along the pixel axes) on random gradients
    and edge pixels: the compiled shares are numpy's bit for bit; an edge drawn along a column
    of edge pixels whose gradients are normal to it is seen on every point."""
    from tileviz.vision.robust import foreign_kernel

    rng = np.random.default_rng(seed)
    h, w = size
    dx, dy, edges = _edge_view(rng, h, w, share)
    seg = np.column_stack([rng.uniform(0, w - 1, count), rng.uniform(0, h - 1, count),
                           rng.uniform(0, w - 1, count), rng.uniform(0, h - 1, count)])
    if count >= 2:
        seg[0, 2:] = seg[0, :2] + rng.uniform(-0.6, 0.6, 2)  # under 1 px
        seg[1, 2] = seg[1, 0]  # along a column
    cos_tol = float(np.cos(DEFAULT_SETTINGS.foreign.normal_tolerance))
    got = foreign_kernel.edge_shares(dx, dy, edges, seg, cos_tol)
    assert got.tobytes() == nk.edge_shares_numpy(dx, dy, edges, seg, cos_tol).tobytes()
    col = w // 2
    edges[:, col] = 255
    dx[:, col] = 300  # a step across the column: its gradient is normal to the column
    dy[:, col] = int(rng.integers(-100, 101))
    along = np.array([[col, 0.0, col, h - 1.0]])
    assert foreign_kernel.edge_shares(dx, dy, edges, along, cos_tol)[0] == 1.0


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), y3=st.one_of(st.just(0.0), st.floats(-0.79, 0.79)),
       angle=st.one_of(st.sampled_from([0.0, np.pi / 2, np.pi, -np.pi / 2]),
                       st.floats(-np.pi, np.pi)),
       lp=st.floats(15.0, 300.0), band=st.floats(2.0, 30.0), share=st.sampled_from([0.0, 0.5]))
def test_the_compiled_end_steps_match_numpy(
    seed: int, y3: float, angle: float, lp: float, band: float, share: float
) -> None:
    """Random edge ends (in the view and on its border, any direction, along the pixel axes
    too) on random lattices, gradients and edge pixels: the compiled steps to the border, the
    bands met and the edge seen before and beyond them are numpy's bit for bit."""
    from tileviz.vision.robust import foreign_kernel

    rng = np.random.default_rng(seed)
    h, w = 240, 320
    dx, dy, edges = _edge_view(rng, h, w, share)
    px = float(rng.choice([rng.uniform(0, w - 1), 0.0, w - 1.0]))
    py = float(rng.uniform(0, h - 1))
    n = (np.sin(y3), -np.cos(y3)), (-np.cos(y3), -np.sin(y3))
    args = (px, py, float(np.cos(angle)), float(np.sin(angle)), band, float(n[0][0]),
            float(n[0][1]), float(n[1][0]), float(n[1][1]), float(rng.uniform(-lp, lp)),
            float(rng.uniform(-lp, lp)), lp,
            float(np.cos(DEFAULT_SETTINGS.foreign.normal_tolerance)), 4, 6, 0.5)
    got = foreign_kernel.end_steps(dx, dy, edges, *args)
    ref = nk.end_steps_numpy(dx, dy, edges, *args)
    assert got[0] == ref[0] and tuple(got[3:8]) == tuple(ref[3:8])
    assert np.array_equal(got[1], ref[1]) and np.array_equal(got[2], ref[2])
    assert float(got[8]).hex() == float(ref[8]).hex()
    if not ref[0]:  # every step lies in the view, the first in a band is i0
        assert ((ref[1] >= 0) & (ref[1] < w) & (ref[2] >= 0) & (ref[2] < h)).all()
        assert 0 <= ref[3] < ref[4] <= ref[5] <= ref[1].size


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), reach=st.integers(10, 300), lo=st.integers(0, 300),
       hi=st.integers(0, 300), step=st.floats(1.0, 20.0))
def test_the_compiled_stretch_range_matches_numpy(
    seed: int, reach: int, lo: int, hi: int, step: float
) -> None:
    """Random gray levels along a grout line (any stretch of it in view, the crossing inside
    or outside it): the compiled largest range of the stretches clear of the crossing is
    numpy's, NaN when too few stretches are clear."""
    from tileviz.vision.robust import foreign_kernel

    rng = np.random.default_rng(seed)
    u = np.arange(-reach, reach + 1) * step
    a, b = sorted((min(lo, u.size - 21), min(hi, u.size - 1)))
    b = max(b, a + 20)
    idx = np.arange(a, b + 1)
    lv = np.floor(rng.uniform(0.0, 256.0, idx.size - 2))
    fst = DEFAULT_SETTINGS.foreign
    args = (lv, idx, u, fst.variation_clear, fst.variation_stretches)
    got = foreign_kernel.stretch_range(*args)
    ref = nk.stretch_range_numpy(*args)
    assert float(got).hex() == float(ref).hex() or (np.isnan(got) and np.isnan(ref))


def test_a_part_without_a_dip_has_no_width() -> None:
    """A part profile lighter at the line than on its plateaus (no dip: a stain, a seam of
    another colour where the line should be) has no half-depth width or rise (NaN), where a
    negative width once led the crossings' windows to read nothing; a dip beside it keeps
    its width. Compiled and numpy reference alike."""
    r = 12
    jf = np.arange(-r, r + 1, dtype=np.float64)
    plateau = np.full(2 * r + 1, 100.0)
    dip = plateau - 40.0 * np.exp(-0.5 * (jf / 1.5) ** 2)
    bump = plateau + 40.0 * np.exp(-0.5 * (jf / 6.0) ** 2)  # a wide light band
    pp = np.stack([dip, bump])
    cj = np.zeros(2)
    hj = np.full(2, 5.0)
    for width, rise, *_ in (kernel.part_rows(pp, jf, cj, hj, r),
                            npf.part_rows_numpy(pp, jf, cj, hj, r)):
        assert width[0] > 2.0 and rise[0] > 0.0
        assert np.isnan(width[1]) and np.isnan(rise[1])
