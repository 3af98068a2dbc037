"""Bounded-error proprioceptive sensors: odometry (speed, yaw rate) and a compass.

The declared bounds are ``NoiseConfig.speed_error`` (m/s), ``yaw_rate_error`` (rad/s) and
``compass_error`` (rad); they go into datasets and into the localizer's ``SensorBounds``. Each error
is drawn uniformly in ``+- fraction * bound``, so with ``fraction <= 1`` the bound always holds
(after rounding: a reading is nudged by one ulp toward the truth when float rounding would push
it past the bound). ``fraction > 1`` makes a sensor that breaks its declared bound on purpose.

What "true" means: the odometry of frame k describes the motion from pose k to pose k+1 held over
dt. Its true values are :attr:`StepTruth.speed` (mean signed forward speed over the step) and
:attr:`StepTruth.yaw_rate` ((theta_{k+1} - theta_k) / dt). When the step obeys the odometry model
(``StepTruth.model_ok``: every piece of the path heads inside hull(theta_k, theta_{k+1}), no
sideways slide, one sign of speed) then for any readings within the bounds of these values,

    theta_{k+1} in theta_k + dt [w]  and  p_{k+1} - p_k in dt [v] (cos, sin)(hull(theta_k,
    theta_k + dt [w])),

with [v] = v_meas +- speed_error and [w] = w_meas +- yaw_rate_error: the mean of vectors that all
lie in the convex box [v](cos, sin)(hull) lies in it (docs/method.md, "Prediction").

Faults (docs/faults.md) add a deliberate error on top: :class:`OdometryFault` values are added
to the readings after the bounded noise, so the reading is off by more than the bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tileviz.config import NoiseConfig
from tileviz.sim.controller import wrap_pi
from tileviz.sim.world import StepTruth
from tileviz.types import Odometry


@dataclass(frozen=True)
class OdometryFault:
    """Extra error added to one odometry reading: ``speed`` m/s and ``yaw_rate`` rad/s."""

    speed: float = 0.0
    yaw_rate: float = 0.0


def within(measured: float, true: float, bound: float) -> float:
    """``measured`` moved toward ``true`` until |measured - true| <= bound (floats).

    Only ever moves a value that rounding pushed a hair past the bound (a few ulps of the values:
    with a bound below an ulp, e.g. 1e-31 rad, that can be the whole reading, and the answer is
    then ``true`` itself); ``measured`` values further out are a caller's bug and raise.
    """
    d = measured - true
    if abs(d) <= bound:
        return measured
    slack = 16.0 * math.ulp(max(abs(measured), abs(true), 1.0))
    if abs(d) > bound + slack:
        raise ValueError(f"reading {measured!r} is not within {bound!r} of {true!r}")
    measured = true + math.copysign(bound, d)
    while abs(measured - true) > bound:  # ends at ``true`` at the latest
        measured = math.nextafter(measured, true)
    return measured


class Sensors:
    """Odometry and compass readings with errors drawn from ``rng`` (numpy Generator)."""

    def __init__(self, noise: NoiseConfig, rng: np.random.Generator) -> None:
        self.noise = noise
        self.rng = rng

    def _error(self, bound: float) -> float:
        f = self.noise.fraction
        return float(self.rng.uniform(-1.0, 1.0)) * f * bound if bound > 0 and f > 0 else 0.0

    def odometry(self, step: StepTruth, fault: OdometryFault | None = None) -> Odometry:
        """The measured (speed, yaw rate) of the motion ``step`` (pose k to k+1) held over dt."""
        nz = self.noise
        v = step.speed + self._error(nz.speed_error)
        w = step.yaw_rate + self._error(nz.yaw_rate_error)
        if nz.fraction <= 1.0:
            v = within(v, step.speed, nz.speed_error)
            w = within(w, step.yaw_rate, nz.yaw_rate_error)
        if fault is not None:
            v += fault.speed
            w += fault.yaw_rate
        return Odometry(speed=v, yaw_rate=w, dt=step.dt)

    def compass(self, theta: float) -> float:
        """Measured heading of the true (continuous) heading ``theta``, wrapped to (-pi, pi] rad,
        within ``compass_error`` of it modulo 2 pi."""
        bound = self.noise.compass_error
        reading = wrap_pi(theta + self._error(bound))
        if self.noise.fraction <= 1.0:
            true = wrap_pi(theta)
            # compare on the circle: shift the reading next to the truth, clamp, wrap back
            near = true + wrap_pi(reading - true)
            near = within(near, true, bound)
            reading = wrap_pi(near)
        return reading


def _cos_range(lo: float, hi: float) -> tuple[float, float]:
    """Range of cos over [lo, hi] (plain floats, not outward-rounded)."""
    c_lo, c_hi = sorted((math.cos(lo), math.cos(hi)))
    if math.floor(hi / (2 * math.pi)) * 2 * math.pi >= lo:  # a multiple of 2 pi inside
        c_hi = 1.0
    if math.floor((hi - math.pi) / (2 * math.pi)) * 2 * math.pi + math.pi >= lo:  # pi + 2 pi k
        c_lo = -1.0
    return c_lo, c_hi


def _mul(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    p = (a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1])
    return min(p), max(p)


def prediction_encloses(start: tuple[float, float, float], end: tuple[float, float, float],
                        odometry: Odometry, speed_error: float, yaw_rate_error: float,
                        tol: float = 1e-9) -> bool:
    """Whether pose ``end`` lies in the prediction from the single pose ``start`` with
    ``odometry`` +- the bounds held over ``odometry.dt`` (docs/method.md, "Prediction"):
    theta_end in theta + dt [w], (x, y)_end in (x, y) + dt [v] (cos, sin)(hull(theta,
    theta + dt [w])). Plain floats with a tolerance ``tol`` (m, rad): a check of the simulator's
    truth against its readings, not the localizer's guaranteed arithmetic.
    """
    x0, y0, t0 = start
    x1, y1, t1 = end
    dt = odometry.dt
    w = (odometry.yaw_rate - yaw_rate_error, odometry.yaw_rate + yaw_rate_error)
    v = (odometry.speed - speed_error, odometry.speed + speed_error)
    if not (t0 + dt * w[0] - tol <= t1 <= t0 + dt * w[1] + tol):
        return False
    lo, hi = t0 + min(0.0, dt * w[0]), t0 + max(0.0, dt * w[1])
    cx = _mul(v, _cos_range(lo, hi))
    cy = _mul(v, _cos_range(lo - math.pi / 2, hi - math.pi / 2))  # sin x = cos(x - pi/2)
    dx, dy = x1 - x0, y1 - y0
    return (dt * cx[0] - tol <= dx <= dt * cx[1] + tol
            and dt * cy[0] - tol <= dy <= dt * cy[1] + tol)
