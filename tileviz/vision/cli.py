"""``python -m tileviz extract IMAGE...``: tile parameters of camera images, one line per image.

Options: ``--preset {default,seed}`` (the camera and vision constants; with a preset given the
image size must be the preset's), ``--ppm P``, ``--tile-size L`` (metres), ``--extractor
{faithful,robust}``, ``--json`` (one JSON object per image and line: ``image``, ``y1``, ``y2``,
``y3`` (docs/method.md convention; null when refused), ``accepted``, ``reason``, ``lines``, ...;
with the robust extractor also ``decision``: every check run with its value and limit, the
readings tried and the refusing check, :meth:`tileviz.vision.decision.Decision.as_dict`),
``--explain`` (after each image's line, the robust extractor's decision path as a table: the
readings tried and, for the view and each reading, every check with its id, value, limit and
pass / fail; the check that refused the view is named first, with its value and limit, then
the scale read, saying when ``--tile-size`` or ``--ppm`` was not given; the check ids and
their settings are listed in :mod:`tileviz.vision.robust.checks`; with
``--json`` the same data is the ``decision`` key), ``--stages DIR`` (every stage image as
``DIR/<image stem>_<nn>_<stage>.png``; a stem met again in the same run becomes ``<stem>-2``,
``<stem>-3``...), ``--camera-model META`` (a dataset's meta.json with a ``camera_model`` block:
each image is a raw camera image, rectified first; the meta's ppm, view size, tile size and
widened view bound are used).

An image that cannot be used (unreadable, wrong size) gives a one-line error on stderr and the
others are still processed. A frame the extractor refuses (e.g. a constant image) is a result:
``no observation (reason)``. Exit status (:data:`EXIT_HELP`): 0 when every image gave an
observation, 1 when an image gave none (and none was bad input), 2 when an image or an option
could not be used. The JSON's ``timings_ms`` are
the view's own: the robust extractor's compiled kernels are loaded before the first image
(:func:`tileviz.vision.warmup.warm_up`), not counted in its stages.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from tileviz.cliutil import (
    EXTRACTOR_HELP,
    FIRST_RUN_NOTICE,
    CliError,
    Parser,
    add_floor_options,
    declared_floor,
    notice_if_slow,
    positive_float,
    read_json,
    run_cli,
)
from tileviz.config import EXTRACTORS, PRESETS, Config, preset
from tileviz.vision import VisionResult, check_tile_span, extract
from tileviz.vision.decision import explain_lines

if TYPE_CHECKING:
    from tileviz.datasets.camera_model import Rectifier

__all__ = ["EXIT_HELP", "main"]

EXIT_HELP = ("exit status: 0 when every image gave an observation, 1 when an image gave none "
             "(the extractor refused it: the line says why), 2 when an image or an option could "
             "not be used (one line on stderr each; the other images are still read), 141 when "
             "the output's reader stopped early (| head)")
"""What ``extract --help`` says of its exit status."""


def _parser(prog: str) -> Parser:
    p = Parser(prog=prog, description="Extract the tile parameters (y1, y2, y3) from images.",
               epilog=EXIT_HELP)
    p.add_argument("images", nargs="+", metavar="IMAGE", help="image files (PNG, JPEG, ...)")
    p.add_argument("--preset", choices=PRESETS, default=None,
                   help="camera/vision constants; given, every image must have the "
                   "preset's size (default: the 'default' constants with each image's own size)")
    p.add_argument("--ppm", type=positive_float("--ppm"), default=None,
                   help="pixels per metre on the floor (default: --camera-model's meta.json, "
                   "else the preset's, 200 for 'default'; the positions in metres scale with "
                   "it)")
    p.add_argument("--tile-size", type=positive_float("--tile-size"), default=None,
                   help="tile size L, metres (default: --camera-model's meta.json, else the "
                   "preset's, 1 for 'default')")
    add_floor_options(p)
    p.add_argument("--extractor", choices=EXTRACTORS, default=None,
                   help=f"{EXTRACTOR_HELP} (default: the preset's)")
    p.add_argument("--json", action="store_true",
                   help="one JSON object per image (with the robust extractor's decision path)")
    p.add_argument("--explain", action="store_true",
                   help="print the robust extractor's decision path: the readings tried and "
                   "every check (id, value, limit, pass/fail)")
    p.add_argument("--stages", metavar="DIR", default=None, help="write every stage image here")
    p.add_argument("--camera-model", metavar="META", default=None,
                   help="meta.json with a camera_model block: rectify each raw image first")
    return p


def _camera_model(path: str, base: Config) -> tuple[Config, Rectifier]:
    """The configuration (over ``base``) and the rectification of a meta.json's camera model;
    CliError naming the file when it has none or is not valid."""
    from tileviz.datasets import DatasetMeta, replay_config
    meta = DatasetMeta.from_json(read_json(path, "--camera-model"), where=path)
    rectifier = meta.rectifier()
    if rectifier is None:
        raise CliError(f"--camera-model: {path} has no camera_model block")
    return replay_config(meta, base=base, where=path), rectifier


def read_image(path: str) -> np.ndarray:
    """An image file as HxWx3 uint8 RGB, decoded as a dataset's images are
    (:func:`~tileviz.datasets.images.decode_image`); CliError naming the file and the problem
    when it cannot be read (missing, a directory, cut off, damaged, a header declaring more
    pixels than tileviz reads, 16-bit data in the low bits, not an image)."""
    from tileviz.datasets.images import decode_image, depth_problem, size_problem, truncated

    if os.path.isdir(path):
        raise CliError(f"{path}: is a directory, not an image")
    if not os.path.isfile(path):
        raise CliError(f"{path}: no such file")
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise CliError(f"{path}: cannot read it ({e.strerror or e})") from None
    if truncated(raw):
        raise CliError(f"{path}: is truncated (no end marker)")
    problem = size_problem(raw) or depth_problem(raw)
    if problem is not None:
        raise CliError(f"{path}: {problem}")
    complaints: list[str] = []
    img = decode_image(raw, complaints=complaints)
    if img is None or img.size == 0:
        why = f" ({complaints[0]})" if complaints else ""
        raise CliError(f"{path}: cannot read it as an image{why}")
    return img


def _config(args: argparse.Namespace, image: np.ndarray, base: Config | None = None) -> Config:
    cfg = base or preset(args.preset or "default")
    h, w = image.shape[:2]
    cam = cfg.camera
    if args.preset is None and base is None:
        cam = replace(cam, width=w, height=h)
    if args.ppm is not None:
        cam = replace(cam, ppm=args.ppm)
    floor = cfg.floor
    if args.tile_size is not None:
        floor = floor.with_tile_size(args.tile_size)
    floor = declared_floor(floor, args)
    vision = cfg.vision
    if args.extractor is not None:
        vision = replace(vision, extractor=args.extractor)
    return replace(cfg, camera=cam, floor=floor, vision=vision)


def _line(path: str, res: VisionResult) -> str:
    obs = res.observation
    if obs is None:
        return f"{path}: no observation ({res.reason}); {_refused_lines(res)}"
    return (
        f"{path}: y1={obs.y1:.6f} m y2={obs.y2:.6f} m y3={obs.y3:.6f} rad "
        f"(+-{obs.position_error:.6f} m, +-{obs.heading_error:.6f} rad); {res.lines} lines"
    )


def _refused_lines(res: VisionResult) -> str:
    """The line count of a refused view, naming the reading whose lines they are (its number
    in ``--explain``) when that is not the reading that refused the view."""
    d = res.decision
    if d is None or d.shown is None or d.shown == d.refused_in:
        return f"{res.lines} lines"
    return f"{res.lines} lines in reading {d.shown + 1}"


def _scale_line(args: argparse.Namespace, cfg: Config) -> str:
    """The scale a view was read at (tile size, ppm, the period in px), and where it came from
    when ``--tile-size`` or ``--ppm`` was not given (a wrong scale refuses views for their
    spacing or reads them a period off: ``--explain`` says which was read)."""
    tile, ppm = cfg.floor.tile_size, float(cfg.camera.ppm)
    missing = [name for name, v in (("--tile-size", args.tile_size), ("--ppm", args.ppm))
               if v is None]
    line = f"  scale: tiles of {tile:g} m at {ppm:g} px/m (a period of {tile * ppm:.1f} px)"
    if missing:
        source = ("the camera model's" if args.camera_model is not None
                  else f"the {args.preset or 'default'} preset's")
        line += f"; {' and '.join(missing)} not given: {source}"
    return line


def _explain(res: VisionResult) -> list[str]:
    """The decision path of ``res`` as indented lines (:func:`~tileviz.vision.decision.
    explain_lines`, with what each check's value is and its unit), or one line saying the
    extractor records none."""
    if res.decision is None:
        return [f"  the {res.extractor} extractor records no decision path "
                "(--extractor robust does)"]
    from tileviz.vision.robust.checks import CHECKS
    from tileviz.vision.views import VIEW_CHECKS_WHAT

    what = {**{c.id: c.what for c in CHECKS.values()}, **VIEW_CHECKS_WHAT}
    return ["  " + line for line in explain_lines(res.decision, what)]


def _stage_stem(path: str, used: dict[str, int]) -> str:
    """The file name stem of ``path``'s stage images: the image's own stem, with ``-2``,
    ``-3``... when an image of the same stem came before in this run (``used`` counts them)."""
    stem = Path(path).stem
    used[stem] = used.get(stem, 0) + 1
    return stem if used[stem] == 1 else f"{stem}-{used[stem]}"


def _write_stages(folder: Path, stem: str, res: VisionResult) -> None:
    for i, (name, img) in enumerate(res.stages.items()):
        out = folder / f"{stem}_{i:02d}_{name}.png"
        if not cv2.imwrite(str(out), cv2.cvtColor(img, cv2.COLOR_RGB2BGR)):
            raise CliError(f"cannot write {out}")


def _extract_one(args: argparse.Namespace, path: str, base: Config | None,
                 rectify: Rectifier | None, *, keep_stages: bool) -> VisionResult:
    """Read the image ``path`` (rectified first with a camera model) and extract it with the
    configuration the options ask for; CliError or ValueError naming the problem."""
    image = read_image(path)
    if rectify is not None:  # the gray view, as replay and the server read it
        image = rectify.gray(image)
    cfg = _config(args, image, base)
    h, w = image.shape[:2]
    if (w, h) != (cfg.camera.width, cfg.camera.height):
        wants = (f"preset {args.preset!r}" if args.preset is not None
                 else f"the camera model ({args.camera_model})")
        raise CliError(f"{path}: image is {w}x{h} but {wants} expects "
                       f"{cfg.camera.width}x{cfg.camera.height}")
    return extract(image, camera=cfg.camera, tile_size=cfg.floor.tile_size, vision=cfg.vision,
                   keep_stages=keep_stages, floor=cfg.floor.model)


def main(command: str, argv: list[str]) -> int:
    """Entry point of ``python -m tileviz extract``; returns the exit status."""
    prog = f"tileviz {command}"
    args = _parser(prog).parse_args(argv)

    def body() -> int:
        folder = None
        if args.stages is not None:
            folder = Path(args.stages)
            try:
                folder.mkdir(parents=True, exist_ok=True)
            except OSError as e:
                raise CliError(f"--stages: cannot create {folder}: {e.strerror}") from None
        base, rectify = None, None
        if args.camera_model is not None:
            base, rectify = _camera_model(args.camera_model, preset(args.preset or "default"))
        # the options' own errors once, before any image (a bad --lattice-tolerance is no
        # image's fault)
        early = _config(args, np.zeros((16, 16, 3), np.uint8), base)
        try:
            check_tile_span(early.floor.tile_size, early.camera.ppm)
        except ValueError as e:
            raise CliError(f"--tile-size x --ppm: {e}") from None
        status = 0
        refused = False
        stems: dict[str, int] = {}
        with notice_if_slow(f"{prog}: {FIRST_RUN_NOTICE}", after=10.0) as slow:
            if args.extractor != "faithful":
                from tileviz.vision.warmup import warm_up

                # the kernels' one-off loading out of the first image's stage timings
                warm_up()
            for path in args.images:
                try:
                    res = _extract_one(args, path, base, rectify, keep_stages=folder is not None)
                except (CliError, ValueError) as e:
                    msg = str(e) if str(e).startswith(path) else f"{path}: {e}"
                    print(f"{prog}: error: {msg}", file=sys.stderr)
                    status = 2
                    continue
                slow.cancel()  # a first result is in: no notice of a slow start
                refused = refused or res.observation is None
                if folder is not None:
                    _write_stages(folder, _stage_stem(path, stems), res)
                if args.json:
                    print(json.dumps({"image": path, **res.as_dict()}))
                else:
                    print(_line(path, res))
                    if args.explain:
                        said = _explain(res)
                        print("\n".join([said[0], _scale_line(args, early), *said[1:]]))
        return status or int(refused)

    return run_cli(prog, body)
