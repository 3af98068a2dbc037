"""``python -m tileviz serve`` / ``python serve.py``: the demo server's command line.

Options (report table 6.1 and the server's own): ``--host`` (default 127.0.0.1: only this machine),
``--port`` (8080; the next free one if taken), ``--preset``, ``--interactive`` (start paused: one
frame per Step), ``--intervals/--no-intervals`` (draw the boxes), ``--display/--no-display``
(stream the stage images), ``--ppm``, ``--tile-size``, ``--output-file NAME`` (CSV of the six
equivalence residuals per frame, written under ``--out-dir``), ``--seed``, ``--history``,
``--push-rate``, ``--image-rate``, ``--speed``, ``--max-speed``, ``--lens`` (a real camera in the
simulator), ``--mcl``/``--particles`` (the Monte Carlo Localization baseline beside the boxes),
``--mode``, ``--extractor``, ``--fault-model``, ``--relocalize-region``, ``--frames N`` (run N
frames, print a summary, exit), ``--dataset DIR``: replay a recorded tileviz-dataset/1 folder
instead of simulating (its meta.json sets the floor and the camera; the boxes are those ``python -m
tileviz replay`` writes), ``--ros``: follow a ROS 1 run live (:mod:`tileviz.ros.viewer`; ROS
arguments ``name:=value`` after it are its node's remappings and private parameters, as for
``python -m tileviz ros``) and ``--foxglove [PORT]``: serve the run live to Foxglove as well.
:func:`main` builds the :class:`tileviz.app.server.App` and runs it until Ctrl-C (or ``--frames``).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from tileviz import cliutil
from tileviz.app import commands as C
from tileviz.app.guard import is_loopback
from tileviz.app.server import DEFAULT_PORT, App
from tileviz.app.session import Session, SessionOptions
from tileviz.cliutil import (
    FIRST_RUN_NOTICE,
    CliError,
    Parser,
    float_in,
    int_in,
    nonneg_int,
    notice_if_slow,
    positive_float,
    positive_int,
    run_cli,
)
from tileviz.config import (
    EXTRACTORS,
    MODES,
    PPM_RANGE,
    PRESETS,
    SEED_RANGE,
    TILE_SIZE_RANGE,
    Config,
    preset,
)
from tileviz.ros.foxglove_live import DEFAULT_PORT as FOXGLOVE_PORT
from tileviz.sim.lens import LENSES
from tileviz.summary import counted

__all__ = ["main", "options_from_args", "parser", "serve_config"]


def parser() -> Parser:
    p = Parser(prog="tileviz serve", description="The live demo: simulation (or a recorded "
               "dataset, --dataset), vision and the interval localizer in the browser (viser).")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=_port, default=None, help=f"port (default {DEFAULT_PORT}, or "
                   "the next free one, said on start; a port given here must be free)")
    p.add_argument("--preset", choices=PRESETS, default=None,
                   help="simulator preset (default: default)")
    p.add_argument("--dataset", metavar="DIR", help="replay this tileviz-dataset/1 folder "
                   "instead of simulating (its meta.json sets the floor and the camera)")
    p.add_argument("--ros", action="store_true",
                   help="follow a ROS 1 run live instead of simulating: the localizer node's "
                   "topics and parameters (name:=value arguments; docs/ros.md), the floor and "
                   "camera from the simulator's /tileviz_sim/meta by default")
    p.add_argument("--foxglove", nargs="?", const=FOXGLOVE_PORT, default=None,
                   type=_port_of("--foxglove"), metavar="PORT",
                   help=f"also serve the run live to Foxglove on 127.0.0.1:PORT (default "
                   f"{FOXGLOVE_PORT}; the topics of replay --mcap)")
    p.add_argument("--lens", choices=LENSES, default=None,
                   help="the simulated camera is a real one (webcam: tilted, a distorting "
                   "lens); its raw and rectified images are shown as stages (a dataset with a "
                   "camera_model shows them too)")
    p.add_argument("--mode", choices=MODES, default=None,
                   help="localizer mode (default autonomous)")
    p.add_argument("--extractor", choices=EXTRACTORS, default=None,
                   help=f"{cliutil.EXTRACTOR_HELP} (default: the preset's or the dataset's)")
    p.add_argument("--interactive", action="store_true",
                   help="start paused; each Step advances one frame")
    p.add_argument("--start-frame", type=nonneg_int("--start-frame"), default=0, metavar="K",
                   help="show frame K first (the frames before it are computed without stage "
                   "images); with --dataset and --interactive: debug a recorded run from K")
    p.add_argument("--frames", type=positive_int("--frames"), default=None, metavar="N",
                   help="run N frames (the page is served meanwhile), print a one-line summary "
                   "and exit (0, or 1 if a frame failed): a smoke test without a browser")
    p.add_argument("--intervals", action=argparse.BooleanOptionalAction, default=True,
                   help="draw the interval boxes (default on)")
    p.add_argument("--display", action=argparse.BooleanOptionalAction, default=True,
                   help="stream the pipeline stage images (default on)")
    cliutil.add_fault_options(p)
    p.add_argument("--ppm", type=float_in("--ppm", *PPM_RANGE, lo_open=False),
                   help="pixels per metre")
    p.add_argument("--tile-size", type=float_in("--tile-size", *TILE_SIZE_RANGE, lo_open=False),
                   help="L, metres")
    cliutil.add_floor_options(p)
    p.add_argument("--output-file", help="CSV of the six equivalence residuals per frame "
                   "(written under --out-dir, name sanitized)")
    p.add_argument("--out-dir", default="runs", help="the only folder the server writes to "
                   "(recordings, CSV); default ./runs")
    p.add_argument("--seed", type=int_in("--seed", *SEED_RANGE), default=None,
                   help="seed of the run's noise")
    p.add_argument("--history", type=positive_int("--history"), default=2000,
                   help="frames kept for stepping back (>= 2, default 2000)")
    p.add_argument("--push-rate", type=_in_range("--push-rate", 1.0, 60.0), default=20.0,
                   help="scene updates sent per second at most (default 20: one per simulated "
                   "frame at real time)")
    p.add_argument("--image-rate", type=_in_range("--image-rate", 1.0, 60.0), default=5.0,
                   help="camera and stage image updates per second at most while playing "
                   "(default 5; a paused or stepped frame always shows its images)")
    p.add_argument("--speed", type=_in_range("--speed", 0.01, C.MAX_SPEED_FACTOR), default=1.0,
                   help="playback speed, x real time (default 1)")
    p.add_argument("--max-speed", action="store_true", help="run as fast as possible")
    p.add_argument("--mcl", action="store_true",
                   help="also run the Monte Carlo Localization baseline, calibrated to the "
                        "views' measured errors (orange particles)")
    p.add_argument("--particles", type=_int_range("--particles", 10, 100_000), default=1000,
                   help="MCL's largest particle count (it keeps 500 to this many; default 1000)")
    return p


def _port_of(name: str) -> Any:
    """argparse type: a port number in [0, 65535] for option ``name``."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}"
                                             ) from None
        if not 0 <= v <= 65535:
            raise argparse.ArgumentTypeError(f"{name} must be in [0, 65535], got {text!r}")
        return v

    return parse


_port = _port_of("--port")


def _ranged(name: str, lo: float, hi: float, check: Any) -> Any:
    """argparse type: ``check(text)`` (a number parser naming ``name``) within [lo, hi]."""

    def parse(text: str) -> Any:
        v = check(text)
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{name} must be in [{lo:g}, {hi:g}], got {text!r}")
        return v

    return parse


def _in_range(name: str, lo: float, hi: float) -> Any:
    return _ranged(name, lo, hi, positive_float(name))


def _int_range(name: str, lo: int, hi: int) -> Any:
    return _ranged(name, lo, hi, positive_int(name))


def check_ros_options(args: argparse.Namespace) -> None:
    """CliError naming the options ``--ros`` cannot be used with (the run's meta sets the
    floor and the camera; one run at a time)."""
    if args.dataset is not None:
        raise CliError("--ros cannot be used with --dataset (one run at a time)")
    clash = [name for name, v in (("--preset", args.preset), ("--tile-size", args.tile_size),
                                  ("--ppm", args.ppm), ("--lens", args.lens)) if v is not None]
    if clash:
        raise CliError(f"{', '.join(clash)} cannot be used with --ros (the ROS run's meta sets "
                       "the floor and the camera)")


def serve_config(args: argparse.Namespace, feed: Any = None) -> Config:
    """``serve``'s configuration: :func:`tileviz.cliutil.config_from_args` (the preset with the
    command line's floor, camera, seed, mode and extractor; the seed leaves the floor's
    appearance alone); with ``--dataset``, the configuration ``python -m tileviz replay`` uses
    for that dataset (its meta and the mode and extractor), the seed (of the MCL baseline) from
    the command line; with ``--ros``, the configuration of the ROS run ``feed`` follows (its
    meta, as ``python -m tileviz ros`` builds it) with the mode and extractor. A bad dataset
    folder or meta.json raises DatasetError (a ValueError) naming the file."""
    if args.ros:
        check_ros_options(args)
        if feed is None:
            raise CliError("--ros: no ROS run to follow")
        cfg = replace(feed.combiner.cfg, localizer=replace(
            feed.combiner.cfg.localizer, **({} if args.mode is None else {"mode": args.mode})))
        if args.extractor is not None:
            cfg = replace(cfg, vision=replace(cfg.vision, extractor=args.extractor))
        return _with_fault_model(_with_seed(cfg, args.seed), args.fault_model)
    if args.dataset is not None:
        from tileviz.app.sources import replay_config
        from tileviz.datasets import DatasetSource

        clash = [name for name, v in (("--preset", args.preset), ("--tile-size", args.tile_size),
                                      ("--ppm", args.ppm), ("--lens", args.lens),
                                      ("--floor-kind", args.floor_kind),
                                      ("--lattice-tolerance", args.lattice_tolerance))
                 if v is not None]
        if clash:
            raise CliError(f"{', '.join(clash)} cannot be used with --dataset (the dataset's "
                           "meta.json sets the floor and the camera)")
        meta = DatasetSource(args.dataset).meta  # checks meta.json and the frames.csv header
        cfg = replay_config(meta, mode=args.mode, extractor=args.extractor,
                            where=str(Path(args.dataset) / "meta.json"))
        return _with_fault_model(_with_seed(cfg, args.seed), args.fault_model)
    _with_seed(preset("default"), args.seed)  # the seed's range, named
    # the run's seed leaves the floor's appearance as the preset has it
    cfg = cliutil.config_from_args(args, floor_seed=False)
    return _with_fault_model(cfg, args.fault_model)


def _with_fault_model(cfg: Config, model: tuple[float, float] | None) -> Config:
    """``cfg`` with the localizer's fault model (m/s, rad/s) when one was given."""
    if model is None:
        return cfg
    return replace(cfg, localizer=replace(cfg.localizer, fault_speed=model[0],
                                          fault_yaw_rate=model[1]))


def _with_seed(cfg: Config, seed: int | None) -> Config:
    if seed is None:
        return cfg
    if not 0 <= seed < 2**32:
        raise ValueError(f"--seed must be in [0, 2^32), got {seed}")
    return replace(cfg, sim=replace(cfg.sim, seed=seed))


def options_from_args(args: argparse.Namespace, feed: Any = None) -> SessionOptions:
    """How the session starts, from the command line (``feed``: the ROS run of ``--ros``)."""
    return SessionOptions(history=args.history, display=args.display, intervals=args.intervals,
                          interactive=args.interactive and args.frames is None,
                          out_dir=Path(args.out_dir),
                          output_file=args.output_file, speed=args.speed,
                          max_speed=args.max_speed, mcl=args.mcl, mcl_particles=args.particles,
                          start_frame=args.start_frame, lens=args.lens,
                          relocalize_region=args.relocalize_region,
                          dataset=Path(args.dataset) if args.dataset is not None else None,
                          ros=feed, foxglove=args.foxglove)


def _summary(s: Session, wanted: int, frames: int, seconds: float) -> int:
    """Print the one-line summary of a ``--frames`` run; its exit status: 1 when a frame failed or
    the dataset stopped at a bad row, else 0."""
    parts = [f"{frames} frames in {seconds:.1f} s ({frames / max(seconds, 1e-9):.1f} frames/s)",
             *s.tally.parts()]
    failed = s.errors > 0 or (s.ended is not None and any(
        n.level == "error" and n.text.startswith(s.ended) for n in s.notes))
    if frames < wanted and s.ended is not None:
        parts.append(f"stopped early: {s.ended}")
    if s.errors:
        parts.append(f"{counted(s.errors, 'frame')} failed")
    print("tileviz serve: " + "; ".join(parts), flush=True)
    return 1 if failed else 0


def _force_exit() -> None:
    """Leave the process when a clean stop hangs (the session's files are closed first)."""
    print("tileviz serve: stopped (the web server did not shut down within 20 s)", flush=True)
    os._exit(0)


def main(command: str = "serve", argv: list[str] | None = None) -> int:
    """Entry for ``python -m tileviz serve`` and ``serve.py``: runs until Ctrl-C."""
    argv = sys.argv[1:] if argv is None else argv
    remaps = [a for a in argv if ":=" in a] if "--ros" in argv else []
    args = parser().parse_args([a for a in argv if a not in remaps])
    if args.history < 2:
        sys.stderr.write("tileviz serve: error: --history must be >= 2\n")
        return 2

    def body() -> int:
        port = DEFAULT_PORT if args.port is None else args.port
        feed = None
        if args.ros:
            check_ros_options(args)  # before connecting
            from tileviz.ros.viewer import RosFeed

            with notice_if_slow(f"tileviz serve: {FIRST_RUN_NOTICE}"):
                feed = RosFeed(remaps)
            print(f"tileviz serve: following the {feed.describe()}", flush=True)
        try:
            return _serve(args, port, feed)
        finally:
            if feed is not None:
                feed.close()

    return run_cli("tileviz serve", body)


def _serve(args: argparse.Namespace, port: int, feed: Any) -> int:
    """Run the server until Ctrl-C (or ``--frames``); the exit status."""
    app = App(serve_config(args, feed), options_from_args(args, feed), host=args.host,
              port=port, strict_port=args.port is not None, push_rate=args.push_rate,
              image_rate=args.image_rate, frames=args.frames)
    stopping = threading.Event()

    def on_term(signum: int, frame: object) -> None:
        stopping.set()

    previous = signal.signal(signal.SIGTERM, on_term)
    # Ctrl-C by the same path: a process started with SIGINT ignored (a background job)
    # would otherwise never see KeyboardInterrupt
    previous_int = signal.signal(signal.SIGINT, on_term)
    status = 0
    started_up = False
    try:
        with notice_if_slow(f"tileviz serve: {FIRST_RUN_NOTICE}"):
            started_up = app.start(cancel=stopping)
        if not started_up:  # Ctrl-C or SIGTERM before the first frame
            print("tileviz serve: stopped", flush=True)
            return 0
        if port != 0 and app.port != port:
            print(f"tileviz serve: port {port} is busy; serving on port {app.port} instead",
                  flush=True)
        print(f"tileviz serve: open {app.url}  (Ctrl-C stops)", flush=True)
        if not is_loopback(args.host):
            print(f"tileviz serve: listening on {args.host} port {app.port}, beyond this "
                  "machine: anyone who can reach it can drive the run and record into "
                  f"{args.out_dir} (there is no password; SECURITY.md)", flush=True)
        started = time.perf_counter()
        done = 0  # frames of the run, frame 0 (made on start) included
        while app.running and not stopping.is_set():
            if args.frames is not None and app.session is not None and (
                    app.session.frames_computed - done >= args.frames
                    or app.session.ended is not None):
                status = _summary(app.session, args.frames,
                                  app.session.frames_computed - done,
                                  time.perf_counter() - started)
                break
            time.sleep(0.05 if args.frames is not None else 0.2)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
        signal.signal(signal.SIGINT, previous_int)
        # a watchdog: once the files are closed, a server that does not shut down in time
        # must not keep the terminal
        watchdog = threading.Timer(20.0, _force_exit)
        watchdog.daemon = True
        watchdog.start()
        # before the first frame, the loop is not waited for (it may be compiling for minutes)
        app.stop(wait=10.0 if started_up else 0.0)
        watchdog.cancel()
    print("tileviz serve: stopped", flush=True)
    return status

