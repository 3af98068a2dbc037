"""calibrate: synthetic checkerboard images drawn through a known camera give back that camera;
bad input is one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from tileviz.config import preset
from tileviz.datasets import DatasetMeta, read_meta
from tileviz.datasets.calibrate import board_floor_points
from tileviz.datasets.sample import floor_board_image, held_board_image
from tileviz.sim.lens import mounted_camera

COLS, ROWS, SQUARE = 7, 5, 0.05
POSE = (0.32, 0.01, 0.2)
TRUE = mounted_camera(raw_size=(480, 360), focal=400.0,
                      dist=(-0.2, 0.07, 0.001, -0.0008, -0.01), target=(0.3, 0.0), height=0.5,
                      pitch=0.05, roll=-0.03)


def _floor_image(pose: tuple[float, float, float] = POSE, square: float = SQUARE) -> np.ndarray:
    """The board lying on the floor at ``pose`` (centre, COLS direction), seen by TRUE."""
    return floor_board_image(TRUE, COLS, ROWS, square, pose)


def _held_image(rvec: tuple[float, float, float], t: tuple[float, float, float]) -> np.ndarray:
    """The board held in front of the camera (rotation ``rvec``, its first corner at ``t``,
    metres, camera frame)."""
    return held_board_image(TRUE, COLS, ROWS, SQUARE, rvec, t)


@pytest.fixture(scope="module")
def boards(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    folder = tmp_path_factory.mktemp("boards")
    images = [_floor_image()]
    for rvec, t in [((0.3, 0.1, 0.05), (-0.15, -0.1, 0.45)), ((-0.25, 0.3, -0.1),
                    (-0.2, -0.05, 0.5)), ((0.1, -0.35, 0.2), (-0.1, -0.12, 0.42)),
                    ((0.4, 0.4, 0.0), (-0.18, -0.1, 0.55))]:
        images.append(_held_image(rvec, t))
    paths = []
    for n, img in enumerate(images):
        p = folder / f"board{n}.png"
        cv2.imwrite(str(p), img)
        paths.append(str(p))
    return paths


def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tileviz", "calibrate", *args],
                          capture_output=True, text=True, timeout=300, cwd=cwd)


def _args() -> list[str]:
    return ["--board", f"{COLS}x{ROWS}", "--square", str(SQUARE), "--board-pose",
            ",".join(str(v) for v in POSE)]


def test_calibrate_recovers_the_camera_and_writes_the_block(boards: list[str],
                                                            tmp_path: Path) -> None:
    ds = tmp_path / "ds"
    ds.mkdir()
    cfg = preset("default")
    meta = DatasetMeta.from_config(cfg)
    doc = meta.to_json()
    doc.update(ppm=500.0, image_width=200, image_height=150, camera_offset=[0.3, 0.0],
               extra_key="kept")
    (ds / "meta.json").write_text(json.dumps(doc))
    r = _cli(*boards, *_args(), "--meta", str(ds / "meta.json"))
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("intrinsics: ") and " px RMS reprojection error over 5 " in lines[0]
    assert lines[1].startswith("floor: ") and "mm RMS on the floor" in lines[1]
    floor_mm = float(lines[1].split(",")[1].split()[0])
    assert floor_mm < 1.0
    got = read_meta(ds)
    assert got.extra["extra_key"] == "kept" and got.camera_model is not None
    model = got.camera_model
    assert 0 < model.reprojection_error_px < 0.5
    # every floor point of the view lands on the raw pixel the true camera puts it on
    f, l = np.meshgrid(np.linspace(0.12, 0.48, 9), np.linspace(-0.15, 0.15, 7))
    floor = np.c_[f.ravel(), l.ravel()]
    want, seen = TRUE.floor_to_raw(floor)
    have, seen2 = model.floor_to_raw(floor)
    assert seen.all() and seen2.all()
    assert np.abs(have - want).max() < 0.5


def test_one_image_gives_the_floor_with_the_given_camera(boards: list[str],
                                                         tmp_path: Path) -> None:
    """One image: the --meta file's intrinsics and distortion are kept, the homography fitted."""
    meta = DatasetMeta.from_config(preset("default"))
    doc = meta.to_json()
    doc["camera_model"] = {**TRUE.to_json(),
                           "floor_homography": [[0, -0.003, 1], [-0.003, 0, 1], [0, 0, 1]]}
    path = tmp_path / "meta.json"
    path.write_text(json.dumps(doc))
    r = _cli(boards[0], *_args(), "--meta", str(path))
    assert r.returncode == 0, r.stderr
    assert not r.stdout.startswith("intrinsics")
    model = DatasetMeta.from_json(json.loads(path.read_text())).camera_model
    assert model.dist_coeffs == TRUE.dist_coeffs
    floor = board_floor_points(COLS, ROWS, SQUARE, POSE)
    assert np.abs(model.floor_to_raw(floor)[0] - TRUE.floor_to_raw(floor)[0]).max() < 0.3


def test_one_image_without_meta_prints_the_block(boards: list[str]) -> None:
    r = _cli(boards[0], *_args())
    assert r.returncode == 0, r.stderr
    block = json.loads(r.stdout)["camera_model"]  # stdout is the JSON alone
    assert block["dist_coeffs"] == [0.0] * 5 and block["raw_width"] == 480
    assert r.stderr.startswith("floor: ") and "mm RMS on the floor" in r.stderr


def test_meta_that_does_not_exist_is_created_with_the_block(boards: list[str],
                                                            tmp_path: Path) -> None:
    """--meta naming a file that does not exist (in a folder that does not either): the file is
    created with the camera_model block alone, which import-bag --camera-model reads; calibrating
    one image into it again keeps its intrinsics."""
    from tileviz.datasets.bag_import import camera_model_file

    cam = tmp_path / "mycam" / "meta.json"
    r = _cli(*boards, *_args(), "--meta", str(cam))
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[-1].startswith(f"created {cam} with the camera_model block")
    doc = json.loads(cam.read_text())
    assert list(doc) == ["camera_model"]
    model, view = camera_model_file(str(cam))
    assert view is None and (model.raw_width, model.raw_height) == (480, 360)
    floor = board_floor_points(COLS, ROWS, SQUARE, POSE)
    assert np.abs(model.floor_to_raw(floor)[0] - TRUE.floor_to_raw(floor)[0]).max() < 0.5
    r = _cli(boards[0], *_args(), "--meta", str(cam))
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[-1] == f"wrote camera_model into {cam}"
    again, _ = camera_model_file(str(cam))
    assert again.dist_coeffs == model.dist_coeffs and again.camera_matrix == model.camera_matrix


def test_bad_input_is_one_line(boards: list[str], tmp_path: Path) -> None:
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((360, 480), 128, np.uint8))
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), _floor_image(square=0.011))
    listed = tmp_path / "list.json"
    listed.write_text("[1, 2]")
    cases = [
        ([boards[0], *_args(), "--meta", str(listed)], f"--meta: {listed} is not a JSON object"),
        ([boards[0], str(blank), boards[1], *_args()], f"{blank}: no 7x5 checkerboard found"),
        ([boards[0], boards[1], *_args()], "too few images for intrinsics: 2"),
        ([str(tiny), *_args()], "degenerate pose: the board covers under"),
        ([boards[0], "--board", "7x7", "--square", "0.05", "--board-pose", "0,0,0"],
         "COLS and ROWS must differ"),
        ([boards[0], "--board", "7x5", "--square", "0.05", "--board-pose", "0,0"],
         "--board-pose must be X,Y,YAW"),
        ([boards[0], "--board", "seven", "--square", "0.05", "--board-pose", "0,0,0"],
         "--board must be COLSxROWS"),
    ]
    for args, needle in cases:
        r = _cli(*args)
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0], r.stderr
