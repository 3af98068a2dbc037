"""The evaluation's outputs: CSV tables, the Markdown table and its figures, the plots."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tileviz.evaluation.metrics import (
    CALIBRATION_COLUMNS,
    COLUMNS,
    aggregate,
    calibration,
)
from tileviz.evaluation.scenarios import SCENARIOS
from tileviz.evaluation.simulate import (
    FAULT_METHODS,
    METHOD_LABELS,
    METHODS,
    STATUS_CODES,
    RunResult,
)
from tileviz.evaluation.store import RUN_COLUMNS, csv_value, run_rows

__all__ = [
    "calibration_table", "figures", "markdown_table", "plot_coverage", "plot_errors",
    "write_csv", "write_outputs",
]

def write_csv(path: Path, rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> None:
    """Write ``rows`` (dicts) with ``columns``; floats with ``repr``, None/NaN as empty cells."""
    with open(path, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(columns)
        for r in rows:
            wr.writerow([csv_value(r[c]) for c in columns])


def _fmt(v: Any, scale: float = 1.0, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    if isinstance(v, int):
        return str(v)
    return f"{v * scale:.{digits}f}"


def _fmt_pct(v: Any) -> str:
    """A percentage rounded *down* to 2 decimals, so 99.999 never reads as 100.00."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    return f"{math.floor(round(v * 100.0, 6)) / 100.0:.2f}"


def _fmt_frames(median: Any, worst: Any) -> str:
    """``median / max`` in frames (a median may end in .5)."""
    if median is None or (isinstance(median, float) and math.isnan(median)):
        return "—"
    return f"{median:g} / {worst}"


def _fmt_missed(missed: Any, events: Any, harmless: Any = 0) -> str:
    """``missed of events``, with the harmless ones among the missed when there are any."""
    if events is None:
        return "—"
    text = f"{missed} of {events}"
    return text + f" ({harmless} harmless)" if harmless else text


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    """The headline table: widths in cm and degrees, CPU in microseconds; percentages rounded
    down; detection delay and recovery time in frames (median / max over the fault events)."""
    head = ("| scenario | method | inputs in bounds % | vouched % | containment % | "
            "false vouches | width x median / p95 (cm) | width y median / p95 (cm) | heading "
            "width median / p95 (deg) | RMSE xy (cm) | RMSE heading (deg) | rejected | lost | "
            "detection delay median / max (frames) | not detected | recovery median / max "
            "(frames) | not recovered | CPU µs/frame |")
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    for r in rows:
        missed = _fmt_missed(r["undetected_events"], r["fault_events"],
                             r["undetected_harmless_events"])
        lines.append(
            f"| {r['scenario']} | {METHOD_LABELS[r['method']]} | "
            f"{_fmt_pct(r['inputs_in_bounds_pct'])} | {_fmt_pct(r['vouched_pct'])} | "
            f"{_fmt_pct(r['containment_pct'])} | {_fmt(r['false_vouches'])} | "
            f"{_fmt(r['width_x_median_m'], 100)} / {_fmt(r['width_x_p95_m'], 100)} | "
            f"{_fmt(r['width_y_median_m'], 100)} / {_fmt(r['width_y_p95_m'], 100)} | "
            f"{_fmt(r['width_theta_median_deg'])} / {_fmt(r['width_theta_p95_deg'])} | "
            f"{_fmt(r['rmse_xy_m'], 100)} | {_fmt(r['rmse_theta_deg'])} | "
            f"{_fmt(r['rejected_frames'])} | {_fmt(r['lost_frames'])} | "
            f"{_fmt_frames(r['detection_median_frames'], r['detection_max_frames'])} | "
            f"{missed} | "
            f"{_fmt_frames(r['recovery_median_frames'], r['recovery_max_frames'])} | "
            f"{_fmt_missed(r['unrecovered_events'], r['fault_events'])} | "
            f"{_fmt(r['cpu_us_per_frame'], digits=0)} |")
    return "\n".join(lines)


def figures(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The headline figures, as sentences: containment of the autonomous interval localizer on the
    scenarios whose inputs respected their bounds, and the CPU ratio MCL / interval."""
    out = []
    by = {(r["scenario"], r["method"]): r for r in rows}
    scns = list(dict.fromkeys(r["scenario"] for r in rows))
    bounded = [s for s in scns if by[(s, "interval")]["inputs_in_bounds_pct"] == 100.0]
    if bounded:
        worst = min(by[(s, "interval")]["containment_pct"] for s in bounded)
        out.append(f"Interval localizer (autonomous) containment on the scenarios whose inputs "
                   f"all respected their bounds ({', '.join(bounded)}): lowest {worst:.2f} %.")
    else:
        out.append("No scenario had all its inputs within their bounds.")
    fv = {(m, part): sum(by[(s, m)]["false_vouches"] for s in group)
          for m in FAULT_METHODS for part, group in (("bounded", bounded), ("all", scns))}
    out.append(f"Frames vouched for while the truth was outside the set (false vouches), "
               f"recovery off / on: {fv[('interval', 'bounded')]} / "
               f"{fv[('interval-recovery', 'bounded')]} on the scenarios whose inputs all "
               f"respected their bounds, {fv[('interval', 'all')]} / "
               f"{fv[('interval-recovery', 'all')]} on all.")
    cpu_i = sum(by[(s, "interval")]["cpu_us_per_frame"] * by[(s, "interval")]["frames"]
                for s in scns)
    cpu_m = sum(by[(s, "mcl")]["cpu_us_per_frame"] * by[(s, "mcl")]["frames"] for s in scns)
    if cpu_i > 0:
        ratio = cpu_m / cpu_i
        out.append(f"CPU per frame, MCL (calibrated) / interval (autonomous), all frames: "
                   f"{ratio:.1f}x.")
    return out


# --------------------------------------------------------------------------------- plots


def plot_coverage(rows: Sequence[dict[str, Any]], path: Path) -> None:
    """Grouped bars: containment % per scenario and method, with the share of frames whose inputs
    respected their bounds as markers; below, the share of frames vouched for (not lost)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scns = list(dict.fromkeys(r["scenario"] for r in rows))
    by = {(r["scenario"], r["method"]): r for r in rows}
    x = np.arange(len(scns))
    width = 0.8 / len(METHODS)
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(max(6.0, 1.3 * len(scns) + 2.0), 5.6), dpi=110,
                                  sharex=True, gridspec_kw={"height_ratios": (3, 1.3)})
    for i, m in enumerate(METHODS):
        dx = (i - (len(METHODS) - 1) / 2) * width
        ax.bar(x + dx, [by[(s, m)]["containment_pct"] for s in scns], width,
               label=METHOD_LABELS[m], color=f"C{i}")
        ax2.bar(x + dx, [by[(s, m)]["vouched_pct"] for s in scns], width, color=f"C{i}")
    ax.plot(x, [by[(s, "interval")]["inputs_in_bounds_pct"] for s in scns], "kD", ms=5,
            label="frames with inputs in bounds")
    ax.axhline(95.0, color="gray", lw=0.8, ls=":")
    ax.set_ylabel("truth inside the reported set, %")
    ax.set_ylim(0, 105)
    ax.set_title("Containment (interval: over vouched frames; MCL: 95 % ellipse)", pad=28)
    ax.legend(fontsize=7, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncols=5,
              frameon=False)
    ax2.set_ylabel("vouched (not lost), %", fontsize=8)
    ax2.set_ylim(0, 105)
    ax2.set_xticks(x, scns)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


PLOT_BINS = 400
"""Error plots show at most this many time bins (a long run is drawn as its envelope)."""


def _bins(n: int) -> np.ndarray:
    """Start indices of at most :data:`PLOT_BINS` consecutive bins of frames covering 0..n-1."""
    k = max(1, math.ceil(n / PLOT_BINS))
    return np.arange(0, n, k)


def plot_errors(res: RunResult, path: Path) -> None:
    """One run: for x, y and heading, the autonomous interval set's bounds (recovery off: band;
    on: dotted lines) and the MCL 95 % region, relative to the truth; bottom: the x width of every
    method, log scale. Fault frames
    shaded gray, lost frames red. Runs longer than :data:`PLOT_BINS` frames are drawn per bin of
    consecutive frames: the lowest lower bound and the highest upper bound (the envelope), the
    mean of the MCL mean, the largest width."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    starts = _bins(res.t.size)

    def lo_env(a: np.ndarray) -> np.ndarray:
        return np.fmin.reduceat(a, starts)

    def hi_env(a: np.ndarray) -> np.ndarray:
        return np.fmax.reduceat(a, starts)

    def mean(a: np.ndarray) -> np.ndarray:
        return np.add.reduceat(a, starts) / np.diff(np.append(starts, a.size))

    t = res.t[starts]
    fig, axes = plt.subplots(4, 1, figsize=(9.0, 9.0), dpi=100, sharex=True)
    iv = res.methods["interval"]
    rc = res.methods["interval-recovery"]
    mc = res.methods["mcl"]
    labels = ("x error (cm)", "y error (cm)", "heading error (deg)")
    scale = (100.0, 100.0, math.degrees(1.0))
    lost = iv.status == STATUS_CODES["lost"]
    for j, ax in enumerate(axes[:3]):
        s = scale[j]
        truth = res.truth[:, j]
        bands = {"iv_lo": lo_env((iv.lo[:, j] - truth) * s),
                 "iv_hi": hi_env((iv.hi[:, j] - truth) * s),
                 "mc_lo": lo_env((mc.lo[:, j] - truth) * s),
                 "mc_hi": hi_env((mc.hi[:, j] - truth) * s)}
        ax.fill_between(t, bands["iv_lo"], bands["iv_hi"], step="post", color="tab:blue",
                        alpha=0.35, lw=0, label="interval set (autonomous)")
        ax.plot(t, lo_env((rc.lo[:, j] - truth) * s), color="tab:orange", lw=1.0, ls=":",
                drawstyle="steps-post", label="interval set, recovery on")
        ax.plot(t, hi_env((rc.hi[:, j] - truth) * s), color="tab:orange", lw=1.0, ls=":",
                drawstyle="steps-post")
        ax.plot(t, bands["mc_lo"], color="tab:red", lw=0.7, ls="--", drawstyle="steps-post",
                label="MCL 95 % bounds")
        ax.plot(t, bands["mc_hi"], color="tab:red", lw=0.7, ls="--", drawstyle="steps-post")
        ax.plot(t, mean((mc.centre[:, j] - truth) * s), color="tab:red", lw=0.8,
                label="MCL mean")
        ax.axhline(0.0, color="k", lw=0.8, label="truth")
        _shade(ax, res.t, res.fault, "0.8", "fault")
        _shade(ax, res.t, lost, "tab:red", "lost")
        ax.set_ylabel(labels[j])
        # the interval band while it is vouched for and the MCL region, unless a few frames would
        # squash the rest
        vouched = ~np.logical_or.reduceat(lost, starts)
        mags = np.abs(np.concatenate([bands["iv_lo"][vouched], bands["iv_hi"][vouched],
                                      bands["mc_lo"], bands["mc_hi"]]))
        lim = min(np.nanmax(mags, initial=0.0), 100.0 * np.nanmedian(mags)) if mags.size else 0.0
        if np.isfinite(lim) and lim > 0:
            ax.set_ylim(-1.2 * lim, 1.2 * lim)
    axes[0].legend(fontsize=7, loc="upper right", ncols=4)
    ax = axes[3]
    for m in METHODS:
        tr = res.methods[m]
        ax.semilogy(t, np.maximum(hi_env((tr.hi[:, 0] - tr.lo[:, 0]) * 100.0), 1e-4), lw=0.9,
                    drawstyle="steps-post", label=METHOD_LABELS[m])
    ax.set_ylabel("x width (cm)")
    ax.set_xlabel("t (s)")
    ax.legend(fontsize=7, loc="upper left", ncols=2)
    fig.suptitle(f"scenario {res.scenario}, run {res.run} (seed {res.seed}): "
                 f"{SCENARIOS[res.scenario].description}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _shade(ax: Any, t: np.ndarray, mask: np.ndarray, color: str, label: str) -> None:
    if not mask.any():
        return
    dt = float(t[1] - t[0]) if t.size > 1 else 1.0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    for a, b in zip(edges[0::2], edges[1::2], strict=True):
        ax.axvspan(t[a] - dt / 2, t[b - 1] + dt / 2, color=color, alpha=0.3, lw=0,
                   label=label if a == edges[0] else None)


def calibration_table(rows: Sequence[dict[str, Any]]) -> str:
    """The calibration rows (:func:`~tileviz.evaluation.metrics.calibration`) as Markdown."""
    levels = [c for c in CALIBRATION_COLUMNS if c.startswith("coverage_")]
    head = "| scenario | method | " + " | ".join(
        f"{c.split('_')[1]} % ellipse" for c in levels) + " |"
    lines = [head, "|---|---|" + "---|" * len(levels)]
    for r in rows:
        lines.append(f"| {r['scenario']} | {METHOD_LABELS[r['method']]} | "
                     + " | ".join(_fmt(r[c], digits=1) for c in levels) + " |")
    return "\n".join(lines)


def write_outputs(results: Sequence[RunResult], out: Path, command: str = "",
                  notes: Sequence[str] = ()) -> list[dict]:
    """Write results.csv, results.md, runs.csv, calibration.csv, coverage.png and
    error_<scenario>.png; ``notes``
    are extra lines for results.md (e.g. the MCL settings)."""
    out.mkdir(parents=True, exist_ok=True)
    rows = aggregate(results)
    write_csv(out / "results.csv", rows, COLUMNS)
    # (written to a temporary file and renamed: a campaign's runs.csv is never half written)
    write_csv(out / "runs.tmp", [row for r in results for row in run_rows(r)], RUN_COLUMNS)
    os.replace(out / "runs.tmp", out / "runs.csv")
    vision_ms = 1e3 * sum(r.vision_s for r in results) / max(1, sum(r.t.size for r in results))
    scns = list(dict.fromkeys(r.scenario for r in results))
    text = ["# Evaluation results", ""]
    if command:
        text += [f"Command: `{command}`", ""]
    text += ["Scenarios:", ""]
    text += [f"- **{s}**: {SCENARIOS[s].description}" for s in scns]
    text += ["", markdown_table(rows), ""]
    text += [f"- {line}" for line in figures(rows)]
    text += [f"- Vision (not counted above): {vision_ms:.2f} ms CPU per frame on average."]
    text += [f"- {line}" for line in notes]
    text += [""]
    cal = calibration(results)
    write_csv(out / "calibration.csv", cal, CALIBRATION_COLUMNS)
    text += ["## Calibration of the particle filters", "",
             "Share of frames (%) whose nominal confidence ellipse holds the true (x, y); a "
             "calibrated filter matches the nominal level.", "", calibration_table(cal), ""]
    text += ["Columns: see `tileviz/evaluation/metrics.py` (module docstring). Widths and RMSE "
             "over the vouched frames; MCL widths are the box around its 95 % ellipse. False "
             "vouches: frames vouched for (not lost) whose set missed the truth. Detection delay "
             "(from the fault's first frame to the first frame that noticed something: a refused "
             "or rejected view, a compass that missed, lost) and recovery time (from the fault's "
             "last frame to the first frame vouched for with the truth inside; 1 = the next frame)"
             " in frames of 0.05 s, median / max over the fault events of every run; \"not "
             "detected\" / \"not recovered\": events without such a frame before the next fault or"
             " the run's end.", ""]
    (out / "results.md").write_text("\n".join(text), encoding="utf-8")
    plot_coverage(rows, out / "coverage.png")
    for s in scns:
        first = next(r for r in results if r.scenario == s)
        plot_errors(first, out / f"error_{s}.png")
    return rows
