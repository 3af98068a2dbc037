"""Files written so that a process killed at any moment (SIGKILL, a full disk, a power cut after
the last sync) leaves them readable: whole-file replacement (:func:`write_atomic`) and whole-line
appends (:class:`LineLog`).

Contracts (``docs/dataset-format.md``, "A dataset being written"):

- :func:`write_atomic`: the file at ``path`` is at every moment either its old content (or absent)
  or the whole new content, never a part: the bytes go to a hidden temporary name in the same
  folder (``.NAME.tmp``), are synced to the disk when ``durable``, and the temporary name is
  renamed over ``path``. A failed write leaves no temporary file behind (unless the process is
  killed during it: a stale ``.NAME.tmp`` is never read by anything).
- :class:`LineLog`: each :meth:`LineLog.append` writes whole lines in one go; when the write fails
  (a full disk) the part already written is cut off again, so the file ends after the last whole
  append. A process killed *inside* a write may still leave a partial last line: readers drop a
  last line that has no line end.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

__all__ = ["LineLog", "fsync_dir", "write_atomic"]


def _temp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp")


def fsync_dir(folder: str | os.PathLike[str]) -> None:
    """Sync a folder's entries (its renames and new names) to the disk; a file system that
    cannot sync a folder is left alone."""
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _write_all(fd: int, data: bytes | memoryview) -> int:
    """Write every byte of ``data`` to ``fd``; returns how many were written before an OSError
    (which is raised with the count in its ``written`` attribute)."""
    view = memoryview(data)
    done = 0
    try:
        while done < len(view):
            done += os.write(fd, view[done:])
    except OSError as e:
        e.written = done  # type: ignore[attr-defined]
        raise
    return done


def write_atomic(path: str | os.PathLike[str], data: bytes, *, durable: bool = True) -> None:
    """Replace ``path`` by ``data`` as a whole (module docstring); ``durable``: sync the bytes
    to the disk before the rename (a power cut then never leaves an empty file under the name).
    OSError (the file system's) when it cannot be written; ``path`` is then unchanged."""
    path = Path(path)
    tmp = _temp_name(path)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        try:
            _write_all(fd, data)
            if durable:
                os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


class LineLog:
    """A text file that grows by whole lines (module docstring). The file must exist (its
    header written by :func:`write_atomic`); ``size`` is its length in bytes, the end of the last
    whole append."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._fd: int | None = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        self.size = os.fstat(self._fd).st_size

    def append(self, data: bytes) -> None:
        """Append ``data`` (whole lines, each ending in a line end). On an OSError the bytes of
        this append that reached the file are cut off again, then the error is raised."""
        if self._fd is None:
            raise ValueError(f"{self.path}: closed")
        try:
            _write_all(self._fd, data)
        except OSError as e:
            if getattr(e, "written", 0):
                with contextlib.suppress(OSError):
                    os.ftruncate(self._fd, self.size)  # shrinking needs no free space
            raise
        self.size += len(data)

    def sync(self) -> None:
        """Sync what was appended to the disk."""
        if self._fd is not None:
            os.fsync(self._fd)

    def close(self) -> None:
        """Close the file (idempotent)."""
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)
