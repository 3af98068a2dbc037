"""The blocks the benches write into ``docs/figures.md`` (``--write-figures``).

Each bench that measures a figure the docs quote owns one block of that file, between the markers
``<!-- figures:NAME -->`` and ``<!-- /figures:NAME -->``: the command that made it, the date, the
commit, the machine's cores and load average, then a table of its rows (one number or a short
range per cell). :func:`write_block` replaces the bench's own block and nothing else: a section
heading and a sentence of interpretation written by a person sit outside the markers and stay. A
block not in the file yet is added at its end under a heading of its own.
"""

from __future__ import annotations

import datetime
import os
import re
import shlex
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from tileviz.testing import REPO

__all__ = ["FIGURES", "Machine", "block", "command_line", "fmt_range", "write_block"]

FIGURES = REPO / "docs" / "figures.md"
"""The file the benches write."""

MAX_CELL = 200
"""The longest a table cell may be (characters)."""


class Machine:
    """The machine a bench ran on: its cores (those this process may use, of all) and its load
    average (1 minute) when the bench started and when it ended (:meth:`end`)."""

    def __init__(self) -> None:
        self.cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (
            os.cpu_count() or 1)
        self.all_cores = os.cpu_count() or self.cores
        self.load_start = os.getloadavg()[0]
        self.load_end: float | None = None

    def end(self) -> None:
        """Note the load average at the end of the measurement."""
        self.load_end = os.getloadavg()[0]

    def describe(self) -> str:
        """E.g. "2 cores, load 0.8-1.6"."""
        cores = (f"{self.cores} cores" if self.cores == self.all_cores
                 else f"{self.cores} of {self.all_cores} cores")
        end = self.load_end if self.load_end is not None else os.getloadavg()[0]
        return f"{cores}, load {fmt_range([self.load_start, end], '.1f')}"


def fmt_range(values: Sequence[float], spec: str = ".2f", unit: str = "") -> str:
    """One value, or the range of several ("1.4-1.7"), formatted by ``spec``; "-" when none."""
    vals = [v for v in values if v == v]  # (NaN: no value)
    if not vals:
        return "-"
    lo, hi = format(min(vals), spec), format(max(vals), spec)
    text = lo if lo == hi else f"{lo}-{hi}"
    return f"{text} {unit}".rstrip()


def command_line(argv: Sequence[str] | None = None, script: str | None = None) -> str:
    """How this bench was started, as a command to type from the repository root
    (``--write-figures`` left out)."""
    args = [a for a in (sys.argv[1:] if argv is None else argv) if a != "--write-figures"]
    if script is None:
        main = Path(sys.argv[0]).resolve()
        try:
            script = str(main.relative_to(REPO))
        except ValueError:
            script = main.name
    return shlex.join(["python", script, *args])


def _commit() -> str:
    """The checkout's commit (short), "+ changes" when the working tree differs from it."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, text=True,
                              capture_output=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--",
                                ".", ":!docs/figures.md"], cwd=REPO, text=True,
                               capture_output=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown commit"
    return f"{head} + changes" if dirty else head


def block(name: str, rows: Sequence[Sequence[str]], *, command: str, machine: Machine,
          header: Sequence[str] = ("what", "figure"), note: str = "") -> str:
    """The Markdown of block ``name`` (markers included): the provenance line, the table of
    ``rows`` under ``header``, then ``note`` (a line of the bench's own, e.g. the run's time).
    ValueError when a cell is longer than :data:`MAX_CELL` characters."""
    for row in rows:
        if len(row) != len(header):
            raise ValueError(f"figures:{name}: row {row!r} has {len(row)} cells, "
                             f"the header {len(header)}")
        for cell in row:
            if len(cell) > MAX_CELL:
                raise ValueError(f"figures:{name}: cell longer than {MAX_CELL} characters: "
                                 f"{cell[:60]}...")
    date = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d")
    lines = [f"<!-- figures:{name} -->",
             f"`{command}` · {date} · commit {_commit()} · {machine.describe()}", "",
             "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(c.replace("|", "/") for c in row) + " |" for row in rows]
    if note:
        lines += ["", note]
    lines.append(f"<!-- /figures:{name} -->")
    return "\n".join(lines)


def write_block(name: str, title: str, rows: Sequence[Sequence[str]], *, machine: Machine,
                command: str | None = None, header: Sequence[str] = ("what", "figure"),
                note: str = "", path: Path = FIGURES) -> None:
    """Put block ``name`` (see :func:`block`; ``command``: by default :func:`command_line`) into
    ``path``, replacing the old one; a new block goes at the end under ``## title``. Says on
    stdout where it went."""
    if machine.load_end is None:
        machine.end()
    text = block(name, rows, command=command or command_line(), machine=machine,
                 header=header, note=note)
    old = path.read_text(encoding="utf-8") if path.exists() else "# Figures\n"
    key = re.escape(name)
    pattern = re.compile(rf"<!-- figures:{key} -->.*?<!-- /figures:{key} -->", re.S)
    if pattern.search(old):
        new = pattern.sub(lambda _: text, old, count=1)
    else:
        new = old.rstrip("\n") + f"\n\n## {title}\n\n{text}\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(new if new.endswith("\n") else new + "\n", encoding="utf-8")
    print(f"wrote figures:{name} into {path}")
