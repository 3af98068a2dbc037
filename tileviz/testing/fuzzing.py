"""Fuzzing every reader a user's file reaches (issue 33): the engine behind ``bench/fuzz.py`` and
``tests/test_fuzz.py``.

A *reader* is one file of a user's input read by a command in this process, exactly as the user
runs it (``tileviz.__main__.main``), with the rest of the input valid:

- ``meta``: a dataset's meta.json (``replay``), generic JSON: every key, a wrong type, unknown
  and missing keys, the stored tileviz configuration, the ``floor`` block (:func:`floor_block`);
- ``camera_model``: the camera_model block of a dataset with raw images (``replay``);
- ``frames``: frames.csv (``replay``); ``faults``: faults.csv (``replay``);
- ``image``: one stored image of a dataset (``replay``); ``extract``: an image given to
  ``extract`` (each image its own size: the reader bounds it from the header);
- ``bag``: a ROS 1 bag, a ROS 2 MCAP file or a ROS 2 sqlite3 database (``import-bag``);
- ``store``: ``runs.csv``, ``campaign.json`` or a run's results file of an ``evaluate --resume``
  folder (the store's reader and the report's tables, :func:`tileviz.evaluation.report.aggregate`).

A *case* is the bytes of that one file, made by a hypothesis strategy (structured: valid files
with wrong pieces) or by mutating a valid file (bit flips, interesting integers, cuts, inserts,
splices; a PNG's chunk CRCs fixed again half the time so that the damage reaches the decoder).
Each case runs in a worker process, its stdout and stderr captured at the file-descriptor level
(what C libraries print counts too). Outcomes:

- ``ok``: the command succeeded (at most one line on stderr, e.g. "ended early"), or ``extract``
  read the image and its extractor refused it (exit status 1, the one line on stdout naming the
  image says why);
- ``error``: exit status 2 and exactly one line on stderr that names the file (its name or its
  folder) - what the project promises for bad input;
- ``traceback``: anything else: an exception the command let through, more than one line, a line
  that does not name the file;
- ``hang``: no answer within the per-case timeout (the worker is killed and replaced);
- ``memory``: a MemoryError, or a case raising the worker's peak resident set past
  :data:`MEMORY_LIMIT_MB`
  (a worker's address space is also capped a little above that, so a case that would allocate
  gigabytes fails instead of taking the machine).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import os
import pickle
import random
import resource
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from tileviz.testing import REPO

MEMORY_LIMIT_MB = 1024
"""Peak resident set a worker may reach (the issue's bound)."""
HEADROOM_MB = 1536
"""A worker's address space is capped at its size after start-up plus this."""
READERS = ("meta", "camera_model", "frames", "faults", "image", "extract", "bag", "store")
OUTCOMES = ("ok", "error", "traceback", "hang", "memory")
W, H = 64, 48
"""The template dataset's view, pixels (tile 0.25 m at 100 px/m: lines every 25 px)."""
RAW = (96, 72)
"""The raw image size of the camera_model template (the webcam lens scaled down)."""


# ------------------------------------------------------------------------------------------ files
def png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def png_bytes(width: int, height: int, *, bit_depth: int = 8, color_type: int = 2,
              interlace: int = 0, rows: bytes | None = None, palette: bytes | None = None,
              extra: tuple[tuple[bytes, bytes], ...] = ()) -> bytes:
    """A PNG file made by hand, any header allowed (``rows``: the raw scanlines with their filter
    bytes, made for a small image when None; a huge header with little data is a valid test)."""
    ihdr = struct.pack(">IIBBBBB", width, height, bit_depth, color_type, 0, 0, interlace)
    if rows is None:
        channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(color_type, 3)
        stride = (min(width, 4096) * channels * bit_depth + 7) // 8
        rows = b"".join(b"\x00" + bytes((i * 37 + j) % 251 for j in range(stride))
                        for i in range(min(height, 64)))
    out = b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr)
    if palette is not None:
        out += png_chunk(b"PLTE", palette)
    for kind, body in extra:
        out += png_chunk(kind, body)
    return out + png_chunk(b"IDAT", zlib.compress(rows)) + png_chunk(b"IEND", b"")


def fix_png_crcs(data: bytes) -> bytes:
    """``data`` with the CRC of every whole chunk recomputed (a mutation then reaches the
    decoder instead of stopping at the CRC check)."""
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        return data
    out = bytearray(data)
    pos = 8
    while pos + 12 <= len(out):
        n = int.from_bytes(out[pos:pos + 4], "big")
        end = pos + 8 + n
        if end + 4 > len(out):
            break
        out[end:end + 4] = struct.pack(">I", zlib.crc32(bytes(out[pos + 4:end])))
        pos = end + 4
    return bytes(out)


def floor_image(w: int, h: int, phase: int = 0) -> Any:
    """A gray floor with dark grout lines every 25 px (uint8 HxWx3)."""
    import numpy as np

    img = np.full((h, w, 3), 190, np.uint8)
    for c in range((phase % 25), w, 25):
        img[:, c:c + 2] = 60
    for r in range((phase * 2) % 25, h, 25):
        img[r:r + 2, :] = 60
    return img


def floor_block(rng: random.Random) -> dict[str, Any]:
    """FLOOR HOOK: a ``floor`` block as the lead is adding it to meta.json (``{kind: "grout" |
    "checker", lattice_tolerance: metres >= 0}``), valid or nearly so. meta.json is fuzzed as
    generic JSON, so this block, unknown today, is read as an unknown key now and by its own
    parser once ``tileviz/datasets/format.py`` has one (then give it its wrong pieces here)."""
    kind = rng.choice(["grout", "checker", "grout", "checker", "tiles", "", 3, None])
    tol = rng.choice([0.0, 0.001, 0.02, 1e-9, -0.01, 1e300, float("nan"), "0.01", None, True])
    block: dict[str, Any] = {"kind": kind, "lattice_tolerance": tol}
    if rng.random() < 0.2:
        del block[rng.choice(list(block))]
    if rng.random() < 0.1:
        block[rng.choice(["extra", "kind2"])] = rng.choice([1, "x", [], {}])
    return block


# ------------------------------------------------------------------------------------- templates
@dataclass
class Templates:
    """Valid inputs every case starts from (made once per process under ``root``)."""

    root: Path
    dataset: Path = field(init=False)
    lens_dataset: Path = field(init=False)
    images: dict[str, bytes] = field(init=False)
    bags: dict[str, Path] = field(init=False)
    store: Path = field(init=False)

    def __post_init__(self) -> None:
        self.dataset = self._dataset(self.root / "ds", lens=False)
        self.lens_dataset = self._dataset(self.root / "lens", lens=True)
        self.images = self._images()
        self.bags = self._bags()
        self.store = self._store()

    @staticmethod
    def _meta(lens: bool) -> Any:
        from dataclasses import replace

        from tileviz.config import preset
        from tileviz.datasets import DatasetMeta

        cfg = preset("default")
        cfg = replace(cfg, floor=cfg.floor.with_tile_size(0.25),
                      camera=replace(cfg.camera, ppm=100.0, width=W, height=H))
        meta = DatasetMeta.from_config(cfg, name="fuzz")
        if lens:
            from tileviz.datasets.camera_model import CameraModel
            from tileviz.sim.lens import webcam_model

            m = webcam_model(cfg.camera)
            s = RAW[0] / m.raw_width
            k = [[m.camera_matrix[0][0] * s, 0.0, m.camera_matrix[0][2] * s],
                 [0.0, m.camera_matrix[1][1] * s, m.camera_matrix[1][2] * s], [0.0, 0.0, 1.0]]
            h = [[e / s if j < 2 else e for j, e in enumerate(r)] for r in m.floor_homography]
            model = CameraModel(RAW[0], RAW[1], tuple(map(tuple, k)), m.dist_coeffs,
                                tuple(map(tuple, h)), 0.3)
            meta = replace(meta, camera_model=model)
        return meta

    def _dataset(self, folder: Path, lens: bool) -> Path:
        from tileviz.datasets import DatasetWriter
        from tileviz.types import FrameInput, Odometry, Pose

        w, h = RAW if lens else (W, H)
        with DatasetWriter(folder, self._meta(lens), durable=False) as wr:
            for k in range(3):
                wr.write(FrameInput(index=k, t=0.05 * k, image=floor_image(w, h, k),
                                    odometry=Odometry(0.1, 0.0, 0.05), compass=0.0,
                                    truth=Pose(0.005 * k, 0.0, 0.0),
                                    faults=("slip",) if k == 1 else ()))
        return folder

    def _images(self) -> dict[str, bytes]:
        import cv2
        import numpy as np

        img = floor_image(W, H)
        out = {"png": (self.dataset / "images/000000.png").read_bytes()}
        for name, arr, ext in [
            ("png9", img, ".png"), ("jpg", img, ".jpg"),
            ("gray", img[:, :, 0], ".png"), ("rgba", np.dstack([img, img[:, :, :1]]), ".png"),
            ("png16", img.astype(np.uint16) * 257, ".png"),
            ("graygray16", img[:, :, 0].astype(np.uint16) * 257, ".png"),
        ]:
            params = [cv2.IMWRITE_PNG_COMPRESSION, 9] if name == "png9" else []
            ok, buf = cv2.imencode(ext, arr, params)
            assert ok
            out[name] = buf.tobytes()
        pal = bytes(range(0, 256, 16)) * 3
        out["palette"] = png_bytes(W, H, bit_depth=4, color_type=3, palette=pal[:48])
        out["interlaced"] = png_bytes(W, H, interlace=1)
        out["wide"] = png_bytes(100_000, H)  # the header says 100 000 px wide
        out["huge"] = png_bytes(100_000, 100_000)
        return out

    def _bags(self) -> dict[str, Path]:
        from tileviz.datasets.sample import write_bag

        return {
            "ros1": write_bag(self.dataset, self.root / "bag1", ros1=True),
            "mcap": next((write_bag(self.dataset, self.root / "bag2m",
                                    storage="mcap")).glob("*.mcap")),
            "sqlite": next((write_bag(self.dataset, self.root / "bag2s")).glob("*.db3")),
        }

    def _store(self) -> Path:
        from tileviz.evaluation.simulate import Task, run_one
        from tileviz.evaluation.store import RunStore

        store = RunStore.open(self.root / "store", STORE_SETTINGS, resume=False)
        for r in range(2):
            store.add(run_one(Task("clean", r, r, 0.2, 50, 0.0, 0.5, None)))
        return self.root / "store"

    def seeds(self, reader: str) -> list[tuple[str, bytes]]:
        """(variant, valid bytes) to mutate for ``reader``."""
        if reader == "meta":
            return [("meta.json", (self.dataset / "meta.json").read_bytes())]
        if reader == "camera_model":
            return [("meta.json", (self.lens_dataset / "meta.json").read_bytes())]
        if reader == "frames":
            return [("frames.csv", (self.dataset / "frames.csv").read_bytes())]
        if reader == "faults":
            return [("faults.csv", (self.dataset / "faults.csv").read_bytes())]
        if reader in ("image", "extract"):
            return sorted(self.images.items())
        if reader == "bag":
            return [(k, p.read_bytes()) for k, p in sorted(self.bags.items())]
        if reader == "store":
            return [(name, (self.store / name).read_bytes()) for name in (
                "runs.csv", "campaign.json", "runs/clean-r0-s0.pkl")]
        raise KeyError(reader)


STORE_SETTINGS = {"duration": 0.2, "particles": 50}


# ------------------------------------------------------------------------------------- mutations
INTERESTING = [0, 1, 0x7F, 0x80, 0xFF, 0x7FFF, 0xFFFF, 0x7FFFFFFF, 0xFFFFFFFF, 100_000,
               65_535, 1 << 30]


def mutate(data: bytes, rng: random.Random, others: list[bytes]) -> bytes:
    """1 to 8 random mutations of ``data``: bit flips, bytes set to interesting values, 4-byte
    big-endian integers set to interesting values, cuts, inserts, deletions, duplicated or
    spliced spans; a PNG's CRCs recomputed half the time."""
    buf = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        op = rng.randrange(9)
        n = len(buf)
        if n == 0:
            buf += bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
            continue
        i = rng.randrange(n)
        if op == 0:
            buf[i] ^= 1 << rng.randrange(8)
        elif op == 1:
            buf[i] = rng.choice([0, 0xFF, 0x7F, 0x80, ord(","), ord("\n"), ord('"'), ord("-"),
                                 ord("9"), ord("e"), ord("{"), ord("]")])
        elif op == 2 and n >= 4:
            i = rng.randrange(n - 3)
            buf[i:i + 4] = (rng.choice(INTERESTING) & 0xFFFFFFFF).to_bytes(4, "big")
        elif op == 3:
            del buf[rng.randrange(n):]  # a cut file
        elif op == 4:
            buf[i:i] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 32)))
        elif op == 5:
            del buf[i:i + rng.randint(1, 64)]
        elif op == 6:
            j = min(n, i + rng.randint(1, 256))
            buf[j:j] = buf[i:j] * rng.randint(1, 4)
        elif op == 7 and others:
            other = rng.choice(others)
            if other:
                a = rng.randrange(len(other))
                buf[i:i + rng.randint(0, 64)] = other[a:a + rng.randint(1, 256)]
        else:
            text = rng.choice([b"nan", b"1e309", b"-0", b"999999999999", b"\x00", b"\xff\xfe",
                               b"null", b"[]", b"{}", b'"', b"\r\n", b"1e-320", b"0x10"])
            buf[i:i + rng.randint(0, 4)] = text
    out = bytes(buf)
    return fix_png_crcs(out) if rng.random() < 0.5 else out


# ---------------------------------------------------------------------------- hypothesis cases
def strategy(reader: str, templates: Templates) -> Any:
    """A hypothesis strategy of (variant, bytes) for ``reader``."""
    from hypothesis import strategies as st

    json_leaf = st.one_of(
        st.none(), st.booleans(), st.integers(min_value=-(1 << 70), max_value=1 << 70),
        st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=20),
        st.sampled_from([0, 1, -1, 0.5, 1e-12, 1e9, 1e300, 1 << 40, 100_000]))
    json_any = st.recursive(json_leaf, lambda inner: st.one_of(
        st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=8), inner, max_size=5)),
        max_leaves=12)

    def dumps(d: Any) -> bytes:
        return json.dumps(d, allow_nan=True).encode()

    if reader in ("meta", "camera_model"):
        seed = json.loads(templates.seeds(reader)[0][1])
        keys = sorted(seed)

        @st.composite
        def meta(draw: Any) -> tuple[str, bytes]:
            d = json.loads(json.dumps(seed))
            for key in draw(st.lists(st.sampled_from(keys), max_size=4, unique=True)):
                action = draw(st.integers(0, 3))
                if action == 0:
                    del d[key]
                elif action == 1:
                    d[key] = draw(json_any)
                elif action == 2 and isinstance(d[key], list):
                    d[key] = [draw(json_leaf) if draw(st.booleans()) else v for v in d[key]]
                else:
                    d[key] = draw(json_leaf)
            if reader == "camera_model":
                cm = d.get("camera_model")
                if isinstance(cm, dict):
                    # (a block the draws above made empty has no key to change)
                    for key in draw(st.lists(st.sampled_from(sorted(cm)), max_size=3,
                                             unique=True)) if cm else ():
                        cm[key] = draw(st.one_of(json_any, st.lists(
                            st.lists(json_leaf, min_size=3, max_size=3), min_size=3,
                            max_size=3)))
                    if draw(st.booleans()):
                        cm["raw_width"] = draw(st.sampled_from([1, 2, RAW[0], 100_000, 1 << 31]))
                        cm["raw_height"] = draw(st.sampled_from([1, 2, RAW[1], 100_000]))
            if draw(st.booleans()):
                d[draw(st.text(max_size=10))] = draw(json_any)
            if draw(st.integers(0, 4)) == 0:  # FLOOR HOOK (floor_block)
                d["floor"] = floor_block(random.Random(draw(st.integers(0, 1 << 30))))
            if draw(st.integers(0, 3)) == 0:
                d["image_width"], d["image_height"] = draw(st.sampled_from(
                    [(W, H), (1, 1), (100_000, 100_000), (1 << 31, 2), (W * 1000, H)]))
            text = dumps(d)
            if draw(st.integers(0, 9)) == 0:
                text = text[: draw(st.integers(0, len(text)))]
            if draw(st.integers(0, 19)) == 0:
                text = b"[" * draw(st.integers(1, 100_000)) + text
            return "meta.json", text

        return meta()
    if reader in ("frames", "faults"):
        number = st.one_of(
            st.floats(allow_nan=True, allow_infinity=True).map(repr),
            st.integers(-(1 << 70), 1 << 70).map(str), st.text(max_size=12),
            st.sampled_from(["", "0", "0.05", "1e309", "nan", "-inf", " 1 ", "1,5", '"x"',
                             "\x00", "0x1"]))
        if reader == "frames":
            header = st.one_of(
                st.just("index,t,image,speed,yaw_rate,compass,x,y,theta"),
                st.permutations(["index", "t", "image", "speed", "yaw_rate", "compass", "x", "y",
                                 "theta"]).map(",".join),
                st.lists(st.sampled_from(["index", "t", "image", "speed", "yaw_rate", "compass",
                                          "x", "y", "theta", "", "extra"]),
                         max_size=12).map(",".join))
            image = st.sampled_from(["images/000000.png", "images/000001.png", "images/",
                                     "../meta.json", "/etc/passwd", "", "missing.png",
                                     "images/000002.png"])
        else:
            header = st.sampled_from(["index,faults", "index", ""])
            image = st.sampled_from(["slip", "slip;kidnap", "", ";;"])

        @st.composite
        def table(draw: Any) -> tuple[str, bytes]:
            lines = [draw(header)]
            for k in range(draw(st.integers(0, 6))):
                cells = [str(k) if draw(st.integers(0, 3)) else draw(number)]
                if reader == "frames":
                    cells += [f"{0.05 * k!r}" if draw(st.integers(0, 3)) else draw(number),
                              draw(image)]
                    cells += [draw(number) if draw(st.integers(0, 2)) == 0 else "0.1"
                              for _ in range(6)]
                else:
                    cells.append(draw(image))
                if draw(st.integers(0, 5)) == 0:
                    cells = cells[: draw(st.integers(0, len(cells)))]
                lines.append(",".join(cells))
            end = draw(st.sampled_from(["\n", "\r\n", "\r"]))
            text = end.join(lines) + (end if draw(st.booleans()) else "")
            if draw(st.integers(0, 19)) == 0:
                text += "x" * draw(st.integers(100_000, 300_000))
            raw = text.encode("utf-8", "surrogatepass")
            if draw(st.integers(0, 9)) == 0:
                raw = raw[: draw(st.integers(0, len(raw)))]
            return (reader + ".csv"), raw

        return table()
    if reader in ("image", "extract"):
        @st.composite
        def image_case(draw: Any) -> tuple[str, bytes]:
            kind = draw(st.integers(0, 3))
            if kind == 0:  # a PNG header of any size and kind, little data
                ct = draw(st.sampled_from([0, 2, 3, 4, 6, 1, 5, 7]))
                bd = draw(st.sampled_from([1, 2, 4, 8, 16, 3]))
                w = draw(st.sampled_from([W, 1, 2, 100_000, 65_535, 1 << 31, 0, W + 1]))
                h = draw(st.sampled_from([H, 1, 2, 100_000, 0, H - 1]))
                pal = draw(st.one_of(st.none(), st.binary(max_size=800)))
                return "png", png_bytes(w, h, bit_depth=bd, color_type=ct,
                                        interlace=draw(st.integers(0, 2)), palette=pal)
            if kind == 1:  # a real image of another size or kind
                import cv2
                import numpy as np

                w = draw(st.integers(1, 3 * W))
                h = draw(st.integers(1, 3 * H))
                ch = draw(st.sampled_from([1, 3, 4]))
                deep = draw(st.booleans())
                arr = np.random.default_rng(draw(st.integers(0, 1 << 30))).integers(
                    0, 65535 if deep else 255, (h, w, ch) if ch > 1 else (h, w),
                    dtype=np.uint16 if deep else np.uint8)
                ext = draw(st.sampled_from([".png", ".jpg"]))
                if ext == ".jpg":
                    arr = (arr >> 8).astype(np.uint8) if deep else arr
                    arr = arr[..., :3] if ch == 4 else arr
                ok, buf = cv2.imencode(ext, arr)
                return ext[1:], buf.tobytes() if ok else b""
            name, data = draw(st.sampled_from(templates.seeds("image")))
            cut = draw(st.integers(0, len(data)))
            if kind == 2:  # cut short
                return name, data[:cut]
            flips = draw(st.lists(st.tuples(st.integers(0, len(data) - 1), st.integers(0, 7)),
                                  min_size=1, max_size=8))
            flipped = bytearray(data)
            for i, b in flips:
                flipped[i] ^= 1 << b
            return name, (fix_png_crcs(bytes(flipped)) if draw(st.booleans())
                          else bytes(flipped))

        return image_case()
    if reader == "bag":
        @st.composite
        def bag(draw: Any) -> tuple[str, bytes]:
            name, data = draw(st.sampled_from(templates.seeds("bag")))
            cut = draw(st.integers(0, len(data)))
            spans = draw(st.lists(st.tuples(st.integers(0, max(0, len(data) - 1)),
                                            st.binary(min_size=1, max_size=8)), max_size=4))
            buf = bytearray(data[:cut] if draw(st.booleans()) else data)
            for i, b in spans:
                if i < len(buf):
                    buf[i:i + len(b)] = b
            return name, bytes(buf)

        return bag()
    if reader == "store":
        seeds = dict(templates.seeds("store"))

        @st.composite
        def store(draw: Any) -> tuple[str, bytes]:
            name = draw(st.sampled_from(sorted(seeds)))
            data = seeds[name]
            if name == "campaign.json":
                d = json.loads(data)
                for key in draw(st.lists(st.sampled_from(sorted(d)), max_size=2, unique=True)):
                    d[key] = draw(json_any)
                return name, dumps(d) if draw(st.integers(0, 4)) else dumps(draw(json_any))
            if name == "runs.csv":
                lines = data.decode().split("\r\n")
                i = draw(st.integers(0, len(lines) - 1))
                cells = lines[i].split(",")
                j = draw(st.integers(0, len(cells) - 1))
                cells[j] = draw(st.text(max_size=12).filter(lambda t: "\n" not in t))
                lines[i] = ",".join(cells)
                text = "\r\n".join(lines).encode()
                return name, text[: draw(st.integers(0, len(text)))] if draw(
                    st.booleans()) else text
            cut = draw(st.integers(0, len(data)))
            spans = draw(st.lists(st.tuples(st.integers(0, len(data) - 1),
                                            st.binary(min_size=1, max_size=4)), max_size=3))
            buf = bytearray(data[:cut] if draw(st.integers(0, 3)) == 0 else data)
            for i, b in spans:
                if i < len(buf):
                    buf[i:i + len(b)] = b
            return name, bytes(buf)

        return store()
    raise KeyError(reader)


def hypothesis_cases(reader: str, templates: Templates, n: int,
                     seed: int) -> list[tuple[str, bytes]]:
    """``n`` cases of :func:`strategy` (fewer when the strategy runs out of new ones), generated
    deterministically from ``seed``."""
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hseed

    out: list[tuple[str, bytes]] = []
    strat = strategy(reader, templates)

    @settings(max_examples=n, database=None, phases=[Phase.generate], deadline=None,
              suppress_health_check=list(HealthCheck), derandomize=False)
    @hseed(seed)
    @given(strat)
    def collect(case: tuple[str, bytes]) -> None:
        out.append(case)

    collect()
    return out[:n]


def mutation_cases(reader: str, templates: Templates, n: int,
                   seed: int) -> list[tuple[str, bytes]]:
    """``n`` mutated valid files of ``reader``, deterministic from ``seed``."""
    seeds = templates.seeds(reader)
    others = [d for _, d in seeds]
    out = []
    for i in range(n):
        rng = random.Random(f"{reader}-{seed}-{i}")
        name, data = seeds[i % len(seeds)]
        out.append((name, mutate(data, rng, others)))
    return out


# --------------------------------------------------------------------------------------- running
@dataclass
class Result:
    """One case's outcome (:data:`OUTCOMES`), its message, its time (s) and the worker's peak
    resident set when this case raised it (MB; 0 when the case stayed under the peak the worker
    already had, e.g. its warm-up's)."""

    outcome: str
    message: str = ""
    seconds: float = 0.0
    maxrss_mb: float = 0.0


def _copy(src: Path, dst: Path) -> None:
    import shutil

    shutil.copytree(src, dst)


@contextlib.contextmanager
def _captured(work: Path) -> Iterator[tuple[Path, Path]]:
    """stdout and stderr of this process (file descriptors 1 and 2) into two files."""
    out, err = work / "stdout.txt", work / "stderr.txt"
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    fo, fe = os.open(out, os.O_WRONLY | os.O_CREAT, 0o644), os.open(err, os.O_WRONLY | os.O_CREAT,
                                                                    0o644)
    os.dup2(fo, 1)
    os.dup2(fe, 2)
    try:
        yield out, err
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, fo, fe):
            os.close(fd)


def _command(reader: str, variant: str, data: bytes, t: Templates,
             work: Path) -> tuple[list[str], list[str]]:
    """Lay out the case's input under ``work``; returns the command line and the names one of
    which an error line must contain (the file, or its folder)."""
    ds = work / "ds"
    if reader in ("meta", "frames", "faults", "image"):
        _copy(t.dataset, ds)
        target = {"meta": ds / "meta.json", "frames": ds / "frames.csv",
                  "faults": ds / "faults.csv", "image": ds / "images/000001.png"}[reader]
        target.write_bytes(data)
        return (["replay", str(ds), "--out", str(work / "r.csv"), "--jobs", "1", "--quiet"],
                [str(ds)])
    if reader == "camera_model":
        _copy(t.lens_dataset, ds)
        (ds / "meta.json").write_bytes(data)
        return (["replay", str(ds), "--out", str(work / "r.csv"), "--jobs", "1", "--quiet"],
                [str(ds)])
    if reader == "extract":
        img = work / f"view.{'jpg' if variant == 'jpg' else 'png'}"
        img.write_bytes(data)
        return ["extract", str(img), "--tile-size", "0.25", "--ppm", "100"], [str(img)]
    if reader == "bag":
        if variant == "ros1":
            bag = work / "in.bag"
            bag.write_bytes(data)
        else:
            _copy(t.bags[variant].parent, work / "bag")
            (work / "bag" / t.bags[variant].name).write_bytes(data)
            bag = work / "bag"
        out = work / "out"
        return (["import-bag", str(bag), str(out), "--image-topic", "/camera/image",
                 "--odom-topic", "/odom", "--imu-topic", "/imu", "--tile-size", "0.25",
                 "--ppm", "100", "--camera-offset", "0,0", "--speed-error", "0.05",
                 "--yaw-rate-error", "0.05", "--compass-error", "0.05"], [str(bag), str(out)])
    if reader == "store":
        _copy(t.store, work / "store")
        (work / "store" / variant).write_bytes(data)
        return ["store", str(work / "store")], [str(work / "store")]
    raise KeyError(reader)


def _store_command(folder: Path) -> int:
    """What ``evaluate --resume FOLDER`` does with the store before it makes new runs: open it,
    read the kept runs back, tabulate them (as the report does). One line on an error."""
    from tileviz.cliutil import run_cli
    from tileviz.evaluation.report import aggregate
    from tileviz.evaluation.store import RunStore

    def body() -> int:
        store = RunStore.open(folder, STORE_SETTINGS, resume=True)
        aggregate(store.results())
        return 0

    return run_cli("tileviz evaluate", body)


def run_case(reader: str, variant: str, data: bytes, t: Templates) -> Result:
    """Run one case in this process (module docstring: the outcomes). A case passes the
    memory limit only by raising the process's peak beyond it (the worker's warm-up may have
    peaked higher: compiling the vision kernels on a fresh install does)."""
    start = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    with tempfile.TemporaryDirectory(prefix="fuzz-") as tmp:
        work = Path(tmp)
        argv, names = _command(reader, variant, data, t, work)
        exc: BaseException | None = None
        code: int | None = None
        with _captured(work) as (out_path, err_path):
            try:
                if argv[0] == "store":
                    code = _store_command(Path(argv[1]))
                else:
                    from tileviz.__main__ import main

                    code = main(argv)
            except SystemExit as e:
                code = e.code if isinstance(e.code, int) else 2
            except MemoryError as e:
                exc = e
            except BaseException as e:  # noqa: BLE001 - the finding
                exc = e
        err = err_path.read_text(errors="replace").strip().splitlines()
        out = out_path.read_text(errors="replace").strip().splitlines()
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    rss = peak if peak > before else 0.0  # the peak this case raised the worker to
    if isinstance(exc, MemoryError) or rss > MEMORY_LIMIT_MB:
        return Result("memory", f"{type(exc).__name__ if exc else 'peak RSS'} "
                      f"({peak:.0f} MB)", seconds, rss)
    if exc is not None:
        import traceback

        tb = "".join(traceback.format_exception(exc)[-3:])
        return Result("traceback", f"{type(exc).__name__}: {exc} | {tb}"[:1500], seconds, rss)
    if code == 0:
        if len(err) > 1:
            return Result("traceback", "success, but stderr has "
                          f"{len(err)} lines: {' | '.join(err[:4])}"[:1500], seconds, rss)
        return Result("ok", err[0] if err else "", seconds, rss)
    if (code == 1 and reader == "extract" and not err and len(out) == 1
            and any(n in out[0] for n in names)):
        # the image was read and the extractor refused it: the line on stdout says why
        return Result("ok", out[0][:300], seconds, rss)
    if len(err) != 1:
        return Result("traceback", f"exit {code}, stderr has {len(err)} lines: "
                      f"{' | '.join(err[:6])}"[:1500], seconds, rss)
    line = err[0]
    if code != 2 or ": error: " not in line:
        return Result("traceback", f"exit {code}: {line}"[:1500], seconds, rss)
    if not any(n in line for n in names):
        return Result("traceback", f"the error does not name the file: {line}"[:1500], seconds,
                      rss)
    return Result("error", line[:300], seconds, rss)


# ---------------------------------------------------------------------------------------- worker
def _send(f: Any, obj: Any) -> None:
    blob = pickle.dumps(obj)
    f.write(struct.pack(">Q", len(blob)) + blob)
    f.flush()


def _recv(f: Any) -> Any:
    head = f.read(8)
    if len(head) < 8:
        raise EOFError
    return pickle.loads(f.read(struct.unpack(">Q", head)[0]))


def _vm_bytes() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
    return 0


def worker_main() -> None:
    """A worker: cases in on stdin, results out on the original stdout (length-prefixed
    pickles); its own stdout goes to /dev/null between cases."""
    proto_in = os.fdopen(os.dup(0), "rb")
    proto_out = os.fdopen(os.dup(1), "wb")
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    from tileviz.vision import set_opencv_threads
    from tileviz.vision.warmup import warm_up

    set_opencv_threads()
    with tempfile.TemporaryDirectory(prefix="fuzz-templates-") as tmp:
        with _captured(Path(tmp)):
            t = Templates(Path(tmp))
            warm_up(("robust", "faithful"))
            import tileviz.datasets.bag_import  # noqa: F401
            import tileviz.evaluation.report  # noqa: F401
            import tileviz.vision.cli  # noqa: F401
        limit = _vm_bytes() + HEADROOM_MB * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        _send(proto_out, "ready")
        while True:
            try:
                reader, variant, data = _recv(proto_in)
            except EOFError:
                return
            try:
                res = run_case(reader, variant, data, t)
            except MemoryError:
                res = Result("memory", "MemoryError in the harness")
            _send(proto_out, res)


class Worker:
    """A worker process and its pipes; :meth:`run` enforces the per-case timeout."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", "from tileviz.testing.fuzzing import worker_main; "
             "worker_main()"],
            cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        self.ready = False

    def start_wait(self, timeout: float) -> None:
        self._wait(timeout)
        self.ready = True

    def _wait(self, timeout: float) -> Any:
        import select

        assert self.proc.stdout is not None
        r, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if not r:
            raise TimeoutError
        return _recv(self.proc.stdout)

    def send(self, case: tuple[str, str, bytes]) -> None:
        assert self.proc.stdin is not None
        _send(self.proc.stdin, case)

    def kill(self) -> None:
        self.proc.kill()
        self.proc.wait()

    def close(self) -> None:
        if self.proc.poll() is None:
            assert self.proc.stdin is not None
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.kill()


@dataclass
class Finding:
    reader: str
    engine: str
    index: int
    variant: str
    data: bytes
    result: Result


@dataclass
class Report:
    """A campaign: outcome counts per reader, the findings, the largest peak resident set a
    case raised a worker to (MB), its time and the slowest case (s)."""

    counts: dict[str, dict[str, int]]
    findings: list[Finding]
    peak_rss_mb: float
    seconds: float
    slowest_s: float


def campaign(readers: list[str], n: int, *, engines: tuple[str, ...] = ("hypothesis", "mutate"),
             seed: int = 0, workers: int = 2, timeout: float = 60.0,
             progress: Callable[[str], None] | None = None,
             minutes: float | None = None) -> Report:
    """``n`` cases per reader (split between ``engines``), in ``workers`` processes, each case
    given ``timeout`` seconds (then a hang: the worker is replaced). The readers' cases run
    interleaved (each reader's k-th case before any reader's k+1-th), so that ``minutes`` (a
    budget from the start, case making included: no case starts after it) stops every reader
    at about the same count; the report counts the cases that ran. ``progress`` gets a line
    every 200 cases and each finding as it is found."""
    import select

    start = time.monotonic()
    gen_root = Path(tempfile.mkdtemp(prefix="fuzz-gen-"))
    with _captured(gen_root):
        templates = Templates(gen_root)
    deadline = start + 60.0 * minutes if minutes is not None else math.inf
    per_reader: list[list[tuple[str, str, int, str, bytes]]] = []
    for reader in readers:
        mine: list[tuple[str, str, int, str, bytes]] = []
        per = [n // len(engines) + (1 if i < n % len(engines) else 0)
               for i in range(len(engines))]
        for engine, k in zip(engines, per, strict=True):
            made = (hypothesis_cases if engine == "hypothesis" else mutation_cases)(
                reader, templates, k, seed)
            if engine == "hypothesis" and len(made) < k:  # the strategy ran dry: mutate more
                made += mutation_cases(reader, templates, k - len(made), seed + 1)
            mine += [(reader, engine, i, v, d) for i, (v, d) in enumerate(made)]
        # the engines' cases alternate too
        by_engine = [[j for j in mine if j[1] == e] for e in engines]
        per_reader.append([j for group in itertools.zip_longest(*by_engine) for j in group
                           if j is not None])
    jobs = [j for group in itertools.zip_longest(*per_reader) for j in group if j is not None]
    counts = {r: dict.fromkeys(OUTCOMES, 0) for r in readers}
    findings: list[Finding] = []
    peak = 0.0
    slowest = 0.0
    pool = [Worker() for _ in range(max(1, workers))]
    for w in pool:
        w.start_wait(1800)
    busy: dict[int, tuple[int, float]] = {}  # worker slot -> (job index, started)
    todo = list(range(len(jobs)))[::-1]
    done = 0

    def record(j: int, res: Result) -> None:
        nonlocal done, peak, slowest
        reader, engine, i, v, d = jobs[j]
        counts[reader][res.outcome] += 1
        peak = max(peak, res.maxrss_mb)
        slowest = max(slowest, res.seconds)
        if res.outcome in ("traceback", "hang", "memory"):
            findings.append(Finding(reader, engine, i, v, d, res))
            if progress is not None:
                progress(describe(findings[-1]))
        done += 1
        if progress is not None and (done % 200 == 0 or done == len(jobs)):
            progress(f"{done}/{len(jobs)} cases, {len(findings)} findings, "
                     f"{time.monotonic() - start:.0f} s")

    try:
        while todo or busy:
            if todo and time.monotonic() > deadline:
                todo.clear()  # out of time: the cases under way end, no new one starts
                if progress is not None:
                    progress(f"{done + len(busy)}/{len(jobs)} cases: the time budget is over")
            for slot, w in enumerate(pool):
                if slot not in busy and todo:
                    j = todo.pop()
                    reader, _, _, v, d = jobs[j]
                    w.send((reader, v, d))
                    busy[slot] = (j, time.monotonic())
            streams: dict[IO[bytes], int] = {}
            for busy_slot in busy:
                stream_of = pool[busy_slot].proc.stdout
                assert stream_of is not None
                streams[stream_of] = busy_slot
            ready, _, _ = select.select(list(streams), [], [], 1.0)
            for stream in ready:
                slot = streams[stream]
                j, _ = busy.pop(slot)
                try:
                    res = _recv(stream)
                except (EOFError, pickle.UnpicklingError):
                    res = Result("memory" if pool[slot].proc.poll() is not None else "traceback",
                                 f"the worker died (exit {pool[slot].proc.poll()})")
                    pool[slot].kill()
                    pool[slot] = Worker()
                    pool[slot].start_wait(1800)
                record(j, res)
            now = time.monotonic()
            for slot, (j, began) in list(busy.items()):
                if now - began > timeout:
                    busy.pop(slot)
                    pool[slot].kill()
                    record(j, Result("hang", f"no answer in {timeout:g} s", now - began))
                    pool[slot] = Worker()
                    pool[slot].start_wait(1800)
    finally:
        for w in pool:
            w.close()
        import shutil

        shutil.rmtree(gen_root, ignore_errors=True)
    return Report(counts, findings, peak, time.monotonic() - start, slowest)


def describe(f: Finding) -> str:
    """One finding in a few lines (the input's first bytes as a Python literal)."""
    head = f.data[:120]
    return (f"[{f.reader} {f.engine} #{f.index} {f.variant} {len(f.data)} bytes] "
            f"{f.result.outcome}: {f.result.message}\n    input starts {head!r}")

