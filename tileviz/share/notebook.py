"""A run in a notebook: ``tileviz.show(DATASET)`` displays the page that ``export-html`` writes
inline (viser's ``show()``: an iframe in Jupyter, a browser tab from a script), and
``tileviz.replay(DATASET)`` returns the per-frame records as a table.

Both replay the dataset as ``python -m tileviz replay`` does (:func:`tileviz.share.run.load_run`):
the same boxes as ``replay --out`` for the same frames. Frame ranges are half-open frame indices.
"""

from __future__ import annotations

import math
import os
from typing import Any

from tileviz.config import Extractor, Mode
from tileviz.pipeline.outputs import REPLAY_COLUMNS

__all__ = ["RECORD_COLUMNS", "records", "replay", "show"]

RECORD_COLUMNS = (*REPLAY_COLUMNS, "truth_x", "truth_y", "truth_theta", "inside", "view",
                  "extractor")
"""The columns of :func:`replay`: those of the replay CSV (docs/dataset-format.md, "Replay
output": index, t s, status, the updated set's hull x, y m and theta rad bounds, box count), the
true pose (m, m, rad; NaN when unknown), ``inside`` (the truth inside the set: True, False or
None when unknown or ``lost``), ``view`` (the frame had an observation) and the extractor that
made it."""


def records(run: Any) -> list[dict[str, Any]]:
    """One dict of :data:`RECORD_COLUMNS` per kept record of ``run`` (a
    :class:`tileviz.share.run.Run`)."""
    out = []
    for r in run.records:
        hull = r.updated.hull()
        bounds = hull.as_tuple() if hull is not None else (math.nan,) * 6
        t = r.truth
        out.append(dict(zip(RECORD_COLUMNS, (
            r.index, r.t, r.status, *bounds, len(r.updated),
            t.x if t is not None else math.nan, t.y if t is not None else math.nan,
            t.theta if t is not None else math.nan,
            r.truth_inside() if r.status != "lost" else None,
            r.vision.observation is not None, r.vision.extractor), strict=True)))
    return out


def replay(dataset: str | os.PathLike[str], *, start: int | None = None,
           end: int | None = None, mode: Mode | None = None,
           extractor: Extractor | None = None, jobs: int | None = None) -> Any:
    """The records of frames [start, end) of ``dataset`` replayed (module docstring): a pandas
    DataFrame of :data:`RECORD_COLUMNS` when pandas is installed, else a list of dicts.
    ``mode``, ``extractor``, ``jobs``: as ``python -m tileviz replay``'s. ValueError in one
    line for a folder that is not a dataset, an empty one or a range outside the run."""
    from tileviz.share.run import load_run

    rows = records(load_run(dataset, start=start, end=end, mode=mode, extractor=extractor,
                            jobs=jobs, names=("start", "end")))
    try:
        import pandas as pd
    except ImportError:
        return rows
    return pd.DataFrame(rows, columns=list(RECORD_COLUMNS))


def show(dataset: str | os.PathLike[str], *, start: int | None = None, end: int | None = None,
         every: int = 1, image_px: int = 200, stage: str | None = "lines",
         mode: Mode | None = None, extractor: Extractor | None = None,
         height: int = 600) -> None:
    """Display the run's page (:func:`tileviz.share.page.build_page`; options as
    ``export-html``'s) inline in Jupyter, ``height`` pixels high (from a script: in a browser
    tab, from a temporary file)."""
    from tileviz.share.page import PageOptions, build_page, page_views
    from tileviz.share.run import load_run

    opts = PageOptions(every=every, image_px=image_px, stage=stage)
    run = load_run(dataset, start=start, end=end, mode=mode, extractor=extractor,
                   names=("start", "end"), views=page_views(opts))
    build_page(run, opts).show(height=height)
