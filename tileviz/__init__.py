"""tileviz: guaranteed robot localization on tiled floors with interval analysis."""

import os as _os

__version__ = "0.1.0"

# OpenCV reads this once, when it loads: its decoders then refuse an image file whose header
# declares more pixels than tileviz reads (tileviz.datasets.images.MAX_IMAGE_PIXELS; for PNG and
# JPEG tileviz reads the header itself first)
_os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(1 << 26))
