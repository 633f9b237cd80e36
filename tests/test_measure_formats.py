"""High-speed camera files: Phantom .cine and Photron .cih/.cihx + .mraw, written by the tests
(tests/camera_files.py): pixels, frame count, frame rate, timestamps, region reads, bad files,
and the same track as from a TIFF stack."""

import json
import struct
import warnings

import numpy as np
import pandas as pd
import pytest
import tifffile
from camera_files import pack12, write_cihx, write_cine, write_mraw
from measure_data import make_recording

from rollfric.cli.main import main
from rollfric.io.readers import RecordingError, open_recording
from rollfric.setup.model import save_setup
from rollfric.track.timestamps import frame_times

rng = np.random.default_rng(5)


def _frames(bits, n=6, h=24, w=32):
    hi = {8: 255, 10: 1023, 12: 4095, 16: 65535}[bits]
    return rng.integers(0, hi + 1, (n, h, w)).astype(np.uint8 if bits == 8 else np.uint16)


def _rois(h, w):
    r = np.random.default_rng(h * w)
    out = [(0, h, 0, w), (0, 1, 0, 1), (h - 1, h, w - 1, w), (0, h, w - 3, w), (h - 2, h, 0, w),
           (3, 4, 0, w)]
    for _ in range(25):
        y0, x0 = int(r.integers(0, h)), int(r.integers(0, w))
        out.append((y0, int(r.integers(y0 + 1, h + 1)), x0, int(r.integers(x0 + 1, w + 1))))
    return out


def _check_pixels(src, frames):
    n, h, w = frames.shape
    assert src.shape == frames.shape and len(src) == n and src.dtype == frames.dtype
    for i in range(n):
        np.testing.assert_array_equal(src[i], frames[i])
    for k, roi in enumerate(_rois(h, w)):
        i = k % n
        y0, y1, x0, x1 = roi
        crop = src.read(i, roi)
        assert crop.dtype == frames.dtype and crop.flags.c_contiguous
        np.testing.assert_array_equal(crop, frames[i, y0:y1, x0:x1])
    with pytest.raises(IndexError, match="roi"):
        src.read(0, (0, h + 1, 0, 2))
    with pytest.raises(IndexError, match="out of range"):
        src[n]


@pytest.mark.parametrize("bits,packed", [(8, False), (16, False), (12, True)])
def test_cine_pixels_rate_times_and_regions(tmp_path, bits, packed):
    import pims

    frames = _frames(bits, h=25, w=34)
    # the camera's own clock: 1 kHz with a little jitter, frame 0 taken 10 ms after the trigger
    times = np.arange(6) / 1000.0 + np.array([0, 3, -2, 5, 0, 1]) * 1e-7
    p = write_cine(tmp_path / "rec.cine", frames, fps=1000.0, times=times, trigger=-0.01,
                   packed12=packed)
    src = open_recording(p)
    _check_pixels(src, frames)
    assert src.fps == 1000.0
    # TIME64 has 2**-32 s steps
    np.testing.assert_allclose(src.timestamps, times - times[0], rtol=0, atol=2 ** -31)
    assert src.attrs["frame0_from_trigger_s"] == pytest.approx(0.01, abs=2 ** -31)
    assert src.attrs["camera_bit_depth"] == bits and src.attrs["format"] == "phantom-cine"
    # the same pixels as pims' own frame reader
    ref = pims.Cine(str(p))
    for i in (0, 5):
        np.testing.assert_array_equal(src[i], np.asarray(ref[i]))


@pytest.mark.parametrize("bits", [8, 12, 16])
def test_photron_pixels_rate_and_regions(tmp_path, bits):
    import pyMRAW

    frames = _frames(8 if bits == 8 else 12 if bits == 12 else 16, h=20, w=36)
    cih, mraw = write_mraw(tmp_path / "rec.cih", frames, fps=2000, bits=bits, start_frame=-3)
    for path in (cih, mraw):  # the header or the frames file
        src = open_recording(path)
        _check_pixels(src, frames)
        assert src.fps == 2000.0 and src.timestamps is None
        assert src.attrs["start_frame"] == -3 and src.attrs["format"] == "photron-mraw"
    # the same pixels as pyMRAW's reader (its own 12-bit unpacking)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pyMRAW warns of any file that is not 12-bit
        ref, _ = pyMRAW.load_video(str(cih))
    np.testing.assert_array_equal(np.stack([src[i] for i in range(len(src))]), ref)


def test_photron_12_bit_odd_width_and_cihx(tmp_path):
    # an odd width: rows do not start on a 3-byte pair
    frames = _frames(12, n=5, h=9, w=13)
    (tmp_path / "odd.mraw").write_bytes(pack12(frames))
    write_cihx(tmp_path / "odd.cihx", 5, 9, 13, fps=5000, bits=12)
    src = open_recording(tmp_path / "odd.cihx")
    _check_pixels(src, frames)
    assert src.fps == 5000.0 and src.attrs["camera"] == "test"
    assert open_recording(tmp_path / "odd.mraw").attrs["header"].endswith("odd.cihx")


def test_frame_times(tmp_path):
    frames = _frames(8, n=8)
    # a dropped frame (a 2 ms gap) and a camera at 1002 Hz: both reported, times used as given
    times = np.r_[np.arange(5), np.arange(6, 9)] / 1002.0
    src = open_recording(write_cine(tmp_path / "a.cine", frames, fps=1002.0, times=times))
    t, desc, notes = frame_times(src, 1000.0)
    np.testing.assert_allclose(t, times, atol=2 ** -31)
    assert desc == "the recording's timestamps" and len(notes) == 2
    assert "1002 frames/s" in notes[0] and "1000 Hz" in notes[0]
    assert "1 of the recording's 7 frame intervals" in notes[1]
    t, desc, notes = frame_times(src, 1000.0, "fps")
    np.testing.assert_array_equal(t, np.arange(8) / 1000.0)
    assert desc == "frame / camera.fps" and notes == []
    # a recording without timestamps
    cih, _ = write_mraw(tmp_path / "b.cih", frames, fps=1000)
    t, desc, notes = frame_times(open_recording(cih), 1000.0)
    np.testing.assert_array_equal(t, np.arange(8) / 1000.0)
    assert desc == "frame / camera.fps" and notes == []


def _bad(capsys, path, match, tmp_path, names=None):
    out = tmp_path / "bad_out"
    code = main(["measure", str(path), "--setup", str(tmp_path / "setup.toml"), "--out",
                 str(out), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert str(names or path) in err and match in err, err
    assert "Traceback" not in err and not out.exists()
    with pytest.raises(RecordingError, match=match):
        open_recording(path)


def test_bad_camera_files_exit_2(tmp_path, capsys):
    save_setup(make_recording(5).setup, tmp_path / "setup.toml")
    frames = _frames(16)
    good = write_cine(tmp_path / "good.cine", frames).read_bytes()
    table = struct.unpack_from("<I", good, 32)[0]  # CINEFILEHEADER's OffImageOffsets
    # cut inside the last frame, before or inside the offsets table, inside the header; not a
    # cine
    for name, data, match in [("cut_frame.cine", good[:-10], "truncated cine file: frame 5"),
                              ("no_table.cine", good[:table], "offsets is missing"),
                              ("cut_table.cine", good[:table + 12], "not a readable Phantom"),
                              ("cut_header.cine", good[:30], "not a readable Phantom cine"),
                              ("junk.cine", b"XX" + good[2:], "no 'CI' signature"),
                              ("empty.cine", b"", "not a readable Phantom cine")]:
        (tmp_path / name).write_bytes(data)
        _bad(capsys, tmp_path / name, match, tmp_path)
    cih, mraw = write_mraw(tmp_path / "rec.cih", frames)
    mraw.write_bytes(mraw.read_bytes()[:-1])
    _bad(capsys, cih, "truncated MRAW file", tmp_path, names=mraw)
    _bad(capsys, mraw, "truncated MRAW file", tmp_path)
    mraw.unlink()
    _bad(capsys, cih, "rec.mraw is missing", tmp_path)
    (tmp_path / "lone.mraw").write_bytes(bytes(100))
    _bad(capsys, tmp_path / "lone.mraw", "no .cih or .cihx header", tmp_path)
    cih2, _ = write_mraw(tmp_path / "colour.cih", frames)
    cih2.write_text(cih2.read_text().replace("Color Type : Mono", "Color Type : Color"))
    _bad(capsys, cih2, "monochrome", tmp_path)
    cih3, _ = write_mraw(tmp_path / "nokey.cih", frames)
    cih3.write_text(cih3.read_text().replace("Image Width", "Width"))
    _bad(capsys, cih3, "Image Width", tmp_path)
    (tmp_path / "junk.cihx").write_text("<cih><fileInfo></cih>")
    (tmp_path / "junk.mraw").write_bytes(bytes(10))
    _bad(capsys, tmp_path / "junk.cihx", "not a readable Photron header", tmp_path)


def test_cine_and_mraw_give_the_tiff_track(tmp_path, capsys):
    rec = make_recording(160, noise=1.0, fps=200.0)
    frames = np.stack(rec.frames)
    tifffile.imwrite(tmp_path / "rec.tif", frames)
    write_cine(tmp_path / "rec.cine", frames, fps=200.0)
    cih, _ = write_mraw(tmp_path / "rec.cih", frames, fps=200)
    save_setup(rec.setup, tmp_path / "setup.toml")
    out = {}
    for name in ("rec.tif", "rec.cine", "rec.cih"):
        d = tmp_path / ("out_" + name.replace(".", "_"))
        assert main(["measure", str(tmp_path / name), "--setup", str(tmp_path / "setup.toml"),
                     "--out", str(d), "--no-progress"]) == 0
        out[name] = (pd.read_csv(d / "track.csv"), json.loads((d / "fit.json").read_text()))
    capsys.readouterr()
    ref, ref_fit = out["rec.tif"]
    assert ref["found"].all() and ref_fit["times"] == "frame / camera.fps"
    for name in ("rec.cine", "rec.cih"):
        df, fit = out[name]
        for col in ("frame", "x_px", "y_px", "theta_rad", "found"):
            np.testing.assert_array_equal(df[col], ref[col])
        # the cine's times are its TIME64 stamps of i / 200 s (2**-32 s steps)
        np.testing.assert_allclose(df["t_s"], ref["t_s"], rtol=0, atol=1e-6)
        assert fit["mu"] == pytest.approx(ref_fit["mu"], rel=1e-6)
        assert fit["warnings"] == ref_fit["warnings"]
    assert out["rec.cine"][1]["times"] == "the recording's timestamps"
    assert out["rec.cih"][1]["times"] == "frame / camera.fps"
