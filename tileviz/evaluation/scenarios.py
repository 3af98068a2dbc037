"""Evaluation scenarios: named simulator conditions and the faults injected into them.

A :class:`Scenario` is a preset, configuration overrides and a list of :class:`FaultEvent`;
:func:`fault_schedule` turns it into the frames at which each fault starts.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from tileviz.config import Config, preset, with_overrides

__all__ = [
    "DEFAULT_SCENARIOS", "RECOVERY_MAX_SLIP", "SCENARIOS", "FaultEvent", "Scenario",
    "fault_schedule",
]

RECOVERY_MAX_SLIP: dict[str, tuple[float, float]] = {"default": (0.1, 0.1), "seed": (0.04, 0.1)}
"""``LocalizerConfig.max_slip`` (metres, radians) of the ``interval-recovery`` method per preset
(and of ``bench/faults.py``'s recovery runs): below half a tile minus the tracking set's width, so
a re-inflation leaves one lattice cell (``tileviz.localizer``, "Recovery"). ``slip_window`` keeps
its default."""


@dataclass(frozen=True)
class FaultEvent:
    """A fault injected into the simulator: ``kind`` (a ``SimSource.inject`` kind; ``kidnap``
    with ``params`` dx, dy, dtheta relative to the pose at that time, m, m, rad; or ``far_view``:
    the frame's image is replaced by the camera's view at a random pose in the room, done here, not
    by the simulator, so the odometry and truth stay right and only the view lies), starting at
    ``start`` (a fraction of the run's duration, in [0, 1)), lasting ``frames`` frames (None: the
    simulator's default). ``every``: repeat with this period, seconds (0 = once); a repeated camera
    fault draws its kind from ``kinds`` when given."""

    kind: str
    start: float
    frames: int | None = None
    every: float = 0.0
    kinds: tuple[str, ...] = ()
    params: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class Scenario:
    """A named evaluation condition: a preset, config overrides, faults. ``bounded``: its inputs
    are meant to respect their declared bounds (the method then claims 100 % containment); the
    table reports the share of frames that actually did."""

    name: str
    description: str
    preset: str = "default"
    overrides: tuple[tuple[str, tuple[tuple[str, Any], ...]], ...] = ()
    faults: tuple[FaultEvent, ...] = ()
    bounded: bool = True

    def config(self, seed: int) -> Config:
        """The scenario's configuration for the run with simulator seed ``seed`` (the floor's
        appearance seed is ``seed + 1``, as ``tileviz record --seed`` does)."""
        cfg = preset(self.preset)
        if self.overrides:
            cfg = with_overrides(cfg, **{sec: dict(vals) for sec, vals in self.overrides})
        return replace(cfg, sim=replace(cfg.sim, seed=seed),
                       floor=replace(cfg.floor, seed=seed + 1))


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario("clean", "L = 1 m, 200 px/m, 320x240, default noise, no fault"),
        Scenario("seed", "the original's constants (seed preset: L = 0.166 m, 620 px/m)",
                 preset="seed"),
        Scenario("heavy", "pixel noise 8, blur 1.2 px, JPEG quality 40",
                 overrides=(("camera", (("noise_sigma", 8.0), ("blur_sigma", 1.2),
                                        ("jpeg_quality", 40))),)),
        Scenario("outliers", "every 1 s, 2 frames with a cable, box edge, shadow edge or glare",
                 faults=(FaultEvent("camera", 0.05, frames=2, every=1.0,
                                    kinds=("cable", "box", "shadow", "glare")),),
                 bounded=False),
        Scenario("slip", "wheel slip beyond the odometry bound for 2 s at 1/3 of the run "
                 "(+0.1 m/s, +0.05 rad/s)",
                 faults=(FaultEvent("slip", 1 / 3, frames=40),), bounded=False),
        Scenario("dropout", "camera dropout (black frames) for 2 s at 1/3 and 2/3 of the run",
                 faults=(FaultEvent("dropout", 1 / 3, frames=40),
                         FaultEvent("dropout", 2 / 3, frames=40))),
        Scenario("far-views", "every 1 s, 1 frame whose image is the view from a random pose in "
                 "the room (a valid floor view that lies)",
                 faults=(FaultEvent("far_view", 0.05, frames=1, every=1.0),), bounded=False),
        Scenario("faithful", "the original pipeline (faithful extractor), no fault check",
                 overrides=(("vision", (("extractor", "faithful"),)),), bounded=False),
        Scenario("kidnap", "teleport by (+0.3 m, -0.2 m, +0.4 rad) at half the run",
                 faults=(FaultEvent("kidnap", 0.5, params=(("dx", 0.3), ("dy", -0.2),
                                                            ("dtheta", 0.4))),),
                 bounded=False),
    )
}
"""The scenarios ``--scenarios`` chooses from."""
DEFAULT_SCENARIOS = ("clean", "seed", "heavy", "outliers", "slip", "dropout")


def fault_schedule(scn: Scenario, frames: int, dt: float,
              rng: np.random.Generator) -> dict[int, list[tuple[str, int | None, dict]]]:
    """Frame index k -> faults to start before frame k is simulated."""
    out: dict[int, list[tuple[str, int | None, dict]]] = {}
    duration = frames * dt
    for ev in scn.faults:
        t = ev.start * duration
        while True:
            k = int(round(t / dt))
            if k >= frames:
                break
            kind = ev.kind
            if ev.kinds:
                kind = str(ev.kinds[int(rng.integers(len(ev.kinds)))])
            out.setdefault(k, []).append((kind, ev.frames, dict(ev.params)))
            if ev.every <= 0:
                break
            t += ev.every
    return out
