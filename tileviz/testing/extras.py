"""Running tileviz's command line as if an optional extra were not installed."""

from __future__ import annotations

__all__ = ["ROS_MODULES", "SHARE_MODULES", "WITHOUT_ROS", "without"]

ROS_MODULES = ("rosbags", "mcap", "mcap_protobuf", "foxglove_schemas_protobuf")
"""The modules of the ``ros`` extra."""

SHARE_MODULES = ("imageio", "imageio_ffmpeg")
"""The modules of the ``share`` extra."""


def without(modules: tuple[str, ...]) -> str:
    """A ``python -c`` program: ``python -m tileviz ARGS...`` as if ``modules`` were not
    installed."""
    return ("import sys\n"
            f"for m in {modules!r}:\n"
            "    sys.modules[m] = None  # as if not installed\n"
            "from tileviz.__main__ import main\n"
            "raise SystemExit(main(sys.argv[1:]))\n")


WITHOUT_ROS = without(ROS_MODULES)
"""A ``python -c`` program: ``python -m tileviz ARGS...`` without the ``ros`` extra's modules."""
