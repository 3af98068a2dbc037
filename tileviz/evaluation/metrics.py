"""The evaluation's metrics: what ``python -m tileviz evaluate`` measures and how.

For every scenario (:data:`SCENARIOS`) and every run r (simulator seed ``--seed`` + r), one
simulated run of ``--duration`` seconds is made: the simulator
(:class:`tileviz.sim.source.SimSource`, faults injected through its ``inject``/``kidnap`` commands),
then vision *once* per frame, then the same inputs go to six methods (:data:`METHODS`):

- ``interval``: the interval localizer, mode ``autonomous`` (only the initial box is known),
  recovery off (``LocalizerConfig.max_slip = (0, 0)``, the default);
- ``interval-recovery``: the same with recovery on: ``max_slip`` from :data:`RECOVERY_MAX_SLIP`
  for the scenario's preset (as ``bench/faults.py``), ``slip_window`` at its default;
- ``interval-truth``: mode ``truth`` (report 7.1: reset every frame to the inflated truth);
- ``odometry``: mode ``odometry`` (prediction and compass only, report Fig 7.1);
- ``mcl``: Monte Carlo Localization (:mod:`tileviz.baselines.mcl`), calibrated
  (:func:`~tileviz.baselines.mcl.calibrated_config`, at most ``--particles`` particles);
- ``mcl-untuned``: the same filter untuned (``MclConfig()``, ``--particles`` particles).

Frame alignment as in :class:`tileviz.pipeline.FrameLoop`: frame k predicts with the odometry of
frame k-1 (the motion into frame k), then uses the compass and the image of frame k.

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
- Calibration of the particle filters (``calibration.csv``, :func:`calibration`): for the
  nominal levels 50, 90, 95 and 99 %, the share of frames whose level ellipse (squared
  Mahalanobis distance of the true (x, y) <= chi2_2(level)) holds the truth; a calibrated filter
  matches each level.
- ``cpu_us_per_frame``: CPU time of the evaluating thread (``time.thread_time``) in the method's
  step alone, per frame, excluding vision and simulation. Each frame steps the methods in an
  order drawn afresh (``FrameLoop(rotate=True)``): the first one pays for the caches vision
  leaves cold, and each inherits the caches its predecessor leaves; a fresh order shares both.

Outputs in ``--out``: ``results.csv`` and ``results.md`` (the table), ``runs.csv`` (one row per run
and method), ``coverage.png`` (containment per scenario and method) and ``error_<scenario>.png``
(the first run: error of each method over time with the set's bounds). Everything but the CPU
times is deterministic for a given ``--seed``, whatever ``--jobs``.
"""


from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from tileviz.baselines.mcl import CALIBRATION_LEVELS, chi2_2d
from tileviz.evaluation.events import EventOutcome, event_outcomes
from tileviz.evaluation.scenarios import SCENARIOS
from tileviz.evaluation.simulate import (
    FAULT_METHODS,
    INTERVAL_METHODS,
    MCL_METHODS,
    METHODS,
    STATUS_CODES,
    RunResult,
)

__all__ = ["CALIBRATION_COLUMNS", "COLUMNS", "FAULT_COLUMNS", "aggregate", "calibration",
           "metrics"]

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


def metrics(results: Sequence[RunResult], method: str) -> dict[str, Any]:
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
            rows.append({"scenario": scn, "method": m, **metrics(group, m)})
    return rows


CALIBRATION_COLUMNS = ("scenario", "method", "runs", "frames",
                       *(f"coverage_{round(100 * lv)}_pct" for lv in CALIBRATION_LEVELS))
"""Columns of ``calibration.csv``: for each particle filter, the share of frames whose nominal
p ellipse (p in :data:`~tileviz.baselines.mcl.CALIBRATION_LEVELS`) holds the true (x, y)."""


def calibration(results: Sequence[RunResult]) -> list[dict[str, Any]]:
    """One row of :data:`CALIBRATION_COLUMNS` per scenario and particle filter
    (:data:`MCL_METHODS`), frames pooled over the runs, then one row ``all`` per filter over
    every run: the share of frames with d2 <= chi2_2(p) (``MethodTrace.d2``), in %."""
    rows = []
    order = list(dict.fromkeys(r.scenario for r in results))
    groups = [(s, [r for r in results if r.scenario == s]) for s in order]
    if len(order) > 1:
        groups.append(("all", list(results)))
    for scn, group in groups:
        for m in MCL_METHODS:
            d2 = np.concatenate([r.methods[m].d2 for r in group])
            row: dict[str, Any] = {"scenario": scn, "method": m, "runs": len(group),
                                   "frames": int(d2.size)}
            for lv, col in zip(CALIBRATION_LEVELS, CALIBRATION_COLUMNS[4:], strict=True):
                row[col] = 100.0 * float(np.mean(d2 <= chi2_2d(lv))) if d2.size else math.nan
            rows.append(row)
    return rows
