"""``python -m tileviz export-html`` and ``python -m tileviz figure``: a dataset (or a recording
of the demo) replayed as ``replay`` does, then shared as a web page, a figure or a movie."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING

from tileviz.cli import _progress
from tileviz.cliutil import EXTRACTOR_HELP, CliError, Parser, int_in, positive_int, run_cli
from tileviz.config import EXTRACTORS, MODES

if TYPE_CHECKING:
    from tileviz.pipeline import FrameRecord
    from tileviz.share.run import Run, Views

__all__ = ["export_html_parser", "figure_parser", "main"]


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mode", choices=MODES, default="autonomous", help="as replay's")
    p.add_argument("--extractor", choices=EXTRACTORS, default=None,
                   help=f"{EXTRACTOR_HELP} (default: the dataset's, else robust)")
    p.add_argument("--jobs", type=positive_int("--jobs"), default=None,
                   help="vision processes, as replay's (a page's stage images need one: its "
                   "vision then runs in this process)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def export_html_parser() -> Parser:
    p = Parser(prog="tileviz export-html", description="Replay a dataset (or a recording of "
               "the demo) and write one self-contained HTML page that plays the run back in "
               "any browser, offline: the floor, the robot, the truth, the predicted and "
               "contracted boxes, the heading wedge and trails, the camera view, a pipeline "
               "stage and the magnified set, with viser's player (play, pause, scrub, speed).")
    p.add_argument("dataset", help="dataset folder")
    p.add_argument("out", nargs="?", default=None, help="the page, OUT.html")
    p.add_argument("--site", default=None, metavar="DIR",
                   help="instead of OUT: a folder for static hosting (index.html, viser's "
                   "client, and run.viser, the recording); serve it over HTTP, e.g. a code "
                   "host's pages (docs/share.md)")
    p.add_argument("--start", type=int_in("--start", 0, 10**9), default=None,
                   help="first frame shown (index; default 0); the localizer still runs from "
                   "frame 0")
    p.add_argument("--end", type=int_in("--end", 1, 10**9), default=None,
                   help="the frame after the last shown (default: the run's end)")
    p.add_argument("--every", type=positive_int("--every"), default=1,
                   help="show every Nth frame (the player still plays in real time)")
    p.add_argument("--image-size", type=int_in("--image-size", 32, 2048), default=200,
                   help="width of the camera and stage images, pixels")
    p.add_argument("--jpeg-quality", type=int_in("--jpeg-quality", 1, 100), default=60)
    p.add_argument("--stage", default="lines",
                   help="the pipeline stage drawn beside the camera view (none: no stage)")
    _common(p)
    return p


def figure_parser() -> Parser:
    p = Parser(prog="tileviz figure", description="Replay a dataset (or a recording of the "
               "demo) and draw its top-down figure: the tiles, the true path, the predicted "
               "(green) and contracted (blue) boxes of every Nth frame and the final set "
               "(OUT.png, .pdf, .svg); or, for OUT.mp4 or .gif, a movie of that view over "
               "time beside the camera view (needs the share extra).")
    p.add_argument("dataset", help="dataset folder")
    p.add_argument("out", help="OUT.png, OUT.pdf, OUT.svg, OUT.mp4 or OUT.gif")
    p.add_argument("--frames", default=None, metavar="A:B",
                   help="frames A to B-1 (indices; A or B may be left out; default: all)")
    p.add_argument("--every", type=positive_int("--every"), default=None,
                   help="the sets of every Nth frame (default 20 for a figure; a movie: one "
                   "movie frame every N run frames, default 2)")
    p.add_argument("--width", type=int_in("--width", 320, 3840), default=960,
                   help="movie width, pixels")
    p.add_argument("--boxes", default=None, metavar="CSV",
                   help="a figure from the CSV replay --out wrote for DATASET instead of "
                   "replaying (much faster): its contracted sets (bounding boxes) and "
                   "statuses, no predicted sets")
    _common(p)
    return p


def _load(args: argparse.Namespace, start: int | None, end: int | None,
          names: tuple[str, str], views: Views | None) -> Run:
    """The run of ``args.dataset`` (frames [start, end), as :func:`load_run`) with a progress
    bar."""
    from tileviz.share.run import load_run

    bar = None

    def on_total(total: int) -> None:
        nonlocal bar
        bar = _progress(total, "replay", not args.quiet)

    def on_frame(rec: FrameRecord) -> None:
        bar.update(1)  # type: ignore[attr-defined]

    try:
        return load_run(args.dataset, start=start, end=end, mode=args.mode,
                        extractor=args.extractor, jobs=args.jobs, names=names, views=views,
                        on_total=on_total, on_frame=on_frame)
    finally:
        if bar is not None:
            bar.close()  # type: ignore[attr-defined]


def _drawing(total: int, desc: str, quiet: bool) -> tuple[object, Callable[..., None]]:
    bar = _progress(total, desc, not quiet)
    return bar, lambda _rec: bar.update(1)  # type: ignore[attr-defined]


def export_html(argv: list[str]) -> int:
    args = export_html_parser().parse_args(argv)

    def body() -> int:
        from tileviz.share.files import check_folder, check_output
        from tileviz.share.page import PageOptions, export_site, page_views
        from tileviz.share.page import export_html as write_html
        from tileviz.share.run import check_dataset

        if (args.out is None) == (args.site is None):
            raise CliError("give OUT.html or --site DIR (one of the two)")
        if args.out is not None:
            check_output(args.out, "OUT", (".html", ".htm"))
        else:
            check_folder(args.site, "--site")
        check_dataset(args.dataset)
        stage = None if args.stage.lower() == "none" else args.stage
        opts = PageOptions(every=args.every, image_px=args.image_size, stage=stage,
                           jpeg_quality=args.jpeg_quality)
        run = _load(args, args.start, args.end, ("--start", "--end"), page_views(opts))
        bar, tick = _drawing(len(run.picks(opts.every)), "page", args.quiet)
        try:
            if args.out is not None:
                path = write_html(run, args.out, opts, on_frame=tick)
                size = path.stat().st_size
            else:
                path = export_site(run, args.site, opts, on_frame=tick)
                size = sum(f.stat().st_size for f in path.iterdir())
        finally:
            bar.close()  # type: ignore[attr-defined]
        print(f"wrote frames {run.start} to {run.end - 1} ({len(run.picks(opts.every))} shown,"
              f" {size / 1e6:.1f} MB) to {path}; {run.summary()}")
        return 0

    return run_cli("tileviz export-html", body)


def figure(argv: list[str]) -> int:
    args = figure_parser().parse_args(argv)

    def body() -> int:
        from tileviz.share.figure import (
            FIGURE_SUFFIXES,
            MOVIE_SUFFIXES,
            movie,
            save_figure,
            share_missing,
        )
        from tileviz.share.files import check_output
        from tileviz.share.run import Views, check_dataset, load_boxes, parse_frames

        path = check_output(args.out, "OUT", FIGURE_SUFFIXES + MOVIE_SUFFIXES)
        is_movie = path.suffix.lower() in MOVIE_SUFFIXES
        if is_movie and args.boxes is not None:
            raise CliError(f"--boxes makes a figure ({', '.join(FIGURE_SUFFIXES)}), not a movie")
        if is_movie and (missing := share_missing()) is not None:
            raise CliError(missing)
        start, end = parse_frames(args.frames) if args.frames is not None else (None, None)
        check_dataset(args.dataset)
        every = args.every or (2 if is_movie else 20)
        views = Views(every=every, width=args.width // 2) if is_movie else None
        names = ("--frames A:B: A", "--frames A:B: B")
        if args.boxes is not None:
            if args.mode != "autonomous" or args.extractor is not None or args.jobs:
                raise CliError("--boxes draws the CSV's sets: --mode, --extractor and --jobs "
                               "do not apply (they were the replay's)")
            run = load_boxes(args.dataset, args.boxes, start=start, end=end, names=names)
        else:
            run = _load(args, start, end, names, views)
        if is_movie:
            bar, tick = _drawing(len(run.picks(every)), "movie", args.quiet)
            try:
                movie(run, path, every=every, width_px=args.width, on_frame=tick)
            finally:
                bar.close()  # type: ignore[attr-defined]
        else:
            save_figure(run, path, every=every)
        print(f"wrote frames {run.start} to {run.end - 1} to {path}; {run.summary()}")
        return 0

    return run_cli("tileviz figure", body)


def main(command: str, argv: list[str]) -> int:
    """Entry for ``python -m tileviz export-html|figure``."""
    if command == "export-html":
        return export_html(argv)
    if command == "figure":
        return figure(argv)
    raise CliError(f"unknown command {command!r}")
