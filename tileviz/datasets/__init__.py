"""tileviz-dataset/1 (``docs/dataset-format.md``): the format (:mod:`~tileviz.datasets.format`),
the reader (:mod:`~tileviz.datasets.reader`), the writer (:mod:`~tileviz.datasets.writer`), the
image files (:mod:`~tileviz.datasets.images`), a real camera's model and rectification
(:mod:`~tileviz.datasets.camera_model`, :mod:`~tileviz.datasets.calibrate`), and conversions from
ROS bags (:mod:`~tileviz.datasets.bag_import`) and to MCAP (:mod:`~tileviz.datasets.mcap_export`).
"""

from tileviz.datasets.format import (
    FAULTS_FILE,
    FORMAT,
    FRAME_COLUMNS,
    MAX_MAGNITUDE,
    REQUIRED_COLUMNS,
    DatasetError,
    DatasetMeta,
    read_meta,
    replay_config,
)
from tileviz.datasets.reader import DatasetSource
from tileviz.datasets.writer import DatasetWriter, dataset_mb

__all__ = [
    "FAULTS_FILE", "FORMAT", "FRAME_COLUMNS", "MAX_MAGNITUDE", "REQUIRED_COLUMNS", "DatasetError",
    "DatasetMeta", "DatasetSource", "DatasetWriter", "dataset_mb", "read_meta", "replay_config",
]
