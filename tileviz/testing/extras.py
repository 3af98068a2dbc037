"""Running tileviz's command line as if an optional extra were not installed."""

from __future__ import annotations

__all__ = ["ROS_MODULES", "WITHOUT_ROS"]

ROS_MODULES = ("rosbags", "mcap", "mcap_protobuf", "foxglove_schemas_protobuf")
"""The modules of the ``ros`` extra."""

WITHOUT_ROS = ("import sys\n"
               f"for m in {ROS_MODULES!r}:\n"
               "    sys.modules[m] = None  # as if not installed\n"
               "from tileviz.__main__ import main\n"
               "raise SystemExit(main(sys.argv[1:]))\n")
"""A ``python -c`` program: ``python -m tileviz ARGS...`` without the ``ros`` extra's modules."""
