"""What showing a stored frame's images costs the server through viser's public API.

    python bench/bench_panel_images.py [--frames 200]

The history keeps each image as JPEG bytes; a panel shows them through ``GuiImageHandle.image``
(decode, then viser encodes the pixels again). This times, per image, on real frames of the
default preset (camera view and every robust-extractor stage, 320x240): the decode, viser's
encode (``viser._scene_api._encode_image_binary``, what the setter calls), and for comparison the
other public way that would take the stored bytes as they are, an HTML ``<img>`` with a base64
data URL (``GuiHtmlHandle.content``). CPU time of this thread (``time.thread_time``).
"""

from __future__ import annotations

import argparse
import base64
import time

import numpy as np

from tileviz.app.history import JPEG_QUALITY, encode_images
from tileviz.app.panels import decode_jpeg
from tileviz.config import preset
from tileviz.pipeline import FrameLoop
from tileviz.sim.source import SimSource


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    args = ap.parse_args()
    from viser._scene_api import _encode_image_binary  # timing only: what the setter calls

    cfg = preset("default")
    source, runner = SimSource(cfg), FrameLoop(cfg, keep_stages=True)
    stored: list[bytes] = []
    for _ in range(args.frames):
        rec = runner.process(next(source))
        stored.extend(b for _, b in encode_images(rec.image, dict(rec.vision.stages)))
    t0 = time.thread_time()
    pixels = [decode_jpeg(b) for b in stored]
    t1 = time.thread_time()
    sizes = [len(_encode_image_binary(p, "jpeg", JPEG_QUALITY)[1]) for p in pixels]
    t2 = time.thread_time()
    html = [f'<img src="data:image/jpeg;base64,{base64.b64encode(b).decode()}">' for b in stored]
    t3 = time.thread_time()
    n = len(stored)
    per = n / args.frames
    print(f"{n} images ({per:.1f} a frame), stored {np.mean([len(b) for b in stored]) / 1e3:.1f} kB"
          f" each")
    print(f"public .image setter: decode {1e3 * (t1 - t0) / n:.3f} ms + viser encode "
          f"{1e3 * (t2 - t1) / n:.3f} ms = {1e3 * (t2 - t0) / n:.3f} ms an image, "
          f"{1e3 * (t2 - t0) / args.frames:.1f} ms a frame shown; sent {np.mean(sizes) / 1e3:.1f}"
          f" kB an image")
    print(f"HTML <img> data URL: {1e3 * (t3 - t2) / n:.3f} ms an image; sent "
          f"{np.mean([len(h) for h in html]) / 1e3:.1f} kB an image")


if __name__ == "__main__":
    main()
