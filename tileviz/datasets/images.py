"""Dataset images: decoding PNG (libspng, OpenCV) and JPEG files into RGB arrays, and telling a
damaged, cut-off or oversized file from a whole one.

Before anything is decoded, the size a PNG's IHDR or a JPEG's frame header declares is read
(:func:`header_size`): a file whose header claims more than :data:`MAX_IMAGE_PIXELS` is refused
before any decoder allocates its pixels (``size_problem``), and a reader that knows the size to
expect compares it first. What the C decoders (libpng, libjpeg) print on stderr while they decode
is collected instead (:func:`decode_image`'s ``complaints``): damaged data is refused with that
reason in the caller's one-line error, and the decoders' own lines never reach the user.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import threading
import zlib
from collections.abc import Iterator

import cv2
import numpy as np
import pyspng

__all__ = [
    "MAX_IMAGE_PIXELS", "MAX_IMAGE_SIDE", "decode_image", "decoder_messages", "depth_problem",
    "header_size",
    "png_chunks_intact", "size_problem", "to_rgb", "truncated",
]

MAX_IMAGE_SIDE = 1 << 15
"""Widest or tallest image tileviz reads, pixels."""
MAX_IMAGE_PIXELS = 1 << 26
"""Most pixels of an image tileviz reads (about 67 megapixels: 200 MB as RGB)."""

def to_rgb(image: np.ndarray) -> np.ndarray:
    """An HxWx3 image from HxWx3 or HxW gray (uint8)."""
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2RGB)
    return image


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def header_size(raw: bytes) -> tuple[int, int] | None:
    """(width, height) that a PNG's IHDR or a JPEG's frame header (SOFn) declares, read without
    decoding; None for another kind of file or a header that cannot be found."""
    if raw.startswith(_PNG_SIGNATURE):
        if len(raw) >= 24 and raw[12:16] == b"IHDR":
            return int.from_bytes(raw[16:20], "big"), int.from_bytes(raw[20:24], "big")
        return None
    if not raw.startswith(b"\xff\xd8"):
        return None
    pos = 2
    n = len(raw)
    while pos + 4 <= n:
        if raw[pos] != 0xFF:
            return None
        marker = raw[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in (0x01, *range(0xD0, 0xD9)):  # no length
            pos += 2
            continue
        length = int.from_bytes(raw[pos + 2:pos + 4], "big")
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            if pos + 9 > n:
                return None
            return (int.from_bytes(raw[pos + 7:pos + 9], "big"),
                    int.from_bytes(raw[pos + 5:pos + 7], "big"))
        if marker == 0xDA or length < 2:  # image data before any frame header
            return None
        pos += 2 + length
    return None


def size_problem(raw: bytes) -> str | None:
    """What is wrong with the size the file's header declares (:func:`header_size`), or None:
    zero, or beyond :data:`MAX_IMAGE_SIDE` / :data:`MAX_IMAGE_PIXELS`."""
    size = header_size(raw)
    if size is None:
        return None
    w, h = size
    if w == 0 or h == 0:
        return f"its header declares an empty image ({w}x{h})"
    if max(w, h) > MAX_IMAGE_SIDE or w * h > MAX_IMAGE_PIXELS:
        return (f"its header declares {w}x{h} pixels, more than tileviz reads (at most "
                f"{MAX_IMAGE_SIDE} a side and {MAX_IMAGE_PIXELS} in all)")
    return None


_STDERR_LOCK = threading.Lock()
_sink_fd: int | None = None
_DECODER = re.compile(r"^(libpng (warning|error)|Corrupt JPEG|Premature end of JPEG|"
                      r"Invalid JPEG|Unsupported JPEG|Not a JPEG|Bogus |Huffman|Quantization|"
                      r"Invalid SOS|Unsupported marker|Warning: |JPEG|Inconsistent|"
                      r"Improper call|Unknown APP|Sampling factors|"
                      r"\[\s*(ERROR|WARN)[^\]]*\]\s+global\s+grfmt_)")
"""The lines libpng and libjpeg print (OpenCV's decoders let them reach stderr), and OpenCV's
own log lines from its image codecs (``[ERROR:0@1.2] global grfmt_png.cpp:296 readHeader ...``)."""
_CV_ERROR = re.compile(r"^\[\s*ERROR[^\]]*\]\s+global\s+grfmt_\S+\s+(\w+\s+)?")
"""An OpenCV codec's error line, up to its message (the data is damaged)."""
_DAMAGE = re.compile(r"^(libpng error|Corrupt JPEG|Premature end of JPEG|Invalid JPEG|"
                     r"Bogus |Huffman|Quantization|Invalid SOS|Unsupported marker)")
"""Those of them that mean the data is damaged (the others are warnings about harmless
ancillary data, e.g. a colour profile)."""


@contextlib.contextmanager
def decoder_messages() -> Iterator[list[str]]:
    """While the block runs, what the C decoders print on stderr (file descriptor 2) is kept
    in the list it yields instead of reaching the user; other lines printed meanwhile (another
    thread's) are passed on to stderr when the block ends. One block at a time per process."""
    global _sink_fd
    found: list[str] = []
    with _STDERR_LOCK:
        if _sink_fd is None:
            _sink_fd = os.memfd_create("tileviz-decoder-messages")
        sink = _sink_fd
        os.ftruncate(sink, 0)
        os.lseek(sink, 0, os.SEEK_SET)
        with contextlib.suppress(Exception):
            sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(sink, 2)
        try:
            yield found
        finally:
            with contextlib.suppress(Exception):
                sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            size = os.lseek(sink, 0, os.SEEK_CUR)
            os.lseek(sink, 0, os.SEEK_SET)
            text = os.read(sink, size).decode("utf-8", "replace") if size else ""
            for line in text.splitlines(keepends=True):
                if _DECODER.match(line):
                    found.append(line.strip())
                else:
                    os.write(2, line.encode("utf-8", "replace"))


def _imdecode(raw: bytes, flags: int, complaints: list[str] | None) -> np.ndarray | None:
    """cv2.imdecode with the decoders' messages kept (:func:`decoder_messages`): None when they
    say the data is damaged, their first such line then added to ``complaints``."""
    with decoder_messages() as said:
        image = cv2.imdecode(np.frombuffer(raw, np.uint8), flags)
    damage = [_CV_ERROR.sub("", line) for line in said
              if _DAMAGE.match(line) or _CV_ERROR.match(line)]
    if damage:
        if complaints is not None:
            complaints.append(damage[0])
        return None
    return image


def decode_image(raw: bytes, spng: bool = True,
                 complaints: list[str] | None = None) -> np.ndarray | None:
    """The image in the file bytes ``raw`` as HxWx3 RGB uint8, or None if it cannot be read.

    With ``spng``, a non-interlaced PNG is decoded by libspng (pyspng): the same pixels as
    OpenCV's decoder for every PNG kind (8/16-bit, gray, RGB, alpha, palette: tested), in less
    time and without the BGR->RGB step; anything else, or a PNG libspng refuses, goes to OpenCV.
    A PNG is read only if every chunk's CRC holds: pyspng decodes damaged data as if it were
    whole, and OpenCV's libpng prints its own complaint on stderr beside the one-line error
    the caller gives. pyspng holds the GIL while it decodes and OpenCV does not, so a background
    decoding thread wants ``spng=False`` to overlap the caller's work. A file whose header
    declares a size :func:`size_problem` refuses is not decoded (None); the caller checks it
    first to say why. What libpng or libjpeg says about damaged data goes to ``complaints``
    (one line each) instead of stderr, and the image is then None."""
    png = raw.startswith(_PNG_SIGNATURE)
    if png and not png_chunks_intact(raw):
        return None
    if size_problem(raw) is not None:
        return None
    if png and spng and len(raw) > 33 and raw[28] == 0:  # IHDR's interlace byte
        try:
            image = pyspng.load(raw, "RGB")
        except Exception:  # noqa: BLE001 - OpenCV decides, and its verdict is the error
            image = None
        if image is not None and image.dtype == np.uint8 and image.ndim == 3:
            return image
    image = _imdecode(raw, cv2.IMREAD_COLOR, complaints) if raw else None
    if image is None:
        return None
    # (the same pixels as image[:, :, ::-1], contiguous, cheaper than numpy's copy)
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


LOW_BITS_MAX = 4096
"""A 16-bit image whose samples all stay below this (the low 12 bits: a 10- or 12-bit camera's
data stored unscaled) would keep at most 16 gray levels in the 8-bit view the extractors read
(:func:`depth_problem`)."""


def depth_problem(raw: bytes) -> str | None:
    """What is wrong with the sample depth of the image file ``raw``, or None: a 16-bit PNG whose
    samples use only the low bits (all below :data:`LOW_BITS_MAX`). The 8-bit view of a 16-bit
    image keeps its high byte, so such an image would read as nearly constant; a full-range
    16-bit image is fine."""
    if not (raw.startswith(_PNG_SIGNATURE) and len(raw) > 24 and raw[24] == 16):
        return None  # IHDR's bit depth (byte 24) is not 16
    if not png_chunks_intact(raw) or size_problem(raw) is not None:
        return None  # not decoded: the caller's decode_image refuses it
    image = _imdecode(raw, cv2.IMREAD_UNCHANGED, None)
    if image is None or image.dtype != np.uint16:
        return None
    top = int(image.max())
    if top >= LOW_BITS_MAX:
        return None
    return (f"16-bit samples reach only {top} of 65535 (data in the low bits?): its 8-bit "
            f"view would keep {top // 256 + 1} gray level(s); scale it to the full 16-bit "
            "range or save it as 8-bit")


def png_chunks_intact(raw: bytes) -> bool:
    """Whether every chunk of the PNG file ``raw`` is complete and matches its CRC, up to IEND."""
    view = memoryview(raw)
    pos = len(_PNG_SIGNATURE)
    while pos + 12 <= len(raw):
        length = int.from_bytes(view[pos:pos + 4], "big")
        end = pos + 8 + length
        if end + 4 > len(raw):
            return False
        if zlib.crc32(view[pos + 4:end]) != int.from_bytes(view[end:end + 4], "big"):
            return False
        if view[pos + 4:pos + 8] == b"IEND":
            return True
        pos = end + 4
    return False


def truncated(raw: bytes) -> bool:
    """Whether a PNG or JPEG file (by its signature) lacks its end marker (IEND chunk, EOI): a
    cut-off file, which the decoders would half-decode or complain about on stderr."""
    if raw.startswith(_PNG_SIGNATURE):
        return raw.rfind(b"IEND") < 0
    if raw.startswith(b"\xff\xd8"):
        return raw.rfind(b"\xff\xd9") < 2
    return False
