"""The live page's readout: what the shown frame says, as HTML, from a snapshot of the state.

:func:`render_status` is a pure function of a :class:`StatusState` (no server, no session);
:meth:`StatusState.of` takes that snapshot from a running :class:`~tileviz.app.session.Session`.
The HTML is two boxes of fixed height (:data:`STATUS_STYLE`, :data:`NOTES_STYLE`): the frame,
its status in words, the set's widths (cm, degrees), its error against the truth, MCL and the
loop's rate; then the newest notes. The boxes scroll rather than grow, so the controls under them
never move.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from tileviz.app.history import Entry
from tileviz.config import LocalizerConfig
from tileviz.core.localizer import FAULT_MAX_REJECTIONS, LocalizerStep
from tileviz.summary import counted, extractor_note

if TYPE_CHECKING:
    from tileviz.app.session import Note, Session

__all__ = ["NOTES_STYLE", "STATUS_STYLE", "STATUS_WORDS", "StatusState", "fault_line",
           "render_status"]

STATUS_WORDS = {
    "contracted": "the camera's view shrank the set",
    "predicted": "no usable view: odometry and compass only",
    "rejected": "the view disagrees with the set (an outlier), ignored",
    "lost": "no set the method can vouch for",
}
"""The statuses in plain words (``tileviz.types.STATUSES``)."""
_BOX = ("box-sizing:border-box;overflow-y:auto;font-size:0.8em;line-height:1.35em;"
        "padding:0.2em 0.4em;")
STATUS_STYLE = _BOX + "height:12.4em;"
"""Fixed height: the status block never grows, so the buttons under it never move."""
NOTES_STYLE = _BOX + "height:5.6em;margin-top:0.2em;border-top:1px solid #8884;opacity:0.85;"


@dataclass(frozen=True)
class StatusState:
    """Everything the readout shows, at one moment.

    ``entry``: the shown frame (None before the first). ``live``: it is the newest frame.
    ``contained``: the truth's containment over the plot window (``tileviz.app.plots.summary``)
    or None. ``rate``: the loop's frames a second. ``notes``: the newest notes, oldest first.
    ``replaying``: the replayed dataset's description (None: the simulator), ``ended``: why
    its replay stopped. ``recording``: (folder, frames written) while recording."""

    entry: Entry | None
    live: bool
    playing: bool
    localizer: LocalizerConfig
    extractor: str
    contained: dict[str, float] | None
    rate: float
    history: tuple[int, int]
    """(frames kept, capacity)"""
    notes: tuple[Note, ...] = ()
    replaying: str | None = None
    ended: str | None = None
    recording: tuple[str, int] | None = None
    degraded: bool = False

    @classmethod
    def of(cls, s: Session, entry: Entry | None, contained: dict[str, float] | None, *,
           live: bool) -> StatusState:
        """The state of session ``s`` with ``entry`` shown."""
        writer = s.recorder.writer
        return cls(
            entry=entry, live=live, playing=s.playing, localizer=s.cfg.localizer,
            extractor=s.cfg.vision.extractor, contained=contained, rate=s.rate,
            history=(len(s.history), s.history.capacity), notes=tuple(s.notes)[-3:],
            replaying=None if s.source.simulator else s.source.describe(), ended=s.ended,
            recording=None if writer is None else (str(s.recorder.path), writer.count),
            degraded=s.degraded)


def render_status(st: StatusState) -> str:
    """The readout of ``st`` as HTML (see the module docstring)."""
    lines: list[str] = []
    state = "playing" if st.playing else "paused"
    entry = st.entry
    if entry is None:
        lines.append(f"<b>no frame yet</b> ({state})")
    else:
        lines += _frame_lines(entry, st, state)
    c = st.contained
    if entry is not None and c is not None and c["frames"] > 0:
        lines.append(f"truth inside the set in {100 * c['contained']:.1f} % of the last "
                     f"{c['frames']:.0f} frames it vouched for")
        note = extractor_note(st.extractor)
        if note:
            lines.append(f"<i>{html.escape(note)}</i>")
    rate = f"{st.rate:.0f} frames/s" if st.playing else "-"
    lines.append(f"loop {rate}, history {st.history[0]}/{st.history[1]}, "
                 f"mode {st.localizer.mode}, extractor {st.extractor}")
    notes: list[str] = []
    recent = st.notes
    if st.replaying is not None:
        # its end stays in view after newer notes pushed the note about it out
        said = st.ended is not None and any(n.text.startswith(st.ended) for n in recent)
        notes.append(f"replaying <code>{html.escape(st.replaying)}</code>"
                     + (f": <b>{html.escape(st.ended)}</b>" if st.ended and not said else ""))
    if st.recording is not None:
        path, count = st.recording
        notes.append(f"recording to <code>{html.escape(path)}</code> ({count} frames)")
    if st.degraded:
        notes.append("<b>a frame failed: the set may miss the truth (Relocalize or "
                     "Reset)</b>")
    for n in reversed(recent):  # newest first
        notes.append(("<b>error:</b> " if n.level == "error" else "") + html.escape(n.text))
    return (f'<div class="tileviz-status" style="{STATUS_STYLE}">{"<br>".join(lines)}</div>'
            f'<div class="tileviz-notes" style="{NOTES_STYLE}">{"<br>".join(notes)}</div>')


def _frame_lines(entry: Entry, st: StatusState, state: str) -> list[str]:
    """The readout's lines about the shown frame: index and time, status, view, set, MCL."""
    r = entry.record
    hull = r.updated.hull()
    lines = [f"<b>frame {r.index}</b>, t = {r.t:.2f} s, {state}"
             f"{'' if st.live else ' (from the history)'}",
             f"status <b>{r.status}</b>: {html.escape(STATUS_WORDS.get(r.status, ''))}"
             f", {counted(len(r.updated), 'box', 'boxes')}"]
    fault = fault_line(r.step, st.localizer)
    if fault:
        lines.append(fault)
    reason = r.vision.reason
    lines.append("camera view used" if r.vision.observation is not None
                 else f"camera view not used: {html.escape(reason)}")
    if hull is not None:
        wx, wy, wt = hull.widths
        lines.append(f"set {100 * wx:.1f} x {100 * wy:.1f} cm, heading "
                     f"{math.degrees(wt):.2f} deg wide")
        if r.truth is not None:
            cx, cy, ct = hull.centre
            err = math.hypot(r.truth.x - cx, r.truth.y - cy)
            inside = r.truth_inside()
            mark = {True: "inside", False: "<b>OUTSIDE</b>", None: "not vouched for"}[inside]
            et = abs(math.degrees(math.remainder(r.truth.theta - ct, 2 * math.pi)))
            lines.append(f"centre {100 * err:.1f} cm, {et:.2f} deg from the truth; truth "
                         f"{mark}")
    if entry.mcl is not None and r.truth is not None:
        m = entry.mcl
        err = math.hypot(r.truth.x - m.mean[0], r.truth.y - m.mean[1])
        where = "inside" if m.covered else "<b>outside</b>"
        lines.append(f"MCL ({len(m.particles)} particles): mean {100 * err:.1f} cm off,"
                     f" truth {where} its 95 % ellipse")
    ms = r.timings.get("vision_ms", 0.0) + r.timings.get("localizer_ms", 0.0)
    lines.append(f"frame time {ms:.1f} ms (vision {r.timings.get('vision_ms', 0.0):.1f},"
                 f" localizer {r.timings.get('localizer_ms', 0.0):.2f})")
    return lines


def fault_line(step: LocalizerStep | None, loc: LocalizerConfig) -> str:
    """The fault model's state at one frame, in words ('' when there is nothing to say): the
    candidates of a re-localization in a region, the frame of a followed fault
    (``LocalizerStep.fault_frame``) and the views in a row that fitted neither the set nor the
    fault set, out of the number that makes the status ``lost``."""
    if step is None or step.status == "lost":
        return ""
    parts = []
    if step.relocalizing:
        merged = " (merged into one box: more than the limit)" if step.hulled else ""
        parts.append(f"re-localizing: {counted(len(step.updated), 'candidate')} in the "
                     f"region{merged}")
    if not (loc.fault_speed or loc.fault_yaw_rate) or loc.max_slip != (0.0, 0.0) or (
            loc.mode != "autonomous"):
        return "; ".join(parts)
    if step.fault_frame > 0:
        parts.append(f"tracking through a fault: frame {step.fault_frame} of the fault set")
    if step.rejections > 0:
        limit = min(loc.max_rejections, FAULT_MAX_REJECTIONS)
        parts.append(f"{counted(step.rejections, 'view')} in a row fit neither set ({limit} make "
                     f"it lost)")
    return "; ".join(parts)
