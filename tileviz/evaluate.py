"""``python -m tileviz evaluate``: the localizer and its baselines over many simulated runs.

For every scenario (:data:`SCENARIOS`) and every run r (simulator seed ``--seed`` + r), one
simulated run of ``--duration`` seconds is made: the simulator
(:class:`tileviz.sim.source.SimSource`, faults injected through its ``inject``/``kidnap`` commands),
then vision *once* per frame, then the same inputs go to five methods (:data:`METHODS`):

- ``interval``: the interval localizer, mode ``autonomous`` (only the initial box is known),
  recovery off (``LocalizerConfig.max_slip = (0, 0)``, the default);
- ``interval-recovery``: the same with recovery on: ``max_slip`` from :data:`RECOVERY_MAX_SLIP`
  for the scenario's preset (as ``bench/faults.py``), ``slip_window`` at its default;
- ``interval-truth``: mode ``truth`` (report 7.1: reset every frame to the inflated truth);
- ``odometry``: mode ``odometry`` (prediction and compass only, report Fig 7.1);
- ``mcl``: Monte Carlo Localization (:mod:`tileviz.baselines.mcl`), ``--particles`` particles.

Frame alignment as in :class:`tileviz.runner.Runner`: frame k predicts with the odometry of frame
k-1 (the motion into frame k), then uses the compass and the image of frame k.

Metrics (per scenario and method, frames pooled over the runs; widths and errors in metres and
degrees):

- ``inputs_in_bounds_pct``: share of frames whose inputs respect their declared bounds: the
  odometry used at the frame is within ``speed_error``/``yaw_rate_error`` of the true step and the
  step obeys the motion model (``StepTruth.model_ok``), the frame is not a kidnap, and the
  observation (if vision gave one) is within its declared errors of the truth
  (:func:`tileviz.vision.observation_error`). The compass is within its bound by construction.
- ``vouched_pct``: interval methods: share of frames whose status is not ``lost``; MCL: 100 (it
  never says it is lost).
- ``containment_pct``: interval methods: share of the vouched frames whose true pose is inside the
  reported set (any box, heading modulo 2 pi); MCL: share of all frames whose true (x, y) is inside
  the 95 % confidence ellipse of the particle mean and covariance
  (:meth:`tileviz.baselines.mcl.MclEstimate.ellipse_contains`).
- ``width_*``: median and 95th percentile over the vouched frames of the width of the reported set's
  hull along x, y (m) and heading (deg); for MCL the sides of the box around the 95 % ellipse and
  the 95 % marginal heading interval (:meth:`~tileviz.baselines.mcl.MclEstimate.half_widths`).
- ``rmse_xy_m`` / ``rmse_theta_deg``: root mean square error of the hull centre (MCL: the particle
  mean) against the truth over the vouched frames.
- ``false_vouches``: interval methods: frames vouched for (not ``lost``) whose set did not hold
  the truth, the frames the guarantee is about (0 whenever its hypotheses hold).
- ``rejected_frames`` / ``lost_frames``: frames with that status (interval methods only).
- Fault events (scenarios with faults, the autonomous interval methods ``interval`` and
  ``interval-recovery``; otherwise empty: truth mode restarts from the truth every frame, odometry
  mode uses no view, MCL has no status): an event is a run of
  consecutive frames the simulator labelled faulty, first frame F, last frame E
  (:func:`fault_events`; a kidnap: one frame). ``fault_events``: their number over the runs.
  ``detection_median_frames`` / ``detection_max_frames``: frames from F to the first frame where
  the method :func:`noticed` something (vision refused the frame, a view ``rejected``, a compass
  that missed the set, ``lost``), searched until the next event's F or the run's end;
  ``undetected_events``: events with no such frame, of which ``undetected_harmless_events`` had
  every input within its bounds (nothing to detect). ``recovery_median_frames`` /
  ``recovery_max_frames``: frames from E to the first later frame that is vouched for and holds
  the truth (1 = the frame after the fault), same search limit; ``unrecovered_events``: events
  with none (e.g. ``lost``, which lasts until a reset). Definitions in :func:`event_outcomes`,
  shared with ``bench/faults.py``.
- ``cpu_us_per_frame``: CPU time of the evaluating thread (``time.thread_time``) in the method's
  step alone, per frame, excluding vision and simulation. The methods take turns at being
  stepped first after vision (frame k starts with method k mod 5), since the first one pays for
  the caches vision leaves cold.

Outputs in ``--out``: ``results.csv`` and ``results.md`` (the table), ``runs.csv`` (one row per run
and method), ``coverage.png`` (containment per scenario and method) and ``error_<scenario>.png``
(the first run: error of each method over time with the set's bounds). Everything but the CPU
times is deterministic for a given ``--seed``, whatever ``--jobs``.
"""

from __future__ import annotations

import csv
import math
import os
import sys
import time
import zlib
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from tileviz.baselines.mcl import MCL, MclConfig
from tileviz.cliutil import CliError, Parser, nonneg_float, positive_float, positive_int, run_cli
from tileviz.config import Config, preset, with_overrides
from tileviz.localizer import Localizer
from tileviz.runner import initial_box
from tileviz.types import Box, BoxSet, FrameInput, Odometry, Pose, SensorBounds

__all__ = [
    "COLUMNS",
    "METHODS",
    "RECOVERY_MAX_SLIP",
    "SCENARIOS",
    "EventOutcome",
    "FaultEvent",
    "RunResult",
    "Scenario",
    "Task",
    "aggregate",
    "evaluate",
    "event_outcomes",
    "fault_events",
    "main",
    "noticed",
    "run_one",
]

METHODS = ("interval", "interval-recovery", "interval-truth", "odometry", "mcl")
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
    "mcl": "MCL",
}
STATUS_CODES = {"contracted": 0, "predicted": 1, "rejected": 2, "lost": 3, "estimate": 4}
"""Per-frame status as a small integer in :class:`MethodTrace` (``estimate``: MCL)."""
RECOVERY_MAX_SLIP: dict[str, tuple[float, float]] = {"default": (0.1, 0.1), "seed": (0.04, 0.1)}
"""``LocalizerConfig.max_slip`` (metres, radians) of the ``interval-recovery`` method per preset
(and of ``bench/faults.py``'s recovery runs): below half a tile minus the tracking set's width, so
a re-inflation leaves one lattice cell (``tileviz.localizer``, "Recovery"). ``slip_window`` keeps
its default."""


# --------------------------------------------------------------------------------- scenarios


@dataclass(frozen=True)
class FaultEvent:
    """A fault injected into the simulator: ``kind`` (a ``SimSource.inject`` kind; ``kidnap``
    with ``params`` dx, dy, dtheta relative to the pose at that time, m, m, rad; or ``far_view``:
    the frame's image is replaced by the camera's view at a random pose in the room, done here, not
    by the simulator, so the odometry and truth stay right and only the view lies), starting at
    ``start`` (a fraction of the run's duration, in [0, 1)), lasting ``frames`` frames (None: the
    simulator's default). ``every``: repeat with this period, seconds (0 = once); a repeated camera
    fault draws its kind from ``kinds`` when given."""

    kind: str
    start: float
    frames: int | None = None
    every: float = 0.0
    kinds: tuple[str, ...] = ()
    params: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class Scenario:
    """A named evaluation condition: a preset, config overrides, faults. ``bounded``: its inputs
    are meant to respect their declared bounds (the method then claims 100 % containment); the
    table reports the share of frames that actually did."""

    name: str
    description: str
    preset: str = "default"
    overrides: tuple[tuple[str, tuple[tuple[str, Any], ...]], ...] = ()
    faults: tuple[FaultEvent, ...] = ()
    bounded: bool = True

    def config(self, seed: int) -> Config:
        """The scenario's configuration for the run with simulator seed ``seed`` (the floor's
        appearance seed is ``seed + 1``, as ``tileviz record --seed`` does)."""
        cfg = preset(self.preset)
        if self.overrides:
            cfg = with_overrides(cfg, **{sec: dict(vals) for sec, vals in self.overrides})
        return replace(cfg, sim=replace(cfg.sim, seed=seed),
                       floor=replace(cfg.floor, seed=seed + 1))


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario("clean", "L = 1 m, 200 px/m, 320x240, default noise, no fault"),
        Scenario("seed", "the original's constants (seed preset: L = 0.166 m, 620 px/m)",
                 preset="seed"),
        Scenario("heavy", "pixel noise 8, blur 1.2 px, JPEG quality 40",
                 overrides=(("camera", (("noise_sigma", 8.0), ("blur_sigma", 1.2),
                                        ("jpeg_quality", 40))),)),
        Scenario("outliers", "every 1 s, 2 frames with a cable, box edge, shadow edge or glare",
                 faults=(FaultEvent("camera", 0.05, frames=2, every=1.0,
                                    kinds=("cable", "box", "shadow", "glare")),),
                 bounded=False),
        Scenario("slip", "wheel slip beyond the odometry bound for 2 s at 1/3 of the run "
                 "(+0.1 m/s, +0.05 rad/s)",
                 faults=(FaultEvent("slip", 1 / 3, frames=40),), bounded=False),
        Scenario("dropout", "camera dropout (black frames) for 2 s at 1/3 and 2/3 of the run",
                 faults=(FaultEvent("dropout", 1 / 3, frames=40),
                         FaultEvent("dropout", 2 / 3, frames=40))),
        Scenario("far-views", "every 1 s, 1 frame whose image is the view from a random pose in "
                 "the room (a valid floor view that lies)",
                 faults=(FaultEvent("far_view", 0.05, frames=1, every=1.0),), bounded=False),
        Scenario("faithful", "the original pipeline (faithful extractor), no fault check",
                 overrides=(("vision", (("extractor", "faithful"),)),), bounded=False),
        Scenario("kidnap", "teleport by (+0.3 m, -0.2 m, +0.4 rad) at half the run",
                 faults=(FaultEvent("kidnap", 0.5, params=(("dx", 0.3), ("dy", -0.2),
                                                            ("dtheta", 0.4))),),
                 bounded=False),
    )
}
"""The scenarios ``--scenarios`` chooses from."""
DEFAULT_SCENARIOS = ("clean", "seed", "heavy", "outliers", "slip", "dropout")


def _schedule(scn: Scenario, frames: int, dt: float,
              rng: np.random.Generator) -> dict[int, list[tuple[str, int | None, dict]]]:
    """Frame index k -> faults to start before frame k is simulated."""
    out: dict[int, list[tuple[str, int | None, dict]]] = {}
    duration = frames * dt
    for ev in scn.faults:
        t = ev.start * duration
        while True:
            k = int(round(t / dt))
            if k >= frames:
                break
            kind = ev.kind
            if ev.kinds:
                kind = str(ev.kinds[int(rng.integers(len(ev.kinds)))])
            out.setdefault(k, []).append((kind, ev.frames, dict(ev.params)))
            if ev.every <= 0:
                break
            t += ev.every
    return out


# --------------------------------------------------------------------------------- fault events
# One implementation for this evaluation and bench/faults.py.


def noticed(status: str, compass_rejected: bool, has_view: bool) -> bool:
    """Whether the autonomous interval localizer showed, at one frame, that something was wrong:
    a view ``rejected``, ``lost``, a compass reading that missed the set (``compass_rejected``),
    or no view to use (``has_view`` False: vision refused the frame, so the status is
    ``predicted``)."""
    return status in ("rejected", "lost") or compass_rejected or not has_view


def fault_events(faulty: np.ndarray) -> list[tuple[int, int]]:
    """The fault events of a run: each maximal run of consecutive faulty frames (``faulty``: (n,)
    bool, the simulator's fault labels) as (F, E), its first and last frame index (a kidnap:
    F = E, the first frame at the new pose)."""
    mask = np.asarray(faulty, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(edges[0::2], edges[1::2], strict=True)]


@dataclass(frozen=True)
class EventOutcome:
    """How one method went through one fault event (frames are indices into the run).

    ``start``/``end``: the event's first and last faulty frame F and E. ``detection``: frames from
    F to the first frame that :func:`noticed` something, searched up to the next event's F (or the
    run's end); None: not detected. ``harmless``: every input used from F to E + 1 respected its
    declared bound (an odometry fault on frame E is used at E + 1), so there was nothing to
    detect. ``recovery``: frames from E to the first later frame that is vouched for (status not
    ``lost``) and whose set holds the truth, searched up to the next event's F (or the run's end);
    None: not recovered (e.g. ``lost``, which lasts until a reset)."""

    start: int
    end: int
    detection: int | None
    harmless: bool
    recovery: int | None


def event_outcomes(faulty: np.ndarray, alarm: np.ndarray, vouched: np.ndarray,
                   inside: np.ndarray, in_bounds: np.ndarray) -> list[EventOutcome]:
    """Detection delay and recovery time of every event of :func:`fault_events` (``faulty``) for
    one method over one run; every argument is an (n,) bool array over the run's frames:
    ``alarm`` (:func:`noticed`), ``vouched`` (status not ``lost``), ``inside`` (the reported set
    holds the truth), ``in_bounds`` (every input used at the frame respected its bound)."""
    alarm = np.asarray(alarm, dtype=bool)
    ok = np.asarray(vouched, dtype=bool) & np.asarray(inside, dtype=bool)
    in_bounds = np.asarray(in_bounds, dtype=bool)
    n = alarm.size
    events = fault_events(faulty)
    out = []
    for i, (f, e) in enumerate(events):
        horizon = events[i + 1][0] if i + 1 < len(events) else n
        hits = np.flatnonzero(alarm[f:horizon])
        back = np.flatnonzero(ok[e + 1:horizon])
        out.append(EventOutcome(
            start=f, end=e,
            detection=int(hits[0]) if hits.size else None,
            harmless=bool(in_bounds[f:min(e + 2, n)].all()),
            recovery=int(back[0]) + 1 if back.size else None,
        ))
    return out


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


@dataclass
class MethodTrace:
    """Per-frame outputs of one method over one run (n frames).

    ``lo``/``hi`` (n, 3): bounds of the reported region (hull of the set; MCL: mean -+ the 95 %
    half-widths) in x, y (m) and theta (rad, continuous). ``centre`` (n, 3): hull centre / particle
    mean. ``inside`` (n,): truth inside the set (MCL: inside the 95 % ellipse). ``status`` (n,)
    :data:`STATUS_CODES`. ``boxes`` (n,): number of boxes (MCL: 0). ``alarm`` (n,): the method
    :func:`noticed` something at the frame (:data:`FAULT_METHODS` only; False for the others).
    ``cpu_s``: total CPU time of the steps, seconds."""

    lo: np.ndarray
    hi: np.ndarray
    centre: np.ndarray
    inside: np.ndarray
    status: np.ndarray
    boxes: np.ndarray
    alarm: np.ndarray
    cpu_s: float = 0.0


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


def _trace(n: int) -> MethodTrace:
    return MethodTrace(lo=np.full((n, 3), np.nan), hi=np.full((n, 3), np.nan),
                       centre=np.full((n, 3), np.nan), inside=np.zeros(n, bool),
                       status=np.zeros(n, np.int8), boxes=np.zeros(n, np.int32),
                       alarm=np.zeros(n, bool))


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
    """Simulate one run of ``task`` and step every method on it (vision once per frame)."""
    from tileviz.sim.source import SimSource  # pymunk: only here, not at import
    from tileviz.vision import extract, observation_error

    scn = SCENARIOS[task.scenario]
    cfg = scn.config(task.seed)
    dt = cfg.sim.dt
    n = max(1, int(round(task.duration / dt)))
    L = cfg.floor.tile_size
    offset = cfg.camera.offset
    bounds = SensorBounds(cfg.noise.speed_error, cfg.noise.yaw_rate_error,
                          cfg.noise.compass_error)
    box0 = initial_box(cfg)
    key = zlib.crc32(task.scenario.encode())
    fault_rng = np.random.default_rng(np.random.SeedSequence([task.seed, key, 1]))
    plan = _schedule(scn, n, dt, fault_rng)

    def localizer(mode: str, max_slip: tuple[float, float] = (0.0, 0.0)) -> Localizer:
        return Localizer(tile_size=L, camera_offset=offset, bounds=bounds,
                         config=replace(cfg.localizer, mode=mode, max_slip=max_slip),
                         initial=box0)

    intervals = {"interval": localizer("autonomous"),
                 "interval-recovery": localizer("autonomous", RECOVERY_MAX_SLIP[scn.preset]),
                 "interval-truth": localizer("truth"), "odometry": localizer("odometry")}
    room = cfg.sim.room_half_size
    mcl = MCL(tile_size=L, camera_offset=offset, bounds=bounds, initial=box0,
              config=MclConfig(particles=task.particles, inject_rate=task.mcl_inject,
                               sigma_scale=task.mcl_sigma_scale,
                               seed=int(np.random.SeedSequence([task.seed, key, 2])
                                        .generate_state(1)[0])),
              region=Box(-room, room, -room, room, -math.pi, math.pi))

    res = RunResult(scenario=task.scenario, run=task.run, seed=task.seed,
                    t=np.zeros(n), truth=np.zeros((n, 3)), fault=np.zeros(n, bool),
                    in_bounds=np.ones(n, bool), accepted=np.zeros(n, bool), vision_s=0.0,
                    methods={m: _trace(n) for m in METHODS})
    src = SimSource(cfg)
    pending: Odometry | None = None
    pending_step: Any = None
    # this thread's CPU time: OpenCV's worker threads, still busy after vision returns, are
    # not charged to the method stepped next
    clock = time.thread_time
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
        step_k = src.last_step
        truth = frame.truth
        assert truth is not None  # the simulator always knows it
        tt = truth.as_tuple()
        res.t[k] = frame.t
        res.truth[k] = tt
        res.fault[k] = bool(frame.faults)
        c0 = clock()
        vision = extract(frame.image, camera=cfg.camera, tile_size=L, vision=cfg.vision)
        res.vision_s += clock() - c0
        obs = vision.observation
        ok = _odometry_ok(pending, pending_step, bounds) and "kidnap" not in frame.faults
        if obs is not None:
            res.accepted[k] = True
            e1, e2, e3 = observation_error(obs, truth, L, offset)
            ok = ok and max(abs(e1), abs(e2)) <= obs.position_error \
                and abs(e3) <= obs.heading_error
        res.in_bounds[k] = ok
        # the methods take turns at being stepped first after vision (which leaves the caches
        # cold for whoever comes next), so none of them pays that alone
        r = k % len(METHODS)
        for name in METHODS[r:] + METHODS[:r]:
            tr = res.methods[name]
            if name == "mcl":
                c0 = clock()
                est = mcl.step(pending, frame.compass, obs)
                tr.cpu_s += clock() - c0
                hw = np.array(est.half_widths())
                mean = est.mean.copy()
                mean[2] += 2.0 * math.pi * round((tt[2] - mean[2]) / (2.0 * math.pi))
                tr.lo[k] = mean - hw
                tr.hi[k] = mean + hw
                tr.centre[k] = mean
                tr.inside[k] = est.ellipse_contains(tt[0], tt[1])
                tr.status[k] = STATUS_CODES["estimate"]
                continue
            loc = intervals[name]
            c0 = clock()
            st = loc.step(pending, frame.compass, obs, truth)
            tr.cpu_s += clock() - c0
            _record_set(tr, k, st.updated, st.status, tt)
            if name in FAULT_METHODS:
                tr.alarm[k] = noticed(st.status, st.compass_rejected, obs is not None)
        pending, pending_step = frame.odometry, step_k
    return res


# --------------------------------------------------------------------------------- metrics

COLUMNS = (
    "scenario", "method", "runs", "frames", "inputs_in_bounds_pct", "vision_accepted_pct",
    "vouched_pct", "containment_pct", "false_vouches", "width_x_median_m", "width_x_p95_m",
    "width_y_median_m", "width_y_p95_m", "width_theta_median_deg", "width_theta_p95_deg",
    "rmse_xy_m", "rmse_theta_deg", "rejected_frames", "lost_frames", "fault_events",
    "detection_median_frames", "detection_max_frames", "undetected_events",
    "undetected_harmless_events", "recovery_median_frames", "recovery_max_frames",
    "unrecovered_events", "cpu_us_per_frame",
)
"""Columns of ``results.csv`` (``runs.csv`` adds ``run`` and ``seed`` after ``method``)."""


def _pct(a: np.ndarray, q: float) -> float:
    return float(np.percentile(a, q)) if a.size else math.nan


FAULT_COLUMNS = COLUMNS[COLUMNS.index("fault_events"):COLUMNS.index("cpu_us_per_frame")]
"""The fault columns: None but for :data:`FAULT_METHODS` on scenarios with faults."""


def _fault_metrics(results: Sequence[RunResult], method: str) -> dict[str, Any]:
    """The :data:`FAULT_COLUMNS` over every fault event of ``results`` (:func:`event_outcomes`);
    medians and maxima in frames, NaN when no event was detected (recovered)."""
    if method not in FAULT_METHODS or not any(SCENARIOS[r.scenario].faults for r in results):
        return dict.fromkeys(FAULT_COLUMNS)
    events: list[EventOutcome] = []
    for r in results:
        tr = r.methods[method]
        events += event_outcomes(r.fault, tr.alarm, tr.status != STATUS_CODES["lost"], tr.inside,
                                 r.in_bounds)
    det = [e.detection for e in events if e.detection is not None]
    rec = [e.recovery for e in events if e.recovery is not None]
    return {
        "fault_events": len(events),
        "detection_median_frames": float(np.median(det)) if det else math.nan,
        "detection_max_frames": max(det) if det else None,
        "undetected_events": len(events) - len(det),
        "undetected_harmless_events": sum(e.detection is None and e.harmless for e in events),
        "recovery_median_frames": float(np.median(rec)) if rec else math.nan,
        "recovery_max_frames": max(rec) if rec else None,
        "unrecovered_events": len(events) - len(rec),
    }


def _metrics(results: Sequence[RunResult], method: str) -> dict[str, Any]:
    truth = np.concatenate([r.truth for r in results])
    lo = np.concatenate([r.methods[method].lo for r in results])
    hi = np.concatenate([r.methods[method].hi for r in results])
    centre = np.concatenate([r.methods[method].centre for r in results])
    inside = np.concatenate([r.methods[method].inside for r in results])
    status = np.concatenate([r.methods[method].status for r in results])
    in_bounds = np.concatenate([r.in_bounds for r in results])
    accepted = np.concatenate([r.accepted for r in results])
    n = truth.shape[0]
    vouched = status != STATUS_CODES["lost"]
    nv = int(vouched.sum())
    w = (hi - lo)[vouched]
    err = (centre - truth)[vouched]
    err[:, 2] = np.remainder(err[:, 2] + math.pi, 2.0 * math.pi) - math.pi
    is_interval = method in INTERVAL_METHODS
    cpu = sum(r.methods[method].cpu_s for r in results)
    return {
        "runs": len(results),
        "frames": n,
        "inputs_in_bounds_pct": 100.0 * float(in_bounds.mean()) if n else math.nan,
        "vision_accepted_pct": 100.0 * float(accepted.mean()) if n else math.nan,
        "vouched_pct": 100.0 * nv / n if n else math.nan,
        "containment_pct": 100.0 * float(inside[vouched].mean()) if nv else math.nan,
        "false_vouches": int((vouched & ~inside).sum()) if is_interval else None,
        "width_x_median_m": _pct(w[:, 0], 50),
        "width_x_p95_m": _pct(w[:, 0], 95),
        "width_y_median_m": _pct(w[:, 1], 50),
        "width_y_p95_m": _pct(w[:, 1], 95),
        "width_theta_median_deg": math.degrees(_pct(w[:, 2], 50)),
        "width_theta_p95_deg": math.degrees(_pct(w[:, 2], 95)),
        "rmse_xy_m": float(np.sqrt(np.mean(err[:, 0] ** 2 + err[:, 1] ** 2))) if nv else math.nan,
        "rmse_theta_deg": math.degrees(float(np.sqrt(np.mean(err[:, 2] ** 2)))) if nv
        else math.nan,
        "rejected_frames": int((status == STATUS_CODES["rejected"]).sum()) if is_interval
        else None,
        "lost_frames": int((status == STATUS_CODES["lost"]).sum()) if is_interval else None,
        **_fault_metrics(results, method),
        "cpu_us_per_frame": 1e6 * cpu / n if n else math.nan,
    }


def aggregate(results: Sequence[RunResult]) -> list[dict[str, Any]]:
    """One row of :data:`COLUMNS` per (scenario, method), frames pooled over the runs; scenarios
    in the order they first appear in ``results``, methods in :data:`METHODS` order."""
    rows = []
    order = list(dict.fromkeys(r.scenario for r in results))
    for scn in order:
        group = sorted((r for r in results if r.scenario == scn), key=lambda r: r.run)
        for m in METHODS:
            rows.append({"scenario": scn, "method": m, **_metrics(group, m)})
    return rows


def _csv_value(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def write_csv(path: Path, rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> None:
    """Write ``rows`` (dicts) with ``columns``; floats with ``repr``, None/NaN as empty cells."""
    with open(path, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(columns)
        for r in rows:
            wr.writerow([_csv_value(r[c]) for c in columns])


def _fmt(v: Any, scale: float = 1.0, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    if isinstance(v, int):
        return str(v)
    return f"{v * scale:.{digits}f}"


def _fmt_pct(v: Any) -> str:
    """A percentage rounded *down* to 2 decimals, so 99.999 never reads as 100.00."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    return f"{math.floor(round(v * 100.0, 6)) / 100.0:.2f}"


def _fmt_frames(median: Any, worst: Any) -> str:
    """``median / max`` in frames (a median may end in .5)."""
    if median is None or (isinstance(median, float) and math.isnan(median)):
        return "—"
    return f"{median:g} / {worst}"


def _fmt_missed(missed: Any, events: Any, harmless: Any = 0) -> str:
    """``missed of events``, with the harmless ones among the missed when there are any."""
    if events is None:
        return "—"
    text = f"{missed} of {events}"
    return text + f" ({harmless} harmless)" if harmless else text


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    """The headline table: widths in cm and degrees, CPU in microseconds; percentages rounded
    down; detection delay and recovery time in frames (median / max over the fault events)."""
    head = ("| scenario | method | inputs in bounds % | vouched % | containment % | "
            "false vouches | width x median / p95 (cm) | width y median / p95 (cm) | heading "
            "width median / p95 (deg) | RMSE xy (cm) | RMSE heading (deg) | rejected | lost | "
            "detection delay median / max (frames) | not detected | recovery median / max "
            "(frames) | not recovered | CPU µs/frame |")
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    for r in rows:
        missed = _fmt_missed(r["undetected_events"], r["fault_events"],
                             r["undetected_harmless_events"])
        lines.append(
            f"| {r['scenario']} | {METHOD_LABELS[r['method']]} | "
            f"{_fmt_pct(r['inputs_in_bounds_pct'])} | {_fmt_pct(r['vouched_pct'])} | "
            f"{_fmt_pct(r['containment_pct'])} | {_fmt(r['false_vouches'])} | "
            f"{_fmt(r['width_x_median_m'], 100)} / {_fmt(r['width_x_p95_m'], 100)} | "
            f"{_fmt(r['width_y_median_m'], 100)} / {_fmt(r['width_y_p95_m'], 100)} | "
            f"{_fmt(r['width_theta_median_deg'])} / {_fmt(r['width_theta_p95_deg'])} | "
            f"{_fmt(r['rmse_xy_m'], 100)} | {_fmt(r['rmse_theta_deg'])} | "
            f"{_fmt(r['rejected_frames'])} | {_fmt(r['lost_frames'])} | "
            f"{_fmt_frames(r['detection_median_frames'], r['detection_max_frames'])} | "
            f"{missed} | "
            f"{_fmt_frames(r['recovery_median_frames'], r['recovery_max_frames'])} | "
            f"{_fmt_missed(r['unrecovered_events'], r['fault_events'])} | "
            f"{_fmt(r['cpu_us_per_frame'], digits=0)} |")
    return "\n".join(lines)


def figures(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The headline figures, as sentences: containment of the autonomous interval localizer on the
    scenarios whose inputs respected their bounds, and the CPU ratio MCL / interval."""
    out = []
    by = {(r["scenario"], r["method"]): r for r in rows}
    scns = list(dict.fromkeys(r["scenario"] for r in rows))
    bounded = [s for s in scns if by[(s, "interval")]["inputs_in_bounds_pct"] == 100.0]
    if bounded:
        worst = min(by[(s, "interval")]["containment_pct"] for s in bounded)
        out.append(f"Interval localizer (autonomous) containment on the scenarios whose inputs "
                   f"all respected their bounds ({', '.join(bounded)}): lowest {worst:.2f} %.")
    else:
        out.append("No scenario had all its inputs within their bounds.")
    fv = {(m, part): sum(by[(s, m)]["false_vouches"] for s in group)
          for m in FAULT_METHODS for part, group in (("bounded", bounded), ("all", scns))}
    out.append(f"Frames vouched for while the truth was outside the set (false vouches), "
               f"recovery off / on: {fv[('interval', 'bounded')]} / "
               f"{fv[('interval-recovery', 'bounded')]} on the scenarios whose inputs all "
               f"respected their bounds, {fv[('interval', 'all')]} / "
               f"{fv[('interval-recovery', 'all')]} on all.")
    cpu_i = sum(by[(s, "interval")]["cpu_us_per_frame"] * by[(s, "interval")]["frames"]
                for s in scns)
    cpu_m = sum(by[(s, "mcl")]["cpu_us_per_frame"] * by[(s, "mcl")]["frames"] for s in scns)
    if cpu_i > 0:
        ratio = cpu_m / cpu_i
        out.append(f"CPU per frame, MCL / interval (autonomous), all frames: {ratio:.1f}x.")
    return out


# --------------------------------------------------------------------------------- plots


def plot_coverage(rows: Sequence[dict[str, Any]], path: Path) -> None:
    """Grouped bars: containment % per scenario and method, with the share of frames whose inputs
    respected their bounds as markers; below, the share of frames vouched for (not lost)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scns = list(dict.fromkeys(r["scenario"] for r in rows))
    by = {(r["scenario"], r["method"]): r for r in rows}
    x = np.arange(len(scns))
    width = 0.8 / len(METHODS)
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(max(6.0, 1.3 * len(scns) + 2.0), 5.6), dpi=110,
                                  sharex=True, gridspec_kw={"height_ratios": (3, 1.3)})
    for i, m in enumerate(METHODS):
        dx = (i - (len(METHODS) - 1) / 2) * width
        ax.bar(x + dx, [by[(s, m)]["containment_pct"] for s in scns], width,
               label=METHOD_LABELS[m], color=f"C{i}")
        ax2.bar(x + dx, [by[(s, m)]["vouched_pct"] for s in scns], width, color=f"C{i}")
    ax.plot(x, [by[(s, "interval")]["inputs_in_bounds_pct"] for s in scns], "kD", ms=5,
            label="frames with inputs in bounds")
    ax.axhline(95.0, color="gray", lw=0.8, ls=":")
    ax.set_ylabel("truth inside the reported set, %")
    ax.set_ylim(0, 105)
    ax.set_title("Containment (interval: over vouched frames; MCL: 95 % ellipse)", pad=28)
    ax.legend(fontsize=7, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncols=5,
              frameon=False)
    ax2.set_ylabel("vouched (not lost), %", fontsize=8)
    ax2.set_ylim(0, 105)
    ax2.set_xticks(x, scns)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


PLOT_BINS = 400
"""Error plots show at most this many time bins (a long run is drawn as its envelope)."""


def _bins(n: int) -> np.ndarray:
    """Start indices of at most :data:`PLOT_BINS` consecutive bins of frames covering 0..n-1."""
    k = max(1, math.ceil(n / PLOT_BINS))
    return np.arange(0, n, k)


def plot_errors(res: RunResult, path: Path) -> None:
    """One run: for x, y and heading, the autonomous interval set's bounds (recovery off: band;
    on: dotted lines) and the MCL 95 % region, relative to the truth; bottom: the x width of every
    method, log scale. Fault frames
    shaded gray, lost frames red. Runs longer than :data:`PLOT_BINS` frames are drawn per bin of
    consecutive frames: the lowest lower bound and the highest upper bound (the envelope), the
    mean of the MCL mean, the largest width."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    starts = _bins(res.t.size)

    def lo_env(a: np.ndarray) -> np.ndarray:
        return np.fmin.reduceat(a, starts)

    def hi_env(a: np.ndarray) -> np.ndarray:
        return np.fmax.reduceat(a, starts)

    def mean(a: np.ndarray) -> np.ndarray:
        return np.add.reduceat(a, starts) / np.diff(np.append(starts, a.size))

    t = res.t[starts]
    fig, axes = plt.subplots(4, 1, figsize=(9.0, 9.0), dpi=100, sharex=True)
    iv = res.methods["interval"]
    rc = res.methods["interval-recovery"]
    mc = res.methods["mcl"]
    labels = ("x error (cm)", "y error (cm)", "heading error (deg)")
    scale = (100.0, 100.0, math.degrees(1.0))
    lost = iv.status == STATUS_CODES["lost"]
    for j, ax in enumerate(axes[:3]):
        s = scale[j]
        truth = res.truth[:, j]
        bands = {"iv_lo": lo_env((iv.lo[:, j] - truth) * s),
                 "iv_hi": hi_env((iv.hi[:, j] - truth) * s),
                 "mc_lo": lo_env((mc.lo[:, j] - truth) * s),
                 "mc_hi": hi_env((mc.hi[:, j] - truth) * s)}
        ax.fill_between(t, bands["iv_lo"], bands["iv_hi"], step="post", color="tab:blue",
                        alpha=0.35, lw=0, label="interval set (autonomous)")
        ax.plot(t, lo_env((rc.lo[:, j] - truth) * s), color="tab:orange", lw=1.0, ls=":",
                drawstyle="steps-post", label="interval set, recovery on")
        ax.plot(t, hi_env((rc.hi[:, j] - truth) * s), color="tab:orange", lw=1.0, ls=":",
                drawstyle="steps-post")
        ax.plot(t, bands["mc_lo"], color="tab:red", lw=0.7, ls="--", drawstyle="steps-post",
                label="MCL 95 % bounds")
        ax.plot(t, bands["mc_hi"], color="tab:red", lw=0.7, ls="--", drawstyle="steps-post")
        ax.plot(t, mean((mc.centre[:, j] - truth) * s), color="tab:red", lw=0.8,
                label="MCL mean")
        ax.axhline(0.0, color="k", lw=0.8, label="truth")
        _shade(ax, res.t, res.fault, "0.8", "fault")
        _shade(ax, res.t, lost, "tab:red", "lost")
        ax.set_ylabel(labels[j])
        # the interval band while it is vouched for and the MCL region, unless a few frames would
        # squash the rest
        vouched = ~np.logical_or.reduceat(lost, starts)
        mags = np.abs(np.concatenate([bands["iv_lo"][vouched], bands["iv_hi"][vouched],
                                      bands["mc_lo"], bands["mc_hi"]]))
        lim = min(np.nanmax(mags, initial=0.0), 100.0 * np.nanmedian(mags)) if mags.size else 0.0
        if np.isfinite(lim) and lim > 0:
            ax.set_ylim(-1.2 * lim, 1.2 * lim)
    axes[0].legend(fontsize=7, loc="upper right", ncols=4)
    ax = axes[3]
    for m in METHODS:
        tr = res.methods[m]
        ax.semilogy(t, np.maximum(hi_env((tr.hi[:, 0] - tr.lo[:, 0]) * 100.0), 1e-4), lw=0.9,
                    drawstyle="steps-post", label=METHOD_LABELS[m])
    ax.set_ylabel("x width (cm)")
    ax.set_xlabel("t (s)")
    ax.legend(fontsize=7, loc="upper left", ncols=2)
    fig.suptitle(f"scenario {res.scenario}, run {res.run} (seed {res.seed}): "
                 f"{SCENARIOS[res.scenario].description}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _shade(ax: Any, t: np.ndarray, mask: np.ndarray, color: str, label: str) -> None:
    if not mask.any():
        return
    dt = float(t[1] - t[0]) if t.size > 1 else 1.0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    for a, b in zip(edges[0::2], edges[1::2], strict=True):
        ax.axvspan(t[a] - dt / 2, t[b - 1] + dt / 2, color=color, alpha=0.3, lw=0,
                   label=label if a == edges[0] else None)


# --------------------------------------------------------------------------------- driver


def evaluate(
    scenarios: Sequence[str],
    *,
    runs: int,
    duration: float,
    jobs: int = 1,
    seed: int = 0,
    particles: int = 1000,
    mcl_inject: float = 0.0,
    mcl_sigma_scale: float = 0.5,
    progress: bool = True,
    on_result: Callable[[RunResult], None] | None = None,
) -> list[RunResult]:
    """Make every (scenario, run) in ``jobs`` processes (1 = in this process); results sorted by
    scenario (in the given order) then run. Run r uses simulator seed ``seed + r``."""
    for s in scenarios:
        if s not in SCENARIOS:
            raise ValueError(f"unknown scenario {s!r} (choose from {', '.join(SCENARIOS)})")
    if int(runs) != runs or runs < 1:
        raise ValueError(f"runs must be an integer >= 1, got {runs!r}")
    if int(jobs) != jobs or jobs < 1:
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    if not math.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration must be a finite number > 0, got {duration!r}")
    tasks = [Task(s, r, seed + r, duration, particles, mcl_inject, mcl_sigma_scale)
             for s in scenarios for r in range(runs)]
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), desc="evaluate", unit="run", disable=not progress,
               file=sys.stderr, dynamic_ncols=True)
    results: list[RunResult] = []
    try:
        if jobs <= 1:
            for task in tasks:
                results.append(run_one(task))
                if on_result:
                    on_result(results[-1])
                bar.update(1)
        else:
            import multiprocessing

            ctx = multiprocessing.get_context("spawn")
            # (OpenCV runs on one thread in each worker: importing tileviz.vision sets it)
            with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
                futures = [pool.submit(run_one, t) for t in tasks]
                for fut in as_completed(futures):
                    results.append(fut.result())
                    if on_result:
                        on_result(results[-1])
                    bar.update(1)
    finally:
        bar.close()
    rank = {s: i for i, s in enumerate(scenarios)}
    results.sort(key=lambda r: (rank[r.scenario], r.run))
    return results


def write_outputs(results: Sequence[RunResult], out: Path, command: str = "",
                  notes: Sequence[str] = ()) -> list[dict]:
    """Write results.csv, results.md, runs.csv, coverage.png and error_<scenario>.png; ``notes``
    are extra lines for results.md (e.g. the MCL settings)."""
    out.mkdir(parents=True, exist_ok=True)
    rows = aggregate(results)
    write_csv(out / "results.csv", rows, COLUMNS)
    per_run = []
    for r in results:
        for m in METHODS:
            per_run.append({"scenario": r.scenario, "method": m, "run": r.run, "seed": r.seed,
                            **_metrics([r], m)})
    run_cols = COLUMNS[:2] + ("run", "seed") + COLUMNS[2:]
    write_csv(out / "runs.csv", per_run, run_cols)
    vision_ms = 1e3 * sum(r.vision_s for r in results) / max(1, sum(r.t.size for r in results))
    scns = list(dict.fromkeys(r.scenario for r in results))
    text = ["# Evaluation results", ""]
    if command:
        text += [f"Command: `{command}`", ""]
    text += ["Scenarios:", ""]
    text += [f"- **{s}**: {SCENARIOS[s].description}" for s in scns]
    text += ["", markdown_table(rows), ""]
    text += [f"- {line}" for line in figures(rows)]
    text += [f"- Vision (not counted above): {vision_ms:.2f} ms CPU per frame on average."]
    text += [f"- {line}" for line in notes]
    text += [""]
    text += ["Columns: see `tileviz/evaluate.py` (module docstring). Widths and RMSE over the "
             "vouched frames; MCL widths are the box around its 95 % ellipse. False vouches: "
             "frames vouched for (not lost) whose set missed the truth. Detection delay (from "
             "the fault's first frame to the first frame that noticed something: a refused or "
             "rejected view, a compass that missed, lost) and recovery time (from the fault's "
             "last frame to the first frame vouched for with the truth inside; 1 = the next "
             "frame) in frames of 0.05 s, median / max over the fault events of every run; "
             "\"not detected\" / \"not recovered\": events without such a frame before the "
             "next fault or the run's end.", ""]
    (out / "results.md").write_text("\n".join(text), encoding="utf-8")
    plot_coverage(rows, out / "coverage.png")
    for s in scns:
        first = next(r for r in results if r.scenario == s)
        plot_errors(first, out / f"error_{s}.png")
    return rows


def _parser() -> Parser:
    p = Parser(prog="tileviz evaluate", description="Evaluate the interval localizer "
               "(recovery off and on), its truth and odometry modes and an MCL baseline over "
               "simulated runs.")
    p.add_argument("--runs", type=positive_int("--runs"), default=2,
                   help="runs (seeds) per scenario (default 2)")
    p.add_argument("--scenarios", default=",".join(DEFAULT_SCENARIOS),
                   help=f"comma-separated, from {', '.join(SCENARIOS)} or 'all' "
                   f"(default {','.join(DEFAULT_SCENARIOS)})")
    p.add_argument("--jobs", type=positive_int("--jobs"), default=min(2, os.cpu_count() or 1),
                   help="worker processes (default min(2, cores))")
    p.add_argument("--duration", type=positive_float("--duration"), default=60.0,
                   help="simulated seconds per run (default 60)")
    p.add_argument("--seed", type=int, default=0, help="simulator seed of run 0 (default 0)")
    p.add_argument("--particles", type=positive_int("--particles"), default=1000,
                   help="MCL particles (default 1000)")
    p.add_argument("--mcl-inject", type=nonneg_float("--mcl-inject"), default=0.0,
                   help="MCL particle injection rate per frame, 0..1, in the room (default 0)")
    p.add_argument("--mcl-sigma-scale", type=positive_float("--mcl-sigma-scale"), default=0.5,
                   help="MCL likelihood sigmas as a multiple of the declared bounds (default 0.5)")
    p.add_argument("--out", default="out/eval", help="output folder (default out/eval)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def _scenario_list(text: str) -> list[str]:
    if text.strip() == "all":
        return list(SCENARIOS)
    names = [s.strip() for s in text.split(",") if s.strip()]
    if not names:
        raise CliError("--scenarios is empty")
    for s in names:
        if s not in SCENARIOS:
            raise CliError(f"--scenarios: unknown scenario {s!r} "
                           f"(choose from {', '.join(SCENARIOS)} or all)")
    if len(set(names)) != len(names):
        raise CliError("--scenarios: a scenario is listed twice")
    return names


def main(command: str, argv: list[str]) -> int:
    """``python -m tileviz evaluate [options]``; returns the exit status."""
    args = _parser().parse_args(argv)

    def body() -> int:
        scenarios = _scenario_list(args.scenarios)
        if args.seed < 0:
            raise CliError(f"--seed must be >= 0, got {args.seed}")
        if args.mcl_inject > 1:
            raise CliError(f"--mcl-inject must be in [0, 1], got {args.mcl_inject}")
        if args.duration > 24 * 3600:
            raise CliError(f"--duration must be at most 86400 s, got {args.duration}")
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise CliError(f"--out {out} exists and is not a folder")
        results = evaluate(scenarios, runs=args.runs, duration=args.duration, jobs=args.jobs,
                           seed=args.seed, particles=args.particles, mcl_inject=args.mcl_inject,
                           mcl_sigma_scale=args.mcl_sigma_scale, progress=not args.quiet)
        cmd = "python -m tileviz evaluate " + " ".join(argv)
        notes = [f"MCL: {args.particles} particles, likelihood sigma = {args.mcl_sigma_scale} x "
                 f"the declared bounds, injection rate {args.mcl_inject}; "
                 f"{args.runs} run(s) of {args.duration:g} s per scenario, seeds {args.seed}.."
                 f"{args.seed + args.runs - 1}."]
        rows = write_outputs(results, out, cmd.strip(), notes)
        for line in figures(rows):
            print(line)
        print(f"wrote {out / 'results.md'}, {out / 'results.csv'}, {out / 'runs.csv'} and plots")
        return 0

    return run_cli(f"tileviz {command}", body)
