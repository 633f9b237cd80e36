"""``rollfric info``: what a recording holds, against the reference readers on the real camera
files (tests/data/real) and against what the tests wrote for the other formats."""

import json
import warnings

import numpy as np
import pytest
import tifffile
from test_real_camera_files import CINES, EXPECTED, P10, PHOTRONS, REAL

from rollfric.cli.main import main
from rollfric.io.formats.phantom_lut import P10_BITS


def _info(capsys, *argv):
    code = main(["info", *map(str, argv), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


@pytest.mark.parametrize("name", CINES)
def test_info_of_the_real_cine_files_against_pims(capsys, name):
    import pims

    ref = pims.Cine(str(REAL / name))
    info = _info(capsys, REAL / name)
    n, w, h, dtype, bits, fps, _, start = EXPECTED[name]
    hw = np.asarray(ref[0]).shape
    assert (info["n_frames"], info["height"], info["width"]) == (len(ref), *hw)
    assert (info["n_frames"], info["width"], info["height"]) == (n, w, h)
    assert info["dtype"] == np.dtype(dtype).name and info["colour"] == "mono"
    assert bits == ref.setup_fields_dict["real_bpp"]
    # a P10 cine's frames are the maker's linear 12-bit values
    assert info["bit_depth"] == (P10_BITS if name in P10 else bits)
    assert info["fps"] == ref.frame_rate == fps
    assert info["shutter_s"] == pytest.approx(float(np.median(ref.all_exposures)), rel=1e-12)
    assert info["start_frame"] == start == ref.header_dict["first_image_no"]
    d0, f0 = ref.frame_time_stamps[0]
    t = [(d - d0).total_seconds() + f - f0 for d, f in ref.frame_time_stamps]
    assert info["fps_timestamps"] == pytest.approx(1 / np.median(np.diff(t)), rel=1e-12)
    assert info["duration_s"] == pytest.approx(t[-1], rel=1e-12)
    rate_notes = [m for m in info["warnings"] if "header says" in m]
    if name == "cine_781.cine":  # the header's 90000 against the times' 9003 Hz
        assert info["fps_timestamps"] == pytest.approx(9003.22, abs=0.01)
        assert len(rate_notes) == 1 and "90000 frames/s" in rate_notes[0]
    else:
        assert rate_notes == []
    # microsecond times (cine_legacy): no interval note
    intervals = [m for m in info["warnings"] if "frame intervals" in m]
    assert len(intervals) == (1 if name == "data_small_cine.cine" else 0)  # its last time: 2027


@pytest.mark.parametrize("name", PHOTRONS)
def test_info_of_the_real_photron_files_against_pymraw(capsys, name):
    import pyMRAW

    cih = pyMRAW.get_cih(str(REAL / name))
    info = _info(capsys, REAL / name)
    n, w, h, dtype, bits, fps, shutter, start = EXPECTED[name]
    assert (info["n_frames"], info["width"], info["height"]) == (
        cih["Total Frame"], cih["Image Width"], cih["Image Height"]) == (n, w, h)
    assert info["fps"] == cih["Record Rate(fps)"] == fps and info["fps_timestamps"] is None
    assert info["dtype"] == np.dtype(dtype).name and info["bit_depth"] == bits
    assert info["shutter_s"] == pytest.approx(shutter, rel=1e-12)
    assert info["start_frame"] == start and info["colour"] == "mono"
    assert info["camera"] == cih["Camera Type"]
    assert info["duration_s"] == pytest.approx((n - 1) / fps)
    short = [m for m in info["warnings"] if "rollfric track" in m]
    assert len(short) == (n < 50)


def test_info_text_shows_both_rates_and_the_exposure_in_seconds(capsys):
    assert main(["info", str(REAL / "cine_781.cine")]) == 0
    out = capsys.readouterr().out
    assert "90000 Hz (header)" in out and "9003.22 Hz (the per-frame times)" in out
    assert "shutter:" in out and "9.69646 us" in out and "-5417" in out
    assert main(["info", str(REAL / "ball_12bit.cihx")]) == 0
    out = capsys.readouterr().out
    assert "20 us" in out and "start frame: 52" in out and "per-frame times" not in out


def test_info_of_tiff_folder_video_and_zarr(tmp_path, capsys):
    import cv2
    import zarr

    rng = np.random.default_rng(3)
    frames = rng.integers(0, 4096, (5, 12, 16)).astype(np.uint16)
    tifffile.imwrite(tmp_path / "rec.tif", frames, photometric="minisblack")
    info = _info(capsys, tmp_path / "rec.tif")
    assert (info["n_frames"], info["width"], info["height"], info["dtype"]) == (5, 16, 12,
                                                                                "uint16")
    assert info["fps"] is None and info["colour"] == "mono"
    if info["bit_depth_from"] == "dtype":
        assert info["bit_depth"] == 16
    assert any("no frame rate" in m for m in info["warnings"])
    # a colour TIFF is read as grey, and said so
    rgb = rng.integers(0, 256, (3, 12, 16, 3)).astype(np.uint8)
    tifffile.imwrite(tmp_path / "rgb.tif", rgb, photometric="rgb")
    info = _info(capsys, tmp_path / "rgb.tif")
    assert info["n_frames"] == 3 and info["colour"] == "colour, read as grey"
    # a folder of PNGs, one of them colour
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(4):
        cv2.imwrite(str(folder / f"f{i}.png"), rgb[0] if i == 0 else rgb[0, ..., 0])
    info = _info(capsys, folder)
    assert (info["n_frames"], info["width"], info["height"]) == (4, 16, 12)
    assert info["colour"] == "colour, read as grey" and info["dtype"] == "uint8"
    # a grey video (OpenCV decodes it to three equal channels) and its rate
    vw = cv2.VideoWriter(str(tmp_path / "v.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25.0,
                         (16, 12))
    for i in range(6):
        vw.write(cv2.cvtColor(np.full((12, 16), 40 * i, np.uint8), cv2.COLOR_GRAY2BGR))
    vw.release()
    info = _info(capsys, tmp_path / "v.avi")
    assert (info["n_frames"], info["width"], info["height"]) == (6, 16, 12)
    assert info["fps"] == pytest.approx(25.0) and info["colour"] == "mono"
    # a Zarr store with times of its own: both rates
    g = zarr.open_group(str(tmp_path / "rec.zarr"), mode="w")
    g.create_array("frames", data=frames)
    g.create_array("timestamps", data=np.arange(5) / 1000.0)
    g.attrs["fps"] = 500.0
    info = _info(capsys, tmp_path / "rec.zarr")
    assert info["n_frames"] == 5 and info["fps"] == 500.0
    assert info["fps_timestamps"] == pytest.approx(1000.0)
    assert any("header says 500 frames/s" in m for m in info["warnings"])


def test_info_of_bad_input_exits_2_with_the_reason(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("x")
    assert main(["info", str(tmp_path / "notes.txt")]) == 2
    err = capsys.readouterr().err
    assert "notes.txt: unknown recording format" in err and "Traceback" not in err
    (tmp_path / "cut.cine").write_bytes((REAL / "cine_781.cine").read_bytes()[:-10])
    assert main(["info", str(tmp_path / "cut.cine")]) == 2
    err = capsys.readouterr().err
    assert "cut.cine: truncated cine file" in err
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["info", str(tmp_path / "missing.cihx")]) == 2
    assert "missing.cihx: no such file" in capsys.readouterr().err
