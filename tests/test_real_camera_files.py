"""Real camera files (tests/data/real, other projects' public test data): every reader pixel for
pixel against the reference reader (pims for .cine, pyMRAW for .cih/.cihx + .mraw), full
frames and regions, and every header field rollfric reports against the file itself."""

import datetime
import shutil
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from camera_files import write_cine

from rollfric.io.formats.phantom_lut import P10_BITS, P10_TO_LINEAR
from rollfric.io.readers import RecordingError, open_recording
from rollfric.track.timestamps import frame_times

REAL = Path(__file__).parent / "data" / "real"
CINES = ["cine_781.cine", "cine_legacy.cine", "data_small_cine.cine"]
PHOTRONS = ["ball_12bit.cihx", "beam.cihx", "data_showcase.cih"]
# packed 10-bit (P10) cines: rollfric gives the maker's linear 12-bit values, pims the codes
P10 = {"data_small_cine.cine"}

# what each file says, read off it by hand (the .cihx/.cih text; the cine's structs by pims):
# frames, width, height, dtype, bits of the stored values, header rate (Hz), exposure (s),
# start frame (frame 0's number from the trigger)
EXPECTED = {
    "ball_12bit.cihx": (15, 384, 384, np.uint16, 12, 30000.0, 20e-6, 52),
    "beam.cihx": (4, 1024, 80, np.uint16, 12, 50000.0, 5e-6, 0),
    # 8-bit values of a 12-bit camera, its upper bits ("EffectiveBit Side : Higher")
    "data_showcase.cih": (75, 640, 40, np.uint8, 8, 15000.0, 65060e-9, 0),
    "cine_781.cine": (15, 256, 256, np.uint16, 12, 90000.0, None, -5417),
    "cine_legacy.cine": (97, 128, 128, np.uint16, 14, 35087.0, None, -7722),
    "data_small_cine.cine": (235, 256, 32, np.uint16, 10, 100.0, None, 0),
}


def _rois(h, w, seed):
    r = np.random.default_rng(seed)
    out = [(0, h, 0, w), (0, 1, 0, 1), (h - 1, h, w - 1, w), (0, h, w - 3, w), (1, 2, 1, w - 1)]
    for _ in range(12):
        y0, x0 = int(r.integers(0, h)), int(r.integers(0, w))
        out.append((y0, int(r.integers(y0 + 1, h + 1)), x0, int(r.integers(x0 + 1, w + 1))))
    return out


def _reference(name):
    """(T, H, W) frames as the reference reader gives them."""
    if name.endswith(".cine"):
        import pims

        ref = pims.Cine(str(REAL / name))
        codes = np.stack([np.asarray(ref[i]) for i in range(len(ref))])
        return P10_TO_LINEAR[codes] if name in P10 else codes
    import pyMRAW

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pyMRAW warns of any file that is not 12-bit
        frames, _ = pyMRAW.load_video(str(REAL / name))
    return np.asarray(frames)


@pytest.mark.parametrize("name", CINES + PHOTRONS)
def test_real_files_pixel_for_pixel_against_the_reference_reader(name):
    ref = _reference(name)
    src = open_recording(REAL / name)
    n, h, w = ref.shape
    assert src.shape == (n, h, w) and src.dtype == ref.dtype
    for i in range(n):
        np.testing.assert_array_equal(src[i], ref[i], err_msg=f"{name} frame {i}")
    for k, (y0, y1, x0, x1) in enumerate(_rois(h, w, n * h)):
        i = (7 * k) % n
        crop = src.read(i, (y0, y1, x0, x1))
        assert crop.flags.c_contiguous and crop.dtype == ref.dtype
        np.testing.assert_array_equal(crop, ref[i, y0:y1, x0:x1], err_msg=f"{name} {i} roi")
    assert ref.max() > 0 and ref.std() > 0  # real pictures, not zeros


def _cihx_fields(path):
    """The .cihx's own entries (xmltodict, as pyMRAW parses it)."""
    import xmltodict

    text = path.read_bytes().decode("utf-8", errors="ignore")
    cih = xmltodict.parse(text[text.find("<cih>"):text.rfind("</cih>") + 6])["cih"]
    img = cih["imageDataInfo"]
    return {"n": int(cih["frameInfo"]["totalFrame"]), "w": int(img["resolution"]["width"]),
            "h": int(img["resolution"]["height"]), "fps": float(cih["recordInfo"]["recordRate"]),
            "shutter_s": int(cih["recordInfo"]["shutterSpeedNsec"]) * 1e-9,
            "shutter_1/s": float(cih["recordInfo"]["shutterSpeed"]),
            "start": int(cih["frameInfo"]["startFrame"]), "colour": img["colorInfo"]["type"],
            "bits": int(img["colorInfo"]["bit"]), "eff": int(img["effectiveBit"]["depth"])}


def _cih_fields(path):
    lines = path.read_text(errors="replace").split("\n\n")[0].splitlines()
    d = dict(line.split(" : ", 1) for line in lines if " : " in line)
    return {"n": int(d["Total Frame"]), "w": int(d["Image Width"]), "h": int(d["Image Height"]),
            "fps": float(d["Record Rate(fps)"]), "shutter_s": int(d["Shutter Type2(nsec)"]) * 1e-9,
            "shutter_1/s": float(d["Shutter Speed(s)"].split("/")[1]),
            "start": int(d["Start Frame"]), "colour": d["Color Type"],
            "bits": int(d["Color Bit"]), "eff": int(d["EffectiveBit Depth"])}


@pytest.mark.parametrize("name", PHOTRONS)
def test_photron_header_fields_against_the_file(name):
    f = (_cihx_fields if name.endswith("x") else _cih_fields)(REAL / name)
    n, w, h, dtype, bits, fps, shutter, start = EXPECTED[name]
    assert (f["n"], f["w"], f["h"], f["fps"], f["start"]) == (n, w, h, fps, start)
    assert f["shutter_s"] == pytest.approx(shutter, rel=1e-12)
    # the exposure both ways the file says it: in ns and as 1/s (the .cihx's 50000 is 20 us)
    assert 1 / f["shutter_1/s"] == pytest.approx(shutter, rel=1e-3)
    src = open_recording(REAL / name)
    assert src.shape == (n, h, w) and src.dtype == dtype and src.fps == fps
    assert src.timestamps is None
    a = src.attrs
    assert a["shutter_s"] == pytest.approx(shutter, rel=1e-12)
    assert a["start_frame"] == start and isinstance(a["start_frame"], int)
    assert a["frame0_from_trigger_s"] == pytest.approx(start / fps)
    assert a["camera_bit_depth"] == bits and a["effective_bit_depth"] == f["eff"]
    assert a["colour"] == "mono" and f["colour"] in ("Mono", "Raw")
    assert a["camera"] in (REAL / name).read_text(errors="ignore")


def _cine_fields(path):
    """The cine's CINEFILEHEADER and BITMAPINFOHEADER unpacked here, field by field."""
    data = path.read_bytes()
    (sig, _, compression, _, _, total, first_no, count, off_bmp, off_setup, _,
     trigger) = struct.unpack_from("<2sHHHiIiIIIIQ", data, 0)
    _, width, height, _, bit_count, bi_compression, _ = struct.unpack_from("<IiiHHII", data,
                                                                            off_bmp)
    frac = (trigger & 0xFFFFFFFF) / 2 ** 32
    when = datetime.datetime(1970, 1, 1, tzinfo=datetime.UTC) + datetime.timedelta(
        seconds=trigger >> 32)
    return {"sig": sig, "n": count, "w": width, "h": abs(height), "first": first_no,
            "trigger": when + datetime.timedelta(seconds=frac),
            "bit_count": bit_count, "compression": compression, "bi_compression": bi_compression,
            "frame_rate_16": struct.unpack_from("<H", data, off_setup)[0]}


@pytest.mark.parametrize("name", CINES)
def test_cine_header_fields_against_the_file(name):
    import pims

    f = _cine_fields(REAL / name)
    n, w, h, dtype, bits, fps, _, start = EXPECTED[name]
    assert (f["sig"], f["n"], f["w"], f["h"], f["first"]) == (b"CI", n, w, h, start)
    ref = pims.Cine(str(REAL / name))
    src = open_recording(REAL / name)
    assert src.shape == (n, h, w) and src.dtype == dtype
    assert src.fps == fps == ref.frame_rate
    a = src.attrs
    assert bits == ref.setup_fields_dict["real_bpp"]
    assert a["camera_bit_depth"] == (P10_BITS if name in P10 else bits)
    assert a["start_frame"] == start and a["colour"] == "mono" and f["compression"] == 0
    assert a["shutter_s"] == pytest.approx(float(np.median(ref.all_exposures)), rel=1e-12)
    # the trigger's date and time in UTC, to the microsecond
    got = datetime.datetime.fromisoformat(a["trigger_time"])
    assert got.utcoffset() == datetime.timedelta(0)
    assert abs((got - f["trigger"]).total_seconds()) < 1e-6
    d0, f0 = ref.frame_time_stamps[0]
    stamps = np.array([(d - d0).total_seconds() + (x - f0) for d, x in ref.frame_time_stamps])
    np.testing.assert_allclose(src.timestamps, stamps, rtol=0, atol=1e-9)
    # frame 0's time from the trigger: its number from the trigger frame at the times' rate
    rate = 1 / np.median(np.diff(stamps))
    assert a["frame0_from_trigger_s"] == pytest.approx(start / rate, abs=3 / rate)


def test_the_cameras_clock_step_is_no_dropped_frame():
    # cine_legacy's times are whole microseconds: every interval 28 or 29 us at 35087 Hz
    src = open_recording(REAL / "cine_legacy.cine")
    d = np.round(np.diff(src.timestamps) * 1e6, 3)
    assert set(np.unique(d)) <= {28.0, 29.0, 27.999, 28.001, 28.999, 29.001}
    assert src.attrs["timestamp_resolution_s"] == 1e-6
    t, desc, notes = frame_times(src, 35087.0)
    assert desc == "the recording's timestamps" and notes == []
    # cine_781: the header's 90000 and the times' 9003 Hz disagree: the times are used, and said
    src = open_recording(REAL / "cine_781.cine")
    assert src.attrs["timestamp_resolution_s"] == 2.0 ** -32
    t, desc, notes = frame_times(src, src.fps)
    assert 1 / np.median(np.diff(t)) == pytest.approx(9003.2, abs=0.1)
    assert len(notes) == 1 and "9003.22 frames/s" in notes[0] and "90000 Hz" in notes[0]


def test_a_dropped_frame_of_a_microsecond_clock_is_still_found(tmp_path):
    frames = np.zeros((12, 8, 8), np.uint16)
    k = np.r_[0:6, 7:13]  # frame 6 lost
    times = np.round(k / 35087.0, 6)  # the camera's microsecond clock
    src = open_recording(write_cine(tmp_path / "a.cine", frames, fps=35087.0, times=times))
    assert src.attrs["timestamp_resolution_s"] == 1e-6
    _, _, notes = frame_times(src, 35087.0)
    assert len(notes) == 1 and "1 of the recording's 11 frame intervals" in notes[0]
    # without the lost frame: no note
    times = np.round(np.arange(12) / 35087.0, 6)
    src = open_recording(write_cine(tmp_path / "b.cine", frames, fps=35087.0, times=times))
    assert frame_times(src, 35087.0)[2] == []


def _copy(tmp_path, pairs):
    for a, b in pairs:
        shutil.copyfile(REAL / a, tmp_path / b)


@pytest.mark.parametrize("given", ["BALL.CIHX", "BALL.MRAW"])
def test_upper_case_photron_names_read_like_lower_case(tmp_path, given):
    _copy(tmp_path, [("ball_12bit.cihx", "BALL.CIHX"), ("ball_12bit.mraw", "BALL.MRAW")])
    src = open_recording(tmp_path / given)
    ref = open_recording(REAL / "ball_12bit.cihx")
    assert src.shape == ref.shape and src.attrs["start_frame"] == 52
    assert src.attrs["shutter_s"] == pytest.approx(20e-6)
    for i in (0, 14):
        np.testing.assert_array_equal(src[i], ref[i])


def test_upper_case_cine_and_text_header(tmp_path):
    _copy(tmp_path, [("cine_legacy.cine", "REC.CINE"), ("data_showcase.cih", "SHOW.CIH"),
                     ("data_showcase.mraw", "SHOW.MRAW")])
    src = open_recording(tmp_path / "REC.CINE")
    np.testing.assert_array_equal(src[96], open_recording(REAL / "cine_legacy.cine")[96])
    src = open_recording(tmp_path / "SHOW.CIH")
    assert src.shape == (75, 40, 640) and src.attrs["shutter_s"] == pytest.approx(65060e-9)


def _header_with(tmp_path, name, old, new):
    text = (REAL / "ball_12bit.cihx").read_bytes()
    assert old in text
    (tmp_path / f"{name}.cihx").write_bytes(text.replace(old, new))
    shutil.copyfile(REAL / "ball_12bit.mraw", tmp_path / f"{name}.mraw")
    return tmp_path / f"{name}.cihx"


def test_a_colour_camera_file_is_refused(tmp_path):
    # a colour file, and a colour camera's raw sensor values (a Bayer mosaic)
    colour = _header_with(tmp_path, "colour", b"<type>Raw</type>", b"<type>Color</type>")
    with pytest.raises(RecordingError, match="Color 12-bit frames .* monochrome"):
        open_recording(colour)
    bayer = _header_with(tmp_path, "bayer", b"1100K-M-64GB", b"1100K-C-64GB")
    with pytest.raises(RecordingError, match="Raw 12-bit frames of a FASTCAM Nova S16 type "
                                             "1100K-C-64GB.*monochrome"):
        open_recording(bayer)
    mono = _header_with(tmp_path, "mono", b"<type>Raw</type>", b"<type>Mono</type>")
    assert open_recording(mono).attrs["colour"] == "mono"


def test_a_colour_cine_is_refused(tmp_path):
    # cine_781 with its SETUP's CFA field set to a Bayer pattern (a colour camera's raw frames)
    from pims.cine import SETUP_FIELDS

    data = bytearray((REAL / "cine_781.cine").read_bytes())
    off_setup = struct.unpack_from("<I", data, 28)[0]
    names = [n for n, _ in SETUP_FIELDS]
    at = off_setup + sum(struct.calcsize("<" + f) for _, f in SETUP_FIELDS[:names.index("cfa")])
    assert struct.unpack_from("<I", data, at)[0] == 0
    struct.pack_into("<I", data, at, 3)  # CFA_BAYER
    (tmp_path / "colour.cine").write_bytes(bytes(data))
    with pytest.raises(RecordingError, match="colour or compressed cine file .*CFA 3.*monochrome"):
        open_recording(tmp_path / "colour.cine")
