"""The pipeline: the one frame loop (:mod:`tileviz.pipeline.frame_loop`) that drives every
estimator over a source of frames, and what runs it in batch."""

from tileviz.pipeline.frame_loop import PRIMARY, FrameLoop, FrameRecord, Source, initial_box

__all__ = ["PRIMARY", "FrameLoop", "FrameRecord", "Source", "initial_box"]
