"""The floor a user declares (``floor`` block: kind and lattice tolerance): the robust
extractor's checks and bound take the tolerance, a sharper camera reads at least as many views,
faint coloured grout is read through a colour projection, ``survey`` measures the tolerance, and
a bad block or option is one line."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tileviz.__main__ import main as tileviz
from tileviz.config import PERFECT_FLOOR, Config, FloorModel, preset, with_floor_style
from tileviz.datasets import DatasetError, DatasetMeta
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision import extract, observation_error, to_gray
from tileviz.vision.robust import extract_robust


def _read(style: str, n: int, *, scale: float = 1.0, declare: bool = True,
          seed: int = 11) -> tuple[int, int]:
    """(accepted, accepted outside their own bound of the ideal lattice) over ``n`` views of
    the floor style ``style`` through the default camera scaled by ``scale`` (ppm and size)."""
    cfg = with_floor_style(preset("default"), style)
    cam = replace(cfg.camera, ppm=cfg.camera.ppm * scale, width=round(320 * scale),
                  height=round(240 * scale))
    r = FloorRenderer(cfg.floor, cam)
    rng = np.random.default_rng(seed)
    model = cfg.floor.model if declare else PERFECT_FLOOR
    accepted = outside = 0
    for _ in range(n):
        pose = Pose(*rng.uniform(-9, 9, 2), rng.uniform(-4, 4))
        res = extract(r.render(pose, rng), camera=cam, tile_size=1.0, vision=cfg.vision,
                      floor=model)
        if res.accepted:
            accepted += 1
            e = observation_error(res.observation, pose, 1.0, cam.offset)
            outside += (max(abs(e[0]), abs(e[1])) > res.observation.position_error
                        or abs(e[2]) > res.observation.heading_error)
    return accepted, outside


def test_panels_laid_off_the_lattice_break_an_undeclared_bound_and_keep_a_declared_one() -> None:
    """A mosaic whose panels lie up to 8 mm off the lattice: read as a perfect lattice, views
    are accepted outside their bound; declared with its tolerance, none is."""
    acc0, out0 = _read("mosaic", 14)
    assert acc0 >= 3 and out0 == 0
    _, out_undeclared = _read("mosaic", 14, declare=False)
    assert out_undeclared >= 1


def test_a_sharper_camera_reads_at_least_as_many_views_of_a_hand_laid_floor() -> None:
    acc1, out1 = _read("hand_laid", 10)
    acc16, out16 = _read("hand_laid", 10, scale=1.6)
    assert out1 == out16 == 0
    assert acc16 >= acc1 >= 8


def test_the_declared_tolerance_is_in_the_view_bound() -> None:
    """The same view declared with a tolerance of 4 mm: a larger bound, of at least 4 mm (a
    floor whose every line lies 4 mm off the lattice moves the view that far), and a tolerance
    of 0 is the perfect lattice."""
    cfg = preset("default")
    img = FloorRenderer(cfg.floor, cfg.camera).render(Pose(0.3, 0.2, 0.25))
    base = extract(img, camera=cfg.camera, tile_size=1.0, vision=cfg.vision)
    zero = extract(img, camera=cfg.camera, tile_size=1.0, vision=cfg.vision,
                   floor=FloorModel("grout", 0.0))
    wide = extract(img, camera=cfg.camera, tile_size=1.0, vision=cfg.vision,
                   floor=FloorModel("grout", 0.004))
    assert base.observation == zero.observation
    assert wide.observation is not None and base.observation is not None
    assert wide.observation.position_error >= 0.004
    assert wide.observation.position_error > base.observation.position_error
    assert wide.observation.heading_error > base.observation.heading_error


def test_faint_coloured_grout_is_read_through_a_colour_projection() -> None:
    """Reddish grout on brown tiles, nearly as light: the luma shows no grout, one colour
    projection does, and the views it gives are within their bound."""
    cfg = with_floor_style(preset("default"), "faint_colour")
    r = FloorRenderer(cfg.floor, cfg.camera)
    rng = np.random.default_rng(3)
    projected = 0
    for _ in range(8):
        pose = Pose(*rng.uniform(-9, 9, 2), rng.uniform(-4, 4))
        img = r.render(pose, rng)
        res = extract(img, camera=cfg.camera, tile_size=1.0, vision=cfg.vision)
        luma = extract_robust(to_gray(img), camera=cfg.camera, tile_size=1.0, vision=cfg.vision)
        assert not luma.accepted  # the luma alone
        if res.accepted:
            assert res.details["projection"] >= 1  # a colour projection
            projected += 1
            e = observation_error(res.observation, pose, 1.0, cfg.camera.offset)
            assert max(abs(e[0]), abs(e[1])) <= res.observation.position_error
    assert projected >= 3


def _meta(**floor: object) -> dict:
    d = DatasetMeta.from_config(Config()).to_json()
    d["floor"] = floor
    return d


def test_the_floor_block_round_trips_and_reaches_the_replay_config() -> None:
    m = DatasetMeta.from_json(_meta(kind="grout", lattice_tolerance=0.004))
    assert m.floor == FloorModel("grout", 0.004)
    again = DatasetMeta.from_json(m.to_json())
    assert again.floor == m.floor
    assert again.to_config().floor.model == FloorModel("grout", 0.004)
    plain = _meta()
    del plain["floor"]
    assert DatasetMeta.from_json(plain).to_config().floor.model == PERFECT_FLOOR


@pytest.mark.parametrize("floor, says", [
    ({"kind": "parquet"}, "floor.kind must be one of grout, checker"),
    ({"lattice_tolerance": -0.001}, "floor.lattice_tolerance must be a finite number >= 0"),
    ({"lattice_tolerance": "2mm"}, "floor.lattice_tolerance must be a finite number >= 0"),
    ({"lattice_tolerance": 0.3}, "below a quarter of the tile"),
])
def test_a_bad_floor_block_is_one_line_and_nothing_is_written(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], floor: dict, says: str) -> None:
    with pytest.raises(DatasetError, match=says):
        DatasetMeta.from_json(_meta(**floor))
    ds = tmp_path / "ds"
    assert tileviz(["record", str(ds), "--duration", "0.2", "--quiet"]) == 0
    meta = json.loads((ds / "meta.json").read_text())
    meta["floor"] = floor
    (ds / "meta.json").write_text(json.dumps(meta))
    capsys.readouterr()
    out = tmp_path / "boxes.csv"
    assert tileviz(["replay", str(ds), "--out", str(out), "--jobs", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0] and "meta.json" in err[0]
    assert not out.exists()


def test_record_and_extract_take_the_floor_options(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    ds = tmp_path / "ds"
    assert tileviz(["record", str(ds), "--duration", "0.2", "--quiet", "--floor-style",
                    "hand_laid", "--lattice-tolerance", "0.007"]) == 0
    meta = json.loads((ds / "meta.json").read_text())
    assert meta["floor"] == {"kind": "grout", "lattice_tolerance": 0.007}
    plain = tmp_path / "plain"
    assert tileviz(["record", str(plain), "--duration", "0.2", "--quiet"]) == 0
    img = str(sorted((plain / "images").iterdir())[0])
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:  # an option's error: argparse's exit
        tileviz(["extract", img, "--lattice-tolerance", "-1"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--lattice-tolerance" in err[0]
    assert tileviz(["extract", img, "--json", "--lattice-tolerance", "0.007"]) == 0
    wide = json.loads(capsys.readouterr().out)
    assert tileviz(["extract", img, "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert wide["position_error"] > plain["position_error"]


def _recorded(tmp_path: Path, style: str) -> Path:
    """A 3 s recording over the floor style ``style``."""
    ds = tmp_path / style
    assert tileviz(["record", str(ds), "--duration", "3", "--quiet", "--floor-style",
                    style]) == 0
    return ds


def test_survey_measures_a_hand_laid_floor_and_writes_the_floor_block(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ds = _recorded(tmp_path, "hand_laid")
    perfect = _recorded(tmp_path, "default")
    meta = tmp_path / "meta.json"
    capsys.readouterr()
    assert tileviz(["survey", str(ds), "--every", "4", "--meta", str(meta)]) == 0
    out = capsys.readouterr().out
    assert json.loads(meta.read_text())["floor"]["kind"] == "grout"
    tol = json.loads(meta.read_text())["floor"]["lattice_tolerance"]
    assert f"lattice_tolerance to declare: {tol:.4f} m" in out
    assert "the largest departure, " in out and "mm, is frame " in out
    assert tileviz(["survey", str(perfect), "--every", "4"]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-2]
    assert 0.0 <= float(line.split(": ")[1].split()[0]) < tol <= 0.005 + 1e-9


def test_survey_of_unusable_views_is_one_line_and_writes_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import cv2

    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((240, 320, 3), 128, np.uint8))
    meta = tmp_path / "meta.json"
    assert tileviz(["survey", str(blank), "--tile-size", "1", "--ppm", "200",
                    "--meta", str(meta)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "too few usable views: 0 of 1" in err[0]
    assert not meta.exists()
    (tmp_path / "bad.png").write_bytes(b"not a png")
    assert tileviz(["survey", str(tmp_path / "bad.png"), "--tile-size", "1", "--ppm",
                    "200"]) == 2
    assert "not a readable image" in capsys.readouterr().err


def test_survey_with_the_truth_covers_the_edges_of_a_checkerboard_with_a_faint_grout() -> None:
    """A checkerboard whose tile edges carry a grout band nearly as dark as its dark squares:
    a view that sees each line on one side of its crossings reads it along the band's stronger
    edge, half the band off the lattice, and shows it in no residual. Surveyed with the true
    poses, the tolerance covers that half band, and views read with it declared hold the
    truth (the view with seed 19 lay outside its bound with the residuals' tolerance)."""
    from tileviz.config import CameraConfig, VisionConfig
    from tileviz.testing import floorgen
    from tileviz.vision.survey import survey

    spec = floorgen.banded_checker(3, "one")
    assert spec.second is not None
    cam = CameraConfig(ppm=spec.ppm, width=spec.width, height=spec.height, offset=(0.0, 0.0))
    vision = VisionConfig(extractor="robust")

    def views(n: int, stream: int) -> list[tuple[np.ndarray, Pose]]:
        rng = np.random.default_rng([3, 7103, stream])
        out = []
        for _ in range(n):
            cx, cy, th = floorgen.draw_view(rng)
            out.append((floorgen.render(spec, cx, cy, th, rng), Pose(cx, cy, th)))
        return out

    report = survey(views(30, 1), camera=cam, tile_size=spec.tile_size, vision=vision,
                    kind="checker")
    assert report.tolerance >= 0.5 * spec.second[0] / spec.ppm
    floor = FloorModel("checker", report.tolerance)
    accepted = 0
    for image, truth in views(20, 2)[15:]:
        res = extract(image, camera=cam, tile_size=spec.tile_size, vision=vision, floor=floor)
        if res.accepted and res.observation is not None:
            accepted += 1
            e = observation_error(res.observation, truth, spec.tile_size, (0.0, 0.0))
            assert max(abs(e[0]), abs(e[1])) <= res.observation.position_error
            assert abs(e[2]) <= res.observation.heading_error
    assert accepted >= 4


def test_survey_of_a_checkerboard_left_undeclared_recommends_the_kind(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ds = _recorded(tmp_path, "checker")
    meta = tmp_path / "meta.json"
    capsys.readouterr()
    assert tileviz(["survey", str(ds), "--every", "4", "--meta", str(meta)]) == 0
    out = capsys.readouterr().out
    assert "surveyed again as kind checker" in out and "kind: checker (its edge images read)" in out
    # the survey not kept is one line, not a second report
    assert out.count("lattice_tolerance to declare") == 1
    assert "read as grout, a checkerboard recognised: " in out
    assert json.loads(meta.read_text())["floor"]["kind"] == "checker"


def test_survey_reads_a_checkerboard_recognised_on_too_few_views_as_checker(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Images of a checkerboard with a faint grout along one family of edges, few of them
    recognised: the survey, its kind not given, reads them as ``checker`` and says so."""
    import cv2

    from tileviz.testing import floorgen

    spec = floorgen.banded_checker(1, "one")
    rng = np.random.default_rng([1, 7103, 1])
    paths = []
    for k in range(20):
        cx, cy, th = floorgen.draw_view(rng)
        path = tmp_path / f"view{k:02d}.png"
        cv2.imwrite(str(path), floorgen.render(spec, cx, cy, th, rng)[..., ::-1])
        paths.append(str(path))
    meta = tmp_path / "meta.json"
    args = ["survey", *paths, "--tile-size", repr(spec.tile_size), "--ppm", repr(spec.ppm)]
    assert tileviz([*args, "--floor-kind", "grout"]) == 2
    assert "too few usable views" in capsys.readouterr().err
    assert tileviz([*args, "--meta", str(meta)]) == 0
    out = capsys.readouterr().out
    assert "surveyed as kind checker" in out and "no true poses" in out
    assert json.loads(meta.read_text())["floor"]["kind"] == "checker"


def _perfect_views(shift: float, n: int = 8, at: int = 5) -> list[tuple[np.ndarray, Pose]]:
    """``n`` views of the default perfect floor with their true poses, view ``at``'s given
    ``shift`` m off in x."""
    cfg = preset("default")
    r = FloorRenderer(cfg.floor, cfg.camera)
    rng = np.random.default_rng(5)
    views = []
    for k in range(n):
        pose = Pose(*rng.uniform(-9, 9, 2), rng.uniform(-4, 4))
        told = Pose(pose.x + (shift if k == at else 0.0), pose.y, pose.theta)
        views.append((r.render(pose, rng), told))
    return views


def test_survey_names_the_view_that_sets_the_tolerance() -> None:
    """Eight views of a perfect floor, one given a true pose 6 mm off: that view alone sets
    the tolerance, and the report names it beside the next largest view's departure."""
    from tileviz.vision.survey import survey

    report = survey(_perfect_views(0.006), camera=preset("default").camera, tile_size=1.0)
    assert report.accepted == 8 and report.widest == 5 and not report.capped
    assert report.tolerance >= 0.006 > 0.003 > report.next_widest
    text = "\n".join(report.lines())
    assert f"the largest departure, {report.shown * 1e3:.1f} mm, is view 6's" in text
    assert "extract IMAGE --explain" in text


def test_survey_says_when_the_views_showed_more_than_a_quarter_tile() -> None:
    from tileviz.vision.survey import survey

    report = survey(_perfect_views(0.3), camera=preset("default").camera, tile_size=1.0)
    assert report.capped and report.shown >= 0.3 > 0.25 > report.tolerance
    assert any("more than tileviz accepts" in line for line in report.lines())


def test_a_failed_checker_survey_leaves_the_grout_survey_standing(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Most views read as a checkerboard but too few accepted as one: the survey as grout is
    the one recommended, and the reason is given."""
    import tileviz.vision.survey as sv

    views = _perfect_views(0.0)
    grout = sv.survey(views, camera=preset("default").camera, tile_size=1.0)
    made = replace(grout, checker=grout.accepted)  # as if every view read as a checkerboard

    def fake(_views: object, *, kind: str = "grout", **_: object) -> sv.SurveyReport:
        if kind == "checker":
            raise ValueError("too few usable views: 2 of 8 accepted")
        return made

    monkeypatch.setattr(sv, "survey", fake)
    report, said = sv.survey_kind(lambda: views, camera=preset("default").camera,
                                  tile_size=1.0)
    assert report is made and report.kind == "grout"
    assert said and said[0][0] is None and "the survey as grout stands" in said[0][1]


def test_a_run_summary_advises_declaring_a_checkerboard_it_recognised() -> None:
    """Five views read as a checkerboard the floor does not declare (``details["checker"]``):
    the summary says to declare its kind and tolerance; four, or views of a declared one, do
    not."""
    from types import SimpleNamespace

    from tileviz.summary import RunTally
    from tileviz.types import BoxSet

    def record(details: dict[str, float]) -> SimpleNamespace:
        return SimpleNamespace(status="contracted", updated=BoxSet(), truth_inside=lambda: None,
                               vision=SimpleNamespace(extractor="robust", details=details))

    said = "views were read as a checkerboard the floor does not declare"
    tally = RunTally()
    for _ in range(4):
        tally.add(record({"checker": 3.0, "checker_sides": 2.0}))
        tally.add(record({"checker_sides": 2.0}))  # a declared checkerboard's view
    assert not any(said in p for p in tally.parts())
    tally.add(record({"checker": 4.0}))
    assert any(f"5 {said}" in p and "python -m tileviz survey" in p for p in tally.parts())


def test_survey_never_lowers_a_declared_tolerance_and_checks_meta_first(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A meta.json that already declares a larger tolerance than the survey measures keeps it
    (docs/dataset-format.md: never taken smaller), and says so; a smaller one is raised to the
    survey's. A --meta in no folder is one line before any view is read."""
    ds = _recorded(tmp_path, "hand_laid")
    meta = tmp_path / "meta.json"
    meta.write_text(json.dumps({"floor": {"kind": "grout", "lattice_tolerance": 0.02},
                                "note": "kept"}))
    capsys.readouterr()
    assert tileviz(["survey", str(ds), "--every", "4", "--meta", str(meta)]) == 0
    out = capsys.readouterr().out
    doc = json.loads(meta.read_text())
    assert doc["floor"] == {"kind": "grout", "lattice_tolerance": 0.02} and doc["note"] == "kept"
    assert "declared lattice_tolerance 0.0200 m, more than this survey's: kept" in out
    measured = float(out.split("lattice_tolerance to declare: ")[1].split()[0])
    assert 0.0 < measured < 0.02
    meta.write_text(json.dumps({"floor": {"kind": "grout", "lattice_tolerance": 0.0}}))
    assert tileviz(["survey", str(ds), "--every", "4", "--meta", str(meta)]) == 0
    assert "kept" not in capsys.readouterr().out
    assert json.loads(meta.read_text())["floor"]["lattice_tolerance"] == measured
    # a declaration tileviz would refuse (a quarter tile or more) is not kept; another kind is
    # replaced, and said; the block's other keys stay: the file written replays
    from tileviz.datasets.format import floor_block

    meta.write_text(json.dumps({"floor": {"kind": "checker", "lattice_tolerance": 0.3,
                                          "by": "another program"}}))
    assert tileviz(["survey", str(ds), "--every", "4", "--meta", str(meta)]) == 0
    out = capsys.readouterr().out
    assert "kept" not in out and "declared kind checker: replaced by the survey's, grout" in out
    block = json.loads(meta.read_text())["floor"]
    assert block == {"kind": "grout", "lattice_tolerance": measured, "by": "another program"}
    assert floor_block(block, 1.0, "meta.json").lattice_tolerance == measured
    nowhere = tmp_path / "no" / "meta.json"
    assert tileviz(["survey", "missing.png", "--tile-size", "1", "--ppm", "200",
                    "--meta", str(nowhere)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--meta: cannot write" in err[0] and "no folder" in err[0]


def test_survey_every_nth_frame_decodes_only_those(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """A damaged image among the frames ``--every`` skips is never read: the survey of the
    others stands; one among those it reads is a one-line error naming its row."""
    ds = _recorded(tmp_path, "hand_laid")
    (ds / "images" / "000001.png").write_bytes(b"\\x89PNG damaged")
    capsys.readouterr()
    assert tileviz(["survey", str(ds), "--every", "4"]) == 0
    assert "lattice_tolerance to declare: " in capsys.readouterr().out
    assert tileviz(["survey", str(ds), "--every", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "(frame 1)" in err[0]
