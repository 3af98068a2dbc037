"""Recording the live run as a dataset, and exporting the last recording to MCAP or as a web page.

:class:`Recorder` belongs to one :class:`tileviz.app.session.Session` and, like it, is only
called from the app's loop thread. A recording asked for starts at the next *new* frame (a frame
computed, not one stepped back to), so its first row and its meta's initial pose agree; every
row is written after its image is whole (``tileviz.datasets.DatasetWriter``), so a recording
stopped by an error, a full disk or a killed server keeps every frame it had. An export
(:class:`McapJob`, :class:`PageJob`) runs on its own thread and :meth:`Recorder.poll` notes its
end; one export runs at a time.
"""

from __future__ import annotations

import shutil
import threading
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from tileviz.config import Config
from tileviz.types import FrameInput

if TYPE_CHECKING:
    from tileviz.datasets import DatasetWriter
    from tileviz.vision.rectify import Rectifier

__all__ = ["ExportJob", "McapJob", "PageJob", "Recorder"]

Note = Callable[[str, str], None]
"""``note(text, level)``: a one-line message for the GUI (level ``info`` or ``error``)."""
MIN_FREE_BYTES = 1 << 30
"""A recording stops (and neither a recording nor an MCAP export starts) when the disk it
writes to has less free space than this: a page visitor recording for hours must not fill the
machine's disk."""
CHECK_EVERY = 20
"""Frames between two looks at the free space while recording."""


def free_bytes(path: Path) -> int:
    """Free bytes on the disk of ``path`` (of its nearest existing folder)."""
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free


def _gib(n: float) -> str:
    return f"{n / (1 << 30):.1f} GiB"


class Recorder:
    """The dataset being recorded (if any), the one asked for, the last finished one and the
    export in progress. ``note`` reports every change in one line."""

    def __init__(self, note: Note) -> None:
        self._note = note
        self.writer: DatasetWriter | None = None
        """The dataset being written, or None."""
        self.path: Path | None = None
        """Its folder (kept after it stops, for the last message)."""
        self.pending: Path | None = None
        """The folder of a recording asked for and not started yet (no new frame since)."""
        self.last: Path | None = None
        """The last finished recording with at least one frame (what Export MCAP and Export
        page export)."""
        self.export: ExportJob | None = None
        """The export running in the background, if any."""

    @property
    def active(self) -> bool:
        """True while recording or waiting for the next new frame to start a recording."""
        return self.writer is not None or self.pending is not None

    def ask(self, folder: Path, playing: bool) -> None:
        """Record from the next new frame to ``folder``; ValueError if already recording."""
        if self.active:
            raise ValueError("already recording; stop the current recording first")
        self.pending = folder
        when = "the next new frame" if playing else "the next new frame (press Play or Step)"
        self._note(f"will record from {when} to {folder}", "info")

    def write(self, frame: FrameInput, cfg: Config, rectifier: Rectifier | None) -> None:
        """Record one new frame (starting the recording asked for, with ``cfg``'s meta; a raw
        image of a lens camera also stores its ``camera_model``). A failed write stops the
        recording with an error note; the rows already written stay."""
        if self.pending is not None:
            self._open(frame, cfg, rectifier)
        if self.writer is None:
            return
        try:
            self.writer.write(frame)
        except (OSError, ValueError) as e:
            self.stop(f"write failed: {e}", level="error")
            return
        if self.writer.count % CHECK_EVERY == 0 and self.path is not None:
            free = free_bytes(self.path)
            if free < MIN_FREE_BYTES:
                self.stop(f"only {_gib(free)} left free on its disk, less than the "
                          f"{_gib(MIN_FREE_BYTES)} kept free", level="error")

    def _open(self, frame: FrameInput, cfg: Config, rectifier: Rectifier | None) -> None:
        from tileviz.datasets import DatasetMeta, DatasetWriter

        folder = self.pending
        assert folder is not None
        self.pending = None
        meta = DatasetMeta.from_config(cfg, name=f"tileviz live run ({folder.name})")
        if rectifier is not None:  # raw images: replay rectifies them
            meta = replace(meta, camera_model=rectifier.model)
        if frame.truth is not None:
            # the run may be under way: the dataset starts at this frame's true pose, known within
            # the configured initial error (docs/dataset-format.md: initial_pose +-
            # initial_pose_error)
            meta = replace(meta, initial_pose=frame.truth.as_tuple())
        free = free_bytes(folder)
        if free < MIN_FREE_BYTES:
            self._note(f"cannot record to {folder}: only {_gib(free)} free on its disk, less "
                       f"than the {_gib(MIN_FREE_BYTES)} kept free", "error")
            return
        try:
            self.writer = DatasetWriter(folder, meta)
        except (OSError, ValueError) as e:
            self._note(f"cannot record to {folder}: {e}", "error")
            return
        self.path = folder
        self._note(f"recording to {folder}", "info")

    def stop(self, why: str = "", level: str = "info") -> None:
        """Close the recording (if any) and say how many frames it kept and why it stopped; a
        recording asked for and not started is kept asked for (see :meth:`cancel`)."""
        w, self.writer = self.writer, None
        if w is None:
            return
        try:
            w.close()
        except OSError as e:  # the frames are there; meta.json still says it ended early
            why, level = (f"{why}; {e}" if why else str(e)), "error"
        if w.count > 0:
            self.last = self.path
        from tileviz.datasets import dataset_mb

        tail = f" ({why})" if why else ""
        self._note(f"recorded {w.count} frames ({dataset_mb(w.folder):.1f} MB) to {self.path}"
                   f"{tail}", level)

    def cancel(self, why: str) -> None:
        """The run restarted or the server stops: stop the recording and forget one asked for."""
        self.stop(why)
        self.pending = None

    def stop_asked(self) -> None:
        """The user's Stop recording: stop, or say that nothing was recorded when no new frame
        came after Start recording."""
        if self.pending is not None and self.writer is None:
            self._note(f"nothing recorded: no new frame was made after Start recording (press "
                       f"Play or Step while recording); {self.pending} was not written", "info")
        self.pending = None
        self.stop()

    def export_mcap(self) -> None:
        """Start exporting :attr:`last` to MCAP on a background thread (a long recording must
        not freeze the loop); ValueError naming why when there is nothing to export or an export
        runs."""
        self._start(McapJob)

    def export_page(self) -> None:
        """Start exporting :attr:`last` as a web page (:class:`PageJob`), as
        :meth:`export_mcap` does."""
        self._start(PageJob)

    def _start(self, kind: Callable[[Path], ExportJob]) -> None:
        if self.export is not None:
            raise ValueError(f"an export is already running ({self.export.out})")
        if self.last is None:
            what = ("stop the recording first" if self.active
                    else "record a run first (Start recording, then Stop recording)")
            raise ValueError(f"nothing to export: {what}")
        from tileviz.datasets import dataset_mb

        size = dataset_mb(self.last) * 1e6
        free = free_bytes(self.last)
        if free < size + MIN_FREE_BYTES:
            raise ValueError(f"no room to export {self.last}: {_gib(free)} free on its disk, "
                             f"the file needs about {_gib(size)} and {_gib(MIN_FREE_BYTES)} are "
                             "kept free")
        self.export = kind(self.last)
        self._note(f"exporting {self.last} to {self.export.out} ...", "info")

    def poll(self) -> None:
        """Note an export that finished since the last call."""
        job = self.export
        if job is None or job.running:
            return
        self.export = None
        if job.error is not None:
            self._note(f"{job.kind} export of {job.dataset} failed: {job.error}", "error")
        else:
            self._note(f"exported {job.frames} frames to {job.out} ({job.hint})", "info")

    def close(self) -> None:
        """Wait for an export in progress, then close the recording (idempotent)."""
        if self.export is not None:
            self.export.join()
        self.cancel("the server stopped")


class ExportJob:
    """An export of a recorded dataset folder on a background thread, written beside it
    (``out``). ``frames``: frames written; ``error``: one line when it failed. Subclasses say
    what is written (:meth:`work`), its ``kind`` and what to do with it (``hint``)."""

    kind = "an"
    hint = ""
    suffix = ""

    def __init__(self, dataset: Path) -> None:
        self.dataset = dataset
        self.out = dataset.with_name(dataset.name + self.suffix)
        self.frames = 0
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, name=f"tileviz-{self.kind}",
                                        daemon=True)
        self._thread.start()

    def work(self) -> int:
        """Write :attr:`out` from :attr:`dataset`; the frames written."""
        raise NotImplementedError

    def _run(self) -> None:
        try:
            self.frames = self.work()
        except Exception as e:  # noqa: BLE001 - reported as one line by Recorder.poll
            self.error = f"{type(e).__name__}: {e}" if not isinstance(e, (OSError, ValueError)) \
                else str(e)

    @property
    def running(self) -> bool:
        """True while the export thread runs."""
        return self._thread.is_alive()

    def join(self, timeout: float | None = None) -> None:
        """Wait for the export (at most ``timeout`` seconds; None: until it ends)."""
        self._thread.join(timeout)


class McapJob(ExportJob):
    """``dataset`` replayed as ``python -m tileviz replay DATASET --mcap`` does, written to
    ``DATASET.mcap`` beside it (the file may be partial when it failed)."""

    kind = "MCAP"
    hint = "open it in Foxglove"
    suffix = ".mcap"

    def work(self) -> int:
        from tileviz.pipeline.replay import replay

        # the replay table is not kept: the MCAP file is what was asked for
        return replay(self.dataset, mcap=self.out, jobs=1)


class PageJob(ExportJob):
    """``dataset`` as the web page ``python -m tileviz export-html DATASET DATASET.html``
    writes, beside it (written whole or not at all)."""

    kind = "page"
    hint = "open it in a browser: it plays offline"
    suffix = ".html"

    def work(self) -> int:
        from tileviz.share.page import PageOptions, export_html, page_views
        from tileviz.share.run import load_run

        opts = PageOptions()
        run = load_run(self.dataset, views=page_views(opts), jobs=1)
        export_html(run, self.out, opts)
        return len(run.records)
