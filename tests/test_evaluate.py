"""``python -m tileviz evaluate``: a tiny end-to-end run, the metric definitions, determinism,
fault scenarios, detection delay and recovery time, one-line errors."""

from __future__ import annotations

import csv
import math

import matplotlib.image
import numpy as np
import pytest

from tileviz import evaluation as ev
from tileviz.__main__ import main as tileviz_main
from tileviz.summary import FAITHFUL_NOTE


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], [dict(zip(rows[0], r, strict=True)) for r in rows[1:]]


def test_tiny_run_writes_the_tables_and_plots(tmp_path, capsys):
    out = tmp_path / "eval"
    code = tileviz_main(["evaluate", "--runs", "1", "--duration", "1.5", "--scenarios",
                         "clean,dropout", "--jobs", "1", "--out", str(out), "--quiet",
                         "--particles", "300"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "containment" in printed and "CPU per frame" in printed

    header, rows = read_csv(out / "results.csv")
    assert tuple(header) == ev.COLUMNS
    assert [(r["scenario"], r["method"]) for r in rows] == [
        (s, m) for s in ("clean", "dropout") for m in ev.METHODS]
    by = {(r["scenario"], r["method"]): r for r in rows}
    for r in rows:
        assert int(r["frames"]) == 30 and int(r["runs"]) == 1
        assert float(r["cpu_us_per_frame"]) > 0
        assert float(r["width_x_median_m"]) > 0
    # the guarantee, on inputs that respect their bounds
    clean = by[("clean", "interval")]
    assert float(clean["inputs_in_bounds_pct"]) == 100.0
    assert float(clean["containment_pct"]) == 100.0
    assert float(clean["vouched_pct"]) == 100.0
    # the dropout starts at 1/3 of the run: black frames give no observation
    assert float(by[("dropout", "interval")]["vision_accepted_pct"]) < 70.0
    # the interval localizer is tighter than the odometry alone, MCL has no rejected/lost notion
    assert float(clean["width_x_median_m"]) < float(by[("clean", "odometry")]["width_x_median_m"])
    mcl = by[("clean", "mcl")]
    assert mcl["rejected_frames"] == "" and mcl["lost_frames"] == ""

    run_header, run_rows = read_csv(out / "runs.csv")
    assert run_header[:4] == ["scenario", "method", "run", "seed"]
    assert len(run_rows) == 2 * len(ev.METHODS)

    md = (out / "results.md").read_text()
    assert "| scenario | method |" in md
    assert "interval (autonomous)" in md and "MCL" in md and "odometry only" in md
    assert "300 particles" in md
    assert "fault model 0.2 m/s, 0.1 rad/s" in md  # the default, said in the notes
    assert FAITHFUL_NOTE not in md  # no scenario with the faithful extractor
    for name in ("coverage.png", "error_clean.png", "error_dropout.png"):
        img = matplotlib.image.imread(out / name)
        assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 400


def test_the_faithful_scenario_is_said_to_break_its_bounds(tmp_path):
    out = tmp_path / "eval"
    assert tileviz_main(["evaluate", "--runs", "1", "--duration", "0.5", "--scenarios",
                         "faithful", "--jobs", "1", "--out", str(out), "--quiet",
                         "--particles", "100"]) == 0
    assert f"- Scenario faithful: {FAITHFUL_NOTE}." in (out / "results.md").read_text()


def test_same_seed_same_run_and_other_seed_other_run():
    a = ev.run_one(ev.Task("outliers", 0, 3, 0.6, particles=200))
    b = ev.run_one(ev.Task("outliers", 0, 3, 0.6, particles=200))
    c = ev.run_one(ev.Task("outliers", 0, 4, 0.6, particles=200))
    assert np.array_equal(a.truth, b.truth)
    for m in ev.METHODS:
        for name in ("lo", "hi", "centre", "inside", "status"):
            assert np.array_equal(getattr(a.methods[m], name), getattr(b.methods[m], name),
                                  equal_nan=name not in ("inside", "status"))
    assert not np.array_equal(a.truth, c.truth)
    assert not np.array_equal(a.methods["mcl"].centre, c.methods["mcl"].centre)


def test_parallel_workers_give_the_serial_results():
    kw = dict(runs=2, duration=0.5, seed=7, particles=200, progress=False)
    serial = ev.aggregate(ev.evaluate(["clean", "slip"], jobs=1, **kw))
    parallel = ev.aggregate(ev.evaluate(["clean", "slip"], jobs=2, **kw))
    assert len(serial) == len(parallel) == 2 * len(ev.METHODS)
    for s, p in zip(serial, parallel, strict=True):
        for col in ev.COLUMNS:
            if col != "cpu_us_per_frame":
                assert s[col] == p[col] or (isinstance(s[col], float) and math.isnan(s[col])
                                            and math.isnan(p[col])), col


def _hand_made(n: int = 4) -> ev.RunResult:
    truth = np.zeros((n, 3))
    res = ev.RunResult(scenario="clean", run=0, seed=0, t=np.arange(n) * 0.05, truth=truth,
                       fault=np.zeros(n, bool), in_bounds=np.array([True, True, False, True]),
                       accepted=np.array([True, False, True, True]), vision_s=0.0)
    for m in ev.METHODS:
        tr = ev.MethodTrace.empty(n)
        tr.lo[:] = [[-0.01, -0.02, -0.1]] * n
        tr.hi[:] = [[0.03, 0.02, 0.1]] * n
        tr.centre[:] = [[0.01, 0.0, 0.0]] * n
        tr.inside[:] = [True, False, True, False]
        codes = ev.STATUS_CODES
        if m in ev.MCL_METHODS:
            tr.status[:] = codes["estimate"]
            tr.d2[:] = [0.5, 3.0, 5.0, 10.0]
        else:
            tr.status[:] = [codes["contracted"], codes["rejected"], codes["predicted"],
                            codes["lost"]]
        tr.cpu_s = 4e-4
        res.methods[m] = tr
    return res


def test_calibration_counts_the_frames_inside_each_nominal_ellipse(tmp_path):
    """d2 = 0.5, 3, 5, 10 against chi2_2(p) = 1.39 (50 %), 4.61 (90 %), 5.99 (95 %), 9.21 (99 %):
    one, two, three and three frames of four inside."""
    rows = ev.calibration([_hand_made()])
    assert [r["method"] for r in rows] == list(ev.MCL_METHODS)
    for r in rows:
        assert (r["coverage_50_pct"], r["coverage_90_pct"], r["coverage_95_pct"],
                r["coverage_99_pct"]) == (25.0, 50.0, 75.0, 75.0)
    ev.write_outputs([_hand_made()], tmp_path)
    text = (tmp_path / "results.md").read_text()
    assert "| clean | MCL (calibrated) | 25.0 | 50.0 | 75.0 | 75.0 |" in text
    assert "| clean | MCL (untuned) | 25.0 | 50.0 | 75.0 | 75.0 |" in text
    lines = (tmp_path / "calibration.csv").read_text().splitlines()
    assert lines[0] == ",".join(ev.CALIBRATION_COLUMNS)
    assert lines[1] == "clean,mcl,1,4,25.0,50.0,75.0,75.0"


def test_metric_definitions():
    rows = {r["method"]: r for r in ev.aggregate([_hand_made()])}
    iv = rows["interval"]
    assert iv["frames"] == 4
    assert iv["inputs_in_bounds_pct"] == 75.0
    assert iv["vision_accepted_pct"] == 75.0
    # the lost frame is not vouched for: containment over the three others, one of them missed
    assert iv["vouched_pct"] == 75.0
    assert iv["containment_pct"] == pytest.approx(200.0 / 3.0)
    assert iv["rejected_frames"] == 1 and iv["lost_frames"] == 1
    assert iv["width_x_median_m"] == pytest.approx(0.04)
    assert iv["width_y_p95_m"] == pytest.approx(0.04)
    assert iv["width_theta_median_deg"] == pytest.approx(math.degrees(0.2))
    assert iv["rmse_xy_m"] == pytest.approx(0.01)
    assert iv["cpu_us_per_frame"] == pytest.approx(100.0)
    mcl = rows["mcl"]
    # MCL never says lost: every frame counts
    assert mcl["vouched_pct"] == 100.0 and mcl["containment_pct"] == 50.0
    assert mcl["rejected_frames"] is None and mcl["lost_frames"] is None
    table = ev.markdown_table(ev.aggregate([_hand_made()]))
    # percentages are rounded down: 2/3 reads 66.66, never more than what was measured
    # one false vouch: the rejected frame 1 vouched for a set without the truth
    assert iv["false_vouches"] == 1 and mcl["false_vouches"] is None
    assert "| clean | interval (autonomous) | 75.00 | 75.00 | 66.66 | 1 | 4.00 / 4.00 |" in table
    lines = ev.figures(ev.aggregate([_hand_made()]))
    assert "No scenario" in lines[0]  # one frame broke its bounds
    # no scenario had its inputs in bounds (0 / 0 there); one false vouch over all
    assert "false vouches" in lines[1] and "0 / 0 on the scenarios" in lines[1]
    assert "1 / 1 on all" in lines[1]
    assert "1.0x" in lines[2] and "target" not in " ".join(lines)  # no internal targets printed


@pytest.mark.parametrize(
    "scenario, kind",
    [("slip", "slip"), ("kidnap", "kidnap"), ("outliers", None), ("dropout", "dropout"),
     ("far-views", "far_view")],
)
def test_fault_scenarios_inject_their_faults(scenario, kind):
    res = ev.run_one(ev.Task(scenario, 0, 1, 3.0, particles=100))
    n = res.t.size
    assert n == 60
    assert res.fault.any()
    faulty = np.flatnonzero(res.fault)
    if scenario == "slip":
        # 2 s (40 frames) from 1/3 of the run; the odometry of those steps breaks its bound
        assert faulty[0] == 20 and faulty.size == 40
        assert not res.in_bounds[21:60].all()
        assert res.in_bounds[:21].all()
    elif scenario == "kidnap":
        assert faulty.tolist() == [30]
        assert not res.in_bounds[30] and res.in_bounds[:30].all()
        # the set before the teleport no longer holds the truth; the method notices
        st = res.methods["interval"].status
        assert (st[30:] == ev.STATUS_CODES["rejected"]).any()
    elif scenario == "outliers":
        # two frames every second from 0.15 s
        assert faulty.tolist() == [3, 4, 23, 24, 43, 44]
    elif scenario == "far-views":
        # one lying view every second from 0.15 s: a floor view of elsewhere, which vision accepts
        # and the localizer refuses (its set does not fit it)
        assert faulty.tolist() == [3, 23, 43]
        # (vision may refuse one of these random views on its own: the others must be refused
        # by the localizer)
        lying = faulty[res.accepted[faulty]]
        assert lying.size >= 2 and not res.in_bounds[lying].any()
        assert res.in_bounds[res.fault == 0].all()
        assert (res.methods["interval"].status[lying] == ev.STATUS_CODES["rejected"]).all()
    else:
        assert faulty[0] == 20
        assert not res.accepted[20:40].any()
        assert res.in_bounds.all()
        assert res.methods["interval"].inside.all()


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--runs", "0"], "--runs"),
        (["--runs", "two"], "--runs"),
        (["--jobs", "0"], "--jobs"),
        (["--duration", "-1"], "--duration"),
        (["--duration", "nan"], "--duration"),
        (["--duration", "1e9"], "--duration"),
        (["--scenarios", "clean,bogus"], "bogus"),
        (["--scenarios", ","], "--scenarios"),
        (["--scenarios", "clean,clean"], "twice"),
        (["--particles", "0"], "--particles"),
        (["--mcl-inject", "2"], "--mcl-inject"),
        (["--mcl-sigma-scale", "0"], "--mcl-sigma-scale"),
        (["--seed", "-3"], "--seed"),
        (["--fault-model", "0.2"], "--fault-model"),
        (["--fault-model", "0.2,-1"], "--fault-model"),
        (["--frobnicate"], "unrecognized"),
    ],
)
def test_bad_options_give_one_line_errors(argv, needle, tmp_path, capsys):
    try:
        code = ev.main("evaluate", [*argv, "--out", str(tmp_path / "o"), "--quiet"])
    except SystemExit as e:
        code = e.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_out_that_is_a_file_is_refused(tmp_path, capsys):
    f = tmp_path / "file.txt"
    f.write_text("keep me")
    code = ev.main("evaluate", ["--out", str(f), "--quiet", "--duration", "0.1"])
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a folder" in err
    assert f.read_text() == "keep me"


# --------------------------------------------------------------------------------- fault events


def test_fault_events_are_runs_of_faulty_frames():
    faulty = np.zeros(12, bool)
    faulty[[2, 3, 4, 7, 11]] = True
    assert ev.fault_events(faulty) == [(2, 4), (7, 7), (11, 11)]
    assert ev.fault_events(np.zeros(5, bool)) == []


def test_event_outcomes_definitions():
    n = 20
    faulty = np.zeros(n, bool)
    faulty[[3, 4, 12]] = True  # events (3, 4) and (12, 12)
    alarm = np.zeros(n, bool)
    alarm[5] = True  # 2 frames after the first event's start
    alarm[15] = True  # the second event's only alarm
    vouched = np.ones(n, bool)
    vouched[16:] = False  # lost from frame 16 on
    inside = np.ones(n, bool)
    inside[4:7] = False  # back at frame 7: 3 frames after the first event's end
    inside[12:] = False
    in_bounds = np.ones(n, bool)
    in_bounds[13] = False  # the frame after the second event (its odometry is used there)
    first, second = ev.event_outcomes(faulty, alarm, vouched, inside, in_bounds)
    assert (first.start, first.end, first.detection, first.recovery) == (3, 4, 2, 3)
    assert first.harmless
    # the second event: noticed 3 frames on, never back (lost, the truth outside)
    assert (second.start, second.end, second.detection, second.recovery) == (12, 12, 3, None)
    assert not second.harmless
    # an alarm only after the next event started belongs to that event
    alarm[5] = False
    first, _ = ev.event_outcomes(faulty, alarm, vouched, inside, in_bounds)
    assert first.detection is None


def test_noticed():
    assert ev.noticed("contracted", False, True) is False
    assert ev.noticed("predicted", False, False)  # vision refused the frame
    assert ev.noticed("rejected", False, True) and ev.noticed("lost", False, True)
    assert ev.noticed("contracted", True, True)  # the compass missed the set


def _row(rows, method):
    return next(r for r in rows if r["method"] == method)


def test_dropout_is_detected_at_once_and_recovered_the_frame_after():
    # 9 s = 180 frames: black frames 60..99 and 120..159
    res = ev.run_one(ev.Task("dropout", 0, 2, 9.0, particles=100))
    assert ev.fault_events(res.fault) == [(60, 99), (120, 159)]
    rows = ev.aggregate([res])
    for m in ("interval", "interval-recovery"):
        r = _row(rows, m)
        assert r["fault_events"] == 2
        assert (r["detection_median_frames"], r["detection_max_frames"]) == (0.0, 0)
        assert (r["recovery_median_frames"], r["recovery_max_frames"]) == (1.0, 1)
        assert r["undetected_events"] == 0 and r["unrecovered_events"] == 0
        assert r["false_vouches"] == 0
    # the references have no detection or recovery to measure (truth mode restarts from the
    # truth, odometry mode uses no view, MCL has no status)
    for m in ("interval-truth", "odometry", "mcl"):
        assert _row(rows, m)["fault_events"] is None
    table = ev.markdown_table(rows)
    line = next(t for t in table.splitlines() if "| interval (autonomous) |" in t)
    assert " | 0 / 0 | 0 of 2 | 1 / 1 | 0 of 2 | " in line


def test_kidnap_is_detected_at_once_and_never_recovered():
    # 4 s = 80 frames, the teleport (beyond max_slip) at frame 40
    res = ev.run_one(ev.Task("kidnap", 0, 1, 4.0, particles=100))
    rows = ev.aggregate([res])
    for m in ("interval", "interval-recovery"):
        r = _row(rows, m)
        assert r["fault_events"] == 1
        assert r["detection_max_frames"] == 0
        assert r["unrecovered_events"] == 1 and math.isnan(r["recovery_median_frames"])
        # rejected frames vouch for the stale set until max_rejections (20) make it lost
        tr = res.methods[m]
        assert (tr.status[60:] == ev.STATUS_CODES["lost"]).all()
        assert r["false_vouches"] == int(((tr.status != ev.STATUS_CODES["lost"])
                                          & ~tr.inside).sum()) > 0
    table = ev.markdown_table(rows)
    line = next(t for t in table.splitlines() if "| interval (autonomous) |" in t)
    assert " | 0 / 0 | 0 of 1 | — | 1 of 1 | " in line


def test_slip_is_recovered_with_recovery_on_only():
    # 6 s = 120 frames, slip on frames 40..79 (beyond the odometry bound); no fault model
    # (evaluate --fault-model 0,0)
    res = ev.run_one(ev.Task("slip", 0, 1, 6.0, particles=100, fault_model=(0.0, 0.0)))
    assert ev.fault_events(res.fault) == [(40, 79)]
    rows = ev.aggregate([res])
    off, on = _row(rows, "interval"), _row(rows, "interval-recovery")
    # the slip goes unnoticed for a few frames, with either setting
    assert 1 <= off["detection_max_frames"] == on["detection_max_frames"] <= 10
    assert off["unrecovered_events"] == 1 and off["lost_frames"] > 0
    assert on["unrecovered_events"] == 0 and on["lost_frames"] == 0
    assert on["recovery_max_frames"] >= 1
    # recovery on vouches wrongly only while the slip is unnoticed; off until it is lost
    assert 0 < on["false_vouches"] < off["false_vouches"]


def test_with_the_default_fault_model_the_autonomous_localizer_tracks_the_slip():
    """``evaluate`` with its default fault model (``--fault-model``): the same slip is noticed
    and followed, never lost, and the wrong vouched frames are only the unnoticed first ones."""
    res = ev.run_one(ev.Task("slip", 0, 1, 6.0, particles=100))
    off = ev.run_one(ev.Task("slip", 0, 1, 6.0, particles=100, fault_model=(0.0, 0.0)))
    model = _row(ev.aggregate([res]), "interval")
    plain = _row(ev.aggregate([off]), "interval")
    assert model["unrecovered_events"] == 0 and model["lost_frames"] == 0
    assert 1 <= model["detection_max_frames"] <= 10
    assert model["false_vouches"] < plain["false_vouches"]
    assert model["false_vouches"] <= 10


def test_clean_scenario_has_no_fault_figures():
    res = ev.run_one(ev.Task("clean", 0, 1, 1.0, particles=100))
    rows = ev.aggregate([res])
    for r in rows:
        for col in ev.FAULT_COLUMNS:
            assert r[col] is None
        if r["method"] not in ev.MCL_METHODS:
            assert r["false_vouches"] == 0
    table = ev.markdown_table(rows)
    line = next(t for t in table.splitlines() if "| interval (autonomous) |" in t)
    assert " | — | — | — | — | " in line
