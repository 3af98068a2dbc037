"""An adversary for the localizer's guarantee, independent of its implementation.

It builds runs that respect every declared bound (hypotheses H1-H4 of ``docs/guarantees.md``) at
their nastiest, computes the truth in exact arithmetic (:mod:`tileviz.testing.exact_truth`, 256
bits) and checks, every frame, that the true pose is in ``predicted``, in ``updated`` and in the
hull that ``replay --out`` writes (``BoxSet.hull()``), and that the status is ``contracted`` or
``predicted`` (under H1-H4 a rejection would mean the truth had been dropped).

- The robot is a unicycle integrated exactly over many sub-steps per frame; within each sub-step
  its speed and yaw rate are held at any value within the bounds, mostly at an extreme
  (bang-bang), including zero, negative and zero-straddling speeds.
- Odometry, compass and view errors are at their bounds, as close as floats allow (each reading is
  a float whose exact distance to the truth is at most the bound, mod L / 2 pi where periodic).
- Geometry: headings at +-pi and many turns away, at the pi/4 branch edges (either branch's
  reading), the camera on a grout line, lever arms from zero and subnormal to several tiles, tiles
  from 1 cm to 10 m, coordinates up to 1e8 m, dt from 1e-6 to 5 s, zero-width initial boxes and
  error bounds, subnormal parameters.

Randomness comes from a :class:`Chooser`: :class:`RandomChooser` (``bench/soundness_audit.py``,
seeded) or a hypothesis ``data`` object (``tests/test_soundness_adversarial.py``, shrinkable).
Nothing here imports ``tileviz.intervals``; the localizer is only driven through its public API.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from typing import Any, Protocol

from tileviz.config import LocalizerConfig
from tileviz.core.localizer import Localizer
from tileviz.testing.exact_truth import HALF_PI, MP, PI, TWO_PI, TWO_PI_FINE, margin, mpf, sub
from tileviz.types import Box, BoxSet, Observation, Odometry, SensorBounds

KINDS = ("wrap", "branch_edge", "grout", "lever", "scales", "speeds", "degenerate", "mixed")
"""The classes of nastiness; ``mixed`` draws every choice freely."""


class Chooser(Protocol):
    def choice(self, options: list[Any] | tuple[Any, ...]) -> Any: ...
    def uniform(self, lo: float, hi: float) -> float: ...
    def integer(self, lo: int, hi: int) -> int: ...
    def bulk(self) -> Chooser: ...


class RandomChooser:
    """Choices from a seeded ``random.Random``."""

    def __init__(self, seed: int) -> None:
        self.rng = random.Random(seed)

    def choice(self, options: list[Any] | tuple[Any, ...]) -> Any:
        return options[self.rng.randrange(len(options))]

    def uniform(self, lo: float, hi: float) -> float:
        return self.rng.uniform(lo, hi)

    def integer(self, lo: int, hi: int) -> int:
        return self.rng.randint(lo, hi)

    def bulk(self) -> Chooser:
        """The chooser for the many small choices (sub-step cuts): this one."""
        return self


class HypothesisChooser:
    """Choices drawn from hypothesis (``st.data()``), so failures shrink."""

    def __init__(self, data: Any) -> None:
        from hypothesis import strategies as st

        self.data = data
        self.st = st

    def choice(self, options: list[Any] | tuple[Any, ...]) -> Any:
        return self.data.draw(self.st.sampled_from(list(options)))

    def uniform(self, lo: float, hi: float) -> float:
        return self.data.draw(self.st.floats(lo, hi, allow_nan=False, allow_infinity=False))

    def integer(self, lo: int, hi: int) -> int:
        return self.data.draw(self.st.integers(lo, hi))

    def bulk(self) -> Chooser:
        """The sub-steps' hundreds of cut points come from a drawn seed (drawing each would
        overrun hypothesis's example size); the structure stays drawn and shrinkable."""
        return RandomChooser(self.integer(0, 2**32 - 1))


# --- exact model ---------------------------------------------------------------------------------


def exact_add(a: float, b: float) -> Any:
    """a + b exactly (two floats)."""
    return MP.fadd(mpf(a), mpf(b), exact=True)


def unicycle(x: Any, y: Any, th: Any, v: Any, w: Any, h: Any) -> tuple[Any, Any, Any]:
    """Exact motion at constant speed v (m/s) and yaw rate w (rad/s) for h s, written with
    sinc so that a tiny w loses no precision: the chord is v h sinc(w h / 2) at th + w h / 2."""
    a = w * h / 2
    s = mpf(1) if a == 0 else MP.sin(a) / a
    mid = th + a
    d = v * h * s
    return x + d * MP.cos(mid), y + d * MP.sin(mid), th + 2 * a


def camera(x: Any, y: Any, th: Any, offset: tuple[float, float]) -> tuple[Any, Any]:
    f, left = mpf(offset[0]), mpf(offset[1])
    c, s = MP.cos(th), MP.sin(th)
    return x + f * c - left * s, y + f * s + left * c


def _mod(v: Any, p: Any) -> Any:
    """v mod p in [0, p)."""
    return v - p * MP.floor(v / p)


def _cdist(a: Any, b: Any, p: Any) -> Any:
    """|a - b| on a circle of period p, exactly (p a float, or 2 pi to 4096 bits)."""
    d = sub(a, b)
    k = MP.floor(d / p)
    d = MP.fsub(d, MP.fmul(k, p, exact=True), exact=True)
    while d < 0:  # (the floor of a rounded quotient may be one off)
        d = MP.fadd(d, p, exact=True)
    while d >= p:
        d = MP.fsub(d, p, exact=True)
    return min(d, MP.fsub(p, d, exact=True))


def reading(truth: Any, bound: float, side: int, period: Any | None = None,
            wrap: tuple[Any, Any] | None = None) -> float | None:
    """A float within ``bound`` of ``truth`` exactly (mod ``period``), as near truth +
    side * bound as floats allow (side in -1, 0, 1); ``wrap``: the float is put in [lo, hi)
    (mod period) first. Moves whole ulps toward the truth until the exact distance holds. None
    when no float is that close (a bound below the float spacing: a zero bound on a truth that
    is not a float) -- a sensor with that bound could not give a reading then."""
    target = truth + side * mpf(bound)
    if wrap is not None:
        lo, _ = wrap
        target = lo + _mod(target - lo, period)
    r = float(target)

    fine = TWO_PI_FINE if period is TWO_PI else period

    def dist(v: float) -> Any:
        if period is not None:
            return _cdist(v, truth, fine)
        d = sub(v, truth)
        return d if d >= 0 else MP.fneg(d, exact=True)  # (abs() would round to PREC bits)

    toward = float(truth) if period is None else None
    for _ in range(64):
        if dist(r) <= bound:
            return r
        if toward is None:  # periodic: step toward the nearest copy of the truth
            assert period is not None
            d = _mod(mpf(r) - truth, period)
            r = math.nextafter(r, -math.inf if d < period / 2 else math.inf)
        else:
            r = math.nextafter(r, toward)
    return None


def exact_view(x: Any, y: Any, th: Any, tile: float, offset: tuple[float, float],
               shift: int) -> tuple[Any, Any, Any]:
    """The exact view parameters (y1, y2 not reduced mod L, y3) of the pose for rotation branch
    m = m0 + shift,
    m0 the canonical one (y3 in [-pi/4, pi/4)); shift +-1 gives the neighbouring branch's
    reading (y3 near -+pi/2), which an extractor may report at a branch edge."""
    L = mpf(tile)
    cx, cy = camera(x, y, th, offset)
    m = int(MP.floor((th + PI / 4) / HALF_PI)) + shift
    y3 = th - m * HALF_PI
    y3 = y3 - TWO_PI * MP.floor((y3 + PI) / TWO_PI)  # in [-pi, pi)
    k = m % 4
    u1, u2 = [(cx, cy), (cy, -cx), (-cx, -cy), (-cy, cx)][k]  # R(-m pi/2) c
    del L
    return u1, u2, y3  # u1, u2 modulo L: reduced by :func:`reading` (exactly checked there)


# --- scenarios -----------------------------------------------------------------------------------


@dataclass
class Frame:
    """One frame's inputs: the motion since the previous frame (None at frame 0) as the odometry
    reading and the true sub-step controls, and which readings are given, with error sides."""

    dt: float = 0.0
    v: float = 0.0
    w: float = 0.0
    controls: list[tuple[Any, Any, Any]] = field(default_factory=list)  # (v, w, h) exact
    compass: int | None = None  # error side, or None: no compass
    view: tuple[int, int, int, int] | None = None  # (side1, side2, side3, branch shift)


@dataclass
class Scenario:
    kind: str
    tile: float
    offset: tuple[float, float]
    bounds: SensorBounds
    e: float
    e3: float
    start: tuple[float, float, float]
    initial: Box
    frames: list[Frame]
    max_boxes: int = 16


def _f(c: Chooser, lo: float, hi: float, log: bool = False) -> float:
    if log:
        return math.exp(c.uniform(math.log(lo), math.log(hi)))
    return c.uniform(lo, hi)


def scenario(c: Chooser, kind: str, frames: int) -> Scenario:
    """A run of ``frames`` frames of class ``kind`` (see :data:`KINDS`)."""
    mixed = kind == "mixed"
    tile = c.choice([0.5, 1.0, 0.166])
    if kind == "scales" or (mixed and c.integer(0, 1)):
        tile = _f(c, 0.01, 10.0, log=True)
    # lever arm
    offset = (c.choice([0.0, 0.1, 0.3]) * tile, c.choice([0.0, 0.0, -0.05]) * tile)
    if kind in ("lever", "degenerate") or mixed:
        offset = c.choice([
            (0.0, 0.0), (5e-324, 0.0), (0.0, 5e-324), (-1e-323, 0.0), (1e-310, -3e-320),
            (_f(c, -5, 5) * tile, _f(c, -5, 5) * tile), (_f(c, 1.0, 5.0) * tile, 0.0),
            (0.0, -_f(c, 1.0, 5.0) * tile),
        ])
    # bounds
    ev = c.choice([0.0, 0.01, 0.05, 0.2])
    ew = c.choice([0.0, 0.01, 0.05, 0.3])
    ec = c.choice([0.0, 0.02, 0.1, 0.5])
    e = c.choice([0.02, 0.1, 0.3]) * tile
    e3 = c.choice([0.01, 0.05, 0.3])
    if kind == "degenerate" or (mixed and c.integer(0, 2) == 0):
        ev, ew, ec = (c.choice([0.0, 5e-324, 1e-300, ev]) for _ in range(3))
        e = c.choice([0.0, 5e-324, e])
        e3 = c.choice([0.0, 5e-324, e3])
    # start pose (floats: the initial box holds it exactly)
    scale = 1e8 if kind == "scales" and c.integer(0, 1) else 10.0
    x0 = c.uniform(-scale, scale)
    y0 = c.uniform(-scale, scale)
    th0 = c.uniform(-4.0, 4.0)
    if kind == "wrap" or (mixed and c.integer(0, 2) == 0):
        th0 = c.choice([math.pi, -math.pi, math.nextafter(math.pi, 0), 3.0 * math.pi,
                        -math.pi + 1e-12, 1000.0 * math.pi, -2.5e4])
    if kind == "branch_edge" or (mixed and c.integer(0, 2) == 0):
        m = c.integer(-8, 8)
        th0 = float(PI / 4 + m * HALF_PI) + c.choice([0.0, 1e-15, -1e-15, 1e-9, -1e-9])
    if kind == "grout" or (mixed and c.integer(0, 1) == 0):
        # put the camera centre on a grout line (x, y or both), as exactly as floats allow
        cx, cy = camera(mpf(x0), mpf(y0), mpf(th0), offset)
        L = mpf(tile)
        which = c.integer(0, 2)
        if which in (0, 2):
            x0 = float(mpf(x0) - (cx - L * MP.nint(cx / L)))
        if which in (1, 2):
            y0 = float(mpf(y0) - (cy - L * MP.nint(cy / L)))
    # initial box around the start (possibly zero-width)
    widths = c.choice([(0.0, 0.0, 0.0), (0.05, 0.05, 0.05), (0.3, 0.3, 0.3), (1.0, 1.0, 2.0),
                       (2.0 * tile, 0.0, 0.5), (1.2 * tile, 1.2 * tile, 7.0),
                       (1.3 * tile, 0.2 * tile, 0.7)])
    lo_hi = []
    for v0, wdt in zip((x0, y0, th0), widths, strict=True):
        a = c.choice([0.0, 1.0, c.uniform(0.0, 1.0)]) * wdt  # the truth on an edge, or inside
        lo, hi = v0 - a, v0 + (wdt - a)
        lo_hi += [min(lo, v0), max(hi, v0)]
    initial = Box(*lo_hi)
    # motion
    out = []
    dts = [1e-6, 0.05, 0.05, 0.1, 1.0, 5.0]
    if kind == "scales" or mixed:
        dts += [_f(c, 1e-6, 5.0, log=True)]
    vmax = 1.0 if tile >= 0.1 else 0.1
    for k in range(frames):
        fr = Frame()
        if k > 0:
            fr.dt = c.choice(dts)
            fr.v = c.choice([0.0, 0.0, vmax, -vmax, 0.5 * vmax, c.uniform(-vmax, vmax),
                             -ev / 2, ev / 2])
            fr.w = c.choice([0.0, 0.5, -1.0, c.uniform(-2.0, 2.0), ew / 2, 5e-324])
            if kind == "speeds":
                fr.v = c.choice([0.0, -vmax, ev / 2, -ev, c.uniform(-ev, ev)])
                fr.w = c.choice([0.0, -ew, ew / 2, c.uniform(-3.0, 3.0)])
            fr.controls = _controls(c.bulk(), fr.dt, fr.v, fr.w, ev, ew)
        if c.integer(0, 3):
            fr.compass = c.choice([-1, 1, 1, -1, 0])
        if c.integer(0, 4):
            fr.view = (c.choice([-1, 1, 0]), c.choice([-1, 1, 0]), c.choice([-1, 1, 0]),
                       c.choice([0, 0, 0, 1, -1]))
        out.append(fr)
    return Scenario(kind, tile, offset, SensorBounds(ev, ew, ec), e, e3, (x0, y0, th0), initial,
                    out)


def _controls(c: Chooser, dt: float, v: float, w: float, ev: float, ew: float
              ) -> list[tuple[Any, Any, Any]]:
    """True (v, w, h) sub-steps summing to dt exactly, each control within its bound of the
    reading: bang-bang (an extreme held), the reading itself, or anything in between."""
    n = c.choice([1, 2, 5, 16, 40])
    cuts = sorted(mpf(c.uniform(0.0, 1.0)) for _ in range(n - 1))
    edges = [mpf(0)] + cuts + [mpf(1)]
    v_lo, v_hi = exact_add(v, -ev), exact_add(v, ev)
    w_lo, w_hi = exact_add(w, -ew), exact_add(w, ew)
    style = c.choice(["bang", "bang", "held", "free"])
    held = (c.choice([v_lo, v_hi]), c.choice([w_lo, w_hi]))
    out = []
    for a, b in zip(edges, edges[1:], strict=False):
        h = (b - a) * mpf(dt)
        if style == "held":
            vv, ww = held
        elif style == "bang":
            vv, ww = c.choice([v_lo, v_hi]), c.choice([w_lo, w_hi])
        else:
            vv = v_lo + (v_hi - v_lo) * mpf(c.uniform(0.0, 1.0))
            ww = w_lo + (w_hi - w_lo) * mpf(c.uniform(0.0, 1.0))
        out.append((vv, ww, h))
    return out


# --- the run -------------------------------------------------------------------------------------


@dataclass
class Report:
    frames: int = 0
    checks: int = 0
    violations: list[str] = field(default_factory=list)
    statuses: dict[str, int] = field(default_factory=dict)


def run(scn: Scenario, stop_at_first: bool = True) -> Report:
    """Drive a Localizer through ``scn`` and check every frame (see the module docstring)."""
    rep = Report()
    loc = Localizer(tile_size=scn.tile, camera_offset=scn.offset, bounds=scn.bounds,
                    config=LocalizerConfig(max_boxes=scn.max_boxes), initial=scn.initial)
    x, y, th = (mpf(v) for v in scn.start)
    L = mpf(scn.tile)
    for k, fr in enumerate(scn.frames):
        if k > 0:
            for v, w, h in fr.controls:
                x, y, th = unicycle(x, y, th, v, w, h)
        odo = None if k == 0 else Odometry(fr.v, fr.w, fr.dt)
        compass = None
        if fr.compass is not None:
            compass = reading(th, scn.bounds.compass_error, fr.compass, TWO_PI, (-PI, PI))
        obs = None
        if fr.view is not None:
            s1, s2, s3, shift = fr.view
            y1, y2, y3 = exact_view(x, y, th, scn.tile, scn.offset, shift)
            if abs(y3) > PI / 4 + mpf(scn.e3):  # not at a branch edge: the canonical reading
                y1, y2, y3 = exact_view(x, y, th, scn.tile, scn.offset, 0)
            r = (reading(y1, scn.e, s1, L, (mpf(0), L)), reading(y2, scn.e, s2, L, (mpf(0), L)),
                 reading(y3, scn.e3, s3))
            r1, r2, r3 = r
            if r1 is not None and r2 is not None and r3 is not None:
                obs = Observation(r1, r2, r3, scn.e, scn.e3)
        where = f"{scn.kind} frame {k}"
        try:
            step = loc.step(odo, compass, obs)
        except Exception as exc:  # noqa: BLE001 - any failure is a finding
            rep.violations.append(f"{where}: {type(exc).__name__}: {exc}")
            return rep
        rep.frames += 1
        rep.statuses[step.status] = rep.statuses.get(step.status, 0) + 1
        if step.status not in ("contracted", "predicted"):
            rep.violations.append(f"{where}: status {step.status} under H1-H4")
        hull = step.updated.hull()
        for name, boxes in (("predicted", step.predicted.boxes),
                            ("updated", step.updated.boxes),
                            ("hull", () if hull is None else (hull,))):
            rep.checks += 1
            best = max((margin(b, x, y, th) for b in boxes), default=None)
            if best is None or best < 0:
                rep.violations.append(
                    f"{where}: truth ({float(x)!r}, {float(y)!r}, {float(th)!r}) not in "
                    f"{name} (by {'-' if best is None else float(-best):.3g}): "
                    f"{BoxSet(tuple(boxes)) if len(boxes) < 4 else len(boxes)}")
        if rep.violations and stop_at_first:
            return rep
    return rep
