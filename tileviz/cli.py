"""``python -m tileviz record`` and ``python -m tileviz replay``."""

from __future__ import annotations

import math
import sys
import threading
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from tileviz.cliutil import (
    EXTRACTOR_HELP,
    FIRST_RUN_NOTICE,
    CliError,
    Parser,
    add_fault_options,
    add_floor_options,
    config_from_args,
    float_in,
    int_in,
    notice_if_slow,
    positive_int,
    run_cli,
)
from tileviz.config import (
    EXTRACTORS,
    FLOOR_STYLES,
    MODES,
    PPM_RANGE,
    PRESETS,
    SEED_RANGE,
    SETPOINTS,
    TILE_SIZE_RANGE,
)
from tileviz.core.constants import MIN_TILE_PX

if TYPE_CHECKING:
    from tileviz.pipeline import FrameRecord

MAX_DURATION = 86400.0
"""Longest recording, simulated seconds (a day)."""
MAX_DT = 1.0
"""Longest frame period, seconds."""


def _progress(total: int | None, desc: str, enabled: bool) -> object:
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="frame", disable=not enabled, file=sys.stderr,
                dynamic_ncols=True)


def record_parser() -> Parser:
    p = Parser(prog="tileviz record", description="Simulate a run and write a "
               "tileviz-dataset/1 folder (meta.json, frames.csv, images/); prints the frames "
               "and megabytes written. The images are stored as they are: about 280 MB a "
               "minute of the default camera, 1.1 GB with --lens webcam (see --png-level).")
    p.add_argument("out", help="output folder (must not exist or be empty)")
    p.add_argument("--duration", type=float_in("--duration", 0.0, MAX_DURATION), required=True,
                   help="simulated seconds")
    p.add_argument("--preset", choices=PRESETS, default="default")
    p.add_argument("--seed", type=int_in("--seed", *SEED_RANGE), default=0,
                   help="seed of the run (noise, floor)")
    p.add_argument("--tile-size", type=float_in("--tile-size", *TILE_SIZE_RANGE, lo_open=False),
                   help="L, metres")
    p.add_argument("--ppm", type=float_in("--ppm", *PPM_RANGE, lo_open=False),
                   help="pixels per metre")
    p.add_argument("--width", type=positive_int("--width"), help="image width, px")
    p.add_argument("--height", type=positive_int("--height"), help="image height, px")
    p.add_argument("--dt", type=float_in("--dt", 0.0, MAX_DT), help="frame period, s")
    p.add_argument("--setpoint", choices=SETPOINTS, help="setpoint kind")
    p.add_argument("--speed-error", type=float_in("--speed-error", 0.0, 10.0, lo_open=False),
                   help="m/s bound")
    p.add_argument("--yaw-rate-error", type=float_in("--yaw-rate-error", 0.0, 10.0,
                                                     lo_open=False), help="rad/s bound")
    p.add_argument("--compass-error", type=float_in("--compass-error", 0.0, math.pi,
                                                    lo_open=False), help="rad bound")
    p.add_argument("--no-compass", action="store_true", help="leave the compass column empty")
    p.add_argument("--lens", choices=("webcam",), default=None,
                   help="a real camera: 640x480 images through a tilted, distorting webcam "
                   "lens; meta.json gets its camera_model and replay rectifies them")
    p.add_argument("--jpg", action="store_true", help="write JPEG images instead of PNG")
    p.add_argument("--png-level", type=int, choices=range(10), default=0, metavar="0..9",
                   help="PNG compression, lossless. Default 0: the pixels stored as they are. "
                   "1 to 9 take less than half the disk, but decoding a compressed image costs "
                   "about as much as vision on it, so a replay of the dataset runs slower (the "
                   "larger the images, the more): that is why 0 is the default (--jpg is smaller "
                   "still but lossy: it changes the views)")
    p.add_argument("--floor-style", choices=tuple(FLOOR_STYLES), default="default",
                   help="the floor's look: light grout, wide grout, a photograph on the tiles, "
                   "uneven lighting, a checkerboard (no grout), hand-laid tiles, a mosaic in "
                   "panels, faint coloured grout (checker, hand_laid and mosaic declare their kind "
                   "or tolerance; default: the preset's floor)")
    add_floor_options(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def record(argv: list[str]) -> int:
    args = record_parser().parse_args(argv)

    def body() -> int:
        from tileviz.datasets import DatasetMeta, DatasetWriter, dataset_mb
        from tileviz.sim.source import SimSource

        cfg = config_from_args(args)
        tile_px = cfg.floor.tile_size * cfg.camera.ppm
        if tile_px < MIN_TILE_PX:
            raise CliError(f"--tile-size x --ppm: a tile must span at least {MIN_TILE_PX:g} "
                           f"pixels, got {tile_px:g}")
        frames = int(math.floor(args.duration / cfg.sim.dt + 1e-9)) + 1
        out = Path(args.out)
        meta = DatasetMeta.from_config(cfg, name=f"tileviz {args.preset} seed {args.seed}")
        renderer = None
        if args.lens is not None:
            from tileviz.sim.lens import LensRenderer, webcam_model

            model = webcam_model(cfg.camera)
            renderer = LensRenderer(cfg.floor, cfg.camera, model)
            meta = replace(meta, camera_model=model)
        writer = DatasetWriter(out, meta, image_format="jpg" if args.jpg else "png",
                               png_level=args.png_level)
        bar = _progress(frames, "record", not args.quiet)
        finished = False
        try:
            for i, frame in enumerate(SimSource(cfg, renderer=renderer)):
                if i >= frames:
                    break
                if args.no_compass:
                    frame = replace(frame, compass=None)
                writer.write(frame)
                bar.update(1)  # type: ignore[attr-defined]
            finished = True
        finally:
            bar.close()  # type: ignore[attr-defined]
            # stopped before the end (an error, Ctrl-C): meta.json says the dataset ended early
            writer.close(complete=finished)
        print(f"wrote {writer.count} frames ({dataset_mb(out):.1f} MB) to {out}")
        return 0

    return run_cli("tileviz record", body)


def replay_parser() -> Parser:
    p = Parser(prog="tileviz replay", description="Replay a tileviz-dataset/1 folder through "
               "vision and the localizer; write one CSV row per frame (--out) and print a "
               "one-line summary.")
    p.add_argument("dataset", help="dataset folder")
    p.add_argument("--mode", choices=MODES, default="autonomous")
    p.add_argument("--out", default=None, help="replay output CSV (docs/dataset-format.md); "
                   "without it only the summary is printed")
    p.add_argument("--output-file", help="CSV of the six equivalence residuals per frame "
                   "(report table 6.1, corrected signs; needs ground truth)")
    p.add_argument("--extractor", choices=EXTRACTORS, default=None,
                   help=f"{EXTRACTOR_HELP} (default: the dataset's, else robust)")
    p.add_argument("--max-boxes", type=positive_int("--max-boxes"), default=None)
    add_fault_options(p)
    p.add_argument("--mcap", default=None, metavar="OUT.mcap",
                   help="also write the run for Foxglove: camera images, truth, the sets as 3-D "
                   "cubes, status and box widths (needs the [ros] extra)")
    p.add_argument("--jobs", type=positive_int("--jobs"), default=None,
                   help="processes that decode images and run vision, several frames at once "
                   "(the localizer stays in order in this process; same output whatever the "
                   "count); default: one per core this process may use, at most 4; 1: one "
                   "process, images decoded ahead on a thread")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def replay(argv: list[str]) -> int:
    args = replay_parser().parse_args(argv)
    from tileviz.pipeline.worker_server import default_jobs, start_worker_server

    if (args.jobs or default_jobs()) > 1:
        # first thing: the workers' fork server loads the vision code on another core while
        # this process imports its own (tileviz.pipeline.worker_server)
        start_worker_server()

    def body() -> int:
        from tileviz.pipeline.heap import keep_freed_memory
        from tileviz.pipeline.replay import replay as run_replay
        from tileviz.summary import RunTally

        keep_freed_memory()  # vision's image-sized arrays reuse the heap (--jobs 1)

        bar = None
        tally = RunTally()

        def on_total(total: int | None) -> None:
            nonlocal bar
            bar = _progress(total, "replay", not args.quiet)

        slow: threading.Timer | None = None
        notices: list[str] = []

        def on_frame(rec: FrameRecord) -> None:
            nonlocal slow
            if slow is not None:  # the first frame is in: no notice of a slow start
                slow.cancel()
                slow = None
            tally.add(rec)
            bar.update(1)  # type: ignore[attr-defined]

        try:
            with notice_if_slow(f"tileviz replay: {FIRST_RUN_NOTICE}", after=10.0) as slow:
                n = run_replay(args.dataset, out=args.out, output_file=args.output_file,
                               mode=args.mode, extractor=args.extractor,
                               max_boxes=args.max_boxes, jobs=args.jobs, mcap=args.mcap,
                               fault_model=args.fault_model,
                               relocalize_region=args.relocalize_region,
                               on_total=on_total, on_frame=on_frame, on_notice=notices.append)
        finally:
            if bar is not None:
                bar.close()  # type: ignore[attr-defined]
        for text in notices:  # after a replay that went through (an error is the one line)
            print(f"tileviz replay: {text}", file=sys.stderr, flush=True)
        into = f" into {args.out}" if args.out is not None else ""
        print("; ".join([f"replayed {n} frames{into}", *tally.parts()]))
        return 0

    return run_cli("tileviz replay", body)


def main(command: str, argv: list[str]) -> int:
    """Entry for ``python -m tileviz record|replay``."""
    if command == "record":
        return record(argv)
    if command == "replay":
        return replay(argv)
    raise CliError(f"unknown command {command!r}")
