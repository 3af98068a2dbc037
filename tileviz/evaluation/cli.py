"""``python -m tileviz evaluate``: its options and its entry point (:func:`main`)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from tileviz.baselines.mcl import CAL_MIN_PARTICLES
from tileviz.cliutil import (
    CliError,
    Parser,
    add_fault_options,
    nonneg_float,
    positive_float,
    positive_int,
    run_cli,
)
from tileviz.config import LocalizerConfig
from tileviz.evaluation.campaign import evaluate
from tileviz.evaluation.cluster import parse_scheduler
from tileviz.evaluation.report import figures, write_outputs
from tileviz.evaluation.scenarios import DEFAULT_SCENARIOS, SCENARIOS
from tileviz.evaluation.store import RunStore
from tileviz.summary import FAITHFUL_NOTE, counted

__all__ = ["main"]


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
    add_fault_options(p, relocalize=False,
                      note="; the interval-recovery method uses max_slip instead")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on a Dask cluster: tcp://host:8786 (a running scheduler) or "
                   "local:N (a local cluster of N worker processes); needs "
                   "pip install -e '.[cluster]'; --jobs is then unused")
    p.add_argument("--out", default=None, help="output folder (default out/eval)")
    p.add_argument("--resume", default=None, metavar="OUT",
                   help="continue the campaign in folder OUT: the runs already in OUT/runs.csv "
                   "are not made again (same settings needed); writes to OUT")
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
        if args.resume and args.out and Path(args.out) != Path(args.resume):
            raise CliError(f"--resume {args.resume} writes to {args.resume}; drop --out "
                           f"{args.out}")
        out = Path(args.resume or args.out or "out/eval")
        if out.exists() and not out.is_dir():
            raise CliError(f"--out {out} exists and is not a folder")
        if args.scheduler is not None:
            parse_scheduler(args.scheduler)
        model = args.fault_model or (LocalizerConfig().fault_speed,
                                     LocalizerConfig().fault_yaw_rate)
        settings = {"duration": args.duration, "particles": args.particles,
                    "mcl_inject": args.mcl_inject, "mcl_sigma_scale": args.mcl_sigma_scale,
                    "fault_model": list(model)}
        store = RunStore.open(out, settings, resume=args.resume is not None)
        wanted = {(s, r, args.seed + r) for s in scenarios for r in range(args.runs)}
        kept = store.done & wanted
        if kept:
            print(f"resuming: {len(kept)} of {len(wanted)} runs already in {out / 'runs.csv'}")
        try:
            made = evaluate(scenarios, runs=args.runs, duration=args.duration, jobs=args.jobs,
                            seed=args.seed, particles=args.particles,
                            mcl_inject=args.mcl_inject, mcl_sigma_scale=args.mcl_sigma_scale,
                            fault_model=tuple(model), progress=not args.quiet, on_result=store.add,
                            scheduler=args.scheduler, skip=kept)
        except KeyboardInterrupt:
            n = len(store.done & wanted)
            sys.stderr.write(f"tileviz {command}: interrupted; {n} of {len(wanted)} finished "
                             f"runs kept in {out / 'runs.csv'} (continue with --resume {out})\n")
            return 130
        rank = {s: i for i, s in enumerate(scenarios)}
        earlier = store.results(kept)
        results = sorted(made + earlier, key=lambda r: (rank[r.scenario], r.run))
        cmd = "python -m tileviz evaluate " + " ".join(argv)
        notes = [f"MCL (untuned): {args.particles} particles, likelihood sigma = "
                 f"{args.mcl_sigma_scale} x the declared bounds, injection rate "
                 f"{args.mcl_inject}; MCL (calibrated): the measured view error model, "
                 f"roughening, KLD-sampling of {min(CAL_MIN_PARTICLES, args.particles)} to "
                 f"{args.particles} particles, AMCL recovery with sensor resetting in place "
                 f"(tileviz/baselines/mcl.py); "
                 f"{counted(args.runs, 'run')} of {args.duration:g} s per scenario, seeds "
                 f"{args.seed}.."
                 f"{args.seed + args.runs - 1}.",
                 "interval (autonomous): " + (
                     f"fault model {model[0]:g} m/s, {model[1]:g} rad/s beyond the odometry "
                     "bounds (--fault-model)" if model[0] > 0 or model[1] > 0 else
                     "no fault model (--fault-model 0,0)") + "; interval (recovery on): "
                 "max_slip recovery, no fault model."]
        faithful = [s for s in scenarios if SCENARIOS[s].config(0).vision.extractor == "faithful"]
        if faithful:
            notes.append(f"Scenario {', '.join(faithful)}: {FAITHFUL_NOTE}.")
        rows = write_outputs(results, out, cmd.strip(), notes)
        for line in figures(rows):
            print(line)
        print(f"wrote {out / 'results.md'}, {out / 'results.csv'}, {out / 'runs.csv'} and plots")
        return 0

    return run_cli(f"tileviz {command}", body)
