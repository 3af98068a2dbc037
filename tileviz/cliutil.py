"""Helpers shared by the command-line entry points: one-line errors, never a traceback."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import NoReturn


class CliError(Exception):
    """An error for the user: printed as one line, exit status 2."""


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line on stderr and exit status 2."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


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


def run_cli(prog: str, body: Callable[[], int]) -> int:
    """Run ``body``; turn expected errors into one line on stderr and exit status 2."""
    try:
        return body()
    except KeyboardInterrupt:
        sys.stderr.write(f"{prog}: interrupted\n")
        return 130
    except (CliError, ValueError, OSError) as e:
        sys.stderr.write(f"{prog}: error: {e}\n")
        return 2


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
