"""Sharing a run: a replayed dataset as a self-contained web page, a figure, a movie, a table.

- :mod:`~tileviz.share.run`: a dataset replayed once through the replay's frame loop
  (:func:`tileviz.pipeline.replay.replay`), the frames of a range kept for drawing;
- :mod:`~tileviz.share.page`: the run as one HTML file that viser's player plays offline
  (``python -m tileviz export-html``), or a folder for static hosting;
- :mod:`~tileviz.share.figure`: the top-down figure of the run and its movie
  (``python -m tileviz figure``);
- :mod:`~tileviz.share.notebook`: ``tileviz.show`` and ``tileviz.replay`` for Jupyter;
- :mod:`~tileviz.share.files`: outputs written to a temporary file and renamed, so a failed
  export leaves nothing half-written;
- :mod:`~tileviz.share.cli`: the two commands.

Nothing here imports viser until a page is made, nor matplotlib until a figure is.
"""
