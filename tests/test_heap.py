"""keep_freed_memory: full-image arrays come from the heap and stay there once freed, so a
replay's next frame reuses them instead of fresh pages from the system."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(
    platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
    reason="glibc's allocator only (elsewhere keep_freed_memory changes nothing and says so)")

_PROBE = """
import ctypes, sys
import numpy as np
from tileviz.pipeline.heap import keep_freed_memory

class Info(ctypes.Structure):  # glibc's struct mallinfo2
    _fields_ = [(n, ctypes.c_size_t) for n in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks",
                 "uordblks", "fordblks", "keepcost")]

libc = ctypes.CDLL(None)
libc.mallinfo2.restype = Info

def allocate() -> tuple[int, int]:
    # (new mappings while an image-sized array lives, heap bytes kept free once it is freed)
    mapped = libc.mallinfo2().hblks
    image = np.ones((480, 640, 3), np.float64)  # 7 MB, as vision's float copies of an image
    mapped = libc.mallinfo2().hblks - mapped
    del image
    return mapped, libc.mallinfo2().fordblks

size = 480 * 640 * 3 * 8
mapped, _ = allocate()
assert keep_freed_memory() is True
mapped_after, kept_after = allocate()
print(mapped, mapped_after, int(kept_after >= size))
"""


def test_full_image_arrays_come_from_the_heap() -> None:
    """Before: an image-sized array is a mapping of its own (given back when freed); after
    keep_freed_memory: it comes from the heap, and its memory stays there once freed."""
    res = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                         check=True, timeout=120)
    mapped_before, mapped_after, kept_after = map(int, res.stdout.split())
    assert mapped_before == 1  # glibc's default: a mapping of its own
    assert (mapped_after, kept_after) == (0, 1)  # from the heap, and kept there once freed
