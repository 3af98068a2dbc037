"""Output files written whole or not at all: a temporary file beside the output, renamed over it
when complete, removed when anything fails (an interrupted or failed export leaves no
half-written file, and an older file of that name stays as it was until the new one is ready)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_output", "check_folder", "check_output"]


def check_output(path: str | os.PathLike[str], option: str = "output",
                 suffixes: tuple[str, ...] = ()) -> Path:
    """``path`` as a Path once it can be written: its folder exists and is writable, it is not a
    folder itself, and (when ``suffixes`` are given) it ends with one of them. OSError naming
    ``option``, the path and the problem otherwise (one line)."""
    p = Path(path)
    if suffixes and p.suffix.lower() not in suffixes:
        raise OSError(f"{option} {p}: the name must end with {' or '.join(suffixes)}")
    if p.is_dir():
        raise OSError(f"{option} {p}: is a folder, not a file")
    parent = p.parent
    if not parent.is_dir():
        raise OSError(f"{option} {p}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OSError(f"{option} {p}: folder {parent} is not writable")
    if p.exists() and not os.access(p, os.W_OK):
        raise OSError(f"{option} {p}: the file exists and is not writable")
    return p


def check_folder(path: str | os.PathLike[str], option: str) -> Path:
    """``path`` as a Path once it can become a new folder: it does not exist (and its parent
    is a writable folder) or is an empty folder. OSError naming ``option`` otherwise."""
    p = Path(path)
    if p.exists():
        if not p.is_dir() or any(p.iterdir()):
            raise OSError(f"{option} {p}: exists and is not an empty folder")
        return p
    return check_output(p, option)


@contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path in ``path``'s folder (same suffix) to write; renamed to ``path`` when the
    block ends normally, removed when it raises."""
    p = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=f".part{p.suffix}", dir=p.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
