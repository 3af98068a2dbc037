"""``python -m tileviz COMMAND ...``: serve, record, replay, extract, survey, evaluate,
calibrate, import-bag, export-html, figure, ros, ros-sim, ros-controller, sample-data."""

from __future__ import annotations

import importlib
import sys

COMMANDS: dict[str, tuple[str, str]] = {
    "serve": ("tileviz.app.serve_cli", "start the live demo server (viser)"),
    "record": ("tileviz.cli", "simulate a run and write a tileviz-dataset/1 folder"),
    "replay": ("tileviz.cli", "replay a dataset through vision and the localizer"),
    "extract": ("tileviz.vision.cli", "extract tile parameters from images"),
    "survey": ("tileviz.vision.survey", "measure how far a floor's lines depart from the ideal "
               "lattice (the floor block's lattice_tolerance)"),
    "evaluate": ("tileviz.evaluation.cli", "evaluate the localizer and baselines over many runs"),
    "calibrate": ("tileviz.datasets.calibrate", "calibrate a real camera from checkerboard "
                  "images (meta.json's camera_model)"),
    "import-bag": ("tileviz.datasets.bag_import", "import a ROS 1 or ROS 2 bag as a dataset"),
    "export-html": ("tileviz.share.cli", "a run as one web page that plays offline (or a folder "
                    "for static hosting)"),
    "figure": ("tileviz.share.cli", "a run's top-down figure (png, pdf, svg) or movie (mp4, "
               "gif)"),
    "ros": ("tileviz.ros.node", "the live localizer as a ROS 1 node (docs/ros.md)"),
    "ros-sim": ("tileviz.ros.sim_node", "the simulator as a ROS 1 robot (camera, odometry, IMU, "
                "/truth)"),
    "ros-controller": ("tileviz.ros.sim_node", "the demo's PD controller as a ROS 1 node"),
    "sample-data": ("tileviz.datasets.sample", "write sample checkerboard images and a small "
                    "ROS bag to try calibrate and import-bag on"),
}


def main(argv: list[str] | None = None) -> int:
    """Dispatch to a sub-command's ``main(command, argv)``."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        lines = ["usage: python -m tileviz COMMAND [options]", "", "commands:"]
        lines += [f"  {name:<12} {text}" for name, (_, text) in COMMANDS.items()]
        lines += ["", "python -m tileviz COMMAND --help shows a command's options."]
        print("\n".join(lines))
        return 0 if args else 2
    command = args[0]
    if command not in COMMANDS:
        sys.stderr.write(
            f"tileviz: error: unknown command {command!r} (choose from {', '.join(COMMANDS)})\n"
        )
        return 2
    from tileviz.cliutil import missing_dependency

    missing = missing_dependency(f"tileviz {command}")
    if missing is not None:
        sys.stderr.write(missing + "\n")
        return 2
    module = importlib.import_module(COMMANDS[command][0])
    return int(module.main(command, args[1:]))


if __name__ == "__main__":
    raise SystemExit(main())
