"""A fault dataset generator for the tests of the fault model (docs/faults.md): a simulated run
of the default preset with a wheel slip beyond the declared speed bound, a kidnap and a camera
dropout, written as a tileviz-dataset/1 folder (``faults.csv`` labels the frames of each
event).

The events are set in frames (20 frames a second in the default preset):

- ``slip``: from ``slip_at`` for ``slip_frames`` frames the odometry reads ``slip_speed`` m/s
  more than the truth along the motion (the wheels spin), beyond ``speed_error``;
- ``kidnap``: at ``kidnap_at`` the robot is carried by ``kidnap`` = (dx, dy, dtheta) (m, m, rad)
  between two frames;
- ``dropout``: from ``dropout_at`` for ``dropout_frames`` frames the camera sends black frames.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from tileviz.config import Config, preset
from tileviz.datasets import DatasetMeta, DatasetWriter
from tileviz.sim.source import SimSource


@dataclass(frozen=True)
class FaultPlan:
    frames: int = 400
    slip_at: int = 60
    slip_frames: int = 40
    slip_speed: float = 0.15
    kidnap_at: int | None = 250
    kidnap: tuple[float, float, float] = (0.37, -0.21, 0.3)
    dropout_at: int | None = 320
    dropout_frames: int = 40
    seed: int = 5


def fault_config(plan: FaultPlan) -> Config:
    cfg = preset("default")
    return replace(cfg, sim=replace(cfg.sim, seed=plan.seed))


def make_fault_dataset(folder: Path, plan: FaultPlan = FaultPlan()) -> Path:
    """Write the run of ``plan`` to ``folder``; returns it."""
    cfg = fault_config(plan)
    src = SimSource(cfg)
    with DatasetWriter(folder, DatasetMeta.from_config(cfg)) as w:
        for k in range(plan.frames):
            if k == plan.slip_at:
                src.inject("slip", frames=plan.slip_frames, speed=plan.slip_speed, yaw_rate=0.0)
            if k == plan.kidnap_at:
                p = src.world.pose
                dx, dy, dth = plan.kidnap
                src.kidnap(p.x + dx, p.y + dy, p.theta + dth)
            if k == plan.dropout_at:
                src.inject("dropout", frames=plan.dropout_frames)
            w.write(next(src))
    return folder
