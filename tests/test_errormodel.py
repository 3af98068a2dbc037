"""The measured view error model: Student-t fit, lag-1 correlation, the slow part of the
autocorrelation and its variance factor, its file."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.baselines.errormodel import (
    MIN_OUTLIER_PROBABILITY,
    StudentT,
    ViewErrorModel,
    fit_slow_component,
    fit_student_t,
    fit_view_errors,
    lag1_correlation,
    load_view_error_model,
    student_t_logpdf,
)


@settings(max_examples=20, deadline=None)
@given(st.floats(0.01, 10.0), st.integers(0, 2**32 - 1))
def test_gaussian_samples_fit_their_scale_and_a_large_nu(scale, seed):
    z = np.random.default_rng(seed).normal(0.0, scale, 4000)
    m = fit_student_t(z)
    assert m.scale == pytest.approx(scale, rel=0.08)
    assert m.nu >= 10


@settings(max_examples=10, deadline=None)
@given(st.sampled_from([1.0, 2.0, 4.0]), st.floats(0.1, 5.0), st.integers(0, 2**32 - 1))
def test_heavy_tailed_samples_fit_a_small_nu(nu, scale, seed):
    z = scale * np.random.default_rng(seed).standard_t(nu, 6000)
    m = fit_student_t(z)
    assert m.nu <= 2 * nu + 1
    assert m.scale == pytest.approx(scale, rel=0.15)


def test_student_t_density_integrates_to_one_and_tends_to_the_gaussian():
    x = np.linspace(-400, 400, 800001)
    for nu in (1.5, 3.0, 30.0, math.inf):
        total = np.trapezoid(np.exp(student_t_logpdf(x, nu, 2.0)), x)
        assert total == pytest.approx(1.0, abs=2e-3 if nu < 2 else 1e-6)
    near = np.exp(student_t_logpdf(x[::1000], 1e7, 2.0))
    gauss = np.exp(student_t_logpdf(x[::1000], math.inf, 2.0))
    assert np.allclose(near, gauss, atol=1e-7)


@settings(max_examples=15, deadline=None)
@given(st.floats(0.0, 0.95), st.integers(0, 2**32 - 1))
def test_lag1_correlation_of_an_ar1_sequence(rho, seed):
    rng = np.random.default_rng(seed)
    runs = []
    for _ in range(4):
        e = np.empty(3000)
        e[0] = rng.normal()
        for k in range(1, e.size):
            e[k] = rho * e[k - 1] + math.sqrt(1 - rho * rho) * rng.normal()
        e[rng.random(e.size) < 0.02] = np.nan  # frames without a view break pairs, nothing else
        runs.append(e)
    assert lag1_correlation(runs) == pytest.approx(rho, abs=0.05)


@settings(max_examples=5, deadline=None)
@given(st.floats(0.3, 0.9), st.floats(0.9, 0.98), st.integers(0, 2**32 - 1))
def test_slow_part_of_white_noise_plus_a_drifting_bias(share, decay, seed):
    """Errors = white noise + a slowly drifting bias (an AR(1) of decay r carrying the share a
    of the variance), as the extractor's are: the fit finds (a, r), and the variance factor is
    that of the mean of such a sequence, far above the AR(1) factor of the lag-1 correlation."""
    rng = np.random.default_rng(seed)
    runs = []
    for _ in range(20):
        n = 3000
        b = np.empty(n)
        b[0] = rng.normal()
        for k in range(1, n):
            b[k] = decay * b[k - 1] + math.sqrt(1 - decay * decay) * rng.normal()
        runs.append(math.sqrt(share) * b + math.sqrt(1 - share) * rng.normal(size=n))
    a, r = fit_slow_component(runs)
    assert a == pytest.approx(share, abs=0.08)
    assert r == pytest.approx(decay, abs=0.01)
    z = np.stack([np.stack([e, e, e], axis=1) for e in runs])
    m = fit_view_errors(list(0.05 * z))
    expected = (1 - share) + share * (1 + decay) / (1 - decay)
    assert m.inflation("position") == pytest.approx(expected, rel=0.3)
    # the batch-means variance of long blocks agrees with the factor
    blocks = np.concatenate([e.reshape(-1, 1000).mean(axis=1) for e in runs])
    assert 1000 * float(np.mean(blocks ** 2)) == pytest.approx(expected, rel=0.35)
    rho = lag1_correlation(runs)
    assert m.inflation("position") > 1.5 * (1 + rho) / (1 - rho)


def test_fit_counts_views_outside_the_bound_as_outliers_and_widens_for_correlation():
    rng = np.random.default_rng(1)
    run = rng.normal(0.0, 0.1, (5000, 3))
    run[::50] = 3.0  # 2 % of views far outside their bound
    run[7::97] = np.nan
    m = fit_view_errors([run], source="test")
    assert m.outlier_probability == pytest.approx(0.02, abs=0.002)
    assert m.position.scale == pytest.approx(0.1, rel=0.05)
    assert m.inflation("position") == pytest.approx(1.0, abs=0.1)  # independent frames
    assert m.slow_position is not None and m.slow_position[0] < 0.05
    clean = fit_view_errors([rng.normal(0.0, 0.1, (2000, 3))])
    assert clean.outlier_probability == MIN_OUTLIER_PROBABILITY


def test_model_file_round_trip_and_bad_files(tmp_path):
    m = ViewErrorModel(StudentT(math.inf, 0.07), StudentT(5.0, 0.1), 0.02, 0.9, 0.8, 123, "x")
    p = tmp_path / "m.json"
    p.write_text(m.to_json())
    assert load_view_error_model(p) == m
    assert m.inflation("position") == pytest.approx(19.0)  # no slow part: AR(1) of rho = 0.9
    slow = ViewErrorModel(StudentT(20.0, 0.03), StudentT(math.inf, 0.03), 0.01, 0.8, 0.7, 7,
                          "y", slow_position=(0.7, 0.98), slow_heading=(0.5, 0.9))
    p.write_text(slow.to_json())
    assert load_view_error_model(p) == slow
    assert slow.inflation("position") == pytest.approx(0.3 + 0.7 * 99.0)
    assert slow.inflation("heading") == pytest.approx(0.5 + 0.5 * 19.0)
    with pytest.raises(ValueError, match="slow_position"):
        ViewErrorModel(StudentT(20.0, 0.03), StudentT(math.inf, 0.03), 0.01,
                       slow_position=(0.7, 1.0))
    with pytest.raises(ValueError, match="cannot read the view error model"):
        load_view_error_model(tmp_path / "missing.json")
    p.write_text('{"position": {"nu": 3}}')
    with pytest.raises(ValueError, match=r"m\.json: bad view error model"):
        load_view_error_model(p)


def test_shipped_model_loads():
    m = load_view_error_model()
    assert m.samples > 1000 and m.source.startswith("python bench/view_errors.py")
