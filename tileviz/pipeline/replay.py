"""Replay a recorded dataset through the frame loop and write its output files
(``python -m tileviz replay``; the CLI in :mod:`tileviz.cli` only parses the options).

Vision runs in ``jobs`` worker processes (:func:`tileviz.pipeline.workers.vision_ahead`) or, with
one job, in this process with the images decoded ahead on a thread; the localizer steps the frames
in order in this process. The output is the same whatever ``jobs``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import replace

from tileviz.config import Extractor, Mode
from tileviz.datasets import DatasetSource, replay_config
from tileviz.pipeline.frame_loop import FrameLoop, FrameRecord
from tileviz.pipeline.outputs import (
    REPLAY_COLUMNS,
    RESIDUAL_COLUMNS,
    CsvOut,
    replay_row,
    residual_row,
)
from tileviz.pipeline.worker_server import default_jobs, start_worker_server

__all__ = ["default_jobs", "replay"]


def replay(
    dataset: str | os.PathLike[str],
    *,
    out: str | os.PathLike[str] | None = None,
    output_file: str | os.PathLike[str] | None = None,
    mode: Mode | None = None,
    extractor: Extractor | None = None,
    max_boxes: int | None = None,
    jobs: int | None = None,
    mcap: str | os.PathLike[str] | None = None,
    fault_model: tuple[float, float] | None = None,
    relocalize_region: tuple[float, float, float, float] | None = None,
    on_total: Callable[[int | None], None] | None = None,
    on_frame: Callable[[FrameRecord], None] | None = None,
    on_notice: Callable[[str], None] | None = None,
    until: int | None = None,
    keep_stages: bool = False,
) -> int:
    """Replay ``dataset`` and write the replay CSV ``out`` (one row per frame; None: no CSV)
    and, when given, the equivalence-residual CSV ``output_file``; returns the number of frames
    replayed. ``mode``,
    ``extractor``, ``max_boxes`` override the dataset's configuration
    (:func:`tileviz.datasets.replay_config`); ``jobs``: vision processes (default
    :func:`default_jobs`). ``mcap``: also write the run for Foxglove to this MCAP file
    (:mod:`tileviz.datasets.mcap_export`; finished even when a bad row stops the replay).
    ``fault_model``: the localizer's fault model (m/s, rad/s; ``LocalizerConfig.fault_speed``,
    ``fault_yaw_rate``). ``relocalize_region``: (x0, y0, x1, y1), metres: whenever the localizer
    is ``lost`` it restarts from "somewhere in this region" at the next frame
    (``Localizer.relocalize``: candidate boxes, heading from the compass).
    ``on_total`` gets the frame count when known (None otherwise) before
    the first frame, ``on_frame`` every record (its ``residuals`` computed only with
    ``output_file``). ``until``: stop after the frame with that index (None: at the dataset's
    end). ``keep_stages``: the records handed to ``on_frame`` carry every vision stage image
    (vision then runs in this process: ``jobs`` is 1). ``on_notice`` gets, before the first
    frame, the one line saying that the dataset ended early
    (:attr:`tileviz.datasets.DatasetSource.ended_early`), if it did. A bad row or image raises
    DatasetError (a ValueError) after every frame before it was written. Every output row is
    written whole as its frame ends, so a replay that is stopped (killed) leaves files readable
    up to their last row (the MCAP file then has no summary: a streaming reader reads it)."""
    jobs = 1 if keep_stages else jobs if jobs is not None else default_jobs()
    if jobs > 1:  # the workers' server loads the vision code while this process reads the rows
        start_worker_server()
    # images decode on a background thread while the previous frame's vision runs
    source = DatasetSource(dataset, prefetch=8)
    cfg = replay_config(source.meta, mode=mode, extractor=extractor,
                        where=str(source.folder / "meta.json"))
    if max_boxes:
        cfg = replace(cfg, localizer=replace(cfg.localizer, max_boxes=max_boxes))
    if fault_model is not None:
        cfg = replace(cfg, localizer=replace(cfg.localizer, fault_speed=fault_model[0],
                                             fault_yaw_rate=fault_model[1]))
    # residuals: for output_file only
    loop = FrameLoop(cfg, residuals=bool(output_file), keep_stages=keep_stages)
    if relocalize_region is not None and loop.primary is not None:
        # too large even with a compass reading to cut the heading: refused now (a lost frame
        # without a compass reading whose region needs one stays lost until a reading comes)
        loop.primary.localizer.candidates(relocalize_region, compass=0.0)
    csv_out = CsvOut(out, REPLAY_COLUMNS) if out is not None else None
    eq = CsvOut(output_file, RESIDUAL_COLUMNS) if output_file else None
    if on_notice is not None and source.ended_early is not None:
        on_notice(source.ended_early)
    if on_total is not None:
        on_total(source.row_count() or None)
    n = 0
    records: Iterator[FrameRecord]
    if jobs > 1:
        from tileviz.pipeline.workers import vision_ahead

        records = (loop.process(frame, vision)
                   for frame, vision in vision_ahead(source, cfg, jobs))
    else:
        records = loop.run(source)
    mcap_out = None
    if mcap is not None:
        from tileviz.datasets.mcap_export import McapExport

        mcap_out = McapExport(mcap, source.folder)
    try:
        for rec in records:
            if csv_out is not None:
                csv_out.row(replay_row(rec))
            if mcap_out is not None:
                mcap_out.write(rec, rec.image_name)
            if eq is not None:
                eq.row(residual_row(rec))
            n += 1
            if relocalize_region is not None and rec.status == "lost":
                relocalize_after(loop, relocalize_region, rec)
            if on_frame is not None:
                on_frame(rec)
            if until is not None and rec.index >= until:
                break
    finally:
        if csv_out is not None:
            csv_out.close()
        if eq is not None:
            eq.close()
        if mcap_out is not None:
            mcap_out.close()
    return n


def relocalize_after(loop: FrameLoop, region: tuple[float, float, float, float],
                     rec: FrameRecord) -> bool:
    """Restart ``loop``'s interval localizer from "somewhere in ``region``" after the frame
    ``rec`` (the pose of that frame; heading from its compass reading when it has one,
    ``Localizer.relocalize``). False (nothing changed) when there is no interval localizer or
    the region needs more candidates than re-localization can follow with that heading."""
    primary = loop.primary
    if primary is None:
        return False
    try:
        primary.localizer.relocalize(region, compass=rec.compass)
    except ValueError:
        return False
    return True
