"""The tileviz-dataset/1 format and what reads or writes it (``docs/dataset-format.md``)."""
