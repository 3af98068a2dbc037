"""tileviz-dataset/1 (``docs/dataset-format.md``): the format (:mod:`~tileviz.datasets.format`),
the reader (:mod:`~tileviz.datasets.reader`), the writer (:mod:`~tileviz.datasets.writer`) and
the image files (:mod:`~tileviz.datasets.images`)."""

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
from tileviz.datasets.writer import DatasetWriter

__all__ = [
    "FAULTS_FILE", "FORMAT", "FRAME_COLUMNS", "MAX_MAGNITUDE", "REQUIRED_COLUMNS", "DatasetError",
    "DatasetMeta", "DatasetSource", "DatasetWriter", "read_meta", "replay_config",
]
