"""The recorded localizer sequences of ``tests/data/localizer_golden.npz`` and their bit-for-bit
comparison (``tests/test_localizer_golden.py``; ``bench/fault_defaults.py`` replays them with the
fault model on).

The file holds, per sequence (:data:`SEQUENCES`), the localizer's constructor arguments, the
inputs of every frame (odometry, compass, observation; the truth in mode truth) and what the
localizer returned: both box sets (every bound as a float64 bit pattern), the status, passes,
rejection streak and flags. The inputs come from the simulator (``SimSource``, fixed seeds)
through the robust extractor and are stored, so a comparison depends neither on vision nor on the
machine.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tileviz.config import Config, LocalizerConfig, preset, with_overrides
from tileviz.core.localizer import Localizer
from tileviz.testing import REPO
from tileviz.types import STATUSES, Box, BoxSet, Observation, Odometry, Pose, SensorBounds

__all__ = ["GOLDEN", "SCALARS", "SEQUENCES", "Golden", "Sequence", "first_difference", "load",
           "make_inputs", "regenerate", "run_localizer", "setup_of"]

GOLDEN = REPO / "tests" / "data" / "localizer_golden.npz"
"""The golden file of this checkout."""

Golden = dict[str, tuple[dict[str, Any], dict[str, np.ndarray], dict[str, np.ndarray]]]
"""name -> (setup, inputs, golden outputs)."""


@dataclass(frozen=True)
class Sequence:
    """One recorded sequence: how its inputs are made and how the localizer is set up.

    ``faults``: (frame, kind, parameters) handed to ``SimSource.inject`` before that frame
    (``kidnap`` parameters are offsets dx, dy, dtheta from the current pose). ``outliers``: every
    n-th frame's view is replaced by a random observation (0: none). ``no_compass`` /
    ``no_view``: every n-th frame has no compass reading / no view. ``wide_heading``: every n-th
    view declares a heading bound of 0.45 rad (>= pi/8: each branch is cut on its own).
    """

    name: str
    preset: str
    frames: int
    mode: str = "autonomous"
    max_slip: tuple[float, float] = (0.0, 0.0)
    offset: tuple[float, float] | None = None
    initial_error: tuple[float, float, float] | None = None
    seed: int = 3
    faults: tuple[tuple[int, str, tuple[tuple[str, float], ...]], ...] = ()
    outliers: int = 0
    no_compass: int = 0
    no_view: int = 0
    wide_heading: int = 0
    localizer: dict[str, Any] = field(default_factory=dict)

    def config(self) -> Config:
        cfg = preset(self.preset)
        loc = {"mode": self.mode, "max_slip": self.max_slip, **self.localizer}
        sim: dict[str, Any] = {"seed": self.seed}
        if self.initial_error is not None:
            sim["initial_pose_error"] = self.initial_error
        over: dict[str, dict[str, Any]] = {"localizer": loc, "sim": sim}
        if self.offset is not None:
            over["camera"] = {"offset": self.offset}
        return with_overrides(cfg, **over)


SEQUENCES = (
    Sequence("default-autonomous", "default", 300, outliers=17, no_compass=9, no_view=23,
             wide_heading=31),
    Sequence("default-recovery", "default", 400, max_slip=(0.25, 0.1), outliers=29,
             faults=((100, "slip", (("speed", 0.3), ("yaw_rate", 0.2))),
                     (240, "kidnap", (("dx", 0.12), ("dy", -0.1), ("dtheta", 0.06))),
                     (340, "odometry_outlier", ()))),
    Sequence("seed-kidnap", "seed", 250, outliers=13,
             faults=((100, "kidnap", (("dx", 0.9), ("dy", 0.4), ("dtheta", 1.0))),)),
    Sequence("seed-recovery", "seed", 300, max_slip=(0.05, 0.1), no_view=11,
             faults=((80, "slip", (("speed", 0.2), ("yaw_rate", 0.1))),
                     (200, "kidnap", (("dx", 0.3), ("dy", 0.0), ("dtheta", 0.5))))),
    Sequence("seed-truth", "seed", 200, mode="truth", outliers=7, no_compass=5,
             wide_heading=13),
    Sequence("default-truth", "default", 150, mode="truth", outliers=7, wide_heading=11),
    Sequence("seed-odometry", "seed", 100, mode="odometry", no_compass=4),
    Sequence("wide-start", "default", 200, initial_error=(1.4, 1.4, math.pi), outliers=19,
             max_slip=(0.2, 0.2), wide_heading=37, no_compass=3,
             localizer={"max_boxes": 6}),
    Sequence("no-lever", "default", 200, offset=(0.0, 0.0), initial_error=(0.6, 0.6, 0.4),
             outliers=11, wide_heading=17),
)
"""The recorded sequences (their names key the golden file)."""


# --- making the inputs ---------------------------------------------------------------------------


def make_inputs(seq: Sequence) -> dict[str, np.ndarray]:
    """Simulate ``seq`` and run the robust extractor: per frame the odometry of the previous
    step (NaN row: none), compass (NaN: none), observation (NaN row: none) and, in mode truth,
    the true pose (no rows otherwise)."""
    from tileviz.sim.source import SimSource
    from tileviz.vision import extract

    cfg = seq.config()
    rng = np.random.default_rng(seq.seed + 1000)
    L = cfg.floor.tile_size
    src = SimSource(cfg)
    faults: dict[int, tuple[str, dict[str, Any]]] = {k: (kind, dict(p))
                                                     for k, kind, p in seq.faults}
    n = seq.frames
    odo = np.full((n, 3), np.nan)
    compass = np.full(n, np.nan)
    obs = np.full((n, 5), np.nan)
    truth = np.full((n if seq.mode == "truth" else 0, 3), np.nan)
    pending: Odometry | None = None
    for k in range(n):
        if k in faults:
            kind, p = faults[k]
            if kind == "kidnap":
                q = src.pose
                src.kidnap(q.x + p["dx"], q.y + p["dy"], q.theta + p["dtheta"])
            else:
                src.inject(kind, **p)
        frame = next(src)
        v = extract(frame.image, camera=cfg.camera, tile_size=L, vision=cfg.vision).observation
        if seq.outliers and k % seq.outliers == seq.outliers - 1:
            v = Observation(float(rng.uniform(0, L)), float(rng.uniform(0, L)),
                            float(rng.uniform(-math.pi / 4, math.pi / 4)),
                            cfg.position_error, cfg.vision.heading_error)
        if v is not None and seq.wide_heading and k % seq.wide_heading == 1:
            v = Observation(v.y1, v.y2, v.y3, v.position_error, 0.45)
        if seq.no_view and k % seq.no_view == 2:
            v = None
        if pending is not None:
            odo[k] = (pending.speed, pending.yaw_rate, pending.dt)
        if frame.compass is not None and not (seq.no_compass and k % seq.no_compass == 3):
            compass[k] = frame.compass
        if v is not None:
            obs[k] = (v.y1, v.y2, v.y3, v.position_error, v.heading_error)
        if seq.mode == "truth":  # elsewhere the localizer only checks it: not stored
            assert frame.truth is not None
            truth[k] = frame.truth.as_tuple()
        pending = frame.odometry
    return {"odometry": odo, "compass": compass, "observation": obs, "truth": truth}


def setup_of(seq: Sequence) -> dict[str, Any]:
    """The localizer's constructor arguments, as JSON-able values."""
    from tileviz.pipeline import initial_box

    cfg = seq.config()
    return {
        "tile_size": cfg.floor.tile_size,
        "camera_offset": list(cfg.camera.offset),
        "bounds": [cfg.noise.speed_error, cfg.noise.yaw_rate_error, cfg.noise.compass_error],
        "config": asdict(cfg.localizer),
        "initial": list(initial_box(cfg).as_tuple()),
    }


# --- running the localizer -----------------------------------------------------------------------


def _flat(sets: list[BoxSet]) -> tuple[np.ndarray, np.ndarray]:
    counts = np.array([len(s) for s in sets], dtype=np.int32)
    boxes = np.array([b.as_tuple() for s in sets for b in s.boxes], dtype=np.float64)
    return counts, boxes.reshape(-1, 6)


def run_localizer(setup: dict[str, Any], inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Step a fresh localizer through the stored inputs; every output of every frame."""
    c = dict(setup["config"])
    c["truth_inflation"] = tuple(c["truth_inflation"])
    c["max_slip"] = tuple(c["max_slip"])
    # sequences recorded before the fault model existed ran without it
    c.setdefault("fault_speed", 0.0)
    c.setdefault("fault_yaw_rate", 0.0)
    loc = Localizer(tile_size=setup["tile_size"], camera_offset=tuple(setup["camera_offset"]),
                    bounds=SensorBounds(*setup["bounds"]), config=LocalizerConfig(**c),
                    initial=Box(*setup["initial"]))
    predicted: list[BoxSet] = []
    updated: list[BoxSet] = []
    scalars = []
    truths = inputs["truth"]
    for k, (odo, comp, ob) in enumerate(zip(inputs["odometry"], inputs["compass"],
                                            inputs["observation"], strict=True)):
        step = loc.step(
            None if np.isnan(odo[0]) else Odometry(*map(float, odo)),
            None if np.isnan(comp) else float(comp),
            None if np.isnan(ob[0]) else Observation(*map(float, ob)),
            Pose(*map(float, truths[k])) if len(truths) else None,
        )
        predicted.append(step.predicted)
        updated.append(step.updated)
        scalars.append((STATUSES.index(step.status), step.passes, step.rejections,
                        step.hulled, step.compass_rejected, step.reinflated))
    pc, pb = _flat(predicted)
    uc, ub = _flat(updated)
    return {"predicted_count": pc, "predicted": pb, "updated_count": uc, "updated": ub,
            "scalars": np.array(scalars, dtype=np.int32).reshape(-1, 6)}


SCALARS = ("status", "passes", "rejections", "hulled", "compass_rejected", "reinflated")


def first_difference(want: dict[str, np.ndarray], got: dict[str, np.ndarray]) -> str | None:
    """None when ``got`` is bit for bit ``want``, else a sentence naming the first frame and
    output that differ."""
    for j, name in enumerate(SCALARS):
        d = np.flatnonzero(want["scalars"][:, j] != got["scalars"][:, j])
        if d.size:
            k = int(d[0])
            return f"frame {k}: {name} {want['scalars'][k, j]} != {got['scalars'][k, j]}"
    for key in ("predicted", "updated"):
        wc, gc = want[f"{key}_count"], got[f"{key}_count"]
        d = np.flatnonzero(wc != gc)
        if d.size:
            k = int(d[0])
            return f"frame {k}: {wc[k]} {key} boxes != {gc[k]}"
        w = want[key].view(np.uint64)
        g = got[key].view(np.uint64)
        rows = np.flatnonzero((w != g).any(axis=1))
        if rows.size:
            k = int(np.searchsorted(np.cumsum(wc), rows[0], side="right"))
            return (f"frame {k}: {key} box {want[key][rows[0]].tolist()} != "
                    f"{got[key][rows[0]].tolist()}")
    return None


def load(path: Path = GOLDEN) -> Golden:
    """The sequences stored in ``path``: name -> (setup, inputs, golden outputs)."""
    with np.load(path) as z:
        names = json.loads(str(z["names"]))
        out = {}
        for name in names:
            setup = json.loads(str(z[f"{name}/setup"]))
            inputs = {k: z[f"{name}/in/{k}"] for k in
                      ("odometry", "compass", "observation", "truth")}
            want = {k: z[f"{name}/out/{k}"] for k in
                    ("predicted_count", "predicted", "updated_count", "updated", "scalars")}
            out[name] = (setup, inputs, want)
    return out



def regenerate(path: Path = GOLDEN) -> None:
    """Rebuild the inputs (a minute of simulation and vision) and record the current
    localizer's output into ``path``."""
    arrays: dict[str, Any] = {"names": json.dumps([s.name for s in SEQUENCES])}
    for seq in SEQUENCES:
        inputs = make_inputs(seq)
        setup = setup_of(seq)
        outputs = run_localizer(setup, inputs)
        arrays[f"{seq.name}/setup"] = json.dumps(setup)
        arrays.update({f"{seq.name}/in/{k}": v for k, v in inputs.items()})
        arrays.update({f"{seq.name}/out/{k}": v for k, v in outputs.items()})
        s = outputs["scalars"]
        print(f"{seq.name}: {seq.frames} frames, statuses "
              f"{dict(zip(STATUSES, np.bincount(s[:, 0], minlength=4).tolist(), strict=True))}, "
              f"max boxes {outputs['updated_count'].max()}, hulled {int(s[:, 3].sum())}, "
              f"compass rejected {int(s[:, 4].sum())}, reinflated {int(s[:, 5].sum())}")
    path.parent.mkdir(exist_ok=True)
    np.savez_compressed(path, **arrays)
    print(f"wrote {path} ({path.stat().st_size // 1024} KiB)")
