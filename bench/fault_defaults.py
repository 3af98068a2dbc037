"""The fault model's default: what turning it on costs and changes.

    python bench/fault_defaults.py              # all three measures
    python bench/fault_defaults.py --skip-dataset
    python -m bench.fault_defaults --frames 500 --repeats 2 --write-figures

1. CPU: ``Localizer.step`` per frame, fault model off and on, on the drive of
   ``bench/bench_localizer.py`` (:func:`tileviz.testing.drives.make_run`: both presets, mode
   autonomous, sensors within their bounds), best of ``--repeats``.
2. Clean runs: every output of every frame (both box sets bit for bit, status, flags) with the
   model off and on, on those drives and on the recorded inputs of
   ``tests/data/localizer_golden.npz`` (outlier views, missing compass readings and views, wide
   heading bounds; some sequences also hold slips and kidnaps: those are expected to differ).
3. The fault dataset of ``tileviz/testing/fault_dataset.py`` (a 2 s slip of 0.15 m/s beyond the
   speed bound, a kidnap of (0.37, -0.21) m, 0.3 rad, a 2 s dropout) replayed (``tileviz
   replay``) with several fault models: longest run of vouched frames without the truth,
   ``lost`` frames from 20 frames after the slip to the kidnap, median hull width there, frames
   from the kidnap to ``lost``, and the widest hull vouched as one box.

The figures go to stdout; ``--write-figures`` also writes them into ``docs/figures.md``
(``figures:fault_defaults``).
"""

from __future__ import annotations

import argparse
import csv
import statistics
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from tileviz.config import LocalizerConfig, preset, with_overrides
from tileviz.testing.drives import localizer_of, make_run, time_step
from tileviz.testing.figures import Machine, write_block
from tileviz.testing.golden import first_difference, load, run_localizer
from tileviz.types import Box

MODELS = ((0.0, 0.0), (0.1, 0.05), (0.2, 0.1), (0.3, 0.2), (0.5, 0.3))
"""Fault models tried on the fault dataset (m/s, rad/s)."""


def _with_model(c: LocalizerConfig, model: tuple[float, float]) -> LocalizerConfig:
    return replace(c, fault_speed=model[0], fault_yaw_rate=model[1])


def _outputs(cfg, run) -> list[tuple]:
    loc = localizer_of(cfg)
    out = []
    for f in run:
        s = loc.step(f["odometry"], f["compass"], f["observation"], f["truth"])
        out.append((s.status, s.predicted.boxes, s.updated.boxes, s.hulled, s.compass_rejected,
                    s.rejections))
    return out


def cpu_and_clean(model: tuple[float, float], frames: int,
                  repeats: int) -> list[tuple[str, str]]:
    """Measure 1 and 2 on the drives; their figure rows."""
    rows = []
    print(f"== CPU and clean drives ({frames} frames, model {model[0]} m/s, {model[1]} rad/s)")
    for name in ("default", "seed"):
        cfg = with_overrides(preset(name), localizer={"mode": "autonomous"})
        cfg_off = replace(cfg, localizer=_with_model(cfg.localizer, (0.0, 0.0)))
        cfg_on = replace(cfg, localizer=_with_model(cfg.localizer, model))
        run = make_run(cfg, frames, 7)
        off_us = time_step(cfg_off, run, repeats)
        on_us = time_step(cfg_on, run, repeats)
        same = _outputs(cfg_off, run) == _outputs(cfg_on, run)
        print(f"   {name}: Localizer.step {off_us:.1f} us/frame off, {on_us:.1f} on "
              f"(x{on_us / off_us:.2f}); outputs identical: {same}")
        rows += [(f"{name} drive: Localizer.step, model off / on",
                  f"{off_us:.1f} / {on_us:.1f} us/frame"),
                 (f"{name} drive: outputs with the model on", "identical" if same else "differ")]
    return rows


def golden(model: tuple[float, float]) -> None:
    print("== recorded inputs of tests/data/localizer_golden.npz, model off vs on")
    for name, (setup, inputs, _) in load().items():
        off = dict(setup, config=dict(setup["config"], fault_speed=0.0, fault_yaw_rate=0.0))
        on = dict(setup, config=dict(setup["config"], fault_speed=model[0],
                                     fault_yaw_rate=model[1]))
        a, b = run_localizer(off, inputs), run_localizer(on, inputs)
        counts = [np.bincount(x["scalars"][:, 0], minlength=4).tolist() for x in (a, b)]
        diff = first_difference(a, b)
        print(f"   {name:20s} {'identical' if diff is None else 'differs: ' + diff}; "
              f"statuses (contracted, predicted, rejected, lost) off {counts[0]} on {counts[1]}")


def dataset(models: tuple[tuple[float, float], ...]) -> list[tuple[str, str]]:
    """Measure 3; its figure rows."""
    figs = []
    from tileviz.pipeline.replay import replay
    from tileviz.testing.exact_truth import in_box
    from tileviz.testing.fault_dataset import FaultPlan, make_fault_dataset

    plan = FaultPlan()
    print(f"== fault dataset ({plan.frames} frames: slip {plan.slip_at}-"
          f"{plan.slip_at + plan.slip_frames - 1}, kidnap {plan.kidnap_at}, dropout "
          f"{plan.dropout_at}-{plan.dropout_at + plan.dropout_frames - 1})")
    with tempfile.TemporaryDirectory() as tmp:
        ds = make_fault_dataset(Path(tmp) / "ds", plan)
        with open(ds / "frames.csv", newline="") as f:
            truth = [(float(r["x"]), float(r["y"]), float(r["theta"])) for r in csv.DictReader(f)]
        for model in models:
            out = Path(tmp) / "out.csv"
            replay(ds, out=out, jobs=1, fault_model=model)
            with open(out, newline="") as f:
                rows = list(csv.DictReader(f))
            streak = best = 0
            one_box_width = 0.0
            inside, status, width = [], [], []
            for r, t in zip(rows, truth, strict=True):
                box = Box(*(float(r[k]) for k in ("x_lo", "x_hi", "y_lo", "y_hi", "theta_lo",
                                                   "theta_hi")))
                ok = in_box(box, *t)
                inside.append(ok)
                status.append(r["status"])
                width.append(max(box.x_hi - box.x_lo, box.y_hi - box.y_lo))
                streak = streak + 1 if r["status"] != "lost" and not ok else 0
                best = max(best, streak)
                if r["status"] != "lost" and r["boxes"] == "1":
                    one_box_width = max(one_box_width, width[-1])
            a, b = plan.slip_at + plan.slip_frames + 20, plan.kidnap_at or plan.frames
            lost = sum(s == "lost" for s in status[a:b])
            med = statistics.median(width[a:b]) if lost < b - a else float("nan")
            to_lost = next((k - plan.kidnap_at for k in range(plan.kidnap_at, plan.frames)
                            if status[k] == "lost"), None) if plan.kidnap_at else None
            wrong = sum(s != "lost" and not ok for s, ok in zip(status, inside, strict=True))
            print(f"   model {model[0]:.2f} m/s {model[1]:.2f} rad/s: longest vouched run "
                  f"without the truth {best}, vouched without the truth {wrong} frames in all; "
                  f"lost {lost}/{b - a} from slip end + 20 to the kidnap, median width there "
                  f"{100 * med:.1f} cm; kidnap -> lost in {to_lost} frames; widest one-box "
                  f"vouched hull {100 * one_box_width:.1f} cm")
            width_cm = "-" if med != med else f"{100 * med:.1f} cm"
            kidnap = "never" if to_lost is None else f"{to_lost} frames"
            figs += [(f"fault dataset, model {model[0]:g} m/s, {model[1]:g} rad/s: longest "
                      "vouched run without the truth; kidnap to lost", f"{best} frames; {kidnap}"),
                     (f"fault dataset, model {model[0]:g} m/s, {model[1]:g} rad/s: lost after "
                      "the slip; median width there", f"{lost} of {b - a} frames; {width_cm}")]
    return figs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--skip-dataset", action="store_true")
    ap.add_argument("--write-figures", action="store_true",
                    help="also write the figures into docs/figures.md (figures:fault_defaults)")
    args = ap.parse_args()
    machine = Machine()
    model = (LocalizerConfig().fault_speed, LocalizerConfig().fault_yaw_rate)
    if model == (0.0, 0.0):
        model = (0.2, 0.1)
    rows = cpu_and_clean(model, args.frames, args.repeats)
    golden(model)
    if not args.skip_dataset:
        rows += dataset(MODELS)
    if args.write_figures:
        write_block("fault_defaults", "The default fault model: what it costs and changes",
                    rows, machine=machine)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
