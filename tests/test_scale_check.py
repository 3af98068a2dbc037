"""A dataset whose declared scale (tile_size x ppm) is off: replay says so.

The views' bounds assume ``ppm`` and ``tile_size`` exact; views with two lines of a family in
view measure the tile period, and the run's summary warns when they disagree with the declared
one (``tileviz.summary.RunTally.scale_warning``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tileviz.__main__ import main as tileviz_main
from tileviz.summary import RunTally


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("scale") / "ds"
    assert tileviz_main(["record", str(folder), "--duration", "2", "--quiet", "--seed", "3"]) == 0
    return folder


@pytest.mark.parametrize(("factor", "words"), [(1.0, None), (1.02, "2.0 % closer together"),
                                                (0.99, "1.0 % farther apart")])
def test_replay_warns_when_the_lines_disagree_with_the_declared_scale(
        recorded: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], factor: float,
        words: str | None) -> None:
    meta = json.loads((recorded / "meta.json").read_text())
    meta["ppm"] *= factor
    (recorded / "meta.json").write_text(json.dumps(meta))
    try:
        capsys.readouterr()
        assert tileviz_main(["replay", str(recorded), "--out", str(tmp_path / "out.csv"),
                             "--quiet", "--jobs", "1"]) == 0
    finally:
        meta["ppm"] /= factor
        (recorded / "meta.json").write_text(json.dumps(meta))
    out = capsys.readouterr().out
    if words is None:
        assert "WARNING" not in out, out
    else:
        assert "WARNING: the grout lines of" in out and words in out, out
        assert "check the camera's ppm and the tile size" in out


class _Vision:
    def __init__(self, ratio: float | None) -> None:
        self.details = {} if ratio is None else {"period_ratio": ratio}


class _Rec:
    status = "tracking"

    def __init__(self, ratio: float | None) -> None:
        self.vision = _Vision(ratio)

    @property
    def updated(self) -> object:
        from tileviz.types import BoxSet

        return BoxSet()

    def truth_inside(self) -> bool | None:
        return None


def test_the_warning_needs_enough_views_and_a_clear_difference() -> None:
    tally = RunTally()
    for _ in range(4):
        tally.add(_Rec(1.02))
    assert tally.scale_warning() == ""  # four views: not yet
    tally.add(_Rec(None))  # a view with one line per family measures nothing
    assert tally.scale_warning() == ""
    tally.add(_Rec(1.02))
    assert "2.0 % farther apart" in tally.scale_warning()
    quiet = RunTally()
    for r in (1.002, 0.999, 1.001, 1.0, 0.998, 1.0025):
        quiet.add(_Rec(r))
    assert quiet.scale_warning() == ""


class _RefusedVision:
    accepted = False
    extractor = "robust"

    def __init__(self, reason: str, check: str | None) -> None:
        from tileviz.vision.decision import CheckResult, Decision

        self.reason = reason
        self.details: dict[str, float] = {}
        self.decision = None if check is None else Decision(
            (), (), None, reason, CheckResult(check, 2.0, 1.0, "<=", False), 0)


def test_the_summary_counts_the_views_refused_by_the_check_that_refused_them() -> None:
    """A run whose views were refused says how many, by which checks (most frequent first),
    and where to look; a run with none refused says nothing of it."""
    tally = RunTally()
    for reason, check, n in (("foreign line", "foreign_line.contrast", 3),
                             ("low contrast", "contrast.depth", 2),
                             ("no lines", None, 1), ("glare", "glare.patches", 1)):
        for _ in range(n):
            rec = _Rec(None)
            rec.vision = _RefusedVision(reason, check)  # type: ignore[assignment]
            tally.add(rec)
    tally.add(_Rec(1.0))
    part = next(p for p in tally.parts() if p.startswith("views refused"))
    assert part == ("views refused: 7 (foreign_line.contrast 3, contrast.depth 2, no lines 1, "
                    "...: extract IMAGE --explain says why)")
    assert "; " not in part  # the summary's parts are joined with "; "
    clean = RunTally()
    clean.add(_Rec(1.0))
    assert not any(p.startswith("views refused") for p in clean.parts())
