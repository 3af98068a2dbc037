"""``python -m tileviz extract``: one line (or JSON object) per image, stage images, and bad
input as one-line errors, never a traceback."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from tileviz.config import preset
from tileviz.core import tiles
from tileviz.sim.camera import FloorRenderer
from tileviz.types import Pose
from tileviz.vision.cli import main

REPO = Path(__file__).resolve().parents[1]
POSE = Pose(0.31, -0.22, 0.4)


def _write(path: Path, rgb: np.ndarray) -> str:
    assert cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    return str(path)


@pytest.fixture(scope="module")
def images(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    d = tmp_path_factory.mktemp("imgs")
    out = {}
    for name in ("default", "seed"):
        cfg = preset(name)
        img = FloorRenderer(cfg.floor, cfg.camera).render(POSE, np.random.default_rng(1))
        out[name] = _write(d / f"{name}.png", img)
    out["constant"] = _write(d / "constant.png", np.full((240, 320, 3), 90, np.uint8))
    (d / "broken.png").write_bytes(b"\x89PNG not really")
    out["broken"] = str(d / "broken.png")
    return out


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main("extract", list(argv))
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def test_one_line_per_image_with_the_design_md_parameters(capsys, images) -> None:
    rc, out, err = _run(capsys, images["default"], images["constant"])
    assert rc == 1 and err == ""  # the constant image gave no observation
    lines = out.strip().splitlines()
    assert len(lines) == 2
    y = tiles.observe(POSE, 1.0, preset("default").camera.offset)
    assert lines[0].startswith(images["default"] + ": y1=")
    got = [float(t.split("=")[1]) for t in lines[0].split() if t[:3] in ("y1=", "y2=", "y3=")]
    assert got == pytest.approx(list(y), abs=0.005)
    assert lines[1] == f"{images['constant']}: no observation (constant image); 0 lines"


@pytest.mark.parametrize("extractor", ["faithful", "robust"])
def test_json_objects(capsys, images, extractor: str) -> None:
    rc, out, _ = _run(capsys, "--json", "--preset", "seed", "--extractor", extractor,
                      images["seed"])
    assert rc == 0
    obj = json.loads(out)
    assert {"image", "y1", "y2", "y3", "accepted", "reason", "lines"} <= set(obj)
    assert obj["accepted"] is True and obj["reason"] == "ok" and obj["lines"] >= 2
    assert obj["extractor"] == extractor
    y = tiles.observe(POSE, 0.166, preset("seed").camera.offset)
    assert (obj["y1"], obj["y2"], obj["y3"]) == pytest.approx(y, abs=0.004)


def test_ppm_and_tile_size_options(capsys, images) -> None:
    """A wrong tile size changes the verdict; the right one is accepted."""
    rc, out, _ = _run(capsys, "--json", "--ppm", "200", "--tile-size", "1", images["default"])
    assert json.loads(out)["accepted"] is True
    rc, out, _ = _run(capsys, "--json", "--tile-size", "0.37", images["default"])
    obj = json.loads(out)
    assert obj["accepted"] is False and obj["y1"] is None


def test_stages_are_written(capsys, images, tmp_path: Path) -> None:
    out_dir = tmp_path / "stages"
    rc, _, _ = _run(capsys, "--stages", str(out_dir), "--extractor", "faithful",
                    images["default"])
    assert rc == 0
    names = sorted(p.name for p in out_dir.iterdir())
    assert "default_00_input.png" in names and "default_02_laplacian.png" in names
    assert len(names) == 10
    img = cv2.imread(str(out_dir / "default_03_canny.png"))
    assert img.shape == (240, 320, 3)


def test_bad_images_are_one_line_errors_and_the_rest_still_runs(capsys, images) -> None:
    rc, out, err = _run(capsys, images["broken"], "/no/such/file.png", images["default"])
    assert rc == 2
    assert out.count("\n") == 1 and "y1=" in out
    errs = err.strip().splitlines()
    assert errs == [
        f"tileviz extract: error: {images['broken']}: cannot read it as an image",
        "tileviz extract: error: /no/such/file.png: no such file",
    ]


def test_wrong_size_for_a_preset(capsys, images) -> None:
    rc, out, err = _run(capsys, "--preset", "seed", images["default"])
    assert rc == 2 and out == ""
    assert err.strip() == (f"tileviz extract: error: {images['default']}: image is 320x240 but "
                           "preset 'seed' expects 256x384")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--ppm", "0", "x.png"], "--ppm must be a finite number > 0"),
        (["--ppm", "-2", "x.png"], "--ppm must be a finite number > 0"),
        (["--tile-size", "nan", "x.png"], "--tile-size must be a finite number > 0"),
        (["--tile-size", "abc", "x.png"], "--tile-size must be a number"),
        (["--extractor", "magic", "x.png"], "invalid choice"),
        ([], "the following arguments are required: IMAGE"),
    ],
)
def test_bad_options(capsys, argv: list[str], message: str) -> None:
    with pytest.raises(SystemExit) as e:
        main("extract", argv)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_module_entry_point_never_tracebacks(images, tmp_path: Path) -> None:
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    proc = subprocess.run(
        [sys.executable, "-m", "tileviz", "extract", "--json", str(empty), images["seed"]],
        capture_output=True, text=True, cwd=REPO, timeout=600,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1
    obj = json.loads(proc.stdout)  # the seed image, read with the default camera settings
    assert obj["image"] == images["seed"]
    assert math.isfinite(obj["lines"])


def test_exit_status_says_whether_an_observation_was_found(images) -> None:
    """0: every image gave an observation; 1: one gave none (a result, stderr empty); 2: bad
    input wins, one line on stderr. --help says so."""

    def run(*argv: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "tileviz", "extract", *argv],
                              capture_output=True, text=True, cwd=REPO, timeout=600)

    found = run(images["default"])
    assert found.returncode == 0 and found.stderr == "" and "y1=" in found.stdout
    none = run(images["constant"])
    assert none.returncode == 1 and none.stderr == ""
    assert none.stdout.strip() == f"{images['constant']}: no observation (constant image); 0 lines"
    assert run(images["default"], images["constant"]).returncode == 1
    bad = run(images["constant"], images["broken"])
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert "exit status: 0 when every image gave an observation, 1 when an image gave none" \
        in " ".join(run("--help").stdout.split())


def test_damaged_odd_and_misplaced_files_each_give_one_line(images, tmp_path: Path) -> None:
    """A cut-off PNG, a float TIFF, a directory and a 16-bit PNG holding 12-bit data: one line
    each on stderr naming the file and the problem (no decoder chatter), the good image still
    read."""
    whole = Path(images["default"]).read_bytes()
    cut = tmp_path / "cut.png"
    cut.write_bytes(whole[: len(whole) // 2])
    tiff = tmp_path / "float.tiff"
    ok, buf = cv2.imencode(".tiff", np.random.default_rng(0).random((24, 32, 3), np.float32))
    assert ok
    tiff.write_bytes(buf.tobytes())
    folder = tmp_path / "adir"
    folder.mkdir()
    gray = cv2.imread(images["default"], cv2.IMREAD_GRAYSCALE)
    twelve = tmp_path / "twelve.png"
    assert cv2.imwrite(str(twelve), gray.astype(np.uint16) * 16)  # 12-bit data, unscaled
    proc = subprocess.run(
        [sys.executable, "-m", "tileviz", "extract", str(cut), str(tiff), str(folder),
         str(twelve), images["default"]],
        capture_output=True, text=True, cwd=REPO, timeout=600,
    )
    assert proc.returncode == 2
    assert proc.stdout.count("\n") == 1 and "y1=" in proc.stdout
    assert proc.stderr.strip().splitlines() == [
        f"tileviz extract: error: {cut}: is truncated (no end marker)",
        f"tileviz extract: error: {tiff}: cannot read it as an image",
        f"tileviz extract: error: {folder}: is a directory, not an image",
        f"tileviz extract: error: {twelve}: 16-bit samples reach only {int(gray.max()) * 16} "
        f"of 65535 (data in the low bits?): its 8-bit view would keep "
        f"{int(gray.max()) * 16 // 256 + 1} gray level(s); scale it to the full 16-bit range "
        "or save it as 8-bit",
    ]


def test_a_full_range_16_bit_png_is_read_as_its_8_bit_view(capsys, images,
                                                          tmp_path: Path) -> None:
    bgr = cv2.imread(images["default"], cv2.IMREAD_COLOR)
    deep = tmp_path / "deep.png"
    assert cv2.imwrite(str(deep), bgr.astype(np.uint16) * 257)
    rc, out, err = _run(capsys, "--json", images["default"], str(deep))
    assert rc == 0 and err == ""
    a, b = (json.loads(line) for line in out.splitlines())
    assert b["accepted"] and (b["y1"], b["y2"], b["y3"]) == (a["y1"], a["y2"], a["y3"])


def test_stage_images_of_two_files_with_one_stem_are_both_kept(capsys, images,
                                                               tmp_path: Path) -> None:
    other = tmp_path / "elsewhere"
    other.mkdir()
    twin = other / Path(images["default"]).name
    twin.write_bytes(Path(images["default"]).read_bytes())
    out_dir = tmp_path / "stages"
    rc, _, _ = _run(capsys, "--stages", str(out_dir), "--extractor", "faithful",
                    images["default"], str(twin))
    assert rc == 0
    names = {p.name for p in out_dir.iterdir()}
    assert len(names) == 20
    assert {"default_00_input.png", "default-2_00_input.png"} <= names


@pytest.fixture(scope="module")
def cable_view(tmp_path_factory: pytest.TempPathFactory) -> str:
    """A rendered default-preset view with a dark cable across it (refused: foreign line)."""
    from tileviz.sim.camera import Fault

    cfg = preset("default")
    img = FloorRenderer(cfg.floor, cfg.camera).render(
        POSE, np.random.default_rng(1),
        faults=[Fault("cable", {"angle": 1.0, "offset": 10.0, "width": 4.0})])
    return _write(tmp_path_factory.mktemp("cable") / "cable.png", img)


def _rows(out: str) -> list[list[str]]:
    """The check rows of an --explain table: [id (and subject), value, relation, limit,
    result ("pass", "fail" or "refused")], without the column saying what the value is."""
    rows = []
    for line in out.splitlines():
        parts = line.split()
        at = next((i for i, p in enumerate(parts) if p in ("pass", "fail", "FAIL:")), None)
        if line.startswith("      ") and at is not None and at >= 4:
            rows.append(parts[:at] + ["refused" if parts[at] == "FAIL:" else parts[at]])
    return rows


def test_explain_names_the_check_that_refused_a_view_with_its_value_and_limit(
        capsys, cable_view: str) -> None:
    """A view with a cable across it: --explain says which check refused it, with the value
    measured and the limit it broke, and lists every check each reading ran; --json carries
    the same refusal."""
    from tileviz.vision.robust.checks import CHECKS

    rc, out, err = _run(capsys, cable_view, "--explain")
    assert rc == 1 and err == ""  # exit 1: the view gave no observation
    lines = out.splitlines()
    assert lines[0] == f"{cable_view}: no observation (foreign line); " + \
        lines[0].split("; ")[-1]
    summary = lines[1].strip()
    assert summary.startswith("refused (foreign line) by ")
    check = summary.split(" by ")[1].split()[0]
    assert CHECKS[check].reason == "foreign line"
    value = float(summary.split("value ")[1].split(",")[0])
    relation, limit = summary.split("must be ")[1].split()
    assert relation == CHECKS[check].relation.symbol
    assert not CHECKS[check].relation.passes(value, float(limit))  # the numbers break it
    refused = [r for r in _rows(out) if r[-1] == "refused"]
    assert len(refused) == 1 and refused[0][0] == check
    assert "reading 1: first heading" in out and "view" in lines[4]
    assert {r[0] for r in _rows(out)} >= {"constant.range", "heading.gradients",
                                           "lines.found", check}
    rc, out, _ = _run(capsys, cable_view, "--json")
    got = json.loads(out)["decision"]
    assert got["reason"] == "foreign line" and got["refusal"]["check"] == check
    assert got["refusal"]["value"] == pytest.approx(value, rel=1e-3)
    assert got["refusal"]["limit"] == pytest.approx(float(limit), rel=1e-3)


def test_explain_of_an_accepted_view_shows_every_check_passed(capsys, images) -> None:
    rc, out, _ = _run(capsys, images["default"], "--explain")
    assert rc == 0
    assert out.splitlines()[1].strip().startswith("accepted")
    rows = _rows(out)
    ids = [r[0] for r in rows]
    assert {"blur.rise", "angle.straight", "spacing", "bound.position", "foreign_edge"} <= set(ids)
    assert all(r[-1] == "pass" for r in rows)
    # each row says what its value is, with its unit
    depth = next(line for line in out.splitlines() if line.strip().startswith("contrast.depth"))
    assert depth.rstrip().endswith("pass           deepest dip (gray levels)")
    rc, out, _ = _run(capsys, "--explain", "--extractor", "faithful", images["default"])
    assert "records no decision path" in out


def test_an_option_error_is_said_once_naming_no_image(capsys, images) -> None:
    """A tolerance of more than a quarter tile is the option's fault, not an image's: one line
    for the whole command."""
    rc, out, err = _run(capsys, images["default"], images["constant"],
                        "--lattice-tolerance", "0.3")
    assert rc == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "lattice_tolerance must be < tile_size/4" in lines[0]
    assert images["default"] not in lines[0]


def test_a_reader_that_stops_early_ends_the_command_quietly(images) -> None:
    """``extract ... | head -1``: once the reader has gone, no error and no traceback."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "tileviz", "extract", "--explain",
         *([images["default"], images["constant"]] * 200)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=REPO)
    assert proc.stdout is not None and proc.stderr is not None
    first = proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=600) == 141  # as a process the pipe signal ends
    assert first.startswith(images["default"].encode()) and err == ""


def test_explain_names_the_image_read_and_every_image_tried_before(capsys,
                                                                    tmp_path: Path) -> None:
    """Faint coloured grout: the luma shows no lattice and a colour projection is read.
    --explain says which image its readings read, and lists every image of the view read,
    in order, with its outcome (the luma's refusal first); --json carries the same."""
    from tileviz.config import with_floor_style

    cfg = with_floor_style(preset("default"), "faint_colour")
    img = FloorRenderer(cfg.floor, cfg.camera).render(Pose(2.3, -4.1, 0.7),
                                                      np.random.default_rng(1))
    path = _write(tmp_path / "faint.png", img)
    rc, out, _ = _run(capsys, path, "--explain")
    lines = out.splitlines()
    assert rc == 0 and "accepted" in lines[1]
    assert lines[2].strip().startswith("scale: ")
    read = lines[3].strip()
    assert read.startswith("the readings below read the colour projection ")
    assert lines[4].strip() == "images of the view read, in order:"
    assert lines[5].strip().startswith("luma: refused (")
    name = read.removeprefix("the readings below read the ")
    assert lines[6].strip() == f"{name}: accepted"
    rc, out, _ = _run(capsys, path, "--json")
    decision = json.loads(out)["decision"]
    assert decision["image"] == name and decision["images"][-1] == f"{name}: accepted"
    assert decision["images"][0].startswith("luma: refused (")


def test_a_broken_pipe_other_than_stdout_is_an_error(capsys) -> None:
    """Only stdout's reader going away ends a command quietly; a broken pipe elsewhere (a
    worker's connection) is one line of error, status 2, and stdout still works."""
    from tileviz.cliutil import run_cli

    def body() -> int:
        raise BrokenPipeError(32, "Broken pipe (a worker's connection)")

    assert run_cli("tileviz x", body) == 2
    print("still here")
    cap = capsys.readouterr()
    assert cap.err.strip() == "tileviz x: error: [Errno 32] Broken pipe (a worker's connection)"
    assert cap.out == "still here\n"


def test_a_refused_views_line_count_names_the_reading_it_comes_from(
        capsys, tmp_path: Path) -> None:
    """A view with a cable across it, refused (one family) by its first reading, whose result
    shows the lines of a later reading: its line says which reading those lines are from, the
    one --explain marks shown."""
    from tileviz.sim.camera import Fault

    cfg = preset("default")
    rng = np.random.default_rng(4)
    pose = Pose(float(rng.uniform(0, 2)), float(rng.uniform(0, 2)), float(rng.uniform(-3, 3)))
    params = {"angle": float(rng.uniform(0, 3)), "offset": float(rng.uniform(-40, 40)),
              "width": 4.0}
    img = FloorRenderer(cfg.floor, cfg.camera).render(pose, rng, faults=[Fault("cable", params)])
    path = _write(tmp_path / "cable.png", img)
    rc, out, err = _run(capsys, path, "--extractor", "robust", "--json")
    got = json.loads(out)
    decision = got["decision"]
    assert rc == 1 and err == "" and not got["accepted"]
    assert decision["shown"] is not None and decision["shown"] != decision["refusal"]["reading"]
    rc, out, err = _run(capsys, path, "--extractor", "robust", "--explain")
    first = out.splitlines()[0]
    shown = decision["shown"] + 1
    assert first == (f"{path}: no observation ({got['reason']}); {got['lines']} lines in "
                     f"reading {shown}")
    assert f"  reading {shown}: " in out and "(shown)" in out.split(f"  reading {shown}: ")[1]\
        .splitlines()[0]


def test_explain_says_the_scale_read_and_that_it_was_not_given(capsys, images) -> None:
    """Without --tile-size and --ppm, extract reads at the preset's scale: --explain says so,
    with the period in px; given, it says the scale alone."""
    rc, out, _ = _run(capsys, images["default"], "--explain")
    assert rc == 0
    assert out.splitlines()[2] == ("  scale: tiles of 1 m at 200 px/m (a period of 200.0 px); "
                                   "--tile-size and --ppm not given: the default preset's")
    rc, out, _ = _run(capsys, images["default"], "--explain", "--tile-size", "0.5", "--ppm",
                      "400")
    assert out.splitlines()[2] == "  scale: tiles of 0.5 m at 400 px/m (a period of 200.0 px)"
    rc, out, _ = _run(capsys, images["default"], "--explain", "--ppm", "200")
    assert out.splitlines()[2].endswith("; --tile-size not given: the default preset's")
