"""Monte Carlo Localization (a particle filter) on the interval localizer's inputs.

The baseline the report's conclusion asks for: the same bounded odometry, the same compass and the
same tile observation as :class:`tileviz.core.localizer.Localizer`, but a cloud of weighted pose
samples instead of a guaranteed set. Frames and units as in ``docs/dataset-format.md``: world
metres, heading theta counter-clockwise from +x in radians; particle headings are continuous (not
wrapped).

One :meth:`MCL.step` per frame, in the localizer's order (:mod:`tileviz.pipeline.frame_loop`):

1. **Motion** (odometry of the step that ended at this frame, held over ``dt``). Each particle draws
   its own speed and yaw rate error. ``MclConfig.motion_noise = "uniform"`` (default) draws them
   uniformly in +- the declared bounds (``SensorBounds``), which is how the simulator makes them,
   so the filter's motion model is the true one; ``"gaussian"`` uses sigma = bound / 2. The particle
   then follows the circular arc of constant (v, w):
   theta' = theta + w dt, (x, y)' = (x, y) + v dt sinc(w dt / 2) (cos, sin)(theta + w dt / 2)
   (the exact chord of the arc; the interval prediction of docs/method.md encloses it).
2. **Injection** (optional recovery, ``inject_rate`` > 0): that share of the particles, picked at
   random, is replaced by new poses with the mean weight. Each starts from an anchor: with
   ``inject_anchor = "region"`` a pose drawn uniformly in the ``region`` box given to the
   constructor (for example the room, heading in [-pi, pi)), with ``"cloud"`` the replaced
   particle itself. When the frame has a view it is then moved onto the view (sensor resetting,
   Lenser and Veloso 2000): heading y3 + m pi/2 (m the branch nearest the compass for region
   anchors, or random without one; the branch nearest the particle's heading for cloud anchors),
   camera centre R(m pi/2) (y1, y2) on the lattice copy nearest the anchor's camera centre, both
   plus noise drawn from the view likelihood of step 4, robot point behind it through the lever
   arm. Uniform draws alone almost never land within the view's few millimetres, so they would
   not recover from a kidnap. The view is periodic (position modulo L, heading modulo pi/2): a
   region anchor lands on any lattice copy of the view in the region, equally likely, which is
   AMCL's global recovery but throws away which cell the cloud was in; a cloud anchor keeps the
   cell (each particle goes to the copy nearest it), so it recovers from a kidnap of less than
   half a tile and a view-less stretch, and follows the wrong copy after a larger kidnap. A
   particle moved by a cloud anchor keeps the prior's say over the cell: its weight is
   multiplied by the cloud's density ratio between its new and old place, mixed with the
   injection probability (``MCL._moved_log_weight``).
3. **Compass** likelihood: Gaussian in the heading residual wrapped to [-pi, pi), sigma =
   ``sigma_scale`` x ``compass_error`` (``likelihood = "measured"``: ``compass_error`` / sqrt 3).
4. **Tile observation** likelihood, from the lattice residuals of the observation model
   (docs/method.md, "The observation"),
   over all four rotation branches m = 0..3. With c the particle's camera centre (through the lever
   arm, c = (x, y) + R(theta) @ offset), (u1, u2) = R(m pi/2) (y1, y2) and
   r1 = wrap_L(c_x - u1), r2 = wrap_L(c_y - u2) in [-L/2, L/2), r3 = wrap_2pi(theta - y3 - m pi/2)
   in [-pi, pi), the density is the sum over m of the Gaussians N(r1; sp) N(r2; sp) N(r3; sh) with
   sp = ``sigma_scale`` x ``position_error``, sh = ``sigma_scale`` x ``heading_error`` (the
   declared bounds are 2 sigma by default), mixed with an outlier density: with probability
   ``outlier_probability`` the view is unrelated to the pose and uniform over one lattice cell and
   one heading branch (density 1 / (L^2 pi/2)). The branches are pi/2 apart in heading, so the sum
   is in practice the best branch; the mixture keeps one outlier view from wiping out the cloud.
   With ``likelihood = "measured"`` the three Gaussians are the measured model's Student-t
   densities (see "Calibration" below) and its outlier weight replaces ``outlier_probability``.
   The log-likelihood is taken relative to its peak (an exactly matching pose scores 0).
5. **Estimate**: the weighted mean (circular mean for the heading, unwrapped next to the previous
   estimate) and the weighted covariance (heading deviations wrapped about the mean).
6. **Resampling**: low-variance (systematic) resampling when the effective sample size
   1 / sum(w^2) falls below ``resample_threshold`` x N (default 0.5; 1.0 resamples every frame).
   The particle count stays ``particles`` unless KLD-sampling is on (``kld_epsilon`` > 0, Fox
   2003): then particles are drawn independently from the weights until their count n satisfies
   the KLD bound of the k histogram bins (``kld_bin``) they occupy, n in [``min_particles``,
   ``particles``]. Optional roughening (``roughening`` = K > 0, default off): Gaussian jitter
   after resampling against sample impoverishment (Gordon et al. 1993), on frames with a view
   only (the jitter is proportional to the cloud's spread, so without a view to pull the cloud
   together it would grow the cloud geometrically, frame after frame, until it covers
   neighbouring lattice cells). Optional AMCL recovery
   (``alpha_slow`` < ``alpha_fast``, default off): on every frame with a view, w_avg updates the
   averages w_slow += alpha_slow (w_avg - w_slow) and w_fast += alpha_fast (w_avg - w_fast)
   (both start at 1 and restart at 1 on the first view the cloud explains, w_avg >= 1/2, since
   the misfit before it was the initial box's width, not a kidnap); after resampling, each
   particle is replaced with probability max(0, 1 - w_fast / w_slow) by a pose drawn as in
   step 2 (Thrun, Burgard and Fox, Probabilistic Robotics, table 8.3). w_avg is the share of
   the view the cloud explains: the probability that the view is an inlier,
   (1 - eps) l_in / ((1 - eps) l_in + eps u) of the mixture of step 4, averaged over the
   particles' prior weights, in [0, 1] (about 1 while the cloud tracks, about 0 when no
   particle is near any lattice copy of the view). AMCL averages
   the raw likelihood instead; with a likelihood a few tenths of a millimetre wide that average
   swings by orders of magnitude between views that fit equally well, and a cloud that starts
   wider than the likelihood (the initial box, a kidnap) would set w_slow to a value that never
   triggers recovery, so such a filter never locks on.

Calibration (:func:`calibrated_config`, what ``tileviz evaluate`` calls ``mcl``; ``MclConfig()``
is the untuned filter, ``mcl-untuned``): the view likelihood of step 4 uses the *measured* error
distribution of the extractor (``likelihood = "measured"``, :mod:`tileviz.baselines.errormodel`:
a Student-t per coordinate fitted to views of simulated runs, scales in units of the declared
bounds, widened by the long-run variance factor of the correlated errors of consecutive views:
the same tile edges give nearly the same error frame after frame, and the errors' autocorrelation
is a white part plus a slow part that decays over seconds (docs/evaluation.md), so a filter
that multiplies the views' likelihoods as if independent averages a bias it cannot see; its
outlier weight is the measured share of views outside their bound, at least 1 %), the compass
likelihood the standard deviation bound / sqrt(3) of its uniform error, resampling every frame
with roughening K = 0.2, KLD-sampling (epsilon 0.05, delta 0.01, bins 5 mm x 5 mm x 0.005 rad,
:data:`CAL_MIN_PARTICLES` to ``particles`` particles) and AMCL recovery (alpha_slow 0.001,
alpha_fast 0.1, AMCL's recommended values) with cloud anchors (sensor resetting in place, step 2,
the moved particles weighted by the cloud's density: global injection would put the cloud on
another lattice copy of the view, since every copy fits it equally well). The measured errors
are a few hundredths of the declared bound, so the likelihood is narrower than one frame's
odometry spread: recovery is what locks a cloud as wide as the initial box onto the view.
``python bench/view_errors.py --write`` refits the model after a change of the extractor;
``python bench/mcl_calibration.py`` prints the calibration table.

Coverage (how the evaluation scores it): a frame is *covered* when the true (x, y) lies inside the
95 % confidence ellipse of the particle mean and covariance in (x, y): the squared Mahalanobis
distance d^2 = (p - mu)^T S^-1 (p - mu) with S the 2x2 (x, y) block of the covariance satisfies
d^2 <= chi2_2(0.95) = -2 ln 0.05 = 5.991 (:data:`CHI2_2D_95`). The heading is not part of the test.

Randomness: one ``numpy.random.Generator`` seeded from ``MclConfig.seed`` (or the constructor's
``seed``); the same seed and the same inputs give the same particles. numpy only: no viser, no
pymunk.
"""

from __future__ import annotations

import math
from dataclasses import replace
from statistics import NormalDist

import numpy as np

from tileviz.baselines.errormodel import (
    ViewErrorModel,
    load_view_error_model,
    student_t_logpdf,
)
from tileviz.baselines.mcl_config import (
    CAL_MIN_PARTICLES,
    CALIBRATION_LEVELS,
    CHI2_2D_95,
    INJECT_ANCHORS,
    KDE_POINTS,
    KLD_CHUNK,
    LIKELIHOODS,
    MIN_HEADING_SIGMA,
    MIN_POSITION_SIGMA,
    MOTION_NOISES,
    MclConfig,
    MclEstimate,
    calibrated_config,
    chi2_2d,
    finite_float,
    wrap_centred,
)
from tileviz.core.constants import HALF_PI, TWO_PI
from tileviz.types import Box, Observation, Odometry, SensorBounds

__all__ = ["CALIBRATION_LEVELS", "CAL_MIN_PARTICLES", "CHI2_2D_95", "INJECT_ANCHORS", "LIKELIHOODS",
           "MCL", "MOTION_NOISES", "MclConfig",
           "MclEstimate", "calibrated_config", "chi2_2d"]

class MCL:
    """Monte Carlo Localization on a tiled floor (see the module docstring).

    ``tile_size``: L, metres. ``camera_offset``: (forward, left) of the camera centre in the robot
    frame, metres. ``bounds``: declared odometry/compass error bounds. ``initial``: the particles
    start uniformly in this box. ``config``: see :class:`MclConfig`. ``seed`` overrides
    ``config.seed``. ``region``: where injected particles are drawn (needed when
    ``config.inject_rate`` > 0).
    """

    def __init__(
        self,
        *,
        tile_size: float,
        camera_offset: tuple[float, float],
        bounds: SensorBounds,
        initial: Box,
        config: MclConfig | None = None,
        seed: int | None = None,
        region: Box | None = None,
    ) -> None:
        self.L = finite_float("tile_size", tile_size)
        if self.L <= 0:
            raise ValueError(f"tile_size must be > 0, got {tile_size!r}")
        if len(camera_offset) != 2:
            raise ValueError(f"camera_offset must be (forward, left), got {camera_offset!r}")
        self.offset = (finite_float("camera_offset[0]", camera_offset[0]),
                       finite_float("camera_offset[1]", camera_offset[1]))
        self.bounds = SensorBounds(
            finite_float("speed_error", bounds.speed_error, nonneg=True),
            finite_float("yaw_rate_error", bounds.yaw_rate_error, nonneg=True),
            finite_float("compass_error", bounds.compass_error, nonneg=True),
        )
        self.config = config if config is not None else MclConfig()
        if not isinstance(self.config, MclConfig):
            raise ValueError(f"config must be an MclConfig, got {type(self.config).__name__}")
        if seed is not None:
            if isinstance(seed, bool) or int(seed) != seed or seed < 0:
                raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
            self.config = replace(self.config, seed=int(seed))
        self.region = _box_array("region", region) if region is not None else None
        cfg = self.config
        if cfg.inject_anchor == "region" and self.region is None:
            if cfg.inject_rate > 0:
                raise ValueError(
                    "inject_rate > 0 needs a region box to draw injected particles in")
            if cfg.recovery:
                raise ValueError(
                    "alpha_slow > 0 needs a region box to draw injected particles in")
        self.rng = np.random.default_rng(cfg.seed)
        self.view_model: ViewErrorModel | None = None
        if cfg.likelihood == "measured":
            self.view_model = cfg.view_model if cfg.view_model is not None \
                else load_view_error_model()
            vm = self.view_model
            outlier = vm.outlier_probability
            # Student-t scales in declared bounds, widened for correlated consecutive views
            self._t_pos = (vm.position.nu, vm.position.scale * math.sqrt(vm.inflation("position")))
            self._t_head = (vm.heading.nu, vm.heading.scale * math.sqrt(vm.inflation("heading")))
        else:
            outlier = cfg.outlier_probability
        self._log_uniform = math.log(outlier / (self.L ** 2 * HALF_PI)) if outlier > 0 \
            else -math.inf
        self._log_inlier = math.log1p(-outlier)
        self.reset(initial)

    # ------------------------------------------------------------------ state
    def reset(self, box: Box) -> None:
        """Draw N particles uniformly in ``box`` (x, y metres, theta rad), equal weights."""
        b = _box_array("initial box", box)
        self.n = int(self.config.particles)
        self._particles = self._uniform(b, self.n)
        self._logw = np.full(self.n, -math.log(self.n))
        self._ref_heading = 0.5 * (b[4] + b[5])
        self._w_slow = self._w_fast = 1.0
        self._locked = False

    @property
    def particles(self) -> np.ndarray:
        """(N, 3) float64 (x m, y m, theta rad) of the current particles, read-only (the array is
        replaced, never changed in place, so a view handed out stays a snapshot)."""
        return self._particles

    @property
    def weights(self) -> np.ndarray:
        """(N,) current normalised weights."""
        return np.exp(self._logw)

    def _uniform(self, b: np.ndarray, n: int) -> np.ndarray:
        lo = b[0::2]
        hi = b[1::2]
        p = lo + (hi - lo) * self.rng.random((n, 3))
        p.flags.writeable = False
        return p

    # ------------------------------------------------------------------ the filter
    def step(
        self,
        odometry: Odometry | None,
        compass: float | None,
        observation: Observation | None,
    ) -> MclEstimate:
        """One frame: move every particle with ``odometry`` (the motion since the previous step;
        None = no motion), inject, weight with ``compass`` (rad, any wrapping, or None) and
        ``observation`` (or None), estimate, resample when the ESS is low. Raises ValueError
        naming the quantity on NaN/inf or a negative dt/bound (the state is then unchanged)."""
        if odometry is not None:
            v = finite_float("odometry.speed", odometry.speed)
            w = finite_float("odometry.yaw_rate", odometry.yaw_rate)
            dt = finite_float("odometry.dt", odometry.dt, nonneg=True)
        if compass is not None:
            compass = finite_float("compass", compass)
        if observation is not None:
            o = observation
            y1, y2, y3 = (finite_float(f"observation.{k}", getattr(o, k))
                          for k in ("y1", "y2", "y3"))
            ep = finite_float("observation.position_error", o.position_error, nonneg=True)
            eh = finite_float("observation.heading_error", o.heading_error, nonneg=True)

        p = self._particles
        if odometry is not None:
            p = self._move(p, v, w, dt)
        logw = self._logw
        injected = 0
        cfg = self.config
        view = (y1, y2, y3, ep, eh) if observation is not None else None
        if cfg.inject_rate > 0:
            injected = int(self.rng.binomial(self.n, cfg.inject_rate))
            if injected:
                idx = self.rng.choice(self.n, size=injected, replace=False)
                p = p.copy()
                new = self._injected(p[idx], view, compass)
                logw = logw.copy()
                logw[idx] = -math.log(self.n)  # the mean weight (weights are normalised)
                if cfg.inject_anchor == "cloud" and view is not None:
                    wts = np.exp(logw - logw.max())
                    pick = self.rng.choice(self.n, size=min(self.n, KDE_POINTS),
                                           p=wts / wts.sum())
                    logw[idx] += self._moved_log_weight(
                        p[pick], p[idx], new, cfg.inject_rate if self._locked else 0.0)
                p[idx] = new
        if compass is not None:
            bound = self.bounds.compass_error
            sc = max(bound / math.sqrt(3.0) if cfg.likelihood == "measured"
                     else cfg.sigma_scale * bound, MIN_HEADING_SIGMA)
            r = wrap_centred(p[:, 2] - compass, TWO_PI)
            logw = logw - 0.5 * (r / sc) ** 2
        if observation is not None:
            ll = self._view_loglik(p, y1, y2, y3, ep, eh)
            # the view's inlier probability averaged over the prior weights
            p_out = np.exp(np.minimum(self._log_uniform - self._view_top - ll, 0.0))
            self._average_likelihood(float(np.dot(np.exp(self._logw), 1.0 - p_out)))
            logw = logw + ll

        # normalise (log-sum-exp), estimate, resample
        top = float(np.max(logw))
        w_ = np.exp(logw - top)
        total = float(w_.sum())
        w_ /= total
        mean, cov = self._estimate(p, w_)
        ess = 1.0 / float(np.dot(w_, w_))
        # (1 resamples every frame, even when all weights are equal)
        resampled = cfg.resample_threshold >= 1.0 or ess < cfg.resample_threshold * self.n
        if resampled:
            p, injected, adj = self._resample(p, w_, view, compass, injected)
            w_ = np.full(self.n, 1.0 / self.n)
            self._logw = np.full(self.n, -math.log(self.n))
            if adj is not None:
                lw = self._logw + adj
                top_w = float(lw.max())
                self._logw = lw - (top_w + math.log(float(np.exp(lw - top_w).sum())))
        else:
            self._logw = logw - (top + math.log(total))
        p.flags.writeable = False
        w_.flags.writeable = False
        self._particles = p
        mean.flags.writeable = False
        cov.flags.writeable = False
        return MclEstimate(mean=mean, cov=cov, particles=p, weights=w_, ess=ess,
                           resampled=bool(resampled), injected=injected)

    def _average_likelihood(self, w_avg: float) -> None:
        """AMCL's short- and long-term averages of ``w_avg``, this frame's share of the view the
        cloud explains (module docstring, step 6)."""
        cfg = self.config
        if not self._locked and w_avg >= 0.5:
            # the first view the cloud explains: the misfit before it was the initial box's
            # width, not a kidnap, so the averages restart
            self._locked = True
            self._w_slow = self._w_fast = 1.0
            return
        if not cfg.recovery:
            return
        self._w_slow += cfg.alpha_slow * (w_avg - self._w_slow)
        self._w_fast += cfg.alpha_fast * (w_avg - self._w_fast)

    @property
    def injection_probability(self) -> float:
        """AMCL recovery's share of random particles at the next resampling,
        max(0, 1 - w_fast / w_slow) (0 without recovery or before the first view)."""
        if not self.config.recovery or self._w_slow <= 0.0:
            return 0.0
        return max(0.0, 1.0 - self._w_fast / self._w_slow)

    def _resample(self, p: np.ndarray, w: np.ndarray,
                  view: tuple[float, float, float, float, float] | None,
                  compass: float | None, injected: int
                  ) -> tuple[np.ndarray, int, np.ndarray | None]:
        """Resampling (module docstring, step 6): systematic, KLD-sampling of the count,
        roughening, AMCL recovery injection. Sets ``self.n``; returns the new particles, the
        number injected this step and the injected particles' log-weight corrections (cloud
        anchors, :meth:`_moved_log_weight`; None when there are none)."""
        cfg = self.config
        if cfg.kld_epsilon > 0:
            # independent draws, in chunks, until the KLD bound of the bins seen so far is met
            c = np.cumsum(w)
            c[-1] = 1.0
            top = int(cfg.particles)
            idx = np.empty(0, np.int64)
            while True:
                more = min(max(KLD_CHUNK, idx.size), top - idx.size)
                draw = np.searchsorted(c, self.rng.random(more), side="right").clip(0, w.size - 1)
                idx = np.concatenate([idx, draw])
                n = self._kld_count(p[idx])
                if n < idx.size or idx.size >= top:
                    break
            idx = idx[:n]
        else:
            n = int(cfg.particles)
            idx = self._systematic(w, n)
        self.n = n
        q = p[idx]
        if cfg.roughening > 0 and view is not None:
            q = self._roughen(q)
        prob = self.injection_probability
        adj = None
        if prob > 0:
            k = int(self.rng.binomial(n, prob))
            if k:
                q = q.copy() if not q.flags.writeable else q
                idx = self.rng.choice(n, size=k, replace=False)
                new = self._injected(q[idx], view, compass)
                if cfg.inject_anchor == "cloud" and view is not None:
                    adj = np.zeros(n)
                    adj[idx] = self._moved_log_weight(q, q[idx], new,
                                                      prob if self._locked else 0.0)
                q[idx] = new
                injected += k
        return q, injected, adj

    def _moved_log_weight(self, cloud: np.ndarray, old: np.ndarray, new: np.ndarray,
                          prob: float) -> np.ndarray:
        """Log-weight factor of particles moved by sensor resetting in place from ``old`` to
        ``new``: log((1 - prob) p(new) / p(old) + prob), p a Gaussian kernel density of
        ``cloud`` (equally weighted; at most :data:`KDE_POINTS` of them), bandwidth per
        coordinate Scott's n^(-1/7) x the cloud's standard deviation (floored at 0.1 mm,
        0.1 mrad), ``prob`` the injection probability once the cloud has explained a view
        (w_avg >= 1/2, module docstring step 6) since the reset, 0 before: until then the cloud
        is the initial box, the only knowledge of which cell the robot is in. The moved
        particle's prior is a mixture: with probability 1 - prob the cloud was right, and a
        particle moved onto a lattice copy of the view where the cloud had no mass (outside the
        initial box, say) keeps almost no weight, as under the prior it was drawn from
        (Mixture MCL weights its dual samples by the prior: Thrun, Fox, Burgard and Dellaert
        2001); with probability prob the robot was moved (a kidnap) and the view's copy is as
        good as the particle's place."""
        m = cloud.shape[0]
        if m > KDE_POINTS:
            cloud = cloud[self.rng.choice(m, size=KDE_POINTS, replace=False)]
        floor = np.array([MIN_POSITION_SIGMA, MIN_POSITION_SIGMA, MIN_HEADING_SIGMA])
        h = np.maximum(cloud.std(axis=0), floor) * cloud.shape[0] ** (-1.0 / 7.0)

        def log_density(x: np.ndarray) -> np.ndarray:
            d = (x[:, None, :] - cloud[None, :, :]) / h
            e = -0.5 * np.sum(d * d, axis=2)
            top = e.max(axis=1)
            return top + np.log(np.exp(e - top[:, None]).sum(axis=1))

        lr = log_density(new) - log_density(old)
        if prob <= 0.0:
            return lr
        if prob >= 1.0:
            return np.zeros_like(lr)
        return np.logaddexp(math.log1p(-prob) + lr, math.log(prob))

    def _kld_count(self, q: np.ndarray) -> int:
        """KLD-sampling (Fox 2003): the smallest n >= ``min_particles`` such that the first n of
        the resampled particles ``q`` (independent draws) occupy k histogram bins with
        n >= (k - 1) / (2 eps) (1 - 2 / (9 (k - 1)) + sqrt(2 / (9 (k - 1))) z_(1 - delta))^3;
        all of ``q`` when no prefix satisfies it."""
        cfg = self.config
        b = np.floor(np.column_stack([q[:, 0], q[:, 1], wrap_centred(q[:, 2], TWO_PI)])
                     / np.asarray(cfg.kld_bin)).astype(np.int64)
        key = (b[:, 0] * 73856093) ^ (b[:, 1] * 19349663) ^ (b[:, 2] * 83492791)
        _, first = np.unique(key, return_index=True)
        new = np.zeros(q.shape[0], np.int64)
        new[first] = 1
        k = np.cumsum(new).astype(float)
        z = NormalDist().inv_cdf(1.0 - cfg.kld_delta)
        km1 = np.maximum(k - 1.0, 1.0)
        a = 2.0 / (9.0 * km1)
        need = km1 / (2.0 * cfg.kld_epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3
        need[k <= 1.0] = 0.0
        count = np.arange(1, q.shape[0] + 1)
        ok = np.flatnonzero((count >= need) & (count >= min(cfg.min_particles, q.shape[0])))
        return int(ok[0]) + 1 if ok.size else int(q.shape[0])

    def _injected(self, replaced: np.ndarray,
                  view: tuple[float, float, float, float, float] | None,
                  compass: float | None) -> np.ndarray:
        """New poses for the particles ``replaced`` ((k, 3)) (module docstring, step 2): anchors
        uniform in the region (``inject_anchor = "region"``) or the replaced particles themselves
        (``"cloud"``), then, when there is a view, moved onto it (sensor resetting): onto the
        view's lattice copy nearest the anchor's camera centre, with the heading branch nearest
        the compass (region anchors; random without a compass) or the anchor's own heading (cloud
        anchors), plus noise drawn from the view likelihood's own distribution."""
        k = replaced.shape[0]
        cloud = self.config.inject_anchor == "cloud"
        q = replaced.copy() if cloud else self._uniform(self.region, k).copy()  # type: ignore
        if view is None:
            return q
        y1, y2, y3, ep, eh = view
        (nu_p, sp), (nu_h, sh) = self._view_scales(ep, eh)
        if cloud:
            m = np.round((q[:, 2] - y3) / HALF_PI).astype(np.int64) & 3
        elif compass is not None:
            m = np.full(k, round((compass - y3) / HALF_PI) & 3, dtype=np.int64)
        else:
            m = self.rng.integers(0, 4, size=(k,))
        th = y3 + HALF_PI * m + sh * self._noise(nu_h, k)
        # the view's camera centre R(m pi/2) (y1, y2) on the lattice copy nearest the camera
        # centre of the anchor, plus the view's noise; the robot point behind it
        u1 = np.array([y1, -y2, -y1, y2])[m]
        u2 = np.array([y2, y1, -y2, -y1])[m]
        f, left = self.offset
        ct, st = np.cos(th), np.sin(th)
        cx = q[:, 0] + f * np.cos(q[:, 2]) - left * np.sin(q[:, 2])
        cy = q[:, 1] + f * np.sin(q[:, 2]) + left * np.cos(q[:, 2])
        cx = cx - wrap_centred(cx - u1, self.L) + sp * self._noise(nu_p, k)
        cy = cy - wrap_centred(cy - u2, self.L) + sp * self._noise(nu_p, k)
        q[:, 0] = cx - (f * ct - left * st)
        q[:, 1] = cy - (f * st + left * ct)
        q[:, 2] = th + TWO_PI * np.round((q[:, 2] - th) / TWO_PI)
        return q

    def _noise(self, nu: float, k: int) -> np.ndarray:
        """k standard draws of the Student-t of ``nu`` degrees of freedom (inf: normal)."""
        if math.isinf(nu):
            return self.rng.standard_normal(k)
        return self.rng.standard_t(nu, size=k)

    def _view_scales(self, ep: float, eh: float) -> tuple[tuple[float, float],
                                                           tuple[float, float]]:
        """((nu, scale m), (nu, scale rad)) of the view likelihood's position and heading
        densities for a view of declared bounds ``ep`` m, ``eh`` rad (module docstring, step 4;
        nu = inf: Gaussian)."""
        if self.view_model is None:
            cfg = self.config
            return ((math.inf, max(cfg.sigma_scale * ep, MIN_POSITION_SIGMA)),
                    (math.inf, max(cfg.sigma_scale * eh, MIN_HEADING_SIGMA)))
        (nu_p, s_p), (nu_h, s_h) = self._t_pos, self._t_head
        return ((nu_p, max(s_p * ep, MIN_POSITION_SIGMA)), (nu_h, max(s_h * eh, MIN_HEADING_SIGMA)))

    def _roughen(self, p: np.ndarray) -> np.ndarray:
        """Roughening after resampling (Gordon, Salmond and Smith 1993): Gaussian jitter of sigma
        K E N^(-1/3) per coordinate, E = max - min of the resampled particles, positions taken
        modulo the tile about their median (a cloud on two lattice copies of the view jitters by
        the spread of each copy's particles, not by the distance between the copies; a few
        particles far away, e.g. injected from a region, still blow the jitter up)."""
        d = p - np.median(p, axis=0)
        d[:, :2] = wrap_centred(d[:, :2], self.L)
        spread = d.max(axis=0) - d.min(axis=0)
        sigma = self.config.roughening * spread * self.n ** (-1.0 / 3.0)
        return p + sigma * self.rng.standard_normal(p.shape)

    def _move(self, p: np.ndarray, v: float, w: float, dt: float) -> np.ndarray:
        """Motion update with per-particle odometry errors (module docstring, step 1)."""
        n = p.shape[0]
        ev, ew = self.bounds.speed_error, self.bounds.yaw_rate_error
        if self.config.motion_noise == "uniform":
            e = self.rng.random((2, n)) * 2.0 - 1.0
        else:
            e = 0.5 * self.rng.standard_normal((2, n))
        vs = v + ev * e[0]
        ws = w + ew * e[1]
        half = (0.5 * dt) * ws
        heading = p[:, 2] + half
        d = (dt * vs) * np.sinc(half / math.pi)
        out = np.empty_like(p)
        out[:, 0] = p[:, 0] + d * np.cos(heading)
        out[:, 1] = p[:, 1] + d * np.sin(heading)
        out[:, 2] = heading + half
        return out

    def view_log_likelihood(self, poses: np.ndarray, observation: Observation) -> np.ndarray:
        """Log of the view density (module docstring, step 4) at each pose of ``poses`` ((N, 3)
        x m, y m, theta rad), up to a constant common to all poses."""
        p = np.asarray(poses, dtype=float)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"poses must be an (N, 3) array, got shape {p.shape}")
        o = observation
        y1, y2, y3 = (finite_float(f"observation.{k}", getattr(o, k)) for k in ("y1", "y2", "y3"))
        return self._view_loglik(
            p, y1, y2, y3,
            finite_float("observation.position_error", o.position_error, nonneg=True),
            finite_float("observation.heading_error", o.heading_error, nonneg=True))

    def _view_loglik(self, p: np.ndarray, y1: float, y2: float, y3: float, ep: float,
                     eh: float) -> np.ndarray:
        """Log of the view density at each particle relative to its peak (the density of a pose
        that matches the view exactly), so at most about 0 (module docstring, step 4)."""
        cfg = self.config
        f, left = self.offset
        ct = np.cos(p[:, 2])
        st = np.sin(p[:, 2])
        cx = p[:, 0] + f * ct - left * st
        cy = p[:, 1] + f * st + left * ct
        L = self.L
        # R(m pi/2) (y1, y2) for m = 0..3, as (4,) arrays
        u1 = np.array([y1, -y2, -y1, y2])
        u2 = np.array([y2, y1, -y2, -y1])
        h = y3 + HALF_PI * np.arange(4)
        r1 = wrap_centred(cx[:, None] - u1, L)
        r2 = wrap_centred(cy[:, None] - u2, L)
        r3 = wrap_centred(p[:, 2, None] - h, TWO_PI)
        if self.view_model is None:
            sp = max(cfg.sigma_scale * ep, MIN_POSITION_SIGMA)
            sh = max(cfg.sigma_scale * eh, MIN_HEADING_SIGMA)
            q = -0.5 * ((r1 * r1 + r2 * r2) * (1.0 / (sp * sp)) + (r3 * r3) * (1.0 / (sh * sh)))
            peak = -1.5 * math.log(TWO_PI) - 2.0 * math.log(sp) - math.log(sh)
        else:
            (nu_p, sp), (nu_h, sh) = self._view_scales(ep, eh)
            q = (student_t_logpdf(r1, nu_p, sp) + student_t_logpdf(r2, nu_p, sp)
                 + student_t_logpdf(r3, nu_h, sh))
            zero = np.zeros(1)
            peak = float(2.0 * student_t_logpdf(zero, nu_p, sp)[0]
                         + student_t_logpdf(zero, nu_h, sh)[0])
            q = q - peak
        qmax = q.max(axis=1)
        log_inlier = qmax + np.log(np.exp(q - qmax[:, None]).sum(axis=1)) + peak
        top = float(np.logaddexp(self._log_inlier + peak, self._log_uniform))
        self._view_top = top
        return np.logaddexp(self._log_inlier + log_inlier, self._log_uniform) - top

    def _estimate(self, p: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean (circular heading, unwrapped next to the last estimate) and covariance."""
        mx = float(np.dot(w, p[:, 0]))
        my = float(np.dot(w, p[:, 1]))
        a = math.atan2(float(np.dot(w, np.sin(p[:, 2]))), float(np.dot(w, np.cos(p[:, 2]))))
        a += TWO_PI * round((self._ref_heading - a) / TWO_PI)
        self._ref_heading = a
        d = np.empty_like(p)
        d[:, 0] = p[:, 0] - mx
        d[:, 1] = p[:, 1] - my
        d[:, 2] = wrap_centred(p[:, 2] - a, TWO_PI)
        cov = (d.T * w) @ d
        return np.array([mx, my, a]), cov

    def _systematic(self, w: np.ndarray, n: int) -> np.ndarray:
        """Low-variance (systematic) resampling: ``n`` indices into ``w`` (normalised weights),
        one uniform draw (Thrun et al., Probabilistic Robotics, table 4.4)."""
        c = np.cumsum(w)
        c[-1] = 1.0
        u = (self.rng.random() + np.arange(n)) / n
        return np.searchsorted(c, u, side="right").clip(0, w.size - 1)


def _box_array(name: str, box: Box) -> np.ndarray:
    if not isinstance(box, Box):
        raise ValueError(f"{name} must be a Box, got {type(box).__name__}")
    b = np.array([finite_float(f"{name}.{k}", getattr(box, k))
                  for k in ("x_lo", "x_hi", "y_lo", "y_hi", "t_lo", "t_hi")])
    for axis, i in zip("xyt", (0, 2, 4), strict=True):
        if b[i] > b[i + 1]:
            raise ValueError(f"{name} is empty: {axis}_lo = {b[i]} > {axis}_hi = {b[i + 1]}")
    return b
