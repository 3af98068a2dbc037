"""Where the live server may write: only inside one output folder, under sanitized names.

A name typed in the GUI or given on the command line (a recording, a CSV) is reduced to letters,
digits, ``.``, ``-`` and ``_``; path separators and ``..`` cannot survive, so nothing lands outside
the output folder. A name already taken gets a numeric suffix instead of overwriting anything.
"""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["output_path", "sanitize_name"]

_BAD = re.compile(r"[^A-Za-z0-9._-]+")
MAX_NAME = 80


def sanitize_name(name: str, default: str = "run") -> str:
    """A safe file or folder name from ``name``: only ``[A-Za-z0-9._-]``, no leading dot or dash,
    at most 80 characters, ``default`` when nothing is left."""
    if not isinstance(name, str):
        raise ValueError(f"name must be text, got {type(name).__name__}")
    text = name.strip().replace("\\", "/").split("/")[-1]
    text = _BAD.sub("_", text).strip("._-")[:MAX_NAME].strip("._-")
    return text or default


def output_path(out_dir: str | Path, name: str, *, suffix: str = "", default: str = "run") -> Path:
    """A fresh path ``out_dir/<sanitized name><suffix>`` (creating ``out_dir``); when it exists,
    ``-1``, ``-2``, ... is added before the suffix. ``suffix`` (e.g. ``.csv``) is appended unless
    the sanitized name already ends with it."""
    root = Path(out_dir)
    root.mkdir(parents=True, exist_ok=True)
    stem = sanitize_name(name, default)
    if suffix and stem.lower().endswith(suffix.lower()):
        stem = stem[: -len(suffix)] or default
    candidate = root / f"{stem}{suffix}"
    n = 1
    while candidate.exists():
        candidate = root / f"{stem}-{n}{suffix}"
        n += 1
    return candidate
