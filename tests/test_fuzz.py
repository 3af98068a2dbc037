"""Fuzzed inputs (issue 33): a short deterministic run of every reader's fuzzing
(``tileviz/testing/fuzzing.py``; the campaign is ``bench/fuzz.py``), and one regression test for
each defect a campaign found. Every case ends in success or one line naming the file and the
problem: never a traceback, a decoder's own message, a hang or gigabytes of memory."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from tileviz.__main__ import main as tileviz_main
from tileviz.testing.fuzz_cases import READERS, Templates, fix_png_crcs, png_bytes
from tileviz.testing.fuzzing import campaign, describe

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_a_short_fuzzing_run_of_every_reader_finds_nothing() -> None:
    report = campaign(list(READERS), 10, seed=33, workers=1, timeout=300)
    assert report.findings == [], "\n".join(describe(f) for f in report.findings)
    assert all(sum(c.values()) == 10 for c in report.counts.values())
    # the cases reach both answers: some inputs are read, most are refused in one line
    assert sum(c["ok"] for c in report.counts.values()) > 0
    assert sum(c["error"] for c in report.counts.values()) > 0
    assert report.peak_rss_mb < 1024


@pytest.fixture(scope="module")
def templates(tmp_path_factory: pytest.TempPathFactory) -> Templates:
    return Templates(tmp_path_factory.mktemp("templates"))


@pytest.fixture()
def dataset(templates: Templates, tmp_path: Path) -> Path:
    shutil.copytree(templates.dataset, tmp_path / "ds")
    return tmp_path / "ds"


def _replay(ds: Path, capfd: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    """``replay`` in this process; its exit status and every line on file descriptor 2 (what C
    libraries print included)."""
    code = tileviz_main(["replay", str(ds), "--out", str(ds.parent / "r.csv"), "--jobs", "1",
                         "--quiet"])
    return code, capfd.readouterr().err.strip().splitlines()


def test_a_frames_csv_cell_beyond_the_csv_modules_limit_is_one_line(
        dataset: Path, capfd: pytest.CaptureFixture[str]) -> None:
    with open(dataset / "frames.csv", "a") as f:
        f.write("3,0.15," + "x" * 200_000 + ",0.1,0,0,0,0,0\r\n")
    code, err = _replay(dataset, capfd)
    assert code == 2 and len(err) == 1
    assert (f"{dataset / 'frames.csv'} line 5: not a CSV row (field larger than field limit"
            in err[0])


def test_a_huge_frames_csv_header_is_one_line(dataset: Path,
                                              capfd: pytest.CaptureFixture[str]) -> None:
    (dataset / "frames.csv").write_text("index,t," + "y" * 200_000 + "\n")
    code, err = _replay(dataset, capfd)
    assert code == 2 and err == [f"tileviz replay: error: {dataset / 'frames.csv'} line 1: not a "
                                 "CSV header (field larger than field limit (131072))"]


def test_a_dataset_that_ended_early_and_has_a_bad_row_says_only_the_error(
        dataset: Path, capfd: pytest.CaptureFixture[str]) -> None:
    lines = (dataset / "frames.csv").read_text().splitlines()
    lines[2] = lines[2].replace("0.1", "nan", 1)
    (dataset / "frames.csv").write_text("\n".join(lines[:3]) + "\n")  # 2 of 3 rows, one bad
    code, err = _replay(dataset, capfd)
    assert code == 2 and len(err) == 1
    assert "frames.csv line 3 (frame 1): speed is not finite" in err[0]


def _bad_idat_png() -> bytes:
    """A whole PNG (every CRC right) whose image data does not inflate."""
    good = png_bytes(64, 48)
    i = good.index(b"IDAT") + 4
    bad = good[:i + 2] + bytes(b ^ 0x5A for b in good[i + 2:i + 40]) + good[i + 40:]
    return fix_png_crcs(bad)


def _idat_first_png() -> bytes:
    """A PNG (every CRC right) whose first chunk is not IHDR: OpenCV's own log line says so."""
    good = bytearray(png_bytes(64, 48))
    good[12:16] = b"IDAT"
    return fix_png_crcs(bytes(good))


def _corrupt_jpeg() -> bytes:
    img = np.random.default_rng(0).integers(0, 255, (48, 64, 3), dtype=np.uint8)
    buf = bytearray(cv2.imencode(".jpg", img)[1].tobytes())
    for i in range(len(buf) // 2, len(buf) // 2 + 40):
        buf[i] = 0x00 if i % 2 else 0xD5
    return bytes(buf)


@pytest.mark.parametrize(("data", "why"), [
    (png_bytes(64, 0), "64x0"),  # replay: not the meta's size; extract: an empty image
    (png_bytes(64, 48, color_type=1), "libpng error: Invalid IHDR data"),
    (_bad_idat_png(), "libpng error"),
    (_corrupt_jpeg(), "Corrupt JPEG data"),
    (_idat_first_png(), "(IHDR chunk shall be first. This data may be broken or malformed.)"),
], ids=["empty", "bad-header", "bad-data", "corrupt-jpeg", "ihdr-not-first"])
@pytest.mark.parametrize("reader", ["replay", "extract"])
def test_what_the_image_decoders_say_is_the_reason_in_one_line(
        data: bytes, why: str, reader: str, dataset: Path,
        capfd: pytest.CaptureFixture[str]) -> None:
    """libpng, libjpeg and OpenCV's codecs print their complaints on stderr (and libjpeg returns
    the damaged pixels): tileviz refuses the image, the complaint inside its own one line."""
    if reader == "replay":
        (dataset / "images/000001.png").write_bytes(data)
        code, err = _replay(dataset, capfd)
        name = "images/000001.png"
    else:
        name = str(dataset / "view.img")
        Path(name).write_bytes(data)
        code = tileviz_main(["extract", name, "--tile-size", "0.25", "--ppm", "100"])
        err = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert name in err[0] and why in err[0]


@pytest.mark.parametrize("reader", ["replay", "extract", "import-bag"])
def test_a_header_claiming_100000_pixels_is_refused_before_anything_is_decoded(
        reader: str, dataset: Path, templates: Templates, capfd: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    import pyspng

    wide = png_bytes(100_000, 48)

    def guarded(decode):  # the decoder, refusing to be given the oversized file
        def call(data, *args, **kw):
            if bytes(data[:24]) == wide[:24]:
                raise AssertionError("an oversized image reached a decoder")
            return decode(data, *args, **kw)
        return call

    monkeypatch.setattr(cv2, "imdecode", guarded(cv2.imdecode))
    monkeypatch.setattr(pyspng, "load", guarded(pyspng.load))
    if reader == "replay":
        (dataset / "images/000001.png").write_bytes(wide)
        code, err = _replay(dataset, capfd)
        assert code == 2 and len(err) == 1
        assert "image 'images/000001.png' is 100000x48, meta.json says 64x48" in err[0]
        return
    if reader == "extract":
        path = dataset.parent / "wide.png"
        path.write_bytes(wide)
        code = tileviz_main(["extract", str(path), "--tile-size", "0.25", "--ppm", "100"])
        err = capfd.readouterr().err.strip().splitlines()
        assert code == 2 and err == [f"tileviz extract: error: {path}: its header declares "
                                     "100000x48 pixels, more than tileviz reads (at most 32768 "
                                     "a side and 67108864 in all)"]
        return
    from tileviz.datasets.bag_import import decode_image_message

    class Msg:
        format = "png"
        data = wide

    with pytest.raises(Exception, match="its header declares 100000x48 pixels"):
        decode_image_message(Msg(), "sensor_msgs/msg/CompressedImage",
                             "bag: '/camera/image' message 0")


def test_a_meta_json_nested_beyond_the_parsers_depth_is_one_line(
        dataset: Path, capfd: pytest.CaptureFixture[str]) -> None:
    (dataset / "meta.json").write_text("[" * 100_000)
    code, err = _replay(dataset, capfd)
    assert code == 2 and err == [f"tileviz replay: error: {dataset / 'meta.json'}: not valid "
                                 "JSON (nested too deeply)"]


@pytest.mark.parametrize(("key", "value", "needle"), [
    ("image_width", 10_000, "image width must be an integer in [16, 8192], got 10000"),
    ("tile_size", 1e5, "a tile must span at most 100000 pixels (tile_size * ppm), got 10000000.0"),
])
def test_a_meta_the_configuration_refuses_names_meta_json(
        key: str, value: float, needle: str, dataset: Path,
        capfd: pytest.CaptureFixture[str]) -> None:
    meta = json.loads((dataset / "meta.json").read_text())
    meta[key] = value
    (dataset / "meta.json").write_text(json.dumps(meta))
    code, err = _replay(dataset, capfd)
    assert code == 2 and len(err) == 1
    assert err[0].startswith(f"tileviz replay: error: {dataset / 'meta.json'}: ")
    assert needle in err[0]


@pytest.mark.parametrize("size", [(1 << 31, 2), (40_000, 40_000)])
def test_a_meta_json_view_too_large_to_rectify_is_one_line_before_any_table(
        size: tuple[int, int], templates: Templates, tmp_path: Path,
        capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """A dataset with a camera_model whose meta.json claims a 2^31-pixel-wide view: refused in
    one line naming meta.json and the size, and no rectification table is made (a campaign
    found it allocating 16 GiB for one)."""
    import tileviz.datasets.camera_model as camera_model

    def refuse(*args: object, **kw: object) -> None:
        raise AssertionError("a rectification table was made")

    monkeypatch.setattr(camera_model, "rectified_floor_points", refuse)
    ds = tmp_path / "ds"
    shutil.copytree(templates.lens_dataset, ds)
    meta = json.loads((ds / "meta.json").read_text())
    assert meta["camera_model"] is not None
    meta["image_width"], meta["image_height"] = size
    (ds / "meta.json").write_text(json.dumps(meta))
    code, err = _replay(ds, capfd)
    assert code == 2 and len(err) == 1
    assert err[0] == (f"tileviz replay: error: {ds / 'meta.json'}: image_width x image_height is "
                      f"{size[0]}x{size[1]}, more than tileviz reads (at most 32768 a side and "
                      "67108864 pixels in all)")


def test_a_stored_config_with_two_truth_inflations_is_not_a_traceback(
        dataset: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """meta.json's tileviz_config with a truth_inflation of 2 values: the stored configuration is
    refused like any other it cannot read (the replay takes the defaults), not a localizer error
    that names no file (found by bench/fuzz.py's meta reader)."""
    meta = json.loads((dataset / "meta.json").read_text())
    meta["tileviz_config"]["localizer"]["truth_inflation"] = [0.3, 0.2]
    (dataset / "meta.json").write_text(json.dumps(meta))
    code, err = _replay(dataset, capfd)
    assert code == 0 and err == [], err


def test_a_results_file_whose_length_field_is_huge_allocates_nothing(templates: Templates,
                                                                      tmp_path: Path) -> None:
    """A results file of 16 bytes that says a 2 GiB bytearray follows: read in a process whose
    address space is 1.5 GiB, the answer is that the file is cut short, not a MemoryError."""
    store = tmp_path / "store"
    shutil.copytree(templates.store, store)
    (store / "runs/clean-r0-s0.pkl").write_bytes(b"\x80\x05\x96" + (2 << 30).to_bytes(8, "little")
                                                 + b"abc.")
    script = f"""
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (3 << 29, 3 << 29))
from pathlib import Path
from tileviz.evaluation.store import load_run
try:
    load_run(Path({str(store / 'runs/clean-r0-s0.pkl')!r}), ("clean", 0, 0))
except ValueError as e:
    print(e)
"""
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=300, cwd=REPO, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin"})
    assert "bytearray8" in r.stdout and "MemoryError" not in r.stdout, (r.stdout, r.stderr)
    assert r.stderr == ""


def test_a_results_file_of_another_kind_is_refused_unpickled(templates: Templates,
                                                             tmp_path: Path) -> None:
    """Only a run's results are unpickled: a planted file that would call something else is
    refused before anything runs."""
    import pickle

    from tileviz.evaluation.store import load_run

    target = tmp_path / "ran"

    class Plant:
        def __reduce__(self) -> tuple:
            return (Path.touch, (target,))

    file = tmp_path / "x.pkl"
    file.write_bytes(pickle.dumps(Plant()))
    with pytest.raises(ValueError, match="pathlib.Path.touch is not part of a run's results"):
        load_run(file, ("clean", 0, 0))
    assert not target.exists()
    file.write_bytes(pickle.dumps([1, 2]))
    with pytest.raises(ValueError, match="it holds a list, not a run's results"):
        load_run(file, ("clean", 0, 0))


def test_a_campaign_json_key_with_line_breaks_stays_one_line(
        templates: Templates, tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    from tileviz.testing.fuzzing import _store_command

    store = tmp_path / "store"
    shutil.copytree(templates.store, store)
    doc = json.loads((store / "campaign.json").read_text())
    doc["a\nb\u2028c"] = 1
    (store / "campaign.json").write_text(json.dumps(doc))
    assert _store_command(store) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'a\\nb\\u2028c' was 1 there, now None" in err[0]


def test_a_run_whose_mcl_lost_the_truth_by_far_is_read_back(templates: Templates,
                                                            tmp_path: Path) -> None:
    """MCL's squared Mahalanobis distance of the truth grows without bound when its particles
    collapse away from it (1e12, inf): a run holding it is its result, read back as kept."""
    import pickle

    from tileviz.evaluation.store import load_run

    file = tmp_path / "run.pkl"
    res = pickle.loads((templates.store / "runs/clean-r0-s0.pkl").read_bytes())
    res.methods["mcl"].d2[0] = 1e12
    res.methods["mcl"].d2[-1] = math.inf
    file.write_bytes(pickle.dumps(res))
    back = load_run(file, ("clean", 0, 0))
    assert back.methods["mcl"].d2[0] == 1e12 and back.methods["mcl"].d2[-1] == math.inf


def _drop_truth(res: object) -> None:
    del res.truth  # type: ignore[attr-defined]


def _rename_method(res: object) -> None:
    res.methods["mcl-untuned2"] = res.methods.pop("mcl-untuned")  # type: ignore[attr-defined]


def _short_status(res: object) -> None:
    res.methods["mcl"].status = res.methods["mcl"].status[:-1]  # type: ignore[attr-defined]


def _other_run(res: object) -> None:
    res.run = 7  # type: ignore[attr-defined]


def _huge_truth(res: object) -> None:
    res.truth[0, 0] = 1e300  # type: ignore[attr-defined]


def _negative_d2(res: object) -> None:
    res.methods["mcl"].d2[0] = -1.0  # type: ignore[attr-defined]


@pytest.mark.parametrize(("damage", "said"), [
    (_drop_truth, "truth is not an array of numbers"),
    (_rename_method, "it has no results of the method(s) mcl-untuned"),
    (_short_status, "method mcl: status has shape"),
    (_other_run, "it holds the run ('clean', 7, 0), not ('clean', 0, 0)"),
    (_huge_truth, "truth holds numbers beyond +-1e+09"),
    (_negative_d2, "method mcl: d2 holds negative numbers"),
], ids=["missing-field", "missing-method", "wrong-shape", "other-run", "huge-number",
        "negative-distance"])
def test_a_results_file_that_unpickles_to_a_damaged_run_is_one_line(
        damage: object, said: str, templates: Templates, tmp_path: Path,
        capfd: pytest.CaptureFixture[str]) -> None:
    """A results file damaged so that it still unpickles as a run (a field gone, a method
    renamed, an array cut, another run's numbers): --resume refuses it in one line naming the
    file, not with a traceback from the report's tables (found by bench/fuzz.py's store
    reader)."""
    import pickle

    from tileviz.testing.fuzzing import _store_command

    store = tmp_path / "store"
    shutil.copytree(templates.store, store)
    file = store / "runs/clean-r0-s0.pkl"
    res = pickle.loads(file.read_bytes())
    damage(res)  # type: ignore[operator]
    file.write_bytes(pickle.dumps(res))
    assert _store_command(store) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(file) in err[0] and said in err[0], err


def test_a_faults_csv_that_is_not_csv_is_one_line(dataset: Path,
                                                  capfd: pytest.CaptureFixture[str]) -> None:
    (dataset / "faults.csv").write_text("index,faults\n1," + "s" * 200_000 + "\n")
    code, err = _replay(dataset, capfd)
    assert code == 2 and len(err) == 1 and "faults.csv line 2: not a CSV row" in err[0]


def test_png_bytes_makes_what_the_decoders_read() -> None:
    """The fuzzer's hand-made PNGs are real PNGs (so its header cases test the readers)."""
    data = png_bytes(64, 48)
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.shape == (48, 64, 3)
    assert zlib.crc32(data[12:29]) == int.from_bytes(data[29:33], "big")


def test_other_output_printed_while_an_image_decodes_still_reaches_stderr(
        capfd: pytest.CaptureFixture[str]) -> None:
    """Only the decoders' lines are kept back: another thread's line printed meanwhile is passed
    on."""
    import os

    from tileviz.datasets.images import decoder_messages

    with decoder_messages() as said:
        os.write(2, b"libpng warning: iCCP: known incorrect sRGB profile\n")
        os.write(2, b"tileviz serve: a note of another thread\n")
        os.write(2, b"Corrupt JPEG data: 3 extraneous bytes before marker 0xd9\n")
    assert said == ["libpng warning: iCCP: known incorrect sRGB profile",
                    "Corrupt JPEG data: 3 extraneous bytes before marker 0xd9"]
    assert capfd.readouterr().err == "tileviz serve: a note of another thread\n"


def test_a_harmless_decoder_warning_does_not_refuse_the_image() -> None:
    """A PNG with a colour profile libpng warns about is still read (only damage refuses)."""
    from tileviz.datasets.images import decode_image

    icc = zlib.compress(b"\x00" * 200)
    data = png_bytes(64, 48, extra=((b"iCCP", b"bad profile\x00\x00" + icc),))
    complaints: list[str] = []
    img = decode_image(data, spng=False, complaints=complaints)
    assert img is not None and img.shape == (48, 64, 3) and complaints == []
