"""One simulated evaluation run: the simulator with its faults, vision once per frame, and every
method of :data:`METHODS` stepped on the same inputs (:func:`run_one`)."""

from __future__ import annotations

import math
import time
import zlib
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from tileviz.baselines import MclConfig, MclEstimate, MclEstimator
from tileviz.baselines.mcl import calibrated_config, chi2_2d
from tileviz.config import Mode
from tileviz.core.estimators import Estimator, IntervalEstimator, sensor_bounds
from tileviz.core.localizer import LocalizerStep
from tileviz.evaluation.events import noticed
from tileviz.evaluation.scenarios import RECOVERY_MAX_SLIP, SCENARIOS, fault_schedule
from tileviz.pipeline import FrameLoop, initial_box
from tileviz.types import STATUSES, Box, BoxSet, FrameInput, Odometry, Pose, SensorBounds

__all__ = [
    "FAULT_METHODS", "INTERVAL_METHODS", "MCL_METHODS", "METHODS", "METHOD_LABELS", "STATUS_CODES",
    "MethodTrace", "RunResult", "Task", "run_one",
]

METHODS = ("interval", "interval-recovery", "interval-truth", "odometry", "mcl", "mcl-untuned")
"""Method names, in table order."""
INTERVAL_METHODS = METHODS[:4]
"""The methods that report a status (the interval localizer in its modes)."""
FAULT_METHODS = ("interval", "interval-recovery")
"""The methods with detection and recovery figures: the autonomous localizer. Truth mode starts
afresh from the truth every frame and odometry mode never uses a view: neither has a fault to
notice or to recover from in the same sense."""
METHOD_LABELS = {
    "interval": "interval (autonomous)",
    "interval-recovery": "interval (autonomous, recovery on)",
    "interval-truth": "interval (truth mode)",
    "odometry": "odometry only",
    "mcl": "MCL (calibrated)",
    "mcl-untuned": "MCL (untuned)",
}
MCL_METHODS = ("mcl", "mcl-untuned")
"""The particle filters: ``mcl`` is the calibrated one
(:func:`tileviz.baselines.mcl.calibrated_config`: measured view likelihood, roughening,
KLD-sampling up to ``--particles``, AMCL recovery), ``mcl-untuned`` the plain one
(``MclConfig()``: Gaussians of ``--mcl-sigma-scale`` x the declared bounds, ``--particles``
particles, ``--mcl-inject``)."""
STATUS_CODES = {s: i for i, s in enumerate((*STATUSES, "estimate"))}
"""Per-frame status as a small integer in :class:`MethodTrace` (``estimate``: MCL)."""

# --------------------------------------------------------------------------------- one run


@dataclass(frozen=True)
class Task:
    """One run to make: scenario name, run index, simulator seed, duration (s), MCL options."""

    scenario: str
    run: int
    seed: int
    duration: float
    particles: int = 1000
    mcl_inject: float = 0.0
    mcl_sigma_scale: float = 0.5
    fault_model: tuple[float, float] | None = None
    """The autonomous localizer's fault model (m/s, rad/s; ``LocalizerConfig.fault_speed``,
    ``fault_yaw_rate``; ``(0, 0)`` off); None keeps the configuration's default. The
    ``interval-recovery`` method uses ``max_slip``, which replaces any fault model."""


@dataclass
class MethodTrace:
    """Per-frame outputs of one method over one run (n frames).

    ``lo``/``hi`` (n, 3): bounds of the reported region (hull of the set; MCL: mean -+ the 95 %
    half-widths) in x, y (m) and theta (rad, continuous). ``centre`` (n, 3): hull centre / particle
    mean. ``inside`` (n,): truth inside the set (MCL: inside the 95 % ellipse). ``status`` (n,)
    :data:`STATUS_CODES`. ``boxes`` (n,): number of boxes (MCL: 0). ``alarm`` (n,): the method
    :func:`noticed` something at the frame (:data:`FAULT_METHODS` only; False for the others).
    ``d2`` (n,): MCL: squared Mahalanobis distance of the true (x, y) from the particle mean in
    the (x, y) covariance (the truth lies in the level-p ellipse when d2 <= chi2_2(p)); NaN for
    the interval methods. ``cpu_s``: total CPU time of the steps, seconds."""

    lo: np.ndarray
    hi: np.ndarray
    centre: np.ndarray
    inside: np.ndarray
    status: np.ndarray
    boxes: np.ndarray
    alarm: np.ndarray
    d2: np.ndarray
    cpu_s: float = 0.0

    @classmethod
    def empty(cls, n: int) -> MethodTrace:
        """A trace of ``n`` frames with nothing recorded (NaN bounds, status 0, no alarm)."""
        return cls(lo=np.full((n, 3), np.nan), hi=np.full((n, 3), np.nan),
                   centre=np.full((n, 3), np.nan), inside=np.zeros(n, bool),
                   status=np.zeros(n, np.int8), boxes=np.zeros(n, np.int32),
                   alarm=np.zeros(n, bool), d2=np.full(n, np.nan))


@dataclass
class RunResult:
    """One run: the truth, what the inputs were like, and a :class:`MethodTrace` per method."""

    scenario: str
    run: int
    seed: int
    t: np.ndarray
    truth: np.ndarray
    fault: np.ndarray
    """(n,) bool: a fault was active at the frame (simulator labels)."""
    in_bounds: np.ndarray
    """(n,) bool: every input used at the frame respected its declared bound."""
    accepted: np.ndarray
    """(n,) bool: vision returned an observation."""
    vision_s: float
    methods: dict[str, MethodTrace] = field(default_factory=dict)


def _record_set(tr: MethodTrace, k: int, s: BoxSet, status: str,
                truth: tuple[float, float, float]) -> None:
    hull: Box | None = s.hull()
    tr.status[k] = STATUS_CODES[status]
    tr.boxes[k] = len(s)
    if hull is None:
        return
    # the hull's heading interval, shifted by 2 pi k next to the true heading
    shift = 2.0 * math.pi * round((truth[2] - 0.5 * (hull.t_lo + hull.t_hi)) / (2.0 * math.pi))
    tr.lo[k] = (hull.x_lo, hull.y_lo, hull.t_lo + shift)
    tr.hi[k] = (hull.x_hi, hull.y_hi, hull.t_hi + shift)
    tr.centre[k] = 0.5 * (tr.lo[k] + tr.hi[k])
    tr.inside[k] = s.contains(*truth)


def _odometry_ok(odo: Odometry | None, step: Any, bounds: SensorBounds) -> bool:
    if odo is None or step is None:
        return True
    return bool(step.model_ok
                and abs(odo.speed - step.speed) <= bounds.speed_error
                and abs(odo.yaw_rate - step.yaw_rate) <= bounds.yaw_rate_error)


def run_one(task: Task) -> RunResult:
    """Simulate one run of ``task`` and step every method on it: one :class:`FrameLoop` (vision
    once per frame) drives every method's estimator; this function only reads its records."""
    from tileviz.sim.source import SimSource  # pymunk: only here, not at import
    from tileviz.vision import observation_error

    scn = SCENARIOS[task.scenario]
    cfg = scn.config(task.seed)
    if task.fault_model is not None:
        cfg = replace(cfg, localizer=replace(cfg.localizer, fault_speed=task.fault_model[0],
                                             fault_yaw_rate=task.fault_model[1]))
    dt = cfg.sim.dt
    n = max(1, int(round(task.duration / dt)))
    L = cfg.floor.tile_size
    offset = cfg.camera.offset
    bounds = sensor_bounds(cfg)
    box0 = initial_box(cfg)
    key = zlib.crc32(task.scenario.encode())
    fault_rng = np.random.default_rng(np.random.SeedSequence([task.seed, key, 1]))
    plan = fault_schedule(scn, n, dt, fault_rng)

    def interval(mode: Mode, max_slip: tuple[float, float] = (0.0, 0.0)) -> IntervalEstimator:
        return IntervalEstimator.from_config(cfg, initial=box0, bounds=bounds, mode=mode,
                                             max_slip=max_slip)

    def mcl_seed(i: int) -> int:
        return int(np.random.SeedSequence([task.seed, key, i]).generate_state(1)[0])

    def mcl(config: MclConfig) -> MclEstimator:
        return MclEstimator.from_config(cfg, initial=box0, bounds=bounds, config=config)

    estimators: dict[str, Estimator[Any]] = {
        "interval": interval("autonomous"),
        "interval-recovery": interval("autonomous", RECOVERY_MAX_SLIP[scn.preset]),
        "interval-truth": interval("truth"),
        "odometry": interval("odometry"),
        "mcl": mcl(calibrated_config(particles=task.particles, seed=mcl_seed(3))),
        "mcl-untuned": mcl(MclConfig(particles=task.particles, inject_rate=task.mcl_inject,
                                     sigma_scale=task.mcl_sigma_scale, seed=mcl_seed(2))),
    }
    assert tuple(estimators) == METHODS
    # this thread's CPU time: OpenCV's worker threads, still busy after vision returns, are
    # not charged to the method stepped next; the methods take turns at being stepped first
    # after vision (which leaves the caches cold for whoever comes next)
    loop = FrameLoop(cfg, estimators=estimators, residuals=False, clock=time.thread_time,
                     rotate=True)
    room = cfg.sim.room_half_size

    res = RunResult(scenario=task.scenario, run=task.run, seed=task.seed,
                    t=np.zeros(n), truth=np.zeros((n, 3)), fault=np.zeros(n, bool),
                    in_bounds=np.ones(n, bool), accepted=np.zeros(n, bool), vision_s=0.0,
                    methods={m: MethodTrace.empty(n) for m in METHODS})
    src = SimSource(cfg)
    pending_step: Any = None  # the simulator's true step behind the odometry used at frame k
    for k in range(n):
        far_view = False
        for kind, frames, params in plan.get(k, []):
            if kind == "kidnap":
                p = src.pose
                src.kidnap(p.x + params["dx"], p.y + params["dy"], p.theta + params["dtheta"])
            elif kind == "far_view":
                far_view = True
            else:
                src.inject(kind, frames=frames, **params)
        frame: FrameInput = next(src)
        if far_view:
            x, y = fault_rng.uniform(-room, room, 2)
            pose = Pose(float(x), float(y), float(fault_rng.uniform(-math.pi, math.pi)))
            frame = replace(frame, image=src.renderer.render(pose, rng=fault_rng),
                            faults=(*frame.faults, "far_view"))
        rec = loop.process(frame)
        truth = rec.truth
        assert truth is not None  # the simulator always knows it
        tt = truth.as_tuple()
        res.t[k] = rec.t
        res.truth[k] = tt
        res.fault[k] = bool(frame.faults)
        res.vision_s += rec.timings["vision_ms"] / 1e3
        obs = rec.vision.observation
        ok = _odometry_ok(rec.motion, pending_step, bounds) and "kidnap" not in frame.faults
        if obs is not None:
            res.accepted[k] = True
            e1, e2, e3 = observation_error(obs, truth, L, offset)
            ok = ok and max(abs(e1), abs(e2)) <= obs.position_error \
                and abs(e3) <= obs.heading_error
        res.in_bounds[k] = ok
        for name in METHODS:
            tr = res.methods[name]
            tr.cpu_s += rec.timings[f"{name}_ms"] / 1e3
            if name in MCL_METHODS:
                est: MclEstimate = rec.estimates[name]
                hw = np.array(est.half_widths())
                mean = est.mean.copy()
                mean[2] += 2.0 * math.pi * round((tt[2] - mean[2]) / (2.0 * math.pi))
                tr.lo[k] = mean - hw
                tr.hi[k] = mean + hw
                tr.centre[k] = mean
                tr.d2[k] = est.mahalanobis2(tt[0], tt[1])
                tr.inside[k] = tr.d2[k] <= chi2_2d(0.95)
                tr.status[k] = STATUS_CODES["estimate"]
                continue
            st: LocalizerStep = rec.estimates[name]
            _record_set(tr, k, st.updated, st.status, tt)
            if name in FAULT_METHODS:
                tr.alarm[k] = noticed(st.status, st.compass_rejected, obs is not None,
                                      st.reinflated)
        pending_step = src.last_step
    return res
