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

from tileviz import tiles
from tileviz.config import preset
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
    assert rc == 0 and err == ""
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
