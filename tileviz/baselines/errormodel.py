"""The measured error distribution of the view (tile observation), for MCL's likelihood.

A particle filter is only as honest as its likelihood. This module holds the view error model the
calibrated MCL uses (:class:`ViewErrorModel`), the fit that makes it from measured errors
(:func:`fit_view_errors`), and its file (``view_error_model.json`` beside this module), written by
``python bench/view_errors.py --write`` and read by :func:`load_view_error_model`.

Units: every error is *normalised by the view's declared bound*: the position residuals e1, e2
(metres, :func:`tileviz.vision.observation_error`) divided by the observation's
``position_error``, the heading residual e3 (rad) by its ``heading_error``. A model fitted on one
preset's camera therefore carries over to another's (their declared bounds are both 1 px of their
own camera, 0.005 rad).

The model per coordinate is a zero-mean Student-t with ``nu`` degrees of freedom and scale
``scale`` (in declared bounds; nu = inf is the Gaussian), fitted by maximum likelihood (EM for the
scale on a grid of nu). ``outlier_probability`` is the weight of a uniform density (the view is
unrelated to the pose): the measured share of accepted views outside their declared bound, floored
at :data:`MIN_OUTLIER_PROBABILITY` (AMCL's ``z_rand``: never trust a view absolutely).
``correlation`` is the lag-1 autocorrelation of the errors over consecutive frames of a run: views
of consecutive frames share their tile edges and their errors, so n views carry less than n
independent views' information. A filter that multiplies their likelihoods as if independent is
overconfident by that factor. The measured autocorrelation is not that of an AR(1) sequence: it
drops at lag 1 (a white part, the pixel noise of each frame) and then decays slowly (a slowly
varying bias, the same edges seen from nearly the same place). :func:`fit_slow_component` fits
acf(k) = a r^k over lags 1..:data:`ACF_LAGS` (a the share of the slow part, r its decay per
frame), and :meth:`ViewErrorModel.inflation` is the long-run variance factor of such a sequence's
mean, (1 - a) + a (1 + r) / (1 - r) (for a = 1 the AR(1) factor (1 + rho) / (1 - rho); a model
without the fit uses that with rho the lag-1 correlation), which the calibrated MCL applies to
the scale.

numpy only.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "ACF_LAGS",
    "MAX_DECAY",
    "MIN_OUTLIER_PROBABILITY",
    "MODEL_PATH",
    "NU_GRID",
    "StudentT",
    "ViewErrorModel",
    "autocorrelation",
    "fit_slow_component",
    "fit_student_t",
    "fit_view_errors",
    "lag1_correlation",
    "load_view_error_model",
    "student_t_logpdf",
]

MODEL_PATH = Path(__file__).with_name("view_error_model.json")
"""Where ``bench/view_errors.py --write`` puts the fitted model and the calibrated MCL reads it."""
MIN_OUTLIER_PROBABILITY = 0.01
"""Floor on the outlier weight of the view likelihood."""
ACF_LAGS = 40
"""Lags (frames) of the autocorrelation the slow component is fitted to (2 s at 20 frames/s)."""
MAX_DECAY = 0.995
"""Ceiling on the fitted decay r of the slow component (its variance factor stays finite)."""
NU_GRID = (1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 50.0, 100.0, math.inf)
"""The degrees of freedom the fit tries (inf: Gaussian)."""


@dataclass(frozen=True)
class StudentT:
    """A zero-mean Student-t: ``nu`` degrees of freedom (inf = Gaussian), ``scale`` > 0."""

    nu: float
    scale: float

    def __post_init__(self) -> None:
        if not (self.nu > 0):
            raise ValueError(f"nu must be > 0, got {self.nu!r}")
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"scale must be a finite number > 0, got {self.scale!r}")

    def logpdf(self, z: np.ndarray) -> np.ndarray:
        """Log density at ``z`` (elementwise)."""
        return student_t_logpdf(np.asarray(z, dtype=float), self.nu, self.scale)


def student_t_logpdf(z: np.ndarray, nu: float, scale: float) -> np.ndarray:
    """Log density of the zero-mean Student-t (``nu`` = inf: the Gaussian) of scale ``scale``."""
    u = z / scale
    if math.isinf(nu):
        return -0.5 * u * u - math.log(scale) - 0.5 * math.log(2.0 * math.pi)
    c = (math.lgamma(0.5 * (nu + 1.0)) - math.lgamma(0.5 * nu)
         - 0.5 * math.log(nu * math.pi) - math.log(scale))
    return c - 0.5 * (nu + 1.0) * np.log1p(u * u / nu)


def fit_student_t(z: np.ndarray, nus: tuple[float, ...] = NU_GRID) -> StudentT:
    """Maximum-likelihood zero-mean Student-t of the samples ``z`` (at least 2, not all zero):
    for each nu of ``nus`` the scale by EM (iteratively reweighted second moment), then the nu of
    the largest log-likelihood."""
    z = np.asarray(z, dtype=float).ravel()
    z = z[np.isfinite(z)]
    if z.size < 2 or not np.any(z != 0.0):
        raise ValueError(f"need at least 2 finite samples, not all zero; got {z.size}")
    z2 = z * z
    best: tuple[float, StudentT] | None = None
    for nu in nus:
        s2 = float(np.mean(z2))
        if not math.isinf(nu):
            for _ in range(200):
                w = (nu + 1.0) / (nu + z2 / s2)
                new = float(np.mean(w * z2))
                done = abs(new - s2) <= 1e-10 * s2
                s2 = new
                if done:
                    break
        model = StudentT(nu, math.sqrt(max(s2, 1e-300)))
        ll = float(np.sum(model.logpdf(z)))
        if best is None or ll > best[0]:
            best = (ll, model)
    assert best is not None
    return best[1]


def autocorrelation(runs: list[np.ndarray], lag: int) -> float:
    """Autocorrelation of the (zero-mean) errors at ``lag`` >= 1 frames, pooled over ``runs``
    (each a 1-D array of one run's consecutive errors; NaN = no view at that frame, which breaks
    the pairs); 0 when no pair exists."""
    num = den = 0.0
    for e in runs:
        e = np.asarray(e, dtype=float)
        a, b = e[:-lag], e[lag:]
        ok = np.isfinite(a) & np.isfinite(b)
        num += float(np.sum(a[ok] * b[ok]))
        den += 0.5 * float(np.sum(a[ok] ** 2 + b[ok] ** 2))
    return num / den if den > 0 else 0.0


def lag1_correlation(runs: list[np.ndarray]) -> float:
    """Lag-1 autocorrelation of the errors (:func:`autocorrelation`), clipped to [0, 0.99]."""
    return min(max(autocorrelation(runs, 1), 0.0), 0.99)


def fit_slow_component(runs: list[np.ndarray], lags: int = ACF_LAGS) -> tuple[float, float]:
    """(a, r): the share a in [0, 1] and the decay per frame r in [0, :data:`MAX_DECAY`] of the
    slow part of the errors, from a least-squares fit of log acf(k) = log a + k log r over the
    lags k = 1..``lags`` whose pooled autocorrelation exceeds 0.02 (module docstring); (0, 0)
    when fewer than two lags do (independent frames)."""
    ks, logs = [], []
    for k in range(1, lags + 1):
        c = autocorrelation(runs, k)
        if c > 0.02:
            ks.append(k)
            logs.append(math.log(c))
    if len(ks) < 2:
        return 0.0, 0.0
    slope, intercept = np.polyfit(np.asarray(ks, float), np.asarray(logs), 1)
    return min(max(math.exp(intercept), 0.0), 1.0), min(max(math.exp(slope), 0.0), MAX_DECAY)


@dataclass(frozen=True)
class ViewErrorModel:
    """The view error model (module docstring): per-coordinate Student-t in units of the declared
    bounds, an outlier weight, the lag-1 correlation of consecutive errors, and where it came
    from (``source``: the command that measured it, ``samples``: views it was fitted on)."""

    position: StudentT
    heading: StudentT
    outlier_probability: float
    correlation_position: float = 0.0
    correlation_heading: float = 0.0
    samples: int = 0
    source: str = ""
    slow_position: tuple[float, float] | None = None
    """(share a, decay r) of the slow part of the position errors (:func:`fit_slow_component`);
    None: an AR(1) sequence of the lag-1 correlation."""
    slow_heading: tuple[float, float] | None = None
    """The same for the heading errors."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.outlier_probability < 1.0:
            raise ValueError(
                f"outlier_probability must be in [0, 1), got {self.outlier_probability!r}")
        for name in ("correlation_position", "correlation_heading"):
            v = getattr(self, name)
            if not 0.0 <= v < 1.0:
                raise ValueError(f"{name} must be in [0, 1), got {v!r}")
        for name in ("slow_position", "slow_heading"):
            v = getattr(self, name)
            if v is not None and not (len(v) == 2 and 0.0 <= v[0] <= 1.0
                                      and 0.0 <= v[1] <= MAX_DECAY):
                raise ValueError(f"{name} must be (share in [0, 1], decay in [0, {MAX_DECAY}]), "
                                 f"got {v!r}")

    def inflation(self, which: str) -> float:
        """Long-run variance factor of the mean of ``which`` ('position' or 'heading') errors:
        (1 - a) + a (1 + r) / (1 - r) of the slow component (a, r), or (1 + rho) / (1 - rho) of
        the lag-1 correlation rho when the model has no slow component (module docstring)."""
        slow = self.slow_position if which == "position" else self.slow_heading
        if slow is None:
            rho = self.correlation_position if which == "position" else self.correlation_heading
            return (1.0 + rho) / (1.0 - rho)
        a, r = slow
        return (1.0 - a) + a * (1.0 + r) / (1.0 - r)

    def to_json(self) -> str:
        """The model as JSON text (inf as the string "inf")."""
        d = asdict(self)
        for k in ("position", "heading"):
            d[k]["nu"] = "inf" if math.isinf(d[k]["nu"]) else d[k]["nu"]
        return json.dumps(d, indent=2) + "\n"

    @classmethod
    def from_json(cls, text: str) -> ViewErrorModel:
        """Parse :meth:`to_json`'s text; ValueError naming the problem."""
        try:
            d = json.loads(text)
            parts = {k: StudentT(float(d[k]["nu"]), float(d[k]["scale"]))
                     for k in ("position", "heading")}
            slow_p, slow_h = ((float(d[k][0]), float(d[k][1])) if d.get(k) is not None
                              else None for k in ("slow_position", "slow_heading"))
            return cls(**parts, outlier_probability=float(d["outlier_probability"]),
                       correlation_position=float(d.get("correlation_position", 0.0)),
                       correlation_heading=float(d.get("correlation_heading", 0.0)),
                       samples=int(d.get("samples", 0)), source=str(d.get("source", "")),
                       slow_position=slow_p, slow_heading=slow_h)
        except (KeyError, TypeError, IndexError, json.JSONDecodeError) as e:
            raise ValueError(f"bad view error model: {e}") from None


def fit_view_errors(runs: list[np.ndarray], source: str = "") -> ViewErrorModel:
    """Fit :class:`ViewErrorModel` to normalised view errors: ``runs`` is a list of (n_i, 3)
    arrays, one per run, rows (e1/ep, e2/ep, e3/eh) of consecutive frames, NaN rows for frames
    without a view. Views outside their declared bound (any |coordinate| > 1) count as outliers
    and are left out of the Student-t fits and of the correlations (their frames break the
    pairs); the correlations of x and y are pooled."""
    allz = np.concatenate([np.asarray(r, dtype=float).reshape(-1, 3) for r in runs])
    allz = allz[np.all(np.isfinite(allz), axis=1)]
    if allz.shape[0] < 2:
        raise ValueError(f"need at least 2 views, got {allz.shape[0]}")
    inlier = np.all(np.abs(allz) <= 1.0, axis=1)
    share = 1.0 - float(inlier.mean())
    good = allz[inlier]
    pos = fit_student_t(good[:, :2].ravel())
    head = fit_student_t(good[:, 2])
    # the two position coordinates pooled (as runs of their own), outliers left out
    clean = [np.where(np.all(np.abs(r) <= 1.0, axis=1, keepdims=True), r, np.nan)
             for r in (np.asarray(r, dtype=float).reshape(-1, 3) for r in runs)]
    xy = [r[:, 0] for r in clean] + [r[:, 1] for r in clean]
    th = [r[:, 2] for r in clean]
    return ViewErrorModel(position=pos, heading=head,
                          outlier_probability=max(share, MIN_OUTLIER_PROBABILITY),
                          correlation_position=lag1_correlation(xy),
                          correlation_heading=lag1_correlation(th),
                          samples=int(allz.shape[0]), source=source,
                          slow_position=fit_slow_component(xy),
                          slow_heading=fit_slow_component(th))


def load_view_error_model(path: Path | None = None) -> ViewErrorModel:
    """The model in ``path`` (default :data:`MODEL_PATH`); ValueError naming the file when it is
    missing or malformed."""
    p = MODEL_PATH if path is None else Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise ValueError(f"cannot read the view error model {p}: {e.strerror}") from None
    try:
        return ViewErrorModel.from_json(text)
    except ValueError as e:
        raise ValueError(f"{p}: {e}") from None
