"""Fault events of one run and how a method went through each: detection delay and recovery
time (:func:`event_outcomes`). One implementation for ``python -m tileviz evaluate`` and
``bench/faults.py``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["EventOutcome", "event_outcomes", "fault_events", "noticed"]



def noticed(status: str, compass_rejected: bool, has_view: bool,
            reinflated: bool = False) -> bool:
    """Whether the autonomous interval localizer showed, at one frame, that something was wrong:
    a view ``rejected``, ``lost``, a compass reading that missed the set (``compass_rejected``),
    or no view to use (``has_view`` False: vision refused the frame, so the status is
    ``predicted``), or, with the fault model, the set taken from the fault set (``reinflated``:
    the view or the compass rejected the set, the status stays ``contracted``)."""
    return status in ("rejected", "lost") or compass_rejected or not has_view or reinflated


def fault_events(faulty: np.ndarray) -> list[tuple[int, int]]:
    """The fault events of a run: each maximal run of consecutive faulty frames (``faulty``: (n,)
    bool, the simulator's fault labels) as (F, E), its first and last frame index (a kidnap:
    F = E, the first frame at the new pose)."""
    mask = np.asarray(faulty, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(edges[0::2], edges[1::2], strict=True)]


@dataclass(frozen=True)
class EventOutcome:
    """How one method went through one fault event (frames are indices into the run).

    ``start``/``end``: the event's first and last faulty frame F and E. ``detection``: frames from
    F to the first frame that :func:`noticed` something, searched up to the next event's F (or the
    run's end); None: not detected. ``harmless``: every input used from F to E + 1 respected its
    declared bound (an odometry fault on frame E is used at E + 1), so there was nothing to
    detect. ``recovery``: frames from E to the first later frame that is vouched for (status not
    ``lost``) and whose set holds the truth, searched up to the next event's F (or the run's end);
    None: not recovered (e.g. ``lost``, which lasts until a reset)."""

    start: int
    end: int
    detection: int | None
    harmless: bool
    recovery: int | None


def event_outcomes(faulty: np.ndarray, alarm: np.ndarray, vouched: np.ndarray,
                   inside: np.ndarray, in_bounds: np.ndarray) -> list[EventOutcome]:
    """Detection delay and recovery time of every event of :func:`fault_events` (``faulty``) for
    one method over one run; every argument is an (n,) bool array over the run's frames:
    ``alarm`` (:func:`noticed`), ``vouched`` (status not ``lost``), ``inside`` (the reported set
    holds the truth), ``in_bounds`` (every input used at the frame respected its bound)."""
    alarm = np.asarray(alarm, dtype=bool)
    ok = np.asarray(vouched, dtype=bool) & np.asarray(inside, dtype=bool)
    in_bounds = np.asarray(in_bounds, dtype=bool)
    n = alarm.size
    events = fault_events(faulty)
    out = []
    for i, (f, e) in enumerate(events):
        horizon = events[i + 1][0] if i + 1 < len(events) else n
        hits = np.flatnonzero(alarm[f:horizon])
        back = np.flatnonzero(ok[e + 1:horizon])
        out.append(EventOutcome(
            start=f, end=e,
            detection=int(hits[0]) if hits.size else None,
            harmless=bool(in_bounds[f:min(e + 2, n)].all()),
            recovery=int(back[0]) + 1 if back.size else None,
        ))
    return out


# --------------------------------------------------------------------------------- metrics
