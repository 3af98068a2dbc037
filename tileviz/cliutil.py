"""Helpers shared by the command-line entry points: one-line errors, never a traceback."""

from __future__ import annotations

import argparse
import math
import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from typing import TYPE_CHECKING, Any, NoReturn

from tileviz.core.constants import LIMIT

if TYPE_CHECKING:
    from tileviz.config import Config, FloorConfig


class CliError(Exception):
    """An error for the user: printed as one line, exit status 2."""


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line on stderr and exit status 2."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


EXTRACTOR_HELP = (
    "vision extractor: robust (checks each view, declares its own bound) or faithful (the "
    "original report's chain, kept for comparison: its views can fall outside their declared "
    "bound, so the set can miss the truth)")
"""The ``--extractor`` help of every command that takes it (docs/guarantees.md, H4)."""


def positive_float(name: str) -> Callable[[str], float]:
    """argparse type: a finite float > 0, the error naming the option."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(v) or v <= 0:
            raise argparse.ArgumentTypeError(f"{name} must be a finite number > 0, got {text!r}")
        return v

    return parse


def nonneg_float(name: str) -> Callable[[str], float]:
    """argparse type: a finite float >= 0, the error naming the option."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(v) or v < 0:
            raise argparse.ArgumentTypeError(f"{name} must be a finite number >= 0, got {text!r}")
        return v

    return parse


def fault_model(name: str) -> Callable[[str], tuple[float, float]]:
    """argparse type: ``SPEED,YAW_RATE`` (m/s, rad/s), two finite floats >= 0: the fault model
    (``LocalizerConfig.fault_speed``, ``fault_yaw_rate``); ``0,0`` turns it off."""
    one = nonneg_float(name)

    def parse(text: str) -> tuple[float, float]:
        parts = text.split(",")
        if len(parts) != 2:
            raise argparse.ArgumentTypeError(
                f"{name} must be SPEED,YAW_RATE (m/s, rad/s), got {text!r}")
        return (one(parts[0]), one(parts[1]))

    return parse


def add_fault_options(p: argparse.ArgumentParser, *, relocalize: bool = True,
                      note: str = "") -> None:
    """Add ``--fault-model SPEED,YAW_RATE`` (m/s, rad/s) and, when ``relocalize``,
    ``--relocalize-region X0,Y0,X1,Y1`` (metres) to ``p``: one definition for every command
    that takes them (docs/faults.md, docs/guarantees.md). ``note`` ends the fault model's help."""
    from tileviz.config import LocalizerConfig

    loc = LocalizerConfig()
    p.add_argument("--fault-model", type=fault_model("--fault-model"), default=None,
                   metavar="SPEED,YAW_RATE",
                   help="how much faster than the odometry bounds a fault (wheel slip, push) may "
                   "move the robot, m/s and rad/s: the localizer then tracks through such a fault "
                   "and says lost beyond it (docs/faults.md); 0,0 turns it off (default "
                   f"{loc.fault_speed:g},{loc.fault_yaw_rate:g}){note}")
    if relocalize:
        p.add_argument("--relocalize-region", type=region("--relocalize-region"), default=None,
                       metavar="X0,Y0,X1,Y1",
                       help="after lost, restart from 'somewhere in this region' (metres; "
                       "heading from the compass): one candidate box per tile cell that fits the "
                       "view, dropped as the robot's motion takes them out of the region; the "
                       "robot must stay in it until one candidate is left (docs/guarantees.md); "
                       "write --relocalize-region=-1,-1,2,2 when X0 is negative")


def add_floor_options(p: argparse.ArgumentParser) -> None:
    """Add ``--floor-kind grout|checker`` and ``--lattice-tolerance METRES`` to ``p``: what is
    declared of the floor (``docs/dataset-format.md``, "floor"; applied by
    :func:`config_from_args` after the floor style)."""
    from tileviz.config import FLOOR_KINDS

    p.add_argument("--floor-kind", choices=FLOOR_KINDS, default=None,
                   help="grout: tiles separated by grout lines; checker: tiles of alternating "
                   "shades edge to edge, no grout (default: the floor style's, else grout)")
    p.add_argument("--lattice-tolerance", type=nonneg_float("--lattice-tolerance"), default=None,
                   metavar="METRES",
                   help="how far the floor's grout lines (tile edges) may lie off the ideal "
                   "lattice (hand-laid tiles, wandering grout): the view bound includes it; "
                   "python -m tileviz survey measures it (default: the floor style's, else 0)")


def declared_floor(floor: FloorConfig, args: argparse.Namespace) -> FloorConfig:
    """``floor`` with the ``--floor-kind`` and ``--lattice-tolerance`` (metres) that ``args``
    gave (:func:`add_floor_options`; absent or None: unchanged); ValueError naming a bad one."""
    kind = getattr(args, "floor_kind", None)
    tol = getattr(args, "lattice_tolerance", None)
    if kind == "grout" and not floor.grout_width > 0:
        raise ValueError("--floor-kind grout: this floor has no grout (the checker style lays its "
                         "tiles edge to edge): give --floor-kind checker, or another --floor-style")
    if kind is not None:
        floor = replace(floor, kind=kind)
    if tol is not None:
        floor = replace(floor, lattice_tolerance=tol)
    return floor


def region(name: str) -> Callable[[str], tuple[float, float, float, float]]:
    """argparse type: ``X0,Y0,X1,Y1`` (metres), four finite floats with x0 <= x1 and y0 <= y1:
    a re-localization region (``Localizer.relocalize``)."""

    def parse(text: str) -> tuple[float, float, float, float]:
        parts = text.split(",")
        if len(parts) != 4:
            raise argparse.ArgumentTypeError(f"{name} must be X0,Y0,X1,Y1 (metres), got {text!r}")
        try:
            x0, y0, x1, y1 = (float(p) for p in parts)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{name} must be four numbers X0,Y0,X1,Y1 (metres), got {text!r}") from None
        if not all(math.isfinite(v) and abs(v) <= LIMIT for v in (x0, y0, x1, y1)):
            raise argparse.ArgumentTypeError(f"{name} must be finite numbers within {LIMIT:g}, "
                                             f"got {text!r}")
        if x0 > x1 or y0 > y1:
            raise argparse.ArgumentTypeError(f"{name} needs X0 <= X1 and Y0 <= Y1, got {text!r}")
        return (x0, y0, x1, y1)

    return parse


def float_in(name: str, lo: float, hi: float, *, lo_open: bool = True) -> Callable[[str], float]:
    """argparse type: a finite float in (lo, hi] ([lo, hi] when not ``lo_open``), the error
    naming the option and the range."""
    rng = f"{'>' if lo_open else '>='} {lo:g} and <= {hi:g}"

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not (lo < v <= hi if lo_open else lo <= v <= hi):
            raise argparse.ArgumentTypeError(
                f"{name} must be a finite number {rng}, got {text!r}")
        return v

    return parse


def int_at_least(name: str, lo: int) -> Callable[[str], int]:
    """argparse type: an integer >= ``lo``, the error naming the option."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{name} must be >= {lo}, got {text!r}")
        return v

    return parse


def int_in(name: str, lo: int, hi: int) -> Callable[[str], int]:
    """argparse type: an integer in [lo, hi], the error naming the option and the range."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{name} must be >= {lo} and <= {hi}, got {text!r}")
        return v

    return parse


def nonneg_int(name: str) -> Callable[[str], int]:
    """argparse type: an integer >= 0, the error naming the option."""
    return int_at_least(name, 0)


def positive_int(name: str) -> Callable[[str], int]:
    """argparse type: an integer >= 1, the error naming the option."""
    return int_at_least(name, 1)


@contextmanager
def notice_if_slow(message: str, after: float = 3.0) -> Iterator[threading.Timer]:
    """Print ``message`` (one line, standard error) if the block is still running ``after``
    seconds (wall clock) after it started; nothing when it ends sooner, or once the block calls
    ``cancel()`` on the timer it gets (its first result is in). For a start that is slow only
    once (the vision kernels compile on the first run after an install), so a user waiting
    knows why."""
    timer = threading.Timer(after, lambda: print(message, file=sys.stderr, flush=True))
    timer.daemon = True
    timer.start()
    try:
        yield timer
    finally:
        timer.cancel()


FIRST_RUN_NOTICE = ("still starting: the first run after an install compiles the vision "
                    "kernels (up to a minute, once)")
"""The second half of the line :func:`notice_if_slow` prints while the kernels compile."""


def read_json(path: str, option: str) -> Any:
    """The JSON document of the file ``path`` given to ``option``; CliError naming both when the
    file cannot be read, is not UTF-8 text or not JSON (the dataset reader's
    :func:`tileviz.datasets.format.json_file`)."""
    from tileviz.datasets.format import DatasetError, json_file

    try:
        return json_file(path, f"{option}: ")
    except DatasetError as e:
        raise CliError(str(e)) from None


def run_cli(prog: str, body: Callable[[], int]) -> int:
    """Run ``body`` as the command ``prog`` (every ``python -m tileviz`` command and ``serve.py``
    go through here): first the process set-up (:func:`tileviz.vision.set_opencv_threads`: OpenCV
    on one thread, so observations do not depend on the core count), then ``body``; expected
    errors become one line on stderr and exit status 2; a closed stdout (``| head``) ends the
    command quietly with :data:`EXIT_PIPE`. OpenCV's own log lines below errors
    (e.g. a warning when it converts an image's samples) are silenced: the command's one-line
    error names the problem."""
    import cv2.utils.logging as cv_log

    from tileviz.vision import set_opencv_threads

    set_opencv_threads()
    cv_log.setLogLevel(cv_log.LOG_LEVEL_ERROR)
    try:
        return body()
    except KeyboardInterrupt:
        _say(f"{prog}: interrupted")
        return 130
    except BrokenPipeError as e:
        if _stdout_closed():
            # the reader of stdout went away (``| head``): stop quietly, as a process the pipe
            # signal ends does, and keep Python's exit from reporting the closed pipe's flush
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return EXIT_PIPE
        _say(f"{prog}: error: {one_line(str(e))}")
        return 2
    except (CliError, ValueError, OSError) as e:
        _say(f"{prog}: error: {one_line(str(e))}")
        return 2


EXIT_PIPE = 141
"""The exit status of a command whose stdout's reader stopped reading (128 + SIGPIPE, what a
shell reports for a process the pipe signal ended)."""


def _stdout_closed() -> bool:
    """Whether stdout is a pipe whose reader has gone (polling its end reports an error)."""
    import select

    if sys.stdout.closed:
        return True
    try:
        fd = sys.stdout.fileno()
    except (ValueError, OSError):  # not a file (a capture): no pipe to lose
        return False
    poll = select.poll()
    poll.register(fd, select.POLLOUT)
    return any(ev & (select.POLLERR | select.POLLHUP) for _, ev in poll.poll(0))


def _say(line: str) -> None:
    """``line`` on stderr, unless stderr's reader has gone too."""
    try:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):
        pass


def one_line(text: str) -> str:
    """``text`` on one line: its line breaks (every character ``str.splitlines`` breaks at)
    become spaces and other control characters ``\\xNN`` escapes (an error quoting a file's
    content must not break the line or drive the terminal)."""
    text = " ".join(text.splitlines())
    return "".join(c if c.isprintable() or c == " " else c.encode("unicode_escape").decode()
                   for c in text)


def config_from_args(args: argparse.Namespace, *, floor_seed: bool = True) -> Config:
    """The configuration a command line asks for: the preset ``args.preset`` (``default`` when
    None or absent) with every option the command has and the user gave (not None) applied:
    ``tile_size`` (metres; the grout follows, :meth:`tileviz.config.FloorConfig.with_tile_size`),
    ``ppm``, ``width``, ``height`` (pixels), ``speed_error``, ``yaw_rate_error``,
    ``compass_error``, ``dt``, ``setpoint``, ``seed`` (the simulator's; with ``floor_seed`` the
    floor's appearance seed becomes ``seed + 1``, as ``record`` does), ``floor_style``
    (:func:`tileviz.config.with_floor_style`), then ``floor_kind`` and ``lattice_tolerance``
    (metres, :func:`add_floor_options`), ``extractor`` and ``mode``. The
    configuration validates itself: a bad value raises ValueError naming it."""
    from tileviz.config import preset, with_floor_style

    a: dict[str, Any] = {k: v for k, v in vars(args).items() if v is not None}
    cfg = preset(a.get("preset", "default"))
    floor, camera, noise, sim = cfg.floor, cfg.camera, cfg.noise, cfg.sim
    if "tile_size" in a:
        floor = floor.with_tile_size(a["tile_size"])
    camera = replace(camera, **{k: a[k] for k in ("ppm", "width", "height") if k in a})
    noise = replace(noise, **{k: a[k] for k in ("speed_error", "yaw_rate_error",
                                                 "compass_error") if k in a})
    sim = replace(sim, **{k: a[k] for k in ("dt", "setpoint", "seed") if k in a})
    if "seed" in a and floor_seed:
        floor = replace(floor, seed=a["seed"] + 1)
    out = replace(cfg, floor=floor, camera=camera, noise=noise, sim=sim)
    if a.get("floor_style", "default") != "default":
        out = with_floor_style(out, a["floor_style"])
    out = replace(out, floor=declared_floor(out.floor, args))
    if "extractor" in a:
        out = replace(out, vision=replace(out.vision, extractor=a["extractor"]))
    if "mode" in a:
        out = replace(out, localizer=replace(out.localizer, mode=a["mode"]))
    return out


REQUIRED: dict[str, str] = {
    "numpy": "numpy", "cv2": "opencv-python-headless", "pymunk": "pymunk", "viser": "viser",
    "tqdm": "tqdm", "matplotlib": "matplotlib", "pyspng": "pyspng",
}
"""Modules tileviz imports -> the package that provides them (``pyproject.toml``)."""


def missing_dependency(prog: str) -> str | None:
    """One line naming the first module of :data:`REQUIRED` this Python cannot import and the
    fix (the project's venv, or installing tileviz), or None when all are there."""
    from importlib.util import find_spec

    for module, package in REQUIRED.items():
        if find_spec(module) is None:
            return (f"{prog}: error: this Python ({sys.executable}) has no module {module!r} "
                    f"(package {package}): activate the project's venv (source .venv/bin/activate)"
                    f" or install tileviz into this Python (pip install -e .)")
    return None
