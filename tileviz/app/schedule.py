"""When the live server's loop thread makes a frame and pushes it, and how often the parts of a
push refresh (seconds on ``time.perf_counter``).

:class:`RateLimit` is the one limiter the server uses: scene pushes, plots, image panels and
readouts each hold one. :class:`LoopSchedule` paces the frames (the run's frame period) and the
pushes, and says how long the loop may wait for a command.
"""

from __future__ import annotations

__all__ = ["FRAME_LAG", "IDLE_WAIT", "LoopSchedule", "RateLimit"]

FRAME_LAG = 0.25
"""Seconds the frame clock may fall behind before it skips ahead (a loop slower than the frame
period makes frames as fast as it can, never a burst to catch up more than this)."""
IDLE_WAIT = 0.25
"""Seconds the loop waits for a command while paused, at most."""


class RateLimit:
    """At most ``rate`` events a second, on a schedule: an event is due once ``now`` reaches
    :attr:`next`; after one, the schedule moves on by one period, but never to earlier than
    ``now - lag``. ``lag`` = 0: events at most ``rate`` a second on average, a late event not
    made up; ``lag`` = one period: one late event may be made up by the next; ``lag`` = minus
    one period: at least one period between two events. ``start``: when the first is due."""

    def __init__(self, rate: float, *, lag: float = 0.0, start: float = 0.0) -> None:
        if not rate > 0:
            raise ValueError(f"a rate must be > 0 per second, got {rate!r}")
        self.period = 1.0 / rate
        self.lag = lag
        self.next = start
        """When the next event is due."""

    def due(self, now: float) -> bool:
        """Whether an event may happen at ``now``."""
        return now >= self.next

    def spend(self, now: float) -> None:
        """An event happened at ``now`` (due or not: a forced refresh counts too)."""
        self.next = max(self.next + self.period, now - self.lag)


class LoopSchedule:
    """The loop thread's clock: the next frame (every ``frame_period`` s while playing) and the
    scene pushes (at most ``push_rate`` a second, a late one made up), plots at most
    ``plot_rate`` a second, at least a period apart. ``now``: the loop's start."""

    def __init__(self, push_rate: float, plot_rate: float, now: float) -> None:
        self.next_frame = now
        self.push = RateLimit(push_rate, lag=1.0 / push_rate, start=now)
        self.plots = RateLimit(plot_rate, lag=-1.0 / plot_rate)

    def wait(self, now: float, *, playing: bool, push_pending: bool) -> float:
        """Seconds the loop may wait for a command: until the next frame while playing (else
        :data:`IDLE_WAIT`), and no later than the next push when one is pending."""
        wait = max(0.0, self.next_frame - now) if playing else IDLE_WAIT
        if push_pending:
            wait = min(wait, max(0.0, self.push.next - now))
        return wait

    def frame_due(self, now: float) -> bool:
        """Whether the next frame is due at ``now``."""
        return now >= self.next_frame

    def frame_made(self, now: float, period: float) -> None:
        """A frame was made at ``now``; the run's frame period is ``period`` s (0: as fast as
        the loop goes)."""
        self.next_frame = (max(self.next_frame + period, now - FRAME_LAG) if period > 0
                           else now)

    def push_due(self, now: float) -> bool:
        """Whether a push (of a changed frame) may happen at ``now``."""
        return self.push.due(now)

    def pushed(self, now: float) -> bool:
        """Count a push at ``now``; whether it refreshes the plots too."""
        self.push.spend(now)
        plots = self.plots.due(now)
        if plots:
            self.plots.spend(now)
        return plots
