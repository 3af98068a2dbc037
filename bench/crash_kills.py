"""Writers killed with SIGKILL, and whether what they left reads back (issue 33).

    python bench/crash_kills.py --kills 50
    python bench/crash_kills.py --kills 200 --target write --target replay

Each target's job is started ``--kills`` times in a process forked from a fork server and killed
with SIGKILL at a random moment (``tileviz.testing.crash`` says which moments and what is checked
after each kill): ``write`` (a DatasetWriter, killed three times in ten right after an image before
its row, three right after a row, three anywhere, one between the set-up's files), ``record``
(``python -m tileviz record``), ``record-button`` (the demo's Record: a live session recording),
``replay`` (``replay --out --mcap``), ``evaluate`` (a campaign killed, resumed with ``--resume``,
killed again; at the end resumed to its end and compared with an uninterrupted campaign). Prints
per target the kills, the frames (runs) the kills left and checked, and the kills whose leftovers
failed a check, with the first failure; the exit status is 1 when one did.
"""

from __future__ import annotations

import argparse
import random
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from tileviz.testing.crash import (
    EVALUATE,
    HOOKS,
    Rig,
    kill_evaluate,
    kill_record,
    kill_replay,
    kill_session,
    kill_write,
    replay_reference,
    runs_table,
)

TARGETS = ("write", "record", "record-button", "replay", "evaluate")


def _tally(kills: int, one: Callable[[int], int]) -> tuple[int, int, str]:
    """(frames kept over the kills, kills that failed a check, the first failure)."""
    kept, failed, first = 0, 0, ""
    for i in range(kills):
        try:
            kept += max(0, one(i))
        except AssertionError as e:
            failed += 1
            first = first or f"kill {i}: {e}"[:300]
    return kept, failed, first


def _target(target: str, kills: int, rng: random.Random, cold: Rig | None, warm: Rig | None,
            work: Path) -> tuple[int, int, str]:
    """Kill ``target``'s job ``kills`` times in ``work``: :func:`_tally`'s figures."""

    def fresh(i: int) -> Path:
        folder = work / f"k{i}"
        if folder.exists():
            shutil.rmtree(folder)
        return folder

    if target in ("write", "record", "record-button"):
        assert cold is not None
        c = cold
        if target == "write":
            cycle = [HOOKS[0], HOOKS[1], HOOKS[3]] * 3 + [HOOKS[2]]  # (image, row, none) x3, setup
            return _tally(kills, lambda i: kill_write(c, fresh(i), cycle[i % 10], rng))
        if target == "record":
            return _tally(kills, lambda i: kill_record(c, fresh(i), rng))

        def button(i: int) -> int:
            folder = fresh(i)
            folder.mkdir()
            return kill_session(c, folder, rng)

        return _tally(kills, button)
    assert warm is not None
    w = warm
    if target == "replay":
        from tileviz.__main__ import main as tileviz_main

        ds = work / "ds"
        assert tileviz_main(["record", str(ds), "--duration", "2", "--quiet", "--seed", "3"]) == 0
        want = replay_reference(w, ds, work)
        return _tally(kills, lambda i: kill_replay(w, ds, work / "k.csv", work / "k.mcap", want,
                                                   rng))
    t0 = time.monotonic()
    clean = w.run(job="cli", argv=[*EVALUATE, "--out", str(work / "clean")])
    span = time.monotonic() - t0
    assert clean.finished, clean
    out = work / "killed"
    kept, failed, first = _tally(kills, lambda i: kill_evaluate(w, out, span, rng))
    resume = ["--resume", str(out)] if (out / "runs.csv").exists() else ["--out", str(out)]
    last = w.run(job="cli", argv=[*EVALUATE, *resume])
    if not last.finished or runs_table(out) != runs_table(work / "clean"):
        failed += 1
        first = first or "the resumed campaign's table is not the uninterrupted one's"
    return kept, failed, first


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kills", type=int, default=50, help="kills per target (default 50)")
    ap.add_argument("--target", action="append", choices=TARGETS,
                    help="kill only this job (repeat for several; default all)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    targets = args.target or list(TARGETS)
    rng = random.Random(args.seed)
    tmp = Path(tempfile.mkdtemp(prefix="crash-kills-"))
    rows: list[tuple[str, int, int, int, str, float]] = []
    cold = Rig() if {"write", "record", "record-button"} & set(targets) else None
    warm = Rig(warm=True) if {"replay", "evaluate"} & set(targets) else None
    try:
        for target in targets:
            start = time.monotonic()
            work = tmp / target
            work.mkdir()
            got = _target(target, args.kills, rng, cold, warm, work)
            rows.append((target, args.kills, *got, time.monotonic() - start))
            shutil.rmtree(work, ignore_errors=True)
            print(f"{target}: {got[0]} kept, {got[1]} failed ({time.monotonic() - start:.0f} s)",
                  flush=True)
    finally:
        for rig in (cold, warm):
            if rig is not None:
                rig.close()
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"command: python bench/crash_kills.py --kills {args.kills} --seed {args.seed}"
          + "".join(f" --target {t}" for t in args.target or ()))
    print(f"{'target':<15}{'kills':>7}{'kept':>9}{'failed':>8}{'seconds':>9}")
    for target, kills, kept, failed, _, secs in rows:
        print(f"{target:<15}{kills:>7}{kept:>9}{failed:>8}{secs:>9.0f}")
    print("kept: frames the killed jobs left, each read back and checked (evaluate: the runs "
          "--resume read back after each kill)")
    for target, _, _, failed, first, _ in rows:
        if failed:
            print(f"{target}: {first}")
    return 1 if any(r[3] for r in rows) else 0


if __name__ == "__main__":
    raise SystemExit(main())
