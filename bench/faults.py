"""Faults: detection delay, recovery time and containment per fault type.

    python bench/faults.py                       # 3 seeds on `default`, 1 on `seed`, 2 processes
    python bench/faults.py --seeds 5 --seed-preset-seeds 2 --jobs 1
    python bench/faults.py --out ''              # print only, do not write docs/eval/faults.md
    python -m bench.faults --seeds 1 --seed-preset-seeds 0 --out '' --write-figures

Each run simulates the preset (``SimSource``, Lissajous setpoint) through ``FrameLoop`` (robust
vision, interval localizer in mode ``autonomous``), injects one fault with ``SimSource.inject``
after ``--before`` frames, and goes on for ``--after`` frames past the fault's end. Every fault
runs three times: recovery off (``LocalizerConfig.max_slip = (0, 0)``, the default), on
(``max_slip`` of the preset, below) and ``model`` (the fault model :data:`FAULT_MODEL`:
``LocalizerConfig.fault_speed``, ``fault_yaw_rate``; there a frame that takes the fault set is a
recovery frame whose hypothesis held when H2', the odometry bounds widened by the model, held at
every frame before it). Frame k's fault labels are those ``SimSource`` puts on the frame; the fault
starts at the first labelled frame F and ends at the last one E (a kidnap: F = E, the first frame
at the new pose).

Measures, per run:

- detection delay: frames from F to the first frame where the method noticed something: a view
  refused by vision, a view ``rejected`` by the localizer, a compass that misses the set, or
  ``lost``. "not needed" when the fault broke no bound the localizer relies on (H2 odometry, H3
  compass, H4 for the views it used, from F to E + 1) and nothing was noticed; "never" when it
  broke one unnoticed.
- recovery time: frames from E to the first later frame that is vouched for (not ``lost``) and
  contains the truth; "never" when there is none (e.g. ``lost``).

Detection and recovery are computed by ``tileviz.evaluation.event_outcomes`` (and
``tileviz.evaluation.noticed``), the code behind the same columns of ``python -m tileviz evaluate``.
- containment: over the frames from F to the end whose status vouches for the set (every status
  but ``lost``), the share whose set contains the true pose.
- wrong vouched frames are then explained or not: each must belong to a run of consecutive
  frames without the truth that starts at a frame where a hypothesis was broken (checked from the
  simulator's truth: H2 with ``tileviz.sim.sensors.prediction_encloses``, H3, H4 with
  ``tileviz.vision.observation_error``; a kidnap breaks H2), and no frame of that run may be a
  recovery frame whose own hypothesis held (H5: the truth within ``max_slip`` of the prediction,
  its view within its bounds). Anything else is "unexplained": a bug in the guarantee.
- views that vision accepted on a faulty frame although they were outside their declared bounds
  are listed with seed, frame and true pose (they would be the vision's fault).

The ``model`` setting is the default ``LocalizerConfig`` (fault model 0.2 m/s, 0.1 rad/s);
``off`` turns the fault model off, ``on`` uses ``max_slip`` (which replaces the fault model).

Recovery setting (``max_slip``, metres and radians, ``tileviz.evaluation.RECOVERY_MAX_SLIP``, the
``interval-recovery`` method of the evaluation): ``default`` (0.1, 0.1), ``seed`` (0.04, 0.1) --
below half a tile minus the tracking set's width, so a re-inflation leaves one lattice cell
(``tileviz.core.localizer``, "Recovery").

The Markdown table goes to stdout and to ``--out`` (default ``docs/eval/faults.md``, the results
page of ``docs/faults.md``); ``--write-figures`` writes the fault model's rows (every fault, the
default preset) into ``docs/figures.md`` (``figures:faults``).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from tileviz.config import Config, LocalizerConfig, preset
from tileviz.evaluation import RECOVERY_MAX_SLIP, event_outcomes, noticed
from tileviz.pipeline import FrameLoop, FrameRecord
from tileviz.sim.sensors import prediction_encloses
from tileviz.sim.source import SimSource
from tileviz.testing.figures import Machine, write_block
from tileviz.types import Box
from tileviz.vision import observation_error, set_opencv_threads

set_opencv_threads()  # as every tileviz entry point (workers re-run this on import)

MAX_SLIP = RECOVERY_MAX_SLIP
"""Recovery setting per preset (metres, radians)."""
FAULT_MODEL = (LocalizerConfig().fault_speed, LocalizerConfig().fault_yaw_rate)
"""The fault model of the third setting, the default (``LocalizerConfig.fault_speed``,
``fault_yaw_rate``: m/s, rad/s beyond the odometry bounds), every preset."""
SETTINGS = ("off", "on", "model")
"""Recovery off, ``max_slip`` on, the fault model on."""


@dataclass(frozen=True)
class FaultSpec:
    """One fault: a table label and how to inject it into a SimSource (``inject(src, cfg)``)."""

    label: str
    kind: str
    inject: Callable[[SimSource, Config], None]
    note: str = ""


def _camera(kind: str, frames: int) -> Callable[[SimSource, Config], None]:
    return lambda src, cfg: src.inject(kind, frames=frames)


def _kidnap(dx_tiles: float, dy_tiles: float, dtheta: float,
            metres: tuple[float, float] | None = None) -> Callable[[SimSource, Config], None]:
    """A teleport by (dx, dy) (in tiles, or in metres when ``metres``) and dtheta rad."""

    def go(src: SimSource, cfg: Config) -> None:
        p = src.pose
        L = cfg.floor.tile_size
        dx, dy = metres if metres is not None else (dx_tiles * L, dy_tiles * L)
        src.inject("kidnap", x=p.x + dx, y=p.y + dy, theta=p.theta + dtheta)

    return go


def fault_specs(name: str) -> list[FaultSpec]:
    """The faults for preset ``name`` (kidnap distances scale with its max_slip)."""
    d, _ = MAX_SLIP[name]
    return [
        FaultSpec("cable", "cable", _camera("cable", 20), "1 s"),
        FaultSpec("shoe box", "box", _camera("box", 20), "1 s"),
        FaultSpec("shadow edge", "shadow", _camera("shadow", 20), "1 s"),
        FaultSpec("glare", "glare", _camera("glare", 20), "1 s"),
        FaultSpec("heavy motion blur", "motion_blur", _camera("motion_blur", 20), "1 s, 25 px"),
        FaultSpec("camera dropout", "dropout", _camera("dropout", 40), "2 s"),
        FaultSpec("wheel slip", "slip", lambda src, cfg: src.inject("slip", frames=40),
                  "2 s, +0.1 m/s, +0.05 rad/s beyond the bounds"),
        FaultSpec("odometry outlier", "odometry_outlier",
                  lambda src, cfg: src.inject("odometry_outlier"),
                  "1 frame, +-0.5 m/s, +-0.5 rad/s"),
        FaultSpec("kidnap within max_slip", "kidnap", _kidnap(0, 0, 0.04, (0.5 * d, -0.3 * d)),
                  f"({0.5 * d:.3g}, {-0.3 * d:.3g}) m, 0.04 rad"),
        FaultSpec("kidnap beyond max_slip", "kidnap", _kidnap(0, 0, 0.3, (0.37, -0.21)),
                  "(0.37, -0.21) m, 0.3 rad"),
        FaultSpec("kidnap by one tile", "kidnap", _kidnap(1, 0, 0.0), "(L, 0) m, 0 rad"),
    ]


# --- one run ------------------------------------------------------------------------------------


@dataclass
class RunResult:
    """The measures of one run (frames are indices into the run)."""

    preset: str
    fault: str
    recovery: str
    seed: int
    start: int = -1
    end: int = -1
    detection: int | None = None
    broke: bool = False
    recovery_frames: int | None = None
    vouched: int = 0
    inside: int = 0
    wrong_explained: int = 0
    wrong_unexplained: list[int] = field(default_factory=list)
    wrong_before_fault: int = 0
    lost_frames: int = 0
    bad_views: list[str] = field(default_factory=list)
    max_width: float = 0.0


def _wrap(a: float) -> float:
    return math.remainder(a, 2.0 * math.pi)


def _view_ok(rec: FrameRecord, cfg: Config) -> bool | None:
    """H4 for this frame's view (None when there is no view or no truth)."""
    obs = rec.vision.observation
    if obs is None or rec.truth is None:
        return None
    e1, e2, e3 = observation_error(obs, rec.truth, cfg.floor.tile_size, cfg.camera.offset)
    return (abs(e1) <= obs.position_error and abs(e2) <= obs.position_error
            and abs(e3) <= obs.heading_error)


def _near(rec: FrameRecord, max_slip: tuple[float, float]) -> bool | None:
    """H5 at a re-inflating frame: the truth within max_slip of the prediction (None when it
    cannot be told: with a compass miss ``predicted`` holds more than the prediction)."""
    if rec.step is None or rec.step.compass_rejected or rec.truth is None:
        return None
    d, a = max_slip
    t = rec.truth
    return any(
        Box(b.x_lo - d, b.x_hi + d, b.y_lo - d, b.y_hi + d, b.t_lo - a, b.t_hi + a).contains(
            t.x, t.y, t.theta)
        for b in rec.predicted.boxes
    )


def run_one(name: str, seed: int, spec: FaultSpec, recovery: str, before: int,
            after: int) -> RunResult:
    """Simulate, inject ``spec`` after ``before`` frames, go on ``after`` frames past its end;
    ``recovery``: one of :data:`SETTINGS`."""
    cfg = preset(name)
    max_slip = MAX_SLIP[name] if recovery == "on" else (0.0, 0.0)
    fs, fw = FAULT_MODEL if recovery == "model" else (0.0, 0.0)
    cfg = replace(cfg, sim=replace(cfg.sim, seed=seed), floor=replace(cfg.floor, seed=seed + 1),
                  localizer=replace(cfg.localizer, max_slip=max_slip, fault_speed=fs,
                                    fault_yaw_rate=fw))
    within_model = True  # H2' (the bounds widened by the fault model) held at every frame so far
    nz = cfg.noise
    src = SimSource(cfg)
    runner = FrameLoop(cfg)
    res = RunResult(name, spec.label, recovery, seed)
    # per frame, for tileviz.evaluation.event_outcomes
    faults: list[bool] = []
    alarms: list[bool] = []
    vouches: list[bool] = []
    insides: list[bool] = []
    holds: list[bool] = []  # no hypothesis broken at the frame
    prev: FrameRecord | None = None
    chain = False  # inside a run of frames without the truth that a broken hypothesis started
    k = 0
    while True:
        if k == before:
            spec.inject(src, cfg)
        frame = next(src)
        rec = runner.process(frame)
        faulty = spec.kind in frame.faults
        if faulty:
            if res.start < 0:
                res.start = k
            res.end = k
        started = res.start >= 0
        truth = rec.truth
        assert truth is not None
        # the hypotheses at this frame, from the simulator's truth
        broken = "kidnap" in frame.faults
        if prev is not None and prev.odometry is not None and prev.truth is not None:
            broken |= not prediction_encloses(prev.truth.as_tuple(), truth.as_tuple(),
                                              prev.odometry, nz.speed_error, nz.yaw_rate_error)
            within_model &= prediction_encloses(prev.truth.as_tuple(), truth.as_tuple(),
                                                prev.odometry, nz.speed_error + fs,
                                                nz.yaw_rate_error + fw)
        within_model &= "kidnap" not in frame.faults
        if rec.compass is not None:
            broken |= abs(_wrap(rec.compass - truth.theta)) > nz.compass_error + 1e-12
        view_ok = _view_ok(rec, cfg)
        step = rec.step
        reinflated = step is not None and step.reinflated
        if view_ok is False and (rec.status == "contracted" or reinflated):
            broken = True
            if faulty:
                res.bad_views.append(
                    f"{name} seed {seed} frame {k} ({spec.kind}): pose ({truth.x:.4f}, "
                    f"{truth.y:.4f}, {truth.theta:.4f}), status {rec.status}")
        inside = rec.updated.contains(truth.x, truth.y, truth.theta)
        faults.append(faulty)
        alarms.append(noticed(rec.status, step is not None and step.compass_rejected,
                              rec.vision.accepted, step is not None and step.reinflated))
        vouches.append(rec.status != "lost")
        insides.append(inside)
        holds.append(not broken)
        if broken:
            chain = True
        if recovery == "model":  # H2' held throughout: the fault set holds the truth
            repaired = reinflated and within_model and view_ok is not False
        else:
            repaired = reinflated and _near(rec, max_slip) is True and view_ok is not False
        if inside:
            chain = False
        vouched = rec.status != "lost"
        if started:
            hull = rec.updated.hull()
            if hull is not None and vouched:
                res.max_width = max(res.max_width, hull.widths[0], hull.widths[1])
            if vouched:
                res.vouched += 1
                res.inside += inside
            else:
                res.lost_frames += 1
            if vouched and not inside:
                if chain and not repaired:
                    res.wrong_explained += 1
                else:
                    res.wrong_unexplained.append(k)
        elif vouched and not inside:
            res.wrong_before_fault += 1
        prev = rec
        k += 1
        if started and k > res.end + after:
            break
        if k > before + 10_000:
            raise RuntimeError(f"fault {spec.label} never showed on a frame")
    events = event_outcomes(np.array(faults), np.array(alarms), np.array(vouches),
                            np.array(insides), np.array(holds))
    if len(events) != 1 or (events[0].start, events[0].end) != (res.start, res.end):
        raise RuntimeError(f"fault {spec.label}: labelled frames are not one run: {events}")
    res.detection = events[0].detection
    res.broke = not events[0].harmless
    res.recovery_frames = events[0].recovery
    return res


# --- the table ----------------------------------------------------------------------------------


def _spread(values: list[int]) -> str:
    if not values:
        return "-"
    lo, hi = min(values), max(values)
    med = statistics.median(values)
    med_s = f"{med:g}"
    return med_s if lo == hi else f"{med_s} ({lo}-{hi})"


def summarize(runs: list[RunResult]) -> list[str]:
    """One Markdown row for runs of the same preset, fault and recovery setting."""
    r0 = runs[0]
    det = [r.detection for r in runs if r.detection is not None]
    undetected = [r for r in runs if r.detection is None]
    if not undetected:
        detection = _spread(det)
    else:
        tags = []
        if any(r.broke for r in undetected):
            tags.append(f"never in {sum(r.broke for r in undetected)}")
        if any(not r.broke for r in undetected):
            tags.append(f"not needed in {sum(not r.broke for r in undetected)}")
        detection = ", ".join(([_spread(det)] if det else []) + tags)
    rec = [r.recovery_frames for r in runs if r.recovery_frames is not None]
    never = sum(r.recovery_frames is None for r in runs)
    recovery = ", ".join(([_spread(rec)] if rec else []) + ([f"never in {never}"] if never else []))
    vouched = sum(r.vouched for r in runs)
    inside = sum(r.inside for r in runs)
    contain = f"{100.0 * inside / vouched:.1f} %" if vouched else "-"
    explained = sum(r.wrong_explained for r in runs)
    unexplained = sum(len(r.wrong_unexplained) for r in runs)
    lost = sum(r.lost_frames > 0 for r in runs)
    width = max(r.max_width for r in runs)
    return [f"| {r0.preset} | {r0.fault} | {r0.recovery} | {len(runs)} | "
            f"{detection} | {recovery} | {contain} ({inside}/{vouched}) | {explained} | "
            f"{unexplained} | {lost}/{len(runs)} | {100 * width:.1f} |"]


HEADER = [
    "| preset | fault | recovery | runs | detection delay (frames) | recovery time (frames) | "
    "containment, vouched frames | wrong: hypothesis broken | wrong: unexplained | "
    "runs lost | widest vouched set (cm) |",
    "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
]


READING = """Reading the table:

- Camera faults: the robust extractor refuses the faulty frames (detection at once), the set is
  only predicted meanwhile (it grows: the last column) and keeps the truth.
- "wrong: hypothesis broken" counts vouched frames without the truth inside a run that a broken
  hypothesis started (``docs/guarantees.md``): an odometry fault not noticed yet (the first frames
  of a slip), a fault noticed with recovery off (``rejected`` frames keep the stale prediction until
  ``lost``), a kidnap beyond ``max_slip`` (H5 broken) or beyond the fault model (H2' broken: at
  most 5 frames before ``lost``), or by a whole tile (never visible).
- "wrong: unexplained" would be a failure of the guarantee itself; "before any fault" too.
"""


def _job(args: tuple[str, int, int, str, int, int]) -> RunResult:
    name, seed, index, recovery, before, after = args
    return run_one(name, seed, fault_specs(name)[index], recovery, before, after)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="seeds on the default preset")
    ap.add_argument("--seed-preset-seeds", type=int, default=1,
                    help="seeds on the seed preset (0: skip it)")
    ap.add_argument("--before", type=int, default=60, help="frames before the fault")
    ap.add_argument("--after", type=int, default=100, help="frames after the fault's end")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--out", default="docs/eval/faults.md", help="Markdown file ('' = none)")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the fault model's rows into docs/figures.md "
                    "(figures:faults)")
    args = ap.parse_args()
    machine = Machine()
    if args.seeds < 0 or args.seed_preset_seeds < 0 or args.before < 1 or args.after < 1:
        ap.error("--seeds, --seed-preset-seeds >= 0; --before, --after >= 1")
    jobs = []
    for name, n in (("default", args.seeds), ("seed", args.seed_preset_seeds)):
        for index in range(len(fault_specs(name))):
            for recovery in SETTINGS:
                for seed in range(n):
                    jobs.append((name, seed, index, recovery, args.before, args.after))
    t0 = time.perf_counter()
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(_job, jobs))
    else:
        results = [_job(j) for j in jobs]
    elapsed = time.perf_counter() - t0
    groups: dict[tuple[str, str, str], list[RunResult]] = {}
    for r in results:
        groups.setdefault((r.preset, r.fault, r.recovery), []).append(r)
    lines = list(HEADER)
    for runs in groups.values():
        lines += summarize(runs)
    notes = []
    before = sum(r.wrong_before_fault for r in results)
    notes.append(f"- wrong vouched frames before any fault: {before}")
    unexplained = [(r, k) for r in results for k in r.wrong_unexplained]
    notes.append(f"- unexplained wrong vouched frames: {len(unexplained)}"
                 + "".join(f"\n  - {r.preset} {r.fault} recovery {r.recovery} "
                           f"seed {r.seed} frame {k}" for r, k in unexplained[:20]))
    bad = [v for r in results for v in r.bad_views]
    notes.append(f"- views vision accepted on a faulty frame outside their declared bounds: "
                 f"{len(bad)}" + "".join(f"\n  - {v}" for v in bad[:20]))
    specs = {(n, s.label): s.note for n in MAX_SLIP for s in fault_specs(n)}
    faults = "\n".join(f"- {label}: {note}" for (n, label), note in specs.items()
                       if n == "default" and note)
    cmd = " ".join(["python bench/faults.py", *sys.argv[1:]])
    text = "\n".join([
        "# Faults: detection, recovery, containment (results)",
        "",
        f"Measured by `{cmd}` ({len(results)} runs, {elapsed:.0f} s). How the faults are made "
        "and measured: [faults.md](../faults.md); the guarantee and its hypotheses: "
        "[guarantees.md](../guarantees.md).",
        "Detection delay and recovery time are computed by the code behind the same columns of "
        "the evaluation table (`tileviz.evaluation.event_outcomes`): there, per scenario, over "
        "long runs with several faults, for the autonomous localizer with its fault model "
        "(`interval`, the `model` rows below) and with recovery on instead "
        "(`interval-recovery`, the `max_slip` below) "
        "([evaluation.md](../evaluation.md), [results.md](results.md)). This page adds "
        "one fault at a time, more fault types, and the explanation of every wrong vouched "
        "frame.",
        f"Fault after {args.before} frames, run on for {args.after} frames after its end; "
        "20 frames a second. Recovery `off`: no recovery and no fault model (`--fault-model "
        "0,0`); `on`: `max_slip` = "
        + ", ".join(f"{n} {v}" for n, v in MAX_SLIP.items()) + " (m, rad); `model`: "
        f"the fault model {FAULT_MODEL[0]} m/s, {FAULT_MODEL[1]} rad/s beyond the odometry "
        "bounds, every preset: **the default** (how it was chosen: `python "
        "bench/fault_defaults.py`, [guarantees.md](../guarantees.md), \"How the default was "
        "chosen\").",
        "",
        *lines,
        "",
        "Faults (default preset):",
        "",
        faults,
        "",
        "Checks over every run:",
        "",
        *notes,
        "",
        READING,
    ])
    print(text)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text, encoding="utf-8")
    if args.write_figures:
        rows = [figure_row(runs) for (name, _, setting), runs in groups.items()
                if name == "default" and setting == "model"]
        rows.append(("every run: unexplained wrong vouched frames; faulty views accepted "
                     "outside their bound", "", "", f"{len(unexplained)}; {len(bad)}"))
        write_block("faults", "Faults, one at a time", rows, machine=machine,
                    header=("fault (default preset, fault model on)", "detection delay (frames)",
                            "recovery time (frames)", "containment, vouched frames"),
                    note=f"{len(results)} runs, {elapsed:.0f} s; every preset and setting: "
                    "[eval/faults.md](eval/faults.md).")
    return 0


def figure_row(runs: list[RunResult]) -> tuple[str, str, str, str]:
    """One fault's figures: detection delay and recovery time (median and range over the runs;
    "never" where a run had none) and containment over the vouched frames."""
    cells = summarize(runs)[0].strip("| ").split(" | ")
    return runs[0].fault, cells[4], cells[5], cells[6].split(" (")[0]


if __name__ == "__main__":
    raise SystemExit(main())
