"""Keeping freed memory in the process's heap (glibc's allocator), for the replay's vision.

Vision allocates and frees full-image arrays on every frame (a decoded 320x240 RGB image is
230 KB, a float64 copy of it 600 KB). glibc serves a block this large with a fresh ``mmap`` and
gives it back to the system when it is freed, or trims the top of the heap, so the next frame's
arrays start again from pages the kernel must fault in and zero. :func:`keep_freed_memory` has
glibc serve such blocks from the heap and keep what is freed for the next allocation. The
results do not change (only where the arrays live does); the process keeps up to its peak
working set instead of handing memory back between frames.

A process that runs for hours (the demo server) has the opposite need: glibc keeps the free
parts of its heaps, which fragment as threads come and go, so the resident set creeps up
although the memory in use does not. :func:`return_freed_memory` hands the free pages back
(``malloc_trim``).

No viser, no pymunk here.
"""

from __future__ import annotations

import ctypes
import platform

__all__ = ["MMAP_THRESHOLD", "TRIM_THRESHOLD", "keep_freed_memory", "return_freed_memory"]

MMAP_THRESHOLD = 32 << 20
"""Bytes: blocks smaller than this come from the heap (glibc's M_MMAP_THRESHOLD; its maximum on
64-bit)."""

TRIM_THRESHOLD = 128 << 20
"""Bytes: free memory at the top of the heap is given back only beyond this
(glibc's M_TRIM_THRESHOLD)."""

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3


def keep_freed_memory() -> bool:
    """Set :data:`MMAP_THRESHOLD` and :data:`TRIM_THRESHOLD` in this process's allocator (and
    in the processes it forks later); True when set, False where the C library is not glibc
    (nothing is changed there)."""
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    try:
        libc = ctypes.CDLL(None)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
                and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))


def return_freed_memory() -> bool:
    """Give the free pages of every heap of this process back to the system (glibc's
    ``malloc_trim(0)``; the memory in use is untouched). True when glibc did, False where the C
    library is not glibc."""
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    try:
        trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):
        return False
    trim.argtypes = (ctypes.c_size_t,)
    trim.restype = ctypes.c_int
    trim(0)
    return True
