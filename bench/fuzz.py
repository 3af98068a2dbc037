"""Fuzz every reader a user's file reaches (issue 33): meta.json, camera_model, frames.csv,
faults.csv, dataset images, extract's images, ROS bags (import-bag), evaluate --resume stores.

    python bench/fuzz.py --cases 10000                       # every reader, 10 000 cases each
    python bench/fuzz.py --cases 2000 --reader image --reader extract
    python bench/fuzz.py --cases 5000 --reader frames --engine atheris
    python bench/fuzz.py --cases 10000 --minutes 50   # what fits in 50 minutes

Each case is one damaged or odd input file run through the command that reads it, in worker
processes (``tileviz/testing/fuzzing.py`` describes the readers, the cases and the outcomes).
Engines: ``hypothesis`` (structured cases from strategies), ``mutate`` (valid files mutated at
random) and, when ``pip install atheris`` works, ``atheris`` (coverage-guided mutation by
libFuzzer, in-process, one process per reader). Prints a table per reader: cases, outcomes, the
peak resident set of the workers and the slowest case; then every finding (traceback, hang,
memory) with the start of its input, saved whole under ``--save DIR``. The exit status is 1 when
there was a finding.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tileviz.testing.fuzz_cases import READERS
from tileviz.testing.fuzzing import (
    OUTCOMES,
    Finding,
    Report,
    Result,
    campaign,
    describe,
)


def _atheris_worker(reader: str, runs: int, seed: int, timeout: float, log: str) -> None:
    """One reader under libFuzzer (atheris); every case's outcome appended to ``log`` (JSON
    lines), the inputs of the bad ones too."""
    import atheris

    from tileviz.testing.fuzz_cases import Templates
    from tileviz.testing.fuzzing import _captured, run_case

    tmp = Path(tempfile.mkdtemp(prefix="fuzz-atheris-"))
    with _captured(tmp):
        t = Templates(tmp)
        import tileviz.__main__  # noqa: F401 - every reader loaded before instrumenting
        import tileviz.datasets.bag_import  # noqa: F401
        import tileviz.evaluation.report  # noqa: F401
        import tileviz.pipeline.replay  # noqa: F401
        import tileviz.vision.cli  # noqa: F401
    atheris.instrument_all()  # libFuzzer's coverage of the Python code loaded
    seeds = t.seeds(reader)
    corpus = tmp / "corpus"
    corpus.mkdir()
    for i, (_, data) in enumerate(seeds):
        (corpus / f"seed{i}").write_bytes(bytes([i]) + data)
    out = open(log, "a")  # noqa: SIM115 - the process's whole life

    def one(data: bytes) -> None:
        if not data:
            return
        variant = seeds[data[0] % len(seeds)][0]
        res = run_case(reader, variant, data[1:], t)
        row = {"outcome": res.outcome, "message": res.message, "seconds": res.seconds,
               "rss": res.maxrss_mb}
        if res.outcome not in ("ok", "error"):
            row["input"] = data[1:].hex()
            row["variant"] = variant
        out.write(json.dumps(row) + "\n")
        out.flush()

    atheris.Setup([sys.argv[0], f"-runs={runs}", f"-seed={seed + 1}",
                   f"-timeout={int(timeout)}", "-rss_limit_mb=2048", "-max_len=400000",
                   str(corpus)], one)
    atheris.Fuzz()


def _atheris(readers: list[str], n: int, seed: int, timeout: float) -> Report:
    counts = {r: dict.fromkeys(OUTCOMES, 0) for r in readers}
    findings: list[Finding] = []
    peak = slowest = 0.0
    start = time.monotonic()
    for reader in readers:
        log = Path(tempfile.mkdtemp(prefix="fuzz-log-")) / "cases.jsonl"
        log.touch()
        seen = 0
        while seen < n:
            r = subprocess.run([sys.executable, __file__, "--atheris-worker", reader, "--cases",
                                str(n - seen), "--seed", str(seed + seen),
                                "--timeout", str(timeout), "--log", str(log)],
                               capture_output=True, text=True)
            rows = [json.loads(x) for x in log.read_text().splitlines()]
            if len(rows) == seen:  # it ended without a case: a hang or a crash of libFuzzer
                counts[reader]["hang" if "timeout" in r.stderr else "traceback"] += 1
                findings.append(Finding(reader, "atheris", seen, "?", b"", Result(
                    "hang" if "timeout" in r.stderr else "traceback", r.stderr[-500:])))
                seen += 1
                continue
            for i, row in enumerate(rows[seen:], start=seen):
                counts[reader][row["outcome"]] += 1
                peak = max(peak, row["rss"])
                slowest = max(slowest, row["seconds"])
                if "input" in row:
                    findings.append(Finding(reader, "atheris", i, row["variant"],
                                            bytes.fromhex(row["input"]),
                                            Result(row["outcome"], row["message"])))
            seen = len(rows)
            if r.returncode != 0 and "timeout" in r.stderr:  # libFuzzer stopped at a hang
                counts[reader]["hang"] += 1
                findings.append(Finding(reader, "atheris", seen, "?", b"",
                                        Result("hang", r.stderr[-500:])))
    return Report(counts, findings, peak, time.monotonic() - start, slowest)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=1000, help="cases per reader (default 1000)")
    ap.add_argument("--reader", action="append", choices=READERS,
                    help="fuzz only this reader (repeat for several; default all)")
    ap.add_argument("--engine", action="append", choices=("hypothesis", "mutate", "atheris"),
                    help="case makers (repeat; default hypothesis and mutate, half each)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--timeout", type=float, default=60.0,
                    help="seconds a case may take before it counts as a hang (default 60)")
    ap.add_argument("--minutes", type=float, default=None,
                    help="time budget: no case starts after it (the readers' cases run "
                    "interleaved, so each stops at about the same count); default none")
    ap.add_argument("--save", default=None, metavar="DIR", help="write each finding's input here")
    ap.add_argument("--atheris-worker", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--log", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.atheris_worker:
        _atheris_worker(args.atheris_worker, args.cases, args.seed, args.timeout, args.log)
        return 0
    readers = args.reader or list(READERS)
    engines = tuple(args.engine or ("hypothesis", "mutate"))
    command = "python bench/fuzz.py " + " ".join(sys.argv[1:])
    if "atheris" in engines:
        try:
            import atheris  # noqa: F401
        except ImportError:
            print("fuzz: atheris is not installed (pip install atheris); use --engine "
                  "hypothesis/mutate")
            return 2
        if len(engines) > 1:
            print("fuzz: --engine atheris runs alone (one libFuzzer process per reader)")
            return 2
        report = _atheris(readers, args.cases, args.seed, args.timeout)
    else:
        report = campaign(readers, args.cases, engines=engines, seed=args.seed,
                          workers=args.workers, timeout=args.timeout, minutes=args.minutes,
                          progress=lambda s: print(s, file=sys.stderr, flush=True))
    print(f"command: {command}")
    print(f"{'reader':<13}" + "".join(f"{o:>10}" for o in ("cases", *OUTCOMES)))
    for reader, c in report.counts.items():
        print(f"{reader:<13}{sum(c.values()):>10}" + "".join(f"{c[o]:>10}" for o in OUTCOMES))
    ran = sum(sum(c.values()) for c in report.counts.values())
    print(f"peak resident set a case raised a worker to: {report.peak_rss_mb:.0f} MB; slowest case "
          f"{report.slowest_s:.1f} s; {report.seconds / 60:.1f} min in all ({ran} cases, "
          f"{ran / report.seconds:.1f} cases/s, case making included)")
    for f in report.findings:
        print(describe(f))
    if args.save and report.findings:
        folder = Path(args.save)
        folder.mkdir(parents=True, exist_ok=True)
        for f in report.findings:
            (folder / f"{f.reader}-{f.engine}-{f.index}-{f.variant.replace('/', '_')}").write_bytes(
                f.data)
        print(f"inputs of the findings written to {folder}")
    return 1 if report.findings else 0


if __name__ == "__main__":
    raise SystemExit(main())
