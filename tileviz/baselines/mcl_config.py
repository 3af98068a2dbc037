"""The configuration and the estimate of :class:`tileviz.baselines.mcl.MCL`: its options
(:class:`MclConfig`, :func:`calibrated_config`), its constants, and what one step returns
(:class:`MclEstimate`: mean, covariance, the (x, y) confidence ellipse of a level). Frames and
units as in ``docs/dataset-format.md``: world metres, heading in radians, counter-clockwise from
+x. The method and the calibration are described in :mod:`tileviz.baselines.mcl`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from tileviz.baselines.errormodel import ViewErrorModel
from tileviz.core.constants import TWO_PI

__all__ = ["CALIBRATION_LEVELS", "CAL_MIN_PARTICLES", "CHI2_2D_95", "INJECT_ANCHORS", "LIKELIHOODS",
           "MOTION_NOISES", "MclConfig", "MclEstimate", "calibrated_config", "chi2_2d"]

CHI2_2D_95 = -2.0 * math.log(0.05)
"""The 95 % quantile of the chi-square distribution with 2 degrees of freedom (5.991)."""
MOTION_NOISES = ("uniform", "gaussian")
INJECT_ANCHORS = ("region", "cloud")
LIKELIHOODS = ("declared", "measured")
CALIBRATION_LEVELS = (0.5, 0.9, 0.95, 0.99)
"""Nominal levels of the calibration table (the share of frames whose level ellipse holds the
truth should match each)."""
KDE_POINTS = 256
"""At most this many particles make the kernel density of
:meth:`tileviz.baselines.mcl.MCL._moved_log_weight`."""
KLD_CHUNK = 256
"""KLD-sampling draws particles in chunks of at least this many (then doubling)."""
CAL_ROUGHENING = 0.2
"""Roughening K of :func:`calibrated_config`."""
CAL_MIN_PARTICLES = 500
"""The fewest particles :func:`calibrated_config` keeps (KLD-sampling's ``min_particles``): with
fewer, the cloud's covariance, estimated from a few tens of effective particles under a
likelihood a few tenths of a millimetre wide, is too noisy for its ellipses to hold the truth
as often as they say."""
MIN_POSITION_SIGMA = 1e-4
"""Floor on the position likelihood sigma, metres (a declared bound of 0 would divide by 0)."""
MIN_HEADING_SIGMA = 1e-4
"""Floor on the heading likelihood sigmas (compass and view), radians."""


def chi2_2d(level: float) -> float:
    """The ``level`` quantile of the chi-square distribution with 2 degrees of freedom,
    -2 ln(1 - level); ``level`` in (0, 1)."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"confidence level must be in (0, 1), got {level!r}")
    return -2.0 * math.log1p(-level)


def finite_float(name: str, v: object, *, nonneg: bool = False) -> float:
    """``v`` as a float; ValueError naming ``name`` when it is not a finite number (or negative,
    with ``nonneg``)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"{name} must be a finite number, got {v!r}")
    if nonneg and v < 0:
        raise ValueError(f"{name} must be >= 0, got {v!r}")
    return float(v)


def wrap_centred(v: np.ndarray, period: float) -> np.ndarray:
    """v wrapped to [-period/2, period/2), elementwise."""
    return v - period * np.floor(v / period + 0.5)


@dataclass(frozen=True)
class MclConfig:
    """Options of the particle filter (see :mod:`tileviz.baselines.mcl` for each step)."""

    particles: int = 1000
    """N, the number of particles (constant over the run)."""
    motion_noise: str = "uniform"
    """``uniform``: speed/yaw-rate errors uniform in +- the declared bounds; ``gaussian``: normal
    with sigma = bound / 2."""
    sigma_scale: float = 0.5
    """Likelihood sigmas (compass, view position, view heading) = this x the declared bound."""
    outlier_probability: float = 0.05
    """Weight of the uniform outlier density in the view likelihood, in [0, 1)."""
    resample_threshold: float = 0.5
    """Resample when ESS < this x N; in [0, 1] (1 = every frame, 0 = never)."""
    roughening: float = 0.0
    """K of the roughening jitter after resampling (0 = none; Gordon et al. suggest 0.2)."""
    inject_rate: float = 0.0
    """Share of the particles replaced each frame by random poses in the region, in [0, 1]."""
    likelihood: str = "declared"
    """``declared``: Gaussians of ``sigma_scale`` x the declared bounds (the untuned filter);
    ``measured``: the view's measured error model (``view_model``, Student-t per coordinate,
    inflated for the correlation of consecutive views) and a compass Gaussian of the uniform
    error's standard deviation, bound / sqrt(3)."""
    view_model: ViewErrorModel | None = None
    """The measured view error model for ``likelihood = "measured"``; None: the fitted one
    shipped with tileviz (:func:`~tileviz.baselines.errormodel.load_view_error_model`)."""
    kld_epsilon: float = 0.0
    """KLD-sampling (Fox 2003): after resampling keep as many particles as the histogram of the
    resampled cloud needs for a KL error below this (0 = a fixed count of ``particles``); the
    count then lies in [``min_particles``, ``particles``]."""
    kld_delta: float = 0.01
    """KLD-sampling: probability that the KL error exceeds ``kld_epsilon``, in (0, 1)."""
    kld_bin: tuple[float, float, float] = (0.005, 0.005, 0.005)
    """KLD-sampling histogram bin (x m, y m, theta rad)."""
    min_particles: int = 100
    """KLD-sampling: the fewest particles kept (at most ``particles``)."""
    alpha_slow: float = 0.0
    """AMCL recovery (Thrun et al., Probabilistic Robotics, table 8.3): smoothing rate of the
    long-term average of the view likelihood (0 = no recovery); with ``alpha_fast``, each
    resampled particle is replaced by a random one (sensor resetting onto the view, as for
    ``inject_rate``; needs a region) with probability max(0, 1 - w_fast / w_slow)."""
    alpha_fast: float = 0.0
    """AMCL recovery: smoothing rate of the short-term average, > ``alpha_slow``."""
    inject_anchor: str = "region"
    """Where injected poses (``inject_rate`` and AMCL recovery) are drawn before they are moved
    onto the view: ``region``, uniformly in the constructor's region (AMCL's global injection;
    on a periodic floor it lands on every lattice copy of the view); ``cloud``, each replaced
    particle itself (sensor resetting in place: the view's lattice copy and heading branch
    nearest the particle, so the cloud keeps the cells it believes in; no region needed)."""
    seed: int = 0
    """Seed of the filter's random generator."""

    def __post_init__(self) -> None:
        if isinstance(self.particles, bool) or int(self.particles) != self.particles \
                or self.particles < 1:
            raise ValueError(f"particles must be an integer >= 1, got {self.particles!r}")
        if self.motion_noise not in MOTION_NOISES:
            raise ValueError(f"motion_noise must be one of {MOTION_NOISES}, "
                             f"got {self.motion_noise!r}")
        if finite_float("sigma_scale", self.sigma_scale) <= 0:
            raise ValueError(f"sigma_scale must be > 0, got {self.sigma_scale!r}")
        if not 0.0 <= finite_float("outlier_probability", self.outlier_probability) < 1.0:
            raise ValueError(
                f"outlier_probability must be in [0, 1), got {self.outlier_probability!r}")
        if not 0.0 <= finite_float("resample_threshold", self.resample_threshold) <= 1.0:
            raise ValueError(
                f"resample_threshold must be in [0, 1], got {self.resample_threshold!r}")
        if finite_float("roughening", self.roughening) < 0:
            raise ValueError(f"roughening must be >= 0, got {self.roughening!r}")
        if not 0.0 <= finite_float("inject_rate", self.inject_rate) <= 1.0:
            raise ValueError(f"inject_rate must be in [0, 1], got {self.inject_rate!r}")
        if isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")
        if self.inject_anchor not in INJECT_ANCHORS:
            raise ValueError(f"inject_anchor must be one of {INJECT_ANCHORS}, "
                             f"got {self.inject_anchor!r}")
        if self.likelihood not in LIKELIHOODS:
            raise ValueError(f"likelihood must be one of {LIKELIHOODS}, got {self.likelihood!r}")
        if self.view_model is not None and not isinstance(self.view_model, ViewErrorModel):
            raise ValueError("view_model must be a ViewErrorModel")
        if not 0.0 <= finite_float("kld_epsilon", self.kld_epsilon) < 1.0:
            raise ValueError(f"kld_epsilon must be in [0, 1), got {self.kld_epsilon!r}")
        if not 0.0 < finite_float("kld_delta", self.kld_delta) < 1.0:
            raise ValueError(f"kld_delta must be in (0, 1), got {self.kld_delta!r}")
        if len(self.kld_bin) != 3 or any(finite_float("kld_bin", b) <= 0 for b in self.kld_bin):
            raise ValueError(f"kld_bin must be three numbers > 0, got {self.kld_bin!r}")
        if isinstance(self.min_particles, bool) or int(self.min_particles) != self.min_particles \
                or self.min_particles < 1:
            raise ValueError(f"min_particles must be an integer >= 1, got {self.min_particles!r}")
        a_s = finite_float("alpha_slow", self.alpha_slow)
        a_f = finite_float("alpha_fast", self.alpha_fast)
        if not (0.0 <= a_s <= 1.0 and 0.0 <= a_f <= 1.0) or (a_s > 0) != (a_f > 0) \
                or (a_s > 0 and a_f <= a_s):
            raise ValueError(f"alpha_slow and alpha_fast must both be 0, or 0 < alpha_slow < "
                             f"alpha_fast <= 1; got {self.alpha_slow!r}, {self.alpha_fast!r}")

    @property
    def recovery(self) -> bool:
        """AMCL recovery is on (``alpha_slow`` > 0)."""
        return self.alpha_slow > 0


def calibrated_config(particles: int = 2000, seed: int = 0,
                      view_model: ViewErrorModel | None = None) -> MclConfig:
    """The calibrated MCL (:mod:`tileviz.baselines.mcl`, "Calibration"): the measured view
    likelihood, roughening, KLD-sampling between :data:`CAL_MIN_PARTICLES` and ``particles``
    particles and AMCL recovery with cloud anchors."""
    return MclConfig(particles=particles, likelihood="measured", view_model=view_model,
                     resample_threshold=1.0, roughening=CAL_ROUGHENING,
                     kld_epsilon=0.05, kld_delta=0.01,
                     min_particles=min(CAL_MIN_PARTICLES, particles),
                     alpha_slow=0.001, alpha_fast=0.1, inject_anchor="cloud", seed=seed)


@dataclass(frozen=True)
class MclEstimate:
    """The filter's state after one step.

    ``mean``: (3,) weighted mean (x m, y m, theta rad; theta continuous, next to the previous
    estimate). ``cov``: (3, 3) weighted covariance (m^2, m rad, rad^2; heading deviations wrapped
    about the mean). ``particles``: (N, 3) float64 (x, y, theta) after this step (after resampling
    when it happened), read-only; ``weights``: (N,) their normalised weights, read-only.
    ``ess``: effective sample size 1 / sum(w^2) of the weights the estimate used (before
    resampling). ``resampled``: resampling ran this step. ``injected``: particles injected.
    """

    mean: np.ndarray
    cov: np.ndarray
    particles: np.ndarray
    weights: np.ndarray
    ess: float
    resampled: bool
    injected: int

    def mahalanobis2(self, x: float, y: float) -> float:
        """Squared Mahalanobis distance of the point (x, y) (metres) from the mean in the (x, y)
        block of the covariance; inf when that block is singular and the point is not the mean."""
        a, b, c = self.cov[0, 0], self.cov[0, 1], self.cov[1, 1]
        dx, dy = x - self.mean[0], y - self.mean[1]
        det = a * c - b * b
        if not det > 0.0:
            return 0.0 if dx == 0.0 and dy == 0.0 else math.inf
        return float((c * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / det)

    def ellipse_contains(self, x: float, y: float, level: float = 0.95) -> bool:
        """Whether (x, y) lies inside the ``level`` confidence ellipse of the particle mean and
        covariance in (x, y): d^2 <= chi2_2(level) (:mod:`tileviz.baselines.mcl`, "Coverage")."""
        return self.mahalanobis2(x, y) <= chi2_2d(level)

    def half_widths(self, level: float = 0.95) -> tuple[float, float, float]:
        """Half-widths (x m, y m, theta rad) of the ``level`` region: x and y are the half sides
        of the box around the (x, y) confidence ellipse, sqrt(chi2_2(level) S_ii); theta is the
        marginal two-sided normal interval z sigma_theta (z = 1.96 at 95 %)."""
        k = math.sqrt(chi2_2d(level))
        z = NormalDist().inv_cdf(0.5 + 0.5 * level)
        return (k * math.sqrt(max(self.cov[0, 0], 0.0)), k * math.sqrt(max(self.cov[1, 1], 0.0)),
                z * math.sqrt(max(self.cov[2, 2], 0.0)))

    def ellipse(self, level: float = 0.95, points: int = 64) -> np.ndarray:
        """(points, 2) x, y on the ``level`` confidence ellipse (metres, world frame), for
        drawing."""
        vals, vecs = np.linalg.eigh(self.cov[:2, :2])
        radii = np.sqrt(np.maximum(vals, 0.0) * chi2_2d(level))
        a = np.linspace(0.0, TWO_PI, int(points), endpoint=True)
        unit = np.stack([np.cos(a) * radii[0], np.sin(a) * radii[1]])
        return (vecs @ unit).T + self.mean[:2]
