"""tileviz-dataset/1: reading datasets written by other programs, and clear errors for bad ones."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from tileviz.config import Config
from tileviz.datasets import (
    FORMAT,
    DatasetError,
    DatasetMeta,
    DatasetSource,
    DatasetWriter,
    read_meta,
)
from tileviz.types import FrameInput, Odometry, Pose

W, H = 64, 48


def _meta(**over: object) -> dict:
    d = {
        "format": FORMAT,
        "name": "foreign",
        "tile_size": 0.5,
        "ppm": 100.0,
        "image_width": W,
        "image_height": H,
        "camera_offset": [0.1, 0.0],
        "dt": 0.1,
        "initial_pose": [0.0, 0.0, 0.0],
        "initial_pose_error": [0.01, 0.01, 0.01],
        "speed_error": 0.02,
        "yaw_rate_error": 0.01,
        "compass_error": 0.02,
        "robot": "someone else's",  # unknown key: kept and ignored
    }
    d.update(over)
    return d


def _foreign_dataset(tmp_path: Path, rows: list[list[str]] | None = None,
                     header: str = "index,t,image,speed,yaw_rate,compass,x,y,theta",
                     meta: dict | None = None) -> Path:
    """A dataset as another program might write it: JPEG and PNG images with free names,
    empty compass cells, an unknown meta key, column order as the spec lists."""
    folder = tmp_path / "ds"
    (folder / "pics").mkdir(parents=True)
    (folder / "meta.json").write_text(json.dumps(meta or _meta()))
    img = np.full((H, W, 3), 200, np.uint8)
    img[:, W // 2] = 40
    cv2.imwrite(str(folder / "pics" / "first frame.jpg"), img)
    cv2.imwrite(str(folder / "pics" / "b.png"), img)
    cv2.imwrite(str(folder / "pics" / "c.png"), img)
    if rows is None:
        rows = [
            ["0", "0.0", "pics/first frame.jpg", "0.5", "0.1", "", "0", "0", "0"],
            ["1", "0.1", "pics/b.png", "0.5", "0.1", "0.01", "", "", ""],
            ["2", "0.25", "pics/c.png", "0.4", "0.0", "-3.1", "0.1", "0.0", "0.02"],
        ]
    lines = [header] + [",".join(f'"{c}"' if " " in c else c for c in r) for r in rows]
    (folder / "frames.csv").write_text("\n".join(lines) + "\n")
    return folder


def test_foreign_dataset_replays_frames(tmp_path: Path) -> None:
    src = DatasetSource(_foreign_dataset(tmp_path))
    frames = list(src)
    assert [f.index for f in frames] == [0, 1, 2]
    assert frames[0].image.shape == (H, W, 3) and frames[0].image.dtype == np.uint8
    assert frames[0].compass is None and frames[1].compass == pytest.approx(0.01)
    assert frames[1].truth is None and frames[2].truth == Pose(0.1, 0.0, 0.02)
    # odometry row k is the motion from k to k+1, held over t[k+1] - t[k]
    assert frames[0].odometry == Odometry(0.5, 0.1, 0.1)
    assert frames[1].odometry is not None
    assert frames[1].odometry.dt == pytest.approx(0.15)
    assert frames[2].odometry is None
    assert src.meta.extra["robot"] == "someone else's"
    cfg = src.meta.to_config()
    assert cfg.floor.tile_size == 0.5 and cfg.camera.ppm == 100.0
    assert cfg.camera.offset == (0.1, 0.0) and cfg.noise.compass_error == 0.02


def test_columns_in_any_order(tmp_path: Path) -> None:
    rows = [["pics/b.png", "0", "0.0", "0.3", "0.0"], ["pics/c.png", "1", "0.1", "0.3", "0.0"]]
    folder = _foreign_dataset(tmp_path, rows, header="image,index,t,speed,yaw_rate")
    frames = list(DatasetSource(folder))
    assert len(frames) == 2 and frames[0].compass is None and frames[0].truth is None


@pytest.mark.parametrize(
    ("meta", "needle"),
    [
        (_meta(format="tileviz-dataset/2"), "format must be"),
        ({k: v for k, v in _meta().items() if k != "ppm"}, "missing key(s) ppm"),
        (_meta(tile_size=-1), "tile_size must be > 0"),
        (_meta(ppm="100"), "ppm must be a finite number"),
        (_meta(image_width=64.5), "image_width must be an integer"),
        (_meta(camera_offset=[0.1]), "camera_offset must be a list of 2"),
        (_meta(speed_error=-0.1), "speed_error must be >= 0"),
        (_meta(initial_pose_error=[0.1, -0.1, 0.0]), "initial_pose_error must be a list of 3"),
    ],
)
def test_bad_meta_is_named(tmp_path: Path, meta: dict, needle: str) -> None:
    folder = _foreign_dataset(tmp_path, meta=meta)
    with pytest.raises(DatasetError) as e:
        DatasetSource(folder)
    assert needle in str(e.value) and "meta.json" in str(e.value)
    assert "\n" not in str(e.value)


def test_meta_not_json(tmp_path: Path) -> None:
    folder = _foreign_dataset(tmp_path)
    (folder / "meta.json").write_text("{nope")
    with pytest.raises(DatasetError, match="not valid JSON"):
        read_meta(folder)


def test_missing_folder_and_frames(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="no such directory"):
        DatasetSource(tmp_path / "nowhere")
    folder = _foreign_dataset(tmp_path)
    (folder / "frames.csv").unlink()
    with pytest.raises(DatasetError, match=r"frames.csv: missing"):
        DatasetSource(folder)


@pytest.mark.parametrize(
    ("bad_row", "needle"),
    [
        (["1", "0.1", "pics/b.png", "abc", "0.1", "", "", "", ""], "speed is not a number"),
        (["1", "0.1", "pics/b.png", "nan", "0.1", "", "", "", ""], "speed is not finite"),
        (["1", "0.1", "pics/b.png", "0.5", "inf", "", "", "", ""], "yaw_rate is not finite"),
        (["1", "0.1", "pics/b.png", "0.5"], "truncated"),
        (["1", "0.1", "pics/missing.png", "0.5", "0.1", "", "", "", ""], "is missing"),
        (["1", "0.0", "pics/b.png", "0.5", "0.1", "", "", "", ""], "does not increase"),
        (["3", "0.1", "pics/b.png", "0.5", "0.1", "", "", "", ""], "expected 1"),
        (["1", "0.1", "pics/b.png", "0.5", "0.1", "7", "", "", ""], "not in (-pi, pi]"),
        (["1", "0.1", "pics/b.png", "0.5", "0.1", "", "1", "", ""], "all given or all empty"),
        (["1", "0.1", "pics/b.png", "0.5", "0.1", "", "1", "2", "x"], "theta is not a number"),
    ],
)
def test_bad_row_names_file_and_row(tmp_path: Path, bad_row: list[str], needle: str) -> None:
    rows = [["0", "0.0", "pics/c.png", "0.5", "0.1", "", "", "", ""], bad_row]
    folder = _foreign_dataset(tmp_path, rows)
    src = DatasetSource(folder)
    with pytest.raises(DatasetError) as e:
        list(src)
    msg = str(e.value)
    assert needle in msg and "frames.csv line 3" in msg and "\n" not in msg


def test_a_bad_row_names_its_line_and_its_frame(tmp_path: Path) -> None:
    """Blank lines before a row: its line in the file is not its frame + 2; the error names
    both (the frame's image is the one the user looks for)."""
    folder = _foreign_dataset(tmp_path)
    lines = (folder / "frames.csv").read_text().splitlines()
    lines[3:3] = ["", ""]  # frame 2 moves to line 6
    lines[5] = lines[5].replace("0.4", "fast", 1)
    (folder / "frames.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError) as e:
        list(DatasetSource(folder))
    assert str(e.value) == (f"{folder / 'frames.csv'} line 6 (frame 2): speed is not a number "
                            "('fast')")


def test_unreadable_and_wrong_size_image(tmp_path: Path) -> None:
    folder = _foreign_dataset(tmp_path)
    (folder / "pics" / "b.png").write_bytes(b"not an image")
    with pytest.raises(DatasetError,
                       match=r"line 3 \(frame 1\): image 'pics/b.png' is not a readable"):
        list(DatasetSource(folder))
    cv2.imwrite(str(folder / "pics" / "b.png"), np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(DatasetError, match="is 10x10, meta.json says 64x48"):
        list(DatasetSource(folder))
    # 10-bit data stored unscaled in a 16-bit PNG: named, not read as a nearly black view
    cv2.imwrite(str(folder / "pics" / "b.png"), np.full((48, 64, 3), 700, np.uint16))
    with pytest.raises(DatasetError, match=r"line 3 \(frame 1\): image 'pics/b.png': 16-bit "
                       r"samples reach only 700 of 65535"):
        list(DatasetSource(folder))


def test_writer_round_trips_exactly(tmp_path: Path) -> None:
    cfg = Config()
    meta = DatasetMeta.from_config(cfg)
    meta = DatasetMeta(**{**meta.__dict__, "image_width": W, "image_height": H})
    rng = np.random.default_rng(3)
    frames = []
    for k in range(4):
        frames.append(FrameInput(
            index=k, t=k * 0.05 + 1e-13 * k,
            image=rng.integers(0, 255, (H, W, 3), dtype=np.uint8),
            odometry=Odometry(float(rng.normal()), float(rng.normal()), 0.05),
            compass=float(rng.uniform(-math.pi, math.pi)) if k != 2 else None,
            truth=Pose(*map(float, rng.normal(size=3))),
        ))
    with DatasetWriter(tmp_path / "out", meta) as w:
        for f in frames:
            w.write(f)
    back = list(DatasetSource(tmp_path / "out"))
    assert len(back) == 4
    for a, b in zip(frames, back, strict=True):
        assert np.array_equal(a.image, b.image)
        assert a.t == b.t and a.compass == b.compass and a.truth == b.truth
    for k in range(3):
        assert back[k].odometry is not None and frames[k].odometry is not None
        assert back[k].odometry.speed == frames[k].odometry.speed
        assert back[k].odometry.yaw_rate == frames[k].odometry.yaw_rate
    assert DatasetSource(tmp_path / "out").meta.to_config().camera.width == W


def test_writer_refuses_non_empty_folder(tmp_path: Path) -> None:
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "keep.txt").write_text("precious")
    with pytest.raises(ValueError, match="exists and is not empty"):
        DatasetWriter(tmp_path / "x", DatasetMeta.from_config(Config()))
    assert (tmp_path / "x" / "keep.txt").read_text() == "precious"


def test_fault_labels_round_trip(tmp_path: Path) -> None:
    meta = DatasetMeta.from_config(Config())
    meta = DatasetMeta(**{**meta.__dict__, "image_width": W, "image_height": H})
    img = np.zeros((H, W, 3), np.uint8)
    with DatasetWriter(tmp_path / "f", meta) as w:
        for k, faults in enumerate([(), ("slip",), (), ("cable", "glare")]):
            w.write(FrameInput(index=k, t=0.1 * k, image=img, odometry=Odometry(0, 0, 0.1),
                               compass=None, faults=faults))
    back = list(DatasetSource(tmp_path / "f"))
    assert [f.faults for f in back] == [(), ("slip",), (), ("cable", "glare")]


def _frames_then_error(folder: Path, prefetch: int) -> tuple[list[FrameInput], str]:
    """Every frame delivered before the reader stopped, and its error ('' if none)."""
    got: list[FrameInput] = []
    try:
        for f in DatasetSource(folder, prefetch=prefetch):
            got.append(f)
    except DatasetError as e:
        return got, str(e)
    return got, ""


@pytest.mark.parametrize("damage", ["none", "bad row", "bad image", "missing image"])
def test_prefetch_gives_the_same_frames_and_the_same_error(tmp_path: Path, damage: str) -> None:
    """Decoding ahead on a thread changes nothing a user sees: same frames (pixels, odometry),
    and a bad row or image stops the replay at the same frame with the same message."""
    rows = [[str(i), f"{0.1 * i:.1f}", "pics/b.png" if i % 2 else "pics/c.png", "0.5", "0.1",
             "", "", "", ""] for i in range(12)]
    if damage == "bad row":
        rows[7][3] = "fast"
    elif damage == "missing image":
        rows[7][2] = "pics/gone.png"
    elif damage == "bad image":
        rows[7][2] = "pics/bad.png"
    folder = _foreign_dataset(tmp_path, rows)
    (folder / "pics" / "bad.png").write_bytes(b"\x89PNG not really")
    plain, plain_err = _frames_then_error(folder, 0)
    ahead, ahead_err = _frames_then_error(folder, 4)
    assert ahead_err == plain_err
    assert (plain_err == "") == (damage == "none")
    assert [f.index for f in ahead] == [f.index for f in plain]
    assert len(plain) == (12 if damage == "none" else 7)
    for a, b in zip(ahead, plain, strict=True):
        assert np.array_equal(a.image, b.image) and a.image.flags.c_contiguous
        assert a.odometry == b.odometry


def test_images_are_rgb(tmp_path: Path) -> None:
    """The file's pixels in RGB order (OpenCV decodes BGR)."""
    folder = _foreign_dataset(tmp_path)
    img = np.zeros((H, W, 3), np.uint8)
    img[..., 0] = 10  # blue in OpenCV's order
    img[..., 2] = 250  # red
    cv2.imwrite(str(folder / "pics" / "b.png"), img)
    frame = list(DatasetSource(folder, prefetch=2))[1]
    assert frame.image[0, 0].tolist() == [250, 0, 10]


def test_prefetch_must_be_a_count(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="prefetch must be an integer >= 0"):
        DatasetSource(_foreign_dataset(tmp_path), prefetch=-1)


@pytest.mark.parametrize("prefetch", [0, 2])
@pytest.mark.parametrize("kind", ["rgb8", "gray8", "rgba8", "rgb16", "gray16", "rgba16",
                                  "palette", "jpeg"])
def test_every_png_kind_reads_as_opencv_reads_it(tmp_path: Path, kind: str,
                                                  prefetch: int) -> None:
    """PNGs go through libspng (in the caller's thread) or OpenCV (a prefetching source), JPEGs
    through OpenCV; either way a frame's pixels are OpenCV's IMREAD_COLOR pixels in RGB order."""
    folder = _foreign_dataset(tmp_path)
    rng = np.random.default_rng(3)
    if kind.endswith("16"):
        img = rng.integers(0, 65536, (H, W, 3), dtype=np.uint16)
    else:
        img = rng.integers(0, 256, (H, W, 4), dtype=np.uint8)
    img = {"rgb8": img[..., :3], "gray8": img[..., 0], "rgba8": img, "rgb16": img[..., :3],
           "gray16": img[..., 0], "rgba16": img, "palette": img[..., :3],
           "jpeg": img[..., :3]}[kind]
    name = "pics/b.jpg" if kind == "jpeg" else "pics/b.png"
    if kind == "palette":  # OpenCV writes no palette PNG; Pillow does (RGB order)
        from PIL import Image

        Image.fromarray(np.ascontiguousarray(img)).quantize(64).save(folder / name)
        assert (folder / name).read_bytes()[25] == 3  # IHDR colour type 3: palette
    else:
        cv2.imwrite(str(folder / name), np.ascontiguousarray(img))
    if kind == "jpeg":
        lines = (folder / "frames.csv").read_text().replace("pics/b.png", name)
        (folder / "frames.csv").write_text(lines)
    expected = cv2.cvtColor(cv2.imread(str(folder / name), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    frame = list(DatasetSource(folder, prefetch=prefetch))[1]
    assert frame.image.dtype == np.uint8 and frame.image.shape == (H, W, 3)
    assert np.array_equal(frame.image, expected)


def test_png_level_trades_disk_for_speed(tmp_path: Path) -> None:
    """Level 0 (the default) stores the pixels; level 9 compresses; both read back exactly."""
    rng = np.random.default_rng(5)
    meta = DatasetMeta.from_config(Config())
    meta = DatasetMeta(**{**meta.__dict__, "image_width": W, "image_height": H})
    img = np.repeat(rng.integers(100, 110, (H, W, 1), dtype=np.uint8), 3, axis=2)
    sizes = {}
    for level in (0, 9):
        with DatasetWriter(tmp_path / f"l{level}", meta, png_level=level) as w:
            w.write(FrameInput(index=0, t=0.0, image=img, odometry=None, compass=None))
        sizes[level] = (tmp_path / f"l{level}" / "images" / "000000.png").stat().st_size
        assert np.array_equal(next(iter(DatasetSource(tmp_path / f"l{level}"))).image, img)
    assert sizes[0] > 3 * W * H > 2 * sizes[9]
    with pytest.raises(ValueError, match="png_level must be an integer 0..9"):
        DatasetWriter(tmp_path / "bad", meta, png_level=10)


def test_row_count_for_the_progress_bar(tmp_path: Path) -> None:
    folder = _foreign_dataset(tmp_path)
    with open(folder / "frames.csv", "a", encoding="utf-8") as f:
        f.write("\n , , \n")  # blank rows: skipped by the reader, not counted
    src = DatasetSource(folder)
    assert src.row_count() == 3 == len(list(src))
