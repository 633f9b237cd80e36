"""The camera's effective bit depth, not the frames' word: read from every file type, the setup's
``camera.bit_depth`` and the data, and used by every threshold (search, edge floors, thesis
locators, saturation)."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile

from rollfric.errors import InputError
from rollfric.geometry.trough import find_cylinder_center
from rollfric.io import bitdepth
from rollfric.io import readers as io
from rollfric.locate import SubpixelOptions, locate_subpixel
from rollfric.locate.thesis import locate_small_thesis
from rollfric.setup.model import SetupError, setup_from_dict, thesis_setup
from synth.drawn.frames import disk_coverage

REAL = Path(__file__).parent / "data" / "real"


def _low_contrast_pair(bits, *, h=120, w=160, cx=81.3, cy=57.6, r=20.0, contrast=0.015,
                       noise=0.0015, seed=0):
    """(frame, background) of a dark disc at ``contrast`` of the camera's full scale below a
    mid-grey level, noise ``noise`` of full scale, in the word a camera of ``bits`` writes."""
    fs = 2 ** bits - 1
    rng = np.random.default_rng(seed + bits)
    dt = np.uint8 if bits <= 8 else np.uint16
    cov = disk_coverage(h, w, cx, cy, r)
    bg = np.clip(np.rint(0.5 * fs + rng.normal(0, noise * fs, (h, w))), 0, fs).astype(dt)
    fr = np.clip(np.rint(0.5 * fs - contrast * fs * cov + rng.normal(0, noise * fs, (h, w))),
                 0, fs).astype(dt)
    return fr, bg


@pytest.mark.parametrize("bits", [8, 10, 12, 14, 16])
def test_a_low_contrast_ball_is_located_at_every_bit_depth(bits):
    """1.5 % of the camera's full scale (15 DN at 10 bits, 61 at 12, 246 at 14): below the
    search's threshold and the edges' floor taken against 65535, plain against 2**bits - 1."""
    cx, cy, r = 81.3, 57.6, 20.0
    fr, bg = _low_contrast_pair(bits, cx=cx, cy=cy, r=r)
    loc = locate_subpixel(fr, bg, r, opts=SubpixelOptions(full_scale=bitdepth.full_scale(bits)))
    assert loc.found, loc.reason
    assert math.hypot(loc.x - cx, loc.y - cy) < 0.08
    # the thesis's small-ball locator: the darkest pixel of the best window lies in the disc
    small = locate_small_thesis(fr, bg, full_scale=bitdepth.full_scale(bits))
    assert small.found and math.hypot(small.x - cx, small.y - cy) < r


def test_the_word_full_scale_hides_what_the_depth_shows():
    """The same 12-bit frames without the camera's depth: the search's threshold of 1 % of 65535
    finds no ball (the defect the depth fixes)."""
    fr, bg = _low_contrast_pair(12)
    assert not locate_subpixel(fr, bg, 20.0).found
    assert locate_subpixel(fr, bg, 20.0, opts=SubpixelOptions(full_scale=4095.0)).found


def _saturated_trough(full_scale, h=1024, w=1280):
    xc, yc, radius = 640.3, 380.7, 635.0
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    rel = (xx - 640) / 1000.0 * 0.3 - (yy - 512) / 1000.0 * 0.5
    c1 = disk_coverage(h, w, xc, yc, radius)
    c2 = disk_coverage(h, w, xc, yc, radius + 70)
    img = c1 * 1.2 * (1 + rel) + (c2 - c1) * 0.2 * (1 - rel) + (1 - c2) * 0.5
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    return np.clip(np.rint(full_scale * img), 0, full_scale).astype(np.uint16), radius


def test_a_12_bit_cameras_clipped_contour_is_flagged_at_4095():
    """A backdrop brighter than a 12-bit sensor's range, clipped at 4095 in 16-bit words."""
    img, radius = _saturated_trough(4095)
    assert img.max() == 4095
    c = find_cylinder_center(img, radius_px=radius, full_scale=4095.0)
    assert c.saturated_fraction > 0.5
    # the word's 65535 never sees it
    assert find_cylinder_center(img, radius_px=radius).saturated_fraction == 0.0


# -- the depth each file type states


@pytest.mark.parametrize("name, bits", [
    ("ball_12bit.cihx", 12),  # EffectiveBit Depth 12, 12-bit packed
    ("beam.cihx", 12),  # 16-bit words, EffectiveBit Depth 12 on the low side
    ("data_showcase.cih", 8),  # 8-bit words (its effective bits on the high side)
    ("cine_781.cine", 12),  # real_bpp 12 in 16-bit words
    ("cine_legacy.cine", 14),  # real_bpp 14
    ("data_small_cine.cine", 12),  # P10: the maker's table gives 12-bit values
])
def test_the_real_files_state_their_bit_depth(name, bits):
    src = io.open_recording(REAL / name)
    assert src.bit_depth_stated == bits and src.bit_depth == bits
    assert max(int(src[i].max()) for i in range(len(src))) <= bitdepth.full_scale(bits)
    assert bitdepth.resolve_bit_depth(src) == (bits, "file", [])


def test_a_tiff_states_its_depth_by_max_sample_value(tmp_path):
    frames = np.full((3, 8, 10), 100, np.uint16)
    tifffile.imwrite(tmp_path / "a.tif", frames, photometric="minisblack",
                     extratags=[(281, "H", 1, 1023, True)])  # MaxSampleValue
    tifffile.imwrite(tmp_path / "b.tif", frames, photometric="minisblack")
    tifffile.imwrite(tmp_path / "c.tif", frames.astype(np.uint8), photometric="minisblack")
    assert io.open_recording(tmp_path / "a.tif").bit_depth == 10
    assert io.open_recording(tmp_path / "b.tif").bit_depth_stated is None  # a 16-bit word only
    assert io.open_recording(tmp_path / "c.tif").bit_depth == 8
    # a folder of TIFF images: the first one's tag
    (tmp_path / "folder").mkdir()
    for i in range(3):
        tifffile.imwrite(tmp_path / "folder" / f"f{i}.tif", frames[i], photometric="minisblack",
                         extratags=[(281, "H", 1, 4095, True)])
    assert io.open_recording(tmp_path / "folder").bit_depth_stated == 12


def test_the_setup_key_and_the_data_guess(tmp_path, caplog):
    frames = np.zeros((7, 8, 10), np.uint16)
    frames[3, 2, 2] = 3000  # the brightest pixel of the recording: 12 bits hold it
    tifffile.imwrite(tmp_path / "r.tif", frames, photometric="minisblack")
    src = io.open_recording(tmp_path / "r.tif")
    bits, how, notes = bitdepth.resolve_bit_depth(src)
    assert (bits, how) == (12, "data") and "3000 DN" in notes[0] and "camera.bit_depth" in notes[0]
    with caplog.at_level(logging.WARNING):
        assert src.bit_depth == 12
    assert any("taken as 12 from the data" in r.getMessage() for r in caplog.records)
    # the setup's key overrides the guess; one the data exceed is refused naming both
    assert bitdepth.resolve_bit_depth(src, 14) == (14, "setup", [])
    with pytest.raises(InputError, match=r"camera.bit_depth = 10 .*3000 DN"):
        bitdepth.resolve_bit_depth(src, 10)
    # a key that contradicts the file's statement is refused naming both
    cine = io.open_recording(REAL / "cine_781.cine")
    with pytest.raises(InputError, match=r"camera.bit_depth = 14 contradicts .*cine_781.* 12"):
        bitdepth.resolve_bit_depth(cine, 14)
    assert bitdepth.resolve_bit_depth(cine, 12) == (12, "setup", [])


def test_a_files_depth_its_frames_exceed_is_not_used(tmp_path):
    frames = np.zeros((3, 8, 10), np.uint16)
    frames[1, 4, 4] = 3000
    tifffile.imwrite(tmp_path / "r.tif", frames, photometric="minisblack",
                     extratags=[(281, "H", 1, 1023, True)])
    src = io.open_recording(tmp_path / "r.tif")
    assert src.bit_depth_stated == 10
    bits, how, notes = bitdepth.resolve_bit_depth(src)
    assert (bits, how) == (12, "data") and "says the camera's bit depth is 10" in notes[0]
    assert bitdepth.resolve_bit_depth(src, 12)[:2] == (12, "setup")


def test_the_setup_key_is_validated():
    base = thesis_setup().to_toml_dict()
    for bad in (0, 17, 12.0, "12", True):
        data = {k: dict(v) for k, v in base.items()}
        data["camera"]["bit_depth"] = bad
        with pytest.raises(SetupError, match="camera.bit_depth"):
            setup_from_dict(data)
    data = {k: dict(v) for k, v in base.items()}
    data["camera"]["bit_depth"] = 12
    assert setup_from_dict(data).bit_depth == 12
    assert thesis_setup(bit_depth=12).to_toml_dict()["camera"]["bit_depth"] == 12


# -- Phantom P10 frames linearised with the maker's table


def test_p10_codes_are_linearised_with_the_makers_table(tmp_path):
    from camera_files import write_cine

    from rollfric.io.formats.phantom_lut import P10_TO_LINEAR

    codes = np.arange(2 * 16 * 32, dtype=np.uint16).reshape(2, 16, 32) % 1024
    path = write_cine(tmp_path / "p10.cine", codes, packed10=True)
    src = io.open_recording(path)
    assert src.bit_depth == 12
    for i in range(2):
        np.testing.assert_array_equal(src[i], P10_TO_LINEAR[codes[i]])
        np.testing.assert_array_equal(src.read(i, (3, 9, 5, 30)),
                                      P10_TO_LINEAR[codes[i]][3:9, 5:30])
    # the maker's table: monotonic, 12-bit, code 0 -> 2, 512 -> 998, codes from 1015 on clipped
    assert P10_TO_LINEAR.shape == (1024,) and np.all(np.diff(P10_TO_LINEAR.astype(int)) >= 0)
    assert (P10_TO_LINEAR[0], P10_TO_LINEAR[512], P10_TO_LINEAR[1014]) == (2, 998, 4064)
    assert np.all(P10_TO_LINEAR[1015:] == 4095)


def test_a_real_p10_file_is_pims_codes_through_the_table():
    from pims.cine import Cine

    from rollfric.io.formats.phantom_lut import P10_TO_LINEAR

    path = REAL / "data_small_cine.cine"
    ref = Cine(str(path))
    src = io.open_recording(path)
    for i in (0, 117, len(src) - 1):
        np.testing.assert_array_equal(src[i], P10_TO_LINEAR[np.asarray(ref.get_frame(i))])


# -- a measurement end to end


def test_a_10_bit_recording_at_half_contrast_in_16_bit_words_measures(tmp_path, capsys):
    """The drawn recording as a 10-bit camera's at half the 8-bit one's contrast, in a 16-bit
    TIFF (ball against trough ~120 DN: under the 328 DN the word's full scale asked for, which
    found the ball in no frame, exit 2). From the TIFF's MaxSampleValue, from the setup's
    camera.bit_depth, or from the data (with a warning): the 8-bit recording's track."""
    import json

    import pandas as pd
    from measure_data import make_recording

    from rollfric.cli.main import main
    from rollfric.setup.model import save_setup

    rec = make_recording(160, noise=1.0, fps=200.0)
    frames8 = np.stack(rec.frames)
    frames10 = frames8.astype(np.uint16) * 2 + 200  # 10-bit values, half the relative contrast
    assert frames10.max() <= 1023
    tifffile.imwrite(tmp_path / "rec8.tif", frames8)
    tifffile.imwrite(tmp_path / "tag.tif", frames10, extratags=[(281, "H", 1, 1023, True)])
    tifffile.imwrite(tmp_path / "plain.tif", frames10)
    save_setup(rec.setup, tmp_path / "setup.toml")
    save_setup(rec.setup.replace(bit_depth=10), tmp_path / "setup10.toml")
    out = {}
    for name, rec_file, setup in (("ref", "rec8.tif", "setup.toml"),
                                  ("tag", "tag.tif", "setup.toml"),
                                  ("key", "plain.tif", "setup10.toml"),
                                  ("data", "plain.tif", "setup.toml")):
        d = tmp_path / name
        assert main(["measure", str(tmp_path / rec_file), "--setup", str(tmp_path / setup),
                     "--out", str(d), "--no-progress"]) == 0, name
        out[name] = (pd.read_csv(d / "track.csv"), json.loads((d / "fit.json").read_text()))
    capsys.readouterr()
    ref, ref_fit = out["ref"]
    assert ref["found"].all()
    for name in ("tag", "key", "data"):
        df, fit = out[name]
        assert df["found"].all(), name
        err = np.hypot(df["x_px"] - rec.centers[:, 0], df["y_px"] - rec.centers[:, 1])
        assert np.sqrt(np.mean(err ** 2)) < 0.05, name
        assert fit["mu"] == pytest.approx(ref_fit["mu"], rel=0.02), name
    guessed = [w for w in out["data"][1]["warnings"] if "bit depth" in w]
    assert len(guessed) == 1 and "taken as 10 from the data" in guessed[0]
    assert not any("bit depth" in w for w in out["tag"][1]["warnings"] + out["key"][1]["warnings"])
    # a key the frames exceed is bad input naming both, nothing written
    save_setup(rec.setup.replace(bit_depth=9), tmp_path / "setup9.toml")
    assert main(["measure", str(tmp_path / "plain.tif"), "--setup", str(tmp_path / "setup9.toml"),
                 "--out", str(tmp_path / "nine"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "camera.bit_depth = 9 (full scale 511 DN) contradicts the data" in err
    assert int(err.split(" reach ")[1].split(" DN")[0]) > 511
    assert not (tmp_path / "nine").exists()


# -- a locator without its feature reports the frame not found


def _backlit_background(frames):
    """The real clip's ball-free background: the backlight is clipped at 4095 all round the
    ball's path, so frame 0 with the path's disc set to 4095."""
    bg = frames[0].copy()
    yy, xx = np.mgrid[0:bg.shape[0], 0:bg.shape[1]]
    bg[np.hypot(xx - 176, yy - 128) < 110] = 4095
    return bg


def test_the_thesis_locators_find_no_highlight_on_a_backlit_ball():
    """The real 12-bit clip of a dark ball on a clipped backlight (r = 63.6 px): no pixel of
    the ball is brighter than the background. thesis-large took the window's first brightest
    pixel for the highlight (all 15 frames found, 111-119 px from the subpixel centre) and
    thesis-small the ball's least dark pixel (33-52 px off): now each frame is not found,
    with the reason; the subpixel locator finds the ball in every frame."""
    from rollfric.locate.thesis import thesis_large_locator, thesis_small_locator

    src = io.open_recording(REAL / "ball_12bit.cihx")
    frames = [src[i] for i in range(len(src))]
    bg = _backlit_background(frames)
    opts = SubpixelOptions(full_scale=4095.0)
    for f in frames:
        sub = locate_subpixel(f, bg, 63.6, opts=opts)
        assert sub.found and 174 < sub.x < 177 and 108 < sub.y < 148
        large = thesis_large_locator(f, bg, 63.6, None, (192.0, -500.0), opts=opts)
        assert not large.found and "highlight" in large.reason
        small = thesis_small_locator(f, bg, 63.6, None, (192.0, -500.0), opts=opts)
        assert not small.found and "spot" in small.reason


def test_thesis_large_on_a_drawn_dark_ball_without_highlight_is_not_found():
    from rollfric.locate.thesis import locate_large_thesis

    cov = disk_coverage(200, 200, 100.3, 99.6, 30.0)
    rng = np.random.default_rng(3)
    bg = np.rint(3500 + rng.normal(0, 4, (200, 200))).astype(np.uint16)
    fr = np.rint(3500 - 3000 * cov + rng.normal(0, 4, (200, 200))).astype(np.uint16)
    for guess in (None, (101.0, 99.0)):
        loc = locate_large_thesis(fr, bg, 30.0, guess=guess, full_scale=4095.0)
        assert not loc.found and "highlight" in loc.reason
    # the same ball with a highlight brighter than the background is located by it
    spot = np.exp(-((np.mgrid[0:200, 0:200][1] - 100.3) ** 2
                    + (np.mgrid[0:200, 0:200][0] - 93.6) ** 2) / (2 * 3.0 ** 2))
    lit = np.clip(fr + 3800 * spot * cov, 0, 4095).astype(np.uint16)
    loc = locate_large_thesis(lit, bg, 30.0, guess=(101.0, 99.0), full_scale=4095.0)
    assert loc.found and math.hypot(loc.x - 100.3, loc.y - 99.6) < 1.5


def test_the_overlay_shows_a_12_bit_frame_to_its_full_scale(tmp_path):
    import pandas as pd

    from rollfric.output.overlay import plot_overlays

    frames = np.full((1, 64, 64), 4095, np.uint16)  # a 12-bit camera's white
    tifffile.imwrite(tmp_path / "w.tif", frames, extratags=[(281, "H", 1, 4095, True)])
    track = pd.DataFrame({"frame": [0], "t_s": [0.0], "x_px": [np.nan], "y_px": [np.nan],
                          "theta_rad": [np.nan], "found": [0]})
    png = plot_overlays(io.open_recording(tmp_path / "w.tif"), track, tmp_path / "o.png",
                        r_px=10.0)
    img = cv2.imread(str(png), cv2.IMREAD_GRAYSCALE)
    # the frame fills the middle of the figure: white, not 4095 / 65535 of it (grey 16)
    h, w = img.shape
    assert np.median(img[h // 3:2 * h // 3, w // 3:2 * w // 3]) > 240


def test_the_real_12_bit_ball_at_110_dn_of_contrast_is_located():
    """The real clip's ball (about 3900 DN below its backlight) scaled to 110 DN of contrast:
    against 4095 every frame is located where the full-contrast frame is (within 0.01 px);
    against the word's 65535 none ("no ball-like change in the frame")."""
    src = io.open_recording(REAL / "ball_12bit.cihx")
    frames = [src[i] for i in range(len(src))]
    bg = _backlit_background(frames)
    depth = SubpixelOptions(full_scale=bitdepth.full_scale(src.bit_depth))
    k = 110.0 / 3900.0
    for f in frames:
        full = locate_subpixel(f, bg, 63.6, opts=depth)
        low = np.rint(bg - (bg.astype(float) - f) * k).astype(np.uint16)
        loc = locate_subpixel(low, bg, 63.6, opts=depth)
        assert loc.found and math.hypot(loc.x - full.x, loc.y - full.y) < 0.01
    assert not locate_subpixel(low, bg, 63.6).found


def test_a_zarr_store_states_its_depth_by_its_bit_depth_attribute(tmp_path):
    import zarr

    from rollfric.io.readers import RecordingError

    frames = np.full((3, 8, 10), 100, np.uint16)
    for name, attr in (("twelve.zarr", 12), ("none.zarr", None), ("bad.zarr", 20)):
        g = zarr.open_group(str(tmp_path / name), mode="w")
        g.create_array("frames", data=frames)
        if attr is not None:
            g.attrs["bit_depth"] = attr
    assert io.open_recording(tmp_path / "twelve.zarr").bit_depth == 12
    assert io.open_recording(tmp_path / "none.zarr").bit_depth_stated is None
    with pytest.raises(RecordingError, match="bit_depth"):
        io.open_recording(tmp_path / "bad.zarr")
