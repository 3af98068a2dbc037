"""Dataset images: decoding PNG (libspng, OpenCV) and JPEG files into RGB arrays, and telling a
damaged or cut-off file from a whole one."""

from __future__ import annotations

import zlib

import cv2
import numpy as np
import pyspng

__all__ = ["decode_image", "depth_problem", "png_chunks_intact", "to_rgb", "truncated"]

def to_rgb(image: np.ndarray) -> np.ndarray:
    """An HxWx3 image from HxWx3 or HxW gray (uint8)."""
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2RGB)
    return image


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def decode_image(raw: bytes, spng: bool = True) -> np.ndarray | None:
    """The image in the file bytes ``raw`` as HxWx3 RGB uint8, or None if it cannot be read.

    With ``spng``, a non-interlaced PNG is decoded by libspng (pyspng): the same pixels as
    OpenCV's decoder for every PNG kind (8/16-bit, gray, RGB, alpha, palette: tested), in less
    time and without the BGR->RGB step; anything else, or a PNG libspng refuses, goes to OpenCV.
    A PNG is read only if every chunk's CRC holds: pyspng decodes damaged data as if it were
    whole, and OpenCV's libpng prints its own complaint on stderr beside the one-line error
    the caller gives. pyspng holds the GIL while it decodes and OpenCV does not, so a background
    decoding thread wants ``spng=False`` to overlap the caller's work."""
    png = raw.startswith(_PNG_SIGNATURE)
    if png and not png_chunks_intact(raw):
        return None
    if png and spng and len(raw) > 33 and raw[28] == 0:  # IHDR's interlace byte
        try:
            image = pyspng.load(raw, "RGB")
        except Exception:  # noqa: BLE001 - OpenCV decides, and its verdict is the error
            image = None
        if image is not None and image.dtype == np.uint8 and image.ndim == 3:
            return image
    image = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_COLOR) if raw else None
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
    image = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_UNCHANGED)
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
