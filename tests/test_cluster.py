"""Evaluation campaigns on Dask (``--scheduler``), the run store and ``--resume``.

Local Dask clusters of worker processes; no timing assertion: every wait is for a condition, with
a generous bound for a loaded machine."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import tileviz.evaluation as ev
from tileviz.evaluation import cluster
from tileviz.evaluation.store import RUN_COLUMNS, RunStore

distributed = pytest.importorskip("distributed")

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[1]


def _rows(path: Path, drop: tuple[str, ...] = ("cpu_us_per_frame",)) -> list[dict]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for c in drop:
            r.pop(c, None)
    return rows


def _wait(cond, what: str, limit: float = 240.0) -> None:
    end = time.monotonic() + limit
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"gave up waiting for {what}")
        time.sleep(0.2)


def _cli(argv: list[str]) -> int:
    return ev.main("evaluate", argv)


def test_local_cluster_gives_the_same_tables_as_one_process(tmp_path, capsys):
    common = ["--runs", "2", "--duration", "1.5", "--scenarios", "clean,dropout", "--quiet",
              "--particles", "200"]
    assert _cli([*common, "--jobs", "1", "--out", str(tmp_path / "one")]) == 0
    assert _cli([*common, "--scheduler", "local:2", "--out", str(tmp_path / "dask")]) == 0
    for name in ("results.csv", "runs.csv", "calibration.csv"):
        one, dask = _rows(tmp_path / "one" / name), _rows(tmp_path / "dask" / name)
        assert one == dask, name
    assert len(_rows(tmp_path / "dask" / "runs.csv")) == 4 * len(ev.METHODS)


def test_a_killed_worker_has_its_runs_made_elsewhere_and_every_run_kept_once(tmp_path):
    """Kill a worker making a run, from the first result's callback: the scheduler gives that run
    to a worker again (the nanny starts a fresh one), as any finished result the worker still
    held and the campaign had not read yet. Meanwhile this process's own Dask client (``spy``)
    is the current one, as in a notebook: the campaign must wait on its own client's event loop
    (it raised "bound to a different event loop" when a lost result was awaited again). Every
    run is kept once."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=40) as lc, \
            distributed.Client(lc) as spy:
        pids = spy.run(os.getpid)
        store = RunStore.open(tmp_path, {"k": 1}, resume=False)
        victim: dict = {}

        def on_result(res: ev.RunResult) -> None:
            store.add(res)
            if victim:
                return

            def busy() -> dict:
                return {w: ks for w, ks in spy.processing().items() if ks}

            _wait(lambda: busy(), "a worker busy with a run")
            worker, keys = next(iter(busy().items()))
            victim.update(worker=worker, keys=list(keys))
            os.kill(pids[worker], signal.SIGKILL)

        made = ev.evaluate(["clean"], runs=6, duration=3.0, particles=200, progress=False,
                           scheduler=lc.scheduler_address, on_result=on_result)
        assert victim["keys"]
    assert sorted((r.scenario, r.run) for r in made) == [("clean", r) for r in range(6)]
    # every run once in the store's runs.csv, whatever the retries
    rows = _rows(tmp_path / "runs.csv")
    assert sorted({int(r["run"]) for r in rows}) == list(range(6))
    assert len(rows) == 6 * len(ev.METHODS)


def test_unreachable_scheduler_is_one_line_with_its_address(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 2.0)
    rc = _cli(["--runs", "1", "--duration", "1", "--scenarios", "clean", "--quiet",
               "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in err


@pytest.mark.parametrize("text", ["local:0", "local:x", "nowhere", "tcp://host:port"])
def test_bad_scheduler_option_is_one_line(text, tmp_path, capsys):
    rc = _cli(["--scenarios", "clean", "--scheduler", text, "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "--scheduler" in err


@pytest.mark.parametrize(("preload", "message"), [
    ("import sys\nsys.modules['tileviz'] = None\n", "cannot import tileviz"),
    ("import tileviz\ntileviz.__version__ = '0.0.0-other'\n", "runs tileviz 0.0.0-other"),
])
def test_workers_without_this_tileviz_are_refused_in_one_line(preload, message, tmp_path,
                                                              capsys):
    script = tmp_path / "preload_tileviz.py"
    script.write_text(preload)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=40,
                                  preload=[str(script)]) as lc:
        rc = _cli(["--runs", "1", "--duration", "1", "--scenarios", "clean", "--quiet",
                   "--scheduler", lc.scheduler_address, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1
    assert message in err and lc.scheduler_address in err


@pytest.mark.parametrize("where", [["--scheduler", "local:2"], ["--jobs", "2"]])
def test_ctrl_c_keeps_the_finished_runs_and_resume_completes_them(where, tmp_path):
    """Ctrl-C a campaign (local cluster, process pool) once a run is kept: exit 130 with one line,
    the kept rows intact; then --resume makes only the others, and the tables equal a campaign
    made in one go."""
    out = tmp_path / "c"
    args = ["--runs", "4", "--duration", "2.5", "--scenarios", "clean", "--quiet",
            "--particles", "200"]
    proc = subprocess.Popen([sys.executable, "-m", "tileviz", "evaluate", *args, *where,
                             "--out", str(out)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True,
                            # as at a terminal, even when these tests run as a background job
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        runs_csv = out / "runs.csv"
        _wait(lambda: runs_csv.exists() and len(_rows(runs_csv)) >= len(ev.METHODS)
              or proc.poll() is not None, "a first finished run")
        assert proc.poll() is None, proc.communicate()
        # Ctrl-C at a terminal reaches the whole process group
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    assert "interrupted" in err and f"--resume {out}" in err
    assert len(err.strip().splitlines()) == 1, err
    kept = _rows(runs_csv)
    assert len(kept) % len(ev.METHODS) == 0
    done = {int(r["run"]) for r in kept}
    assert len(kept) == len(done) * len(ev.METHODS) and len(done) >= 1

    res = subprocess.run([sys.executable, "-m", "tileviz", "evaluate", *args, "--jobs", "2",
                          "--resume", str(out)], cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    assert res.returncode == 0, res.stderr
    assert f"resuming: {len(done)} of 4 runs" in res.stdout
    assert len(_rows(out / "runs.csv")) == 4 * len(ev.METHODS)
    if where[0] == "--jobs":
        return  # (a resumed campaign's tables do not depend on the backend: checked once)
    assert _cli([*args, "--jobs", "1", "--out", str(tmp_path / "fresh")]) == 0
    for name in ("results.csv", "runs.csv", "calibration.csv"):
        assert _rows(out / name) == _rows(tmp_path / "fresh" / name), name


def _result(run: int) -> ev.RunResult:
    return ev.run_one(ev.Task("clean", run, run, 0.2, particles=50))


def test_store_keeps_a_run_once_and_resumes_only_with_the_same_settings(tmp_path):
    store = RunStore.open(tmp_path, {"duration": 0.2}, resume=False)
    res = _result(0)
    assert store.add(res) is True
    assert store.add(res) is False
    assert len(_rows(tmp_path / "runs.csv")) == len(ev.METHODS)
    again = RunStore.open(tmp_path, {"duration": 0.2}, resume=True)
    assert again.done == {("clean", 0, 0)}
    back = again.results()
    assert len(back) == 1 and (back[0].truth == res.truth).all()
    with pytest.raises(ValueError, match="duration was 0.2 there, now 0.5"):
        RunStore.open(tmp_path, {"duration": 0.5}, resume=True)
    (tmp_path / "runs" / "clean-r0-s0.pkl").unlink()
    with pytest.raises(ValueError, match="its results file .* is missing"):
        RunStore.open(tmp_path, {"duration": 0.2}, resume=True)
    with pytest.raises(ValueError, match="no runs.csv there"):
        RunStore.open(tmp_path / "empty", {"duration": 0.2}, resume=True)
    # a fresh campaign in the same folder starts empty
    fresh = RunStore.open(tmp_path, {"duration": 0.2}, resume=False)
    assert fresh.done == set()
    assert (tmp_path / "runs.csv").read_text().strip() == ",".join(RUN_COLUMNS)


def test_resume_with_other_settings_is_one_line(tmp_path, capsys):
    args = ["--runs", "1", "--duration", "0.5", "--scenarios", "clean", "--quiet", "--jobs", "1"]
    assert _cli([*args, "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    assert _cli([*args[:3], "1.0", *args[4:], "--resume", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "duration was 0.5 there, now 1.0" in err
