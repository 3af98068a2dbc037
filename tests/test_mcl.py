"""Monte Carlo Localization baseline: tracking on exact views, resampling, injection, seeding,
the four-branch lattice likelihood, the 95 % ellipse, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tileviz.baselines import CHI2_2D_95, MCL, MclConfig
from tileviz.baselines.errormodel import StudentT, ViewErrorModel
from tileviz.baselines.mcl import calibrated_config
from tileviz.core.tiles import equivalent_pose, observe
from tileviz.types import Box, Observation, Odometry, Pose, SensorBounds

L = 1.0
OFFSET = (0.3, 0.0)
BOUNDS = SensorBounds(speed_error=0.02, yaw_rate_error=0.01, compass_error=0.02)
POS_ERR = 0.01
HEAD_ERR = 0.02
DT = 0.05


def synthetic_run(frames: int, seed: int, *, views: bool = True, speed: float = 0.4):
    """A robot on a gentle curve; odometry within its bounds; exact observations (tiles.observe)
    perturbed within their declared errors; compass within its bound. Yields
    (odometry into the frame or None, compass, observation or None, truth) per frame."""
    rng = np.random.default_rng(seed)
    pose = Pose(0.2, -0.1, 0.4)
    pending = None
    out = []
    for k in range(frames):
        y1, y2, y3 = observe(pose, L, OFFSET)
        obs = None
        if views:
            obs = Observation((y1 + rng.uniform(-POS_ERR, POS_ERR)) % L,
                              (y2 + rng.uniform(-POS_ERR, POS_ERR)) % L,
                              y3 + rng.uniform(-HEAD_ERR, HEAD_ERR), POS_ERR, HEAD_ERR)
        compass = math.remainder(pose.theta + rng.uniform(-0.02, 0.02), 2 * math.pi)
        out.append((pending, compass, obs, pose))
        v = speed
        w = 0.3 * math.sin(0.05 * k)
        # true motion: constant-rate arc over dt; the reading is off by at most the bounds
        th = pose.theta + w * DT
        d = v * DT * np.sinc(w * DT / (2 * math.pi))
        pose = Pose(pose.x + d * math.cos(pose.theta + w * DT / 2),
                    pose.y + d * math.sin(pose.theta + w * DT / 2), th)
        pending = Odometry(v + rng.uniform(-0.02, 0.02), w + rng.uniform(-0.01, 0.01), DT)
    return out


def start_box(truth: Pose, ex: float = 0.2, et: float = 0.2) -> Box:
    return Box(truth.x - ex, truth.x + ex, truth.y - ex, truth.y + ex,
               truth.theta - et, truth.theta + et)


def make(initial: Box, **kw) -> MCL:
    region = kw.pop("region", None)
    seed = kw.pop("seed", None)
    return MCL(tile_size=L, camera_offset=OFFSET, bounds=BOUNDS, initial=initial,
               config=MclConfig(**kw), seed=seed, region=region)


def test_converges_and_tracks_on_exact_views():
    run = synthetic_run(300, seed=3)
    truth0 = run[0][3]
    mcl = make(start_box(truth0, ex=0.1, et=0.1), seed=5)
    errs = []
    for k, (odo, comp, obs, truth) in enumerate(run):
        est = mcl.step(odo, comp, obs)
        if k >= 50:
            errs.append(math.hypot(est.mean[0] - truth.x, est.mean[1] - truth.y))
            dth = math.remainder(est.mean[2] - truth.theta, 2 * math.pi)
            assert abs(dth) < 0.03
    # from +-10 cm down to millimetres, and it keeps up over 15 s of curved motion
    assert max(errs) < 0.02
    assert float(np.sqrt(np.mean(np.square(errs)))) < 0.006
    hw = est.half_widths()
    assert hw[0] < 0.01 and hw[1] < 0.01


def test_ellipse_is_honest_when_the_likelihood_matches_the_noise():
    """The synthetic errors are uniform within their bounds (standard deviation bound / sqrt 3);
    with sigma_scale = 1 / sqrt 3 the filter's model is right, and then the 95 % ellipse holds
    the truth about 95 % of the time (mean squared Mahalanobis distance about 2, the chi-square
    mean)."""
    d2 = []
    for seed in range(4):
        run = synthetic_run(250, seed=seed)
        mcl = make(start_box(run[0][3], ex=0.02, et=0.02), seed=100 + seed,
                   sigma_scale=1 / math.sqrt(3))
        for k, (odo, comp, obs, truth) in enumerate(run):
            est = mcl.step(odo, comp, obs)
            if k >= 50:
                d2.append(est.mahalanobis2(truth.x, truth.y))
    d2 = np.array(d2)
    assert 0.88 < np.mean(d2 <= CHI2_2D_95) < 0.99
    assert 1.5 < np.mean(d2) < 2.6


def test_without_views_the_cloud_spreads_and_still_covers_the_truth():
    run = synthetic_run(200, seed=4, views=False)
    mcl = make(start_box(run[0][3], ex=0.01, et=0.01), seed=1)
    widths = []
    covered = []
    for odo, comp, _, truth in run:
        est = mcl.step(odo, comp, None)
        widths.append(est.half_widths()[0] + est.half_widths()[1])
        covered.append(est.ellipse_contains(truth.x, truth.y))
    assert widths[-1] > 1.3 * widths[0]
    assert np.mean(covered) > 0.9


def test_roughening_spreads_the_duplicates_that_resampling_makes():
    """Resampling a sharply weighted cloud copies a few particles many times; roughening (Gordon's
    jitter, sigma = K (max - min) N^(-1/3) per coordinate) makes every copy distinct again."""
    run = synthetic_run(2, seed=0)
    clouds = {}
    for k_rough in (0.0, 0.2):
        mcl = make(start_box(run[0][3]), seed=1, roughening=k_rough, resample_threshold=1.0)
        est = mcl.step(*run[0][:3])
        assert est.resampled
        clouds[k_rough] = est.particles
    plain, rough = clouds[0.0], clouds[0.2]
    assert len(np.unique(plain, axis=0)) < 200  # a 1 cm view keeps few of 1000 from +-20 cm
    assert len(np.unique(rough, axis=0)) == 1000
    # same seed, same resampling: the difference is the jitter alone
    jitter = rough - plain
    sigma = 0.2 * np.ptp(plain, axis=0) * 1000 ** (-1 / 3)
    assert np.allclose(jitter.std(axis=0), sigma, rtol=0.15)


@pytest.mark.parametrize("threshold", [1.0, 0.5, 0.0])
def test_resampling_keeps_the_particle_count(threshold):
    run = synthetic_run(40, seed=1)
    mcl = make(start_box(run[0][3]), particles=257, resample_threshold=threshold, seed=2)
    resampled = 0
    for odo, comp, obs, _ in run:
        est = mcl.step(odo, comp, obs)
        assert est.particles.shape == (257, 3)
        assert est.weights.shape == (257,)
        assert math.isclose(float(est.weights.sum()), 1.0, rel_tol=1e-9)
        resampled += est.resampled
        if est.resampled:
            assert np.all(est.weights == est.weights[0])
    if threshold == 1.0:
        assert resampled == len(run)
    elif threshold == 0.0:
        assert resampled == 0
    else:
        assert 0 < resampled < len(run)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 10.0), min_size=1, max_size=40).filter(lambda w: sum(w) > 1e-6),
       st.integers(1, 500))
def test_low_variance_resampling_draws_each_particle_its_share(raw, n):
    """Systematic resampling gives particle i either floor or ceil of N w_i copies (+-1 for the
    float rounding of the cumulative sum)."""
    w = np.array(raw) / sum(raw)
    mcl = make(Box(0, 1, 0, 1, 0, 1), particles=n, seed=0)
    idx = mcl._systematic(w, n)
    assert idx.shape == (n,)
    counts = np.bincount(idx, minlength=w.size)
    assert np.all(np.abs(counts - n * w) <= 1.0 + 1e-9)


def test_injection_puts_particles_in_the_region():
    far = Box(10.0, 11.0, -5.0, -4.0, -math.pi, math.pi)
    mcl = make(Box(0, 0.1, 0, 0.1, 0, 0.1), inject_rate=0.2, region=far, seed=3)
    counts = []
    for _ in range(20):
        est = mcl.step(None, None, None)
        p = est.particles
        in_far = (p[:, 0] >= 10.0) & (p[:, 0] <= 11.0) & (p[:, 1] >= -5.0) & (p[:, 1] <= -4.0)
        counts.append(est.injected)
        assert in_far.sum() >= est.injected
    # about 20 % of 1000 a frame (binomial)
    assert 150 < np.mean(counts) < 250
    everything = make(Box(0, 0.1, 0, 0.1, 0, 0.1), inject_rate=1.0, region=far, seed=3)
    p = everything.step(None, None, None).particles
    assert p[:, 0].min() >= 10.0 and p[:, 1].max() <= -4.0


def test_injection_recovers_from_a_kidnap_that_plain_mcl_never_notices():
    """After a teleport the odometry says nothing; with injection (sensor resetting: injected
    particles are put on the view) in a region around the new pose, small enough that only one
    lattice copy of the view lies near it, the cloud moves there; without injection it stays put.
    (With a region wider than a tile the injected particles would sit on every lattice copy: the
    periodic floor's ambiguity, which the evaluation's kidnap scenario shows.)"""
    run = synthetic_run(160, seed=6, speed=0.05)
    kid = 60
    shift = (0.25, -0.2, 0.3)
    kidnapped = []
    for k, (odo, comp, obs, truth) in enumerate(run):
        if k >= kid:
            t = Pose(truth.x + shift[0], truth.y + shift[1], truth.theta + shift[2])
            y1, y2, y3 = observe(t, L, OFFSET)
            obs = Observation(y1, y2, y3, POS_ERR, HEAD_ERR)
            comp = math.remainder(t.theta, 2 * math.pi)
            truth = t
        kidnapped.append((odo, comp, obs, truth))
    t_k = kidnapped[kid][3]
    region = Box(t_k.x - 0.15, t_k.x + 0.15, t_k.y - 0.15, t_k.y + 0.15, t_k.theta - 0.3,
                 t_k.theta + 0.3)
    after = {}
    for rate in (0.0, 0.05):
        mcl = make(start_box(run[0][3]), inject_rate=rate, region=region, seed=9)
        errs = []
        for k, (odo, comp, obs, truth) in enumerate(kidnapped):
            est = mcl.step(odo, comp, obs)
            if kid + 10 <= k <= kid + 60:  # 0.5 s after the kidnap, while the robot is near it
                errs.append(math.hypot(est.mean[0] - truth.x, est.mean[1] - truth.y))
        after[rate] = errs
    assert max(after[0.05]) < 0.03
    assert min(after[0.0]) > 0.15


def test_same_seed_same_particles_other_seed_other_particles():
    run = synthetic_run(30, seed=2)

    def particles(seed: int) -> np.ndarray:
        mcl = make(start_box(run[0][3]), seed=seed, inject_rate=0.01,
                   region=Box(-1, 1, -1, 1, -3, 3))
        for odo, comp, obs, _ in run:
            est = mcl.step(odo, comp, obs)
        return est.particles

    a, b, c = particles(11), particles(11), particles(12)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_view_likelihood_is_the_same_for_every_equivalent_pose():
    """The corrected equivalence (docs/method.md): poses turned by m quarter turns about a crossing
    (camera centre through the lever arm) or shifted by whole tiles see the same view, so all four
    rotation branches and every lattice shift score alike; a pose off by half a tile scores far
    lower."""
    truth = Pose(0.37, -1.21, 0.3)
    y1, y2, y3 = observe(truth, L, OFFSET)
    obs = Observation(y1, y2, y3, POS_ERR, HEAD_ERR)
    mcl = make(start_box(truth))
    poses = [equivalent_pose(truth, m, L, OFFSET, shift) for m in range(4)
             for shift in ((0, 0), (2, -1))]
    off = Pose(truth.x + 0.5, truth.y, truth.theta)
    turned = Pose(truth.x, truth.y, truth.theta + 0.2)
    arr = np.array([p.as_tuple() for p in [*poses, off, turned]])
    ll = mcl.view_log_likelihood(arr, obs)
    assert np.allclose(ll[: len(poses)], ll[0], atol=1e-6)
    assert ll[-2] < ll[0] - 10 and ll[-1] < ll[0] - 10
    # relative to the peak: the exact pose scores 0
    assert ll[0] == pytest.approx(0.0, abs=1e-9)
    # the outlier mixture bounds how low a view can push a particle: the uniform density over a
    # cell and a heading branch, weighted by the outlier probability, relative to the peak
    sp, sh = 0.5 * POS_ERR, 0.5 * HEAD_ERR
    peak = math.exp(-1.5 * math.log(2 * math.pi)) / (sp * sp * sh)
    uniform = 0.05 / (L * L * math.pi / 2)
    floor = math.log(uniform / (0.95 * peak + uniform))
    assert ll[-2] == pytest.approx(floor, abs=1e-9) and ll[-1] == pytest.approx(floor, abs=1e-9)
    no_outliers = make(start_box(truth), outlier_probability=0.0)
    assert no_outliers.view_log_likelihood(arr, obs)[-2] < ll[0] - 1000


def test_compass_wraps_around_pi():
    """A reading of +pi - 0.001 supports a particle heading -pi + 0.001 (same direction)."""
    mcl = make(Box(0, 0, 0, 0, -math.pi + 0.001, -math.pi + 0.001), particles=10)
    est = mcl.step(None, math.pi - 0.001, None)
    assert est.ess == pytest.approx(10.0)
    assert abs(math.remainder(est.mean[2] - math.pi, 2 * math.pi)) < 0.002


def test_ellipse_coverage_of_a_gaussian_cloud_is_95_percent():
    """With the particles drawn from a known correlated Gaussian the 95 % ellipse of their mean and
    covariance holds about 95 % of fresh samples of that Gaussian."""
    rng = np.random.default_rng(0)
    cov = np.array([[0.04, 0.015], [0.015, 0.01]])
    mcl = make(Box(0, 0, 0, 0, 0, 0), particles=20000)
    xy = rng.multivariate_normal([1.0, 2.0], cov, size=20000)
    mcl._particles = np.column_stack([xy, np.zeros(len(xy))])
    est = mcl.step(None, None, None)
    assert np.allclose(est.cov[:2, :2], cov, rtol=0.05, atol=1e-4)
    test = rng.multivariate_normal([1.0, 2.0], cov, size=4000)
    inside = np.mean([est.ellipse_contains(x, y) for x, y in test])
    assert 0.93 < inside < 0.97
    d2 = est.mahalanobis2(*test[0])
    assert est.ellipse_contains(*test[0]) == (d2 <= CHI2_2D_95)
    hx, hy, _ = est.half_widths()
    assert hx == pytest.approx(math.sqrt(CHI2_2D_95 * est.cov[0, 0]))
    ring = est.ellipse(points=16)
    assert ring.shape == (16, 2)
    assert all(est.mahalanobis2(x, y) == pytest.approx(CHI2_2D_95) for x, y in ring)


def test_particles_handed_out_are_read_only_snapshots():
    run = synthetic_run(3, seed=0)
    mcl = make(start_box(run[0][3]), seed=0)
    est0 = mcl.step(*run[0][:3])
    before = est0.particles.copy()
    mcl.step(*run[1][:3])
    assert np.array_equal(est0.particles, before)
    with pytest.raises(ValueError):
        est0.particles[0, 0] = 1.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"particles": 0}, "particles"),
        ({"particles": 2.5}, "particles"),
        ({"motion_noise": "laplace"}, "motion_noise"),
        ({"sigma_scale": 0.0}, "sigma_scale"),
        ({"outlier_probability": 1.0}, "outlier_probability"),
        ({"resample_threshold": 1.5}, "resample_threshold"),
        ({"inject_rate": -0.1}, "inject_rate"),
        ({"inject_rate": float("nan")}, "inject_rate"),
        ({"seed": -1}, "seed"),
    ],
)
def test_bad_config_names_the_option(kwargs, match):
    with pytest.raises(ValueError, match=match):
        MclConfig(**kwargs)


def test_bad_inputs_name_the_quantity_and_change_nothing():
    mcl = make(Box(0, 0.1, 0, 0.1, 0, 0.1), seed=0)
    before = mcl.particles.copy()
    obs = Observation(0.1, 0.2, 0.0, POS_ERR, HEAD_ERR)
    cases = [
        ((Odometry(float("nan"), 0.0, DT), None, None), "odometry.speed"),
        ((Odometry(0.1, float("inf"), DT), None, None), "odometry.yaw_rate"),
        ((Odometry(0.1, 0.0, -DT), None, None), "odometry.dt"),
        ((None, float("nan"), None), "compass"),
        ((None, None, Observation(float("nan"), 0.2, 0.0, POS_ERR, HEAD_ERR)), "observation.y1"),
        ((None, None, Observation(0.1, 0.2, 0.0, -1.0, HEAD_ERR)), "position_error"),
    ]
    for args, match in cases:
        with pytest.raises(ValueError, match=match):
            mcl.step(*args)
    assert np.array_equal(mcl.particles, before)
    mcl.step(None, None, obs)  # still usable
    with pytest.raises(ValueError, match="region"):
        make(Box(0, 1, 0, 1, 0, 1), inject_rate=0.1)
    with pytest.raises(ValueError, match="initial box is empty"):
        make(Box(1, 0, 0, 1, 0, 1))
    with pytest.raises(ValueError, match="tile_size"):
        MCL(tile_size=0.0, camera_offset=OFFSET, bounds=BOUNDS, initial=Box(0, 1, 0, 1, 0, 1))
    with pytest.raises(ValueError, match="speed_error"):
        MCL(tile_size=L, camera_offset=OFFSET, bounds=SensorBounds(-1.0, 0.0, 0.0),
            initial=Box(0, 1, 0, 1, 0, 1))
    with pytest.raises(ValueError, match="poses"):
        mcl.view_log_likelihood(np.zeros((3, 2)), obs)


SYNTH_MODEL = ViewErrorModel(StudentT(math.inf, 1 / math.sqrt(3)),
                             StudentT(math.inf, 1 / math.sqrt(3)), 0.01)
"""The synthetic runs' view errors: uniform within the bound (standard deviation bound / sqrt 3),
independent from frame to frame."""


def calibrated(**changes) -> dict:
    """calibrated_config() on the synthetic model, with ``changes``, as make() keywords."""
    cfg = {k: getattr(calibrated_config(view_model=SYNTH_MODEL), k)
           for k in MclConfig.__dataclass_fields__ if k != "seed"}
    return {**cfg, **changes}


def test_kld_sampling_shrinks_the_cloud_once_it_tracks_and_grows_it_when_unsure():
    run = synthetic_run(200, seed=4)
    mcl = make(start_box(run[0][3], ex=0.2, et=0.3), seed=3,
               **calibrated(particles=3000, min_particles=100, alpha_slow=0.0, alpha_fast=0.0))
    counts = []
    for odo, comp, obs, _ in run:
        counts.append(mcl.step(odo, comp, obs).particles.shape[0])
    # the first resamplings still see a cloud over many bins; tracking needs far fewer
    assert all(100 <= c <= 3000 for c in counts)
    assert counts[0] > 2 * max(counts[100:])
    assert min(counts[100:]) < 300
    # a cloud over a whole tile with nothing to weight it: every one of the 3000 is needed
    wide = make(Box(0, 1, 0, 1, -3, 3), seed=3, **calibrated(particles=3000, alpha_slow=0.0,
                                                              alpha_fast=0.0))
    assert wide.step(None, None, None).particles.shape[0] == 3000


def test_calibrated_ellipse_holds_the_truth_about_as_often_as_it_says():
    d2 = []
    for seed in range(4):
        run = synthetic_run(250, seed=seed)
        mcl = make(start_box(run[0][3], ex=0.02, et=0.02), seed=100 + seed,
                   region=Box(-5, 5, -5, 5, -math.pi, math.pi), **calibrated())
        for k, (odo, comp, obs, truth) in enumerate(run):
            est = mcl.step(odo, comp, obs)
            if k >= 50:
                d2.append(est.mahalanobis2(truth.x, truth.y))
    cover = np.mean(np.array(d2) <= CHI2_2D_95)
    assert 0.88 < cover < 0.995


def test_amcl_recovery_injects_only_when_the_views_stop_fitting():
    """AMCL recovery: while tracking, the short- and long-term averages of the view likelihood
    agree and nothing is injected; after a kidnap the short-term one drops, particles are
    injected onto the view and the cloud follows; with recovery off it stays put."""
    run = synthetic_run(160, seed=6, speed=0.05)
    kid = 60
    shift = (0.25, -0.2, 0.3)
    kidnapped = []
    for k, (odo, comp, obs, truth) in enumerate(run):
        if k >= kid:
            t = Pose(truth.x + shift[0], truth.y + shift[1], truth.theta + shift[2])
            y1, y2, y3 = observe(t, L, OFFSET)
            obs = Observation(y1, y2, y3, POS_ERR, HEAD_ERR)
            comp = math.remainder(t.theta, 2 * math.pi)
            truth = t
        kidnapped.append((odo, comp, obs, truth))
    t_k = kidnapped[kid][3]
    region = Box(t_k.x - 0.15, t_k.x + 0.15, t_k.y - 0.15, t_k.y + 0.15, t_k.theta - 0.3,
                 t_k.theta + 0.3)
    after, injected = {}, {}
    for recovery in (False, True):
        cfg = calibrated() if recovery else calibrated(alpha_slow=0.0, alpha_fast=0.0)
        mcl = make(start_box(run[0][3]), region=region, seed=9, **cfg)
        errs, inj = [], []
        for k, (odo, comp, obs, truth) in enumerate(kidnapped):
            est = mcl.step(odo, comp, obs)
            inj.append(est.injected)
            # the short-term average needs about 25 frames (alpha_fast = 0.1) to fall below the
            # long-term one; after the kidnap the synthetic truth no longer follows the odometry
            # exactly (its heading turned), so look soon after
            if kid + 35 <= k <= kid + 60:
                errs.append(math.hypot(est.mean[0] - truth.x, est.mean[1] - truth.y))
        after[recovery], injected[recovery] = errs, inj
    assert max(after[True]) < 0.03
    assert min(after[False]) > 0.15
    assert sum(injected[True][20:kid]) == 0 and sum(injected[True][kid:]) > 0
    assert sum(injected[False]) == 0


def test_recovery_needs_a_region_and_ordered_rates():
    with pytest.raises(ValueError, match="alpha_slow > 0 needs a region"):
        make(Box(0, 1, 0, 1, 0, 1), alpha_slow=0.001, alpha_fast=0.1)
    with pytest.raises(ValueError, match="alpha_slow and alpha_fast"):
        MclConfig(alpha_slow=0.1, alpha_fast=0.01)
    with pytest.raises(ValueError, match="likelihood must be one of"):
        MclConfig(likelihood="magic")


@pytest.mark.parametrize("scenario, seed", [("clean", 5), ("seed", 6)])
def test_calibrated_mcl_holds_the_truth_in_its_95_region_on_a_simulated_clean_run(scenario, seed):
    """The shipped error model and the real extractor on a short simulated run of each preset:
    the calibrated filter locks on from the initial box onto the right lattice cell (no
    aliasing onto a neighbouring copy of the periodic view) and its 95 % ellipse holds the truth
    on most frames, where the untuned filter's does on far fewer."""
    from tileviz.evaluation import Task, run_one

    res = run_one(Task(scenario, 0, seed, 12.0, particles=1000))
    d2 = res.methods["mcl"].d2
    centre = res.methods["mcl"].centre
    err = np.hypot(centre[:, 0] - res.truth[:, 0], centre[:, 1] - res.truth[:, 1])
    assert float(np.max(err[40:])) < 0.005  # millimetres, not a tile away
    assert float(np.mean(d2 <= CHI2_2D_95)) >= 0.85
    assert float(np.mean(res.methods["mcl-untuned"].d2 <= CHI2_2D_95)) < 0.85


@pytest.mark.parametrize("anchor", ["cloud", "region"])
def test_recovery_locks_on_inside_the_initial_box_not_on_another_lattice_copy(anchor):
    """A cloud as wide as +-0.3 m (0.6 tile) that no particle of it explains: AMCL recovery
    locks it onto the view. Moved in place (cloud anchors, the calibrated filter's), the
    particles land on the view's copy inside the initial box; drawn over the room (region
    anchors, AMCL's global injection), they land on any copy, every one fitting the periodic
    view equally well, and the cloud ends metres away."""
    worst = []
    for seed in range(4):
        run = synthetic_run(120, seed=seed)
        mcl = make(start_box(run[0][3], ex=0.3, et=0.2), seed=50 + seed,
                   region=Box(-5, 5, -5, 5, -math.pi, math.pi),
                   **calibrated(inject_anchor=anchor))
        errs = []
        for k, (odo, comp, obs, truth) in enumerate(run):
            est = mcl.step(odo, comp, obs)
            if k >= 40:
                errs.append(math.hypot(est.mean[0] - truth.x, est.mean[1] - truth.y))
        worst.append(max(errs))
    if anchor == "cloud":
        assert max(worst) < 0.01
    else:
        assert min(worst) > 0.5
