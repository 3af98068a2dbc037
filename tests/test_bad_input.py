"""Bad input, everywhere (issue 7): a catalogue with one test each.

Command lines out of range, missing or corrupt dataset pieces, unreadable/empty/constant/huge
images, NaN, inf and absurd magnitudes in every numeric field of meta.json, frames.csv and the
Localizer/FrameLoop inputs. Each gives one clear error naming the problem (a CLI: one line on
stderr, a non-zero exit, no traceback) and nothing already written is lost.

Cases already covered elsewhere are not repeated: ``tests/test_dataset.py`` (bad meta keys and
rows, unreadable and wrong-size images), ``tests/test_record_replay.py`` (the first CLI errors, a
replay stopping at a non-numeric row), ``tests/test_extract_cli.py`` (extract's options, broken
and missing image files), ``tests/test_localizer.py`` (bad Localizer inputs).
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from tileviz.config import LocalizerConfig, preset
from tileviz.core.constants import LIMIT
from tileviz.core.localizer import Localizer
from tileviz.datasets import (
    FORMAT,
    DatasetError,
    DatasetMeta,
    DatasetSource,
    DatasetWriter,
    read_meta,
)
from tileviz.pipeline import FrameLoop
from tileviz.sim.source import SimSource
from tileviz.types import Box, FrameInput, Observation, Odometry, Pose, SensorBounds
from tileviz.vision import extract

REPO = Path(__file__).resolve().parents[1]
BAD_NUMBERS = [math.nan, math.inf, -math.inf, 1e300]
BAD_TEXT = ["nan", "inf", "-inf", "1e300"]


def _cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tileviz", *args], capture_output=True,
                          text=True, timeout=300, cwd=cwd,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})


def _one_line_error(r: subprocess.CompletedProcess[str], needle: str) -> None:
    assert r.returncode != 0, r.stdout
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], r.stderr


def _read_csv(path: Path) -> list[list[str]]:
    with open(path, newline="") as f:
        return list(csv.reader(f))


# --- command lines ------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--duration", "1e6"], "--duration must be a finite number > 0 and <= 86400"),
        (["--duration", "inf"], "--duration must be a finite number"),
        (["--duration", "1", "--tile-size", "1e300"], "--tile-size must be a finite number"),
        (["--duration", "1", "--ppm", "1e9"], "--ppm must be a finite number >= 20 and <= 2000"),
        (["--duration", "1", "--ppm", "5"], "--ppm must be a finite number >= 20 and <= 2000"),
        (["--duration", "1", "--dt", "5"], "--dt must be a finite number > 0 and <= 1"),
        (["--duration", "1", "--seed", "-1"], "--seed must be >= 0 and <= 4294967295"),
        (["--duration", "1", "--seed", "abc"], "--seed must be an integer"),
        (["--duration", "1", "--speed-error", "-0.1"], "--speed-error must be a finite number"),
        (["--duration", "1", "--compass-error", "4"], "--compass-error must be a finite number"),
        (["--duration", "1", "--width", "3"], "image width must be an integer in [16, 8192]"),
        (["--duration", "1", "--height", "100000"],
         "image height must be an integer in [16, 8192]"),
        (["--duration", "1", "--tile-size", "0.05", "--ppm", "20"], "a tile must span at least"),
        (["--duration", "1", "--setpoint", "zigzag"], "invalid choice: 'zigzag'"),
        (["--preset", "seed"], "required: --duration"),
    ],
)
def test_record_options_out_of_range(args: list[str], needle: str, tmp_path: Path) -> None:
    r = _cli(["record", "out", *args], tmp_path)
    _one_line_error(r, needle)
    assert not (tmp_path / "out").exists()  # nothing was written


def test_record_into_a_file(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("keep me")
    _one_line_error(_cli(["record", "afile", "--duration", "0.1", "--quiet"], tmp_path),
                    "afile: is a file, not an output folder")
    _one_line_error(_cli(["record", "afile/meta.json", "--duration", "0.1", "--quiet"],
                         tmp_path), "afile/meta.json: afile is a file, not a folder")
    assert (tmp_path / "afile").read_text() == "keep me"


def test_survey_of_a_missing_file_or_a_folder_that_is_no_dataset(tmp_path: Path) -> None:
    """The file's absence, or the folder's missing meta.json, is what the one line names (not
    the scale options, not a meta.json that cannot be read)."""
    _one_line_error(_cli(["survey", "nowhere.png"], tmp_path), "nowhere.png: no such file")
    (tmp_path / "shots").mkdir()
    _one_line_error(_cli(["survey", "shots"], tmp_path),
                    "shots: a folder with no meta.json, not a dataset (give its images as files")


@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--out", "x.csv", "--max-boxes", "0"], "--max-boxes must be >= 1"),
        (["--out", "x.csv", "--max-boxes", "abc"], "--max-boxes must be an integer"),
        (["--out", "x.csv", "--extractor", "magic"], "invalid choice: 'magic'"),
        (["--out", "no/such/dir/x.csv"], "output directory does not exist"),
    ],
)
def test_replay_options_out_of_range(args: list[str], needle: str, recorded: Path,
                                     tmp_path: Path) -> None:
    _one_line_error(_cli(["replay", str(recorded), *args, "--quiet"], tmp_path), needle)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--dataset", "no/such/folder"], "no/such/folder: no such directory"),
        (["--dataset", "{bad_meta}"], 'meta.json: format must be "tileviz-dataset/1"'),
        (["--dataset", "{recorded}", "--tile-size", "0.5"],
         "--tile-size cannot be used with --dataset"),
        (["--dataset", "{recorded}", "--lattice-tolerance", "0.002"],
         "--lattice-tolerance cannot be used with --dataset"),
        (["--lattice-tolerance", "-0.002"], "--lattice-tolerance must be a finite number >= 0"),
        (["--dataset", "{recorded}", "--mode", "psychic"], "invalid choice: 'psychic'"),
    ],
)
def test_serve_dataset_that_cannot_be_replayed(args: list[str], needle: str, recorded: Path,
                                               tmp_path: Path) -> None:
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "meta.json").write_text('{"format": "other"}')
    (tmp_path / "bad" / "frames.csv").write_text("index,t,image,speed,yaw_rate\n")
    args = [a.format(bad_meta=tmp_path / "bad", recorded=recorded) for a in args]
    r = _cli(["serve", "--port", "0", *args], tmp_path)
    _one_line_error(r, needle)
    assert r.returncode == 2 and "open http" not in r.stdout  # no server was started


@pytest.fixture(scope="module")
def images(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Image files as a user might pass them: broken ones and good ones."""
    d = tmp_path_factory.mktemp("images")
    cv2.imwrite(str(d / "tiny.png"), np.zeros((1, 1, 3), np.uint8))
    cv2.imwrite(str(d / "huge.png"), np.full((20, 9000, 3), 128, np.uint8))
    cv2.imwrite(str(d / "constant.png"), np.full((240, 320, 3), 128, np.uint8))
    ok, buf = cv2.imencode(".png", np.full((240, 320, 3), 90, np.uint8))
    (d / "cut.png").write_bytes(buf.tobytes()[:200])
    (d / "afile").write_text("x")
    return d


@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["cut.png"], "cut.png"),
        (["tiny.png"], "image width must be an integer in [16, 8192], got 1"),
        (["huge.png"], "image width must be an integer in [16, 8192], got 9000"),
        (["constant.png", "--stages", "afile"], "--stages: cannot create afile"),
        # absurd scales used to hang the robust extractor (or eat gigabytes): now refused at once
        (["constant.png", "--ppm", "1e-290"], "a tile must span 4 to 100000 pixels"),
        (["constant.png", "--ppm", "1e9"], "a tile must span 4 to 100000 pixels"),
    ],
)
def test_extract_bad_options_and_images(args: list[str], needle: str, images: Path) -> None:
    _one_line_error(_cli(["extract", *args], images), needle)


def test_extract_of_a_constant_image_is_a_refusal_not_an_error(images: Path) -> None:
    r = _cli(["extract", "constant.png"], images)
    assert r.returncode == 1 and r.stderr == ""  # 1: no observation found (not bad input)
    assert r.stdout.strip() == "constant.png: no observation (constant image); 0 lines"


# --- images in the library ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("image", "needle"),
    [
        (np.zeros((0, 0, 3), np.uint8), "image is empty"),
        (np.zeros((240, 320, 3), np.float64), "image must be uint8"),
        (np.full((240, 320, 3), np.nan, np.float32), "image must be uint8"),
        (np.zeros((1, 240, 320, 3), np.uint8), "image must be HxW, HxWx3 or HxWx4"),
        (np.zeros((2400, 3200, 3), np.uint8), "image is 3200x2400 but the camera is 320x240"),
        ([[0, 1], [2, 3]], "image must be a numpy array"),
    ],
)
def test_vision_refuses_bad_arrays_with_a_named_error(image: object, needle: str) -> None:
    cfg = preset("default")
    with pytest.raises(ValueError, match=needle.replace("(", r"\(")):
        extract(image, camera=cfg.camera, tile_size=1.0, vision=cfg.vision)  # type: ignore[arg-type]


@pytest.mark.parametrize("gray", [0, 128, 255])
def test_vision_refuses_a_constant_image(gray: int) -> None:
    cfg = preset("default")
    res = extract(np.full((240, 320, 3), gray, np.uint8), camera=cfg.camera, tile_size=1.0,
                  vision=cfg.vision)
    assert not res.accepted and res.observation is None and res.reason == "constant image"


@pytest.mark.parametrize("tile_size", [math.nan, math.inf, 0.0, -1.0])
def test_vision_names_a_bad_tile_size(tile_size: float) -> None:
    cfg = preset("default")
    with pytest.raises(ValueError, match="tile_size"):
        extract(np.zeros((240, 320, 3), np.uint8), camera=cfg.camera, tile_size=tile_size,
                vision=cfg.vision)


# --- datasets: missing and corrupt pieces -------------------------------------------------------

W, H = 64, 48


def _meta_dict(**over: object) -> dict:
    d = {
        "format": FORMAT, "name": "t", "tile_size": 0.5, "ppm": 100.0, "image_width": W,
        "image_height": H, "camera_offset": [0.1, 0.0], "dt": 0.1,
        "initial_pose": [0.0, 0.0, 0.0], "initial_pose_error": [0.01, 0.01, 0.01],
        "speed_error": 0.02, "yaw_rate_error": 0.01, "compass_error": 0.02,
    }
    d.update(over)
    return d


ROWS = [
    ["0", "0.0", "images/a.png", "0.5", "0.1", "0.1", "0.0", "0.0", "0.1"],
    ["1", "0.1", "images/b.jpg", "0.5", "0.1", "0.11", "0.05", "0.0", "0.11"],
    ["2", "0.2", "images/a.png", "0.5", "0.1", "0.12", "0.1", "0.0", "0.12"],
]


def _dataset(tmp_path: Path, rows: list[list[str]] | None = None) -> Path:
    folder = tmp_path / "ds"
    (folder / "images").mkdir(parents=True)
    (folder / "meta.json").write_text(json.dumps(_meta_dict()))
    img = np.full((H, W, 3), 200, np.uint8)
    img[:, W // 2] = 40
    cv2.imwrite(str(folder / "images" / "a.png"), img)
    cv2.imwrite(str(folder / "images" / "b.jpg"), img)
    lines = ["index,t,image,speed,yaw_rate,compass,x,y,theta"]
    lines += [",".join(r) for r in (ROWS if rows is None else rows)]
    (folder / "frames.csv").write_text("\n".join(lines) + "\n")
    return folder


def _cut(path: Path, size: int) -> None:
    """Keep only the first ``size`` bytes of a file (a copy that was cut off)."""
    path.write_bytes(path.read_bytes()[:size])


def _expect(folder: Path, needle: str) -> None:
    with pytest.raises(DatasetError) as e:
        list(DatasetSource(folder))
    msg = str(e.value)
    assert needle in msg and "\n" not in msg, msg


def test_a_good_dataset_reads(tmp_path: Path) -> None:
    assert [f.index for f in DatasetSource(_dataset(tmp_path))] == [0, 1, 2]


@pytest.mark.parametrize(
    ("damage", "needle"),
    [
        (lambda d: (d / "meta.json").unlink(), "meta.json: cannot read"),
        (lambda d: (d / "meta.json").write_text(""), "meta.json: not valid JSON"),
        (lambda d: (d / "meta.json").write_text("[1, 2]"), "meta.json: must be a JSON object"),
        (lambda d: (d / "meta.json").write_bytes(bytes(range(256))), "meta.json: not UTF-8"),
        (lambda d: ((d / "meta.json").unlink(), (d / "meta.json").mkdir()),
         "meta.json: cannot read"),
        (lambda d: (d / "frames.csv").write_text(""), "frames.csv: empty (no header row)"),
        (lambda d: (d / "frames.csv").write_bytes(bytes(range(256)) * 3), "frames.csv: not UTF-8"),
        (lambda d: (d / "frames.csv").write_text("index,t,image,speed\n0,0,images/a.png,1\n"),
         "frames.csv: missing column(s) yaw_rate"),
        (lambda d: shutil.rmtree(d / "images"),
         "line 2 (frame 0): image 'images/a.png' is missing"),
        (lambda d: (d / "images" / "b.jpg").write_bytes(b""),
         "line 3 (frame 1): image 'images/b.jpg' is not a readable PNG/JPEG"),
        (lambda d: _cut(d / "images" / "a.png", 60),
         "line 2 (frame 0): image 'images/a.png' is truncated"),
        (lambda d: _cut(d / "images" / "b.jpg", 300),
         "line 3 (frame 1): image 'images/b.jpg' is truncated"),
        (lambda d: ((d / "images" / "b.jpg").unlink(), (d / "images" / "b.jpg").mkdir()),
         "line 3 (frame 1): image 'images/b.jpg' is missing"),
        (lambda d: (d / "faults.csv").write_text("index,faults\nthree,cable\n"),
         "faults.csv line 2: expected 'index,labels'"),
        (lambda d: (d / "faults.csv").write_bytes(bytes(range(256))), "faults.csv: not UTF-8"),
    ],
    ids=["no meta", "empty meta", "meta array", "binary meta", "meta is a folder",
         "empty frames", "binary frames", "missing column", "no images folder", "empty image",
         "truncated png", "truncated jpg", "image is a folder", "bad faults row",
         "binary faults"],
)
def test_missing_or_corrupt_piece_is_named(damage, needle: str, tmp_path: Path) -> None:
    folder = _dataset(tmp_path)
    damage(folder)
    _expect(folder, needle)


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_damaged_png_data_is_one_line(tmp_path: Path, jobs: str) -> None:
    """A PNG whose compressed pixels were damaged (end marker intact): one line naming the row
    and the file, not also the PNG library's own complaint, whichever decoder met it."""
    folder = _dataset(tmp_path)
    png = folder / "images" / "a.png"
    cv2.imwrite(str(png), np.random.default_rng(1).integers(0, 256, (H, W, 3), np.uint8))
    raw = bytearray(png.read_bytes())
    raw[60:160] = bytes(100)  # inside the IDAT chunk
    png.write_bytes(bytes(raw))
    r = subprocess.run([sys.executable, "-m", "tileviz", "replay", str(folder), "--out",
                        str(tmp_path / "out.csv"), "--quiet", "--jobs", jobs],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1, r.stderr
    assert "line 2 (frame 0): image 'images/a.png' is not a readable PNG/JPEG" in r.stderr


def test_a_dataset_with_a_header_only_has_no_frames(tmp_path: Path) -> None:
    assert list(DatasetSource(_dataset(tmp_path, rows=[]))) == []


# --- NaN, inf and absurd magnitudes in every numeric field --------------------------------------

META_NUMBERS = ["tile_size", "ppm", "image_width", "image_height", "dt", "speed_error",
                "yaw_rate_error", "compass_error"]
META_VECTORS = [("camera_offset", 2), ("initial_pose", 3), ("initial_pose_error", 3)]


@pytest.mark.parametrize("value", BAD_NUMBERS)
@pytest.mark.parametrize(
    "field", META_NUMBERS + [f"{k}[{i}]" for k, n in META_VECTORS for i in range(n)])
def test_meta_json_number_that_is_not_finite_or_absurd(field: str, value: float,
                                                       tmp_path: Path) -> None:
    d = _meta_dict()
    key = field.split("[")[0]
    if "[" in field:
        d[key] = list(d[key])
        d[key][int(field[-2])] = value
    else:
        d[key] = value
    (tmp_path / "meta.json").write_text(json.dumps(d))  # NaN, Infinity: JSON as Python writes it
    with pytest.raises(DatasetError) as e:
        read_meta(tmp_path)
    assert key in str(e.value) and "meta.json" in str(e.value)


@pytest.mark.parametrize(
    ("over", "needle"),
    [
        ({"tile_size": 0.001, "ppm": 100.0}, "a tile must span at least 4 pixels"),
        ({"ppm": 1e6}, "ppm must be <= 100000"),
    ],
)
def test_meta_json_scale_that_no_camera_has(over: dict, needle: str, tmp_path: Path) -> None:
    (tmp_path / "meta.json").write_text(json.dumps(_meta_dict(**over)))
    with pytest.raises(DatasetError, match=needle):
        read_meta(tmp_path)


FRAME_NUMBERS = {"t": 1, "speed": 3, "yaw_rate": 4, "compass": 5, "x": 6, "y": 7, "theta": 8}


@pytest.mark.parametrize("text", BAD_TEXT)
@pytest.mark.parametrize("column", list(FRAME_NUMBERS) + ["index"])
def test_frames_csv_number_that_is_not_finite_or_absurd(column: str, text: str,
                                                        tmp_path: Path) -> None:
    rows = [list(r) for r in ROWS]
    rows[1][FRAME_NUMBERS.get(column, 0)] = text
    folder = _dataset(tmp_path, rows)
    with pytest.raises(DatasetError) as e:
        list(DatasetSource(folder))
    msg = str(e.value)
    assert "frames.csv line 3" in msg and column in msg and "\n" not in msg, msg


ODO, OBS = Odometry(0.1, 0.0, 0.05), Observation(0.3, 0.4, 0.1, 0.01, 0.02)
STEP_FIELDS = {
    "odometry.speed": lambda v: {"odometry": replace(ODO, speed=v)},
    "odometry.yaw_rate": lambda v: {"odometry": replace(ODO, yaw_rate=v)},
    "odometry.dt": lambda v: {"odometry": replace(ODO, dt=v)},
    "compass": lambda v: {"compass": v},
    "observation.y1": lambda v: {"observation": replace(OBS, y1=v)},
    "observation.y2": lambda v: {"observation": replace(OBS, y2=v)},
    "observation.y3": lambda v: {"observation": replace(OBS, y3=v)},
    "observation.position_error": lambda v: {"observation": replace(OBS, position_error=v)},
    "observation.heading_error": lambda v: {"observation": replace(OBS, heading_error=v)},
    "truth.x": lambda v: {"truth": Pose(v, 0.0, 0.0)},
    "truth.y": lambda v: {"truth": Pose(0.0, v, 0.0)},
    "truth.theta": lambda v: {"truth": Pose(0.0, 0.0, v)},
}
BOUNDS = SensorBounds(0.02, 0.01, 0.02)
BOX = Box(-0.1, 0.1, -0.1, 0.1, -0.05, 0.05)


def _localizer(**over: object) -> Localizer:
    args: dict = {"tile_size": 1.0, "camera_offset": (0.3, 0.0), "bounds": BOUNDS,
                  "config": LocalizerConfig(max_slip=(0.1, 0.1)), "initial": BOX}
    args.update(over)
    return Localizer(**args)


@pytest.mark.parametrize("value", BAD_NUMBERS)
@pytest.mark.parametrize("field", list(STEP_FIELDS))
def test_localizer_step_input_that_is_not_finite_or_absurd(field: str, value: float) -> None:
    loc = _localizer()
    before = loc.current
    args = {"odometry": None, "compass": None, "observation": None} | STEP_FIELDS[field](value)
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        loc.step(**args)
    assert loc.current == before  # nothing changed
    assert loc.step(None, None, None).status == "predicted"  # and it goes on


CONSTRUCTION_FIELDS = {
    "tile_size": lambda v: {"tile_size": v},
    r"camera_offset\[0\]": lambda v: {"camera_offset": (v, 0.0)},
    r"camera_offset\[1\]": lambda v: {"camera_offset": (0.3, v)},
    "speed_error": lambda v: {"bounds": replace(BOUNDS, speed_error=v)},
    "yaw_rate_error": lambda v: {"bounds": replace(BOUNDS, yaw_rate_error=v)},
    "compass_error": lambda v: {"bounds": replace(BOUNDS, compass_error=v)},
    "x_lo": lambda v: {"initial": BOX._replace(x_lo=v)},
    "x_hi": lambda v: {"initial": BOX._replace(x_hi=v)},
    "y_lo": lambda v: {"initial": BOX._replace(y_lo=v)},
    "y_hi": lambda v: {"initial": BOX._replace(y_hi=v)},
    "t_lo": lambda v: {"initial": BOX._replace(t_lo=v)},
    "t_hi": lambda v: {"initial": BOX._replace(t_hi=v)},
}


@pytest.mark.parametrize("value", BAD_NUMBERS)
@pytest.mark.parametrize("field", list(CONSTRUCTION_FIELDS))
def test_localizer_setting_that_is_not_finite_or_absurd(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        _localizer(**CONSTRUCTION_FIELDS[field](value))


@pytest.mark.parametrize(
    ("config", "needle"),
    [
        ({"max_slip": (math.nan, 0.1)}, r"max_slip\[0\]"),
        ({"max_slip": (0.1, math.inf)}, r"max_slip\[1\]"),
        ({"max_boxes": math.inf}, "max_boxes"),
        ({"passes": math.nan}, "passes"),
        ({"max_rejections": math.inf}, "max_rejections"),
        ({"truth_inflation": (0.3, math.nan, 0.2)}, r"truth_inflation\[1\]"),
    ],
)
def test_localizer_config_that_is_not_finite(config: dict, needle: str) -> None:
    with pytest.raises(ValueError, match=needle):
        LocalizerConfig(**config)


def test_the_magnitude_limit_is_where_it_says() -> None:
    loc = _localizer()
    assert loc.step(None, LIMIT, None).status == "predicted"
    with pytest.raises(ValueError, match="compass"):
        loc.step(None, math.nextafter(LIMIT, math.inf), None)


def test_a_heading_wider_than_a_turn_is_one_turn() -> None:
    # every heading: 1e6 rad of it would be 160 000 compass pieces; one turn says the same
    loc = _localizer(initial=Box(-0.1, 0.1, -0.1, 0.1, -1e6, 1e6))
    assert loc.current.boxes[0].widths[2] == pytest.approx(2 * math.pi)
    step = loc.step(Odometry(0.1, 0.0, 0.05), 0.3, None)
    assert step.updated.contains(0.0, 0.0, 0.3 + 2 * math.pi * 7)
    assert step.updated.hull().widths[2] < 0.05


def test_a_prediction_that_leaves_the_representable_range_is_refused() -> None:
    loc = _localizer()
    before = loc.current
    with pytest.raises(ValueError, match="the set left"):
        loc.step(Odometry(0.9 * LIMIT, 0.0, 10.0), None, None)
    assert loc.current == before


def test_runner_names_the_frame_with_a_bad_number_and_goes_on() -> None:
    cfg = preset("default")
    frames = list(itertools.islice(SimSource(cfg), 4))
    runner, clean = FrameLoop(cfg), FrameLoop(cfg)
    assert runner.process(frames[0]).updated == clean.process(frames[0]).updated
    bad_odometry = replace(frames[1], odometry=replace(frames[1].odometry, speed=math.nan))
    with pytest.raises(ValueError, match="frame 1: odometry"):
        runner.process(bad_odometry)  # named at the frame that carries it
    with pytest.raises(ValueError, match="frame 1: compass"):
        runner.process(replace(frames[1], compass=math.inf))
    with pytest.raises(ValueError, match=r"frame 1: truth\.x"):
        runner.process(replace(frames[1], truth=Pose(math.nan, 0.0, 0.0)))
    # the bad frames changed nothing: the good ones give the sets of an undisturbed run
    for f in frames[1:]:
        assert runner.process(f).updated == clean.process(f).updated


# --- nothing already written is lost ------------------------------------------------------------

RECORDED = 12


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset of RECORDED simulated frames (default preset)."""
    cfg = preset("default")
    folder = tmp_path_factory.mktemp("rec") / "ds"
    with DatasetWriter(folder, DatasetMeta.from_config(cfg)) as w:
        for frame in itertools.islice(SimSource(cfg), RECORDED):
            w.write(frame)
    return folder


@pytest.fixture(scope="module")
def clean_replay(recorded: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[list, list]:
    out = tmp_path_factory.mktemp("clean")
    r = _cli(["replay", str(recorded), "--out", "r.csv", "--output-file", "eq.csv", "--quiet"],
             out)
    assert r.returncode == 0, r.stderr
    return _read_csv(out / "r.csv"), _read_csv(out / "eq.csv")


def _break_row(cells: list[str], folder: Path) -> None:
    cells[3] = "nan"


def _missing_image(cells: list[str], folder: Path) -> None:
    (folder / cells[2]).unlink()


def _cut_image(cells: list[str], folder: Path) -> None:
    _cut(folder / cells[2], 100)


def _cut_row(cells: list[str], folder: Path) -> None:
    del cells[4:]


def _huge_t(cells: list[str], folder: Path) -> None:
    cells[1] = "1e300"


@pytest.mark.slow
@pytest.mark.parametrize("damage", [_break_row, _missing_image, _cut_image, _cut_row, _huge_t])
def test_a_replay_keeps_every_row_before_the_bad_one(damage, recorded: Path,
                                                     clean_replay: tuple[list, list],
                                                     tmp_path: Path) -> None:
    folder = tmp_path / "ds"
    shutil.copytree(recorded, folder)
    lines = (folder / "frames.csv").read_text().splitlines()
    bad = 7  # frame 7 (line 9 of frames.csv) is damaged
    cells = lines[bad + 1].split(",")
    damage(cells, folder)
    lines[bad + 1] = ",".join(cells)
    (folder / "frames.csv").write_text("\n".join(lines) + "\n")
    r = _cli(["replay", str(folder), "--out", "r.csv", "--output-file", "eq.csv", "--quiet"],
             tmp_path)
    _one_line_error(r, f"frames.csv line {bad + 2} (frame {bad})")
    rows, eq = clean_replay
    # every frame before the bad one is there, complete and as in an undamaged replay
    assert _read_csv(tmp_path / "r.csv") == rows[: bad + 1]
    assert _read_csv(tmp_path / "eq.csv") == eq[: bad + 1]


def test_a_recording_that_stops_leaves_a_readable_dataset(tmp_path: Path) -> None:
    cfg = preset("default")
    writer = DatasetWriter(tmp_path / "ds", DatasetMeta.from_config(cfg))
    frames: list[FrameInput] = list(itertools.islice(SimSource(cfg), 3))
    for f in frames:
        writer.write(f)
    # no close(): as if the program died here
    back = list(DatasetSource(tmp_path / "ds"))
    assert [f.index for f in back] == [0, 1, 2]
    assert all(np.array_equal(a.image, b.image) for a, b in zip(frames, back, strict=True))
    writer.close()
