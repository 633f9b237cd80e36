"""Recording readers: every input format, 8 and 16 bit, and bad input."""

import logging
import math
import os
import sys
import textwrap

import cv2
import numpy as np
import pytest
import tifffile
import zarr

from rollfric.io.readers import (
    RecordingError,
    check_background,
    open_recording,
    read_image,
)

rng = np.random.default_rng(0)
FR8 = rng.integers(0, 255, (5, 24, 32), dtype=np.uint8)
FR16 = rng.integers(0, 65535, (5, 24, 32), dtype=np.uint16)


@pytest.mark.parametrize("frames", [FR8, FR16])
def test_tiff_stack(tmp_path, frames):
    p = tmp_path / "rec.tif"
    tifffile.imwrite(p, frames)
    src = open_recording(p)
    assert src.shape == frames.shape and src.dtype == frames.dtype and len(src) == 5
    for i in range(5):
        np.testing.assert_array_equal(src[i], frames[i])
    # page by page, too
    p2 = tmp_path / "pages.tiff"
    with tifffile.TiffWriter(p2) as tw:
        for f in frames:
            tw.write(f, contiguous=False)
    src2 = open_recording(p2)
    assert len(src2) == 5
    np.testing.assert_array_equal(src2[3], frames[3])


@pytest.mark.parametrize("frames", [FR8, FR16])
def test_png_folder_sorted_by_name(tmp_path, frames):
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"img_{i:04d}.png"), f)
    (tmp_path / "notes.txt").write_text("not an image")
    src = open_recording(tmp_path)
    assert src.shape == frames.shape and src.dtype == frames.dtype
    np.testing.assert_array_equal(src[4], frames[4])
    np.testing.assert_array_equal(np.stack(list(src)), frames)


def _end_of_page(path, k: int) -> int:
    """The byte offset just after page ``k``'s data in a TIFF file."""
    with tifffile.TiffFile(path) as tif:
        page = tif.pages[k]
        return int(page.dataoffsets[0] + page.databytecounts[0])


def test_folder_numbered_without_leading_zeros_in_natural_order(tmp_path):
    # audit 2026-11-24: img_9.png sorted after img_10.png, so a camera numbering its files
    # without leading zeros had its frames shuffled (exit 3, the period blamed on the setup)
    frames = np.random.default_rng(3).integers(0, 255, (12, 24, 32), dtype=np.uint8)
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"img_{i}.png"), f)
    np.testing.assert_array_equal(np.stack(list(open_recording(tmp_path))), frames)


def test_natural_key_orders_numbers_as_numbers():
    from rollfric.io.readers import natural_key

    names = ["img_10.png", "img_", "img_9.png", "img_.png", "img_0009.png", "x2y10", "x2y9"]
    assert sorted(names, key=natural_key) == ["img_", "img_0009.png", "img_9.png",
                                             "img_10.png", "img_.png", "x2y9", "x2y10"]
    # zero-padded names keep their plain order
    padded = [f"f{i:05d}.tif" for i in (3, 100, 20, 7)]
    assert sorted(padded, key=natural_key) == sorted(padded)


def test_lzw_compressed_tiff_stack_as_opencv_writes_it(tmp_path):
    # audit 2026-11-24: a multi-page TIFF from cv2.imwritemulti (LZW) was refused: tifffile
    # needs imagecodecs to decode it, now a dependency
    p = tmp_path / "cv.tif"
    assert cv2.imwritemulti(str(p), list(FR8))
    with tifffile.TiffFile(p) as tif:
        assert tif.pages[0].compression == tifffile.COMPRESSION.LZW
    src = open_recording(p)
    assert len(src) == 5
    np.testing.assert_array_equal(np.stack(list(src)), FR8)
    np.testing.assert_array_equal(src.read(3, (2, 9, 5, 20)), FR8[3, 2:9, 5:20])


def test_a_broken_tiff_is_refused_without_tifffiles_own_log_line(tmp_path, caplog):
    p = tmp_path / "rec.tif"
    with tifffile.TiffWriter(p) as tw:
        for f in FR8:
            tw.write(f, contiguous=False)
    end = _end_of_page(p, 2)
    cut = tmp_path / "cut.tif"
    cut.write_bytes(p.read_bytes()[:end])
    with caplog.at_level("DEBUG"), pytest.raises(RecordingError, match="cut.tif"):
        open_recording(cut)
    assert not [r for r in caplog.records if r.name.startswith("tifffile")]
    # the filter is gone afterwards: tifffile's log is the user's again
    assert not logging.getLogger("tifffile").filters


@pytest.mark.parametrize("fourcc,lossless", [("FFV1", True), ("MJPG", False)])
def test_video(tmp_path, fourcc, lossless):
    p = tmp_path / "rec.avi"
    yy, xx = np.mgrid[0:48, 0:64]
    frames = [((xx * 3 + yy * 2 + 20 * i) % 200 + 20).astype(np.uint8) for i in range(6)]
    vw = cv2.VideoWriter(str(p), cv2.VideoWriter_fourcc(*fourcc), 50.0, (64, 48), isColor=False)
    assert vw.isOpened()
    for f in frames:
        vw.write(f)
    vw.release()
    src = open_recording(p)
    assert src.shape == (6, 48, 64) and src.dtype == np.uint8
    assert src.fps == pytest.approx(50.0)
    for i in (0, 1, 2, 5, 3):  # in order and out of order
        err = np.abs(src[i].astype(int) - frames[i]).mean()
        assert err == 0 if lossless else err < 6


def test_zarr_frames_array(tmp_path):
    p = tmp_path / "rec.zarr"
    g = zarr.open_group(str(p), mode="w")
    g.create_array("frames", data=FR16, chunks=(1, 24, 32))
    g.create_array("background", data=FR16[0])
    g.attrs["fps"] = 1000.0
    g.attrs["setup"] = {"cylinder": {"radius_mm": 85.3}}
    src = open_recording(p)
    assert src.shape == FR16.shape and src.dtype == np.uint16 and src.fps == 1000.0
    np.testing.assert_array_equal(src[2], FR16[2])
    np.testing.assert_array_equal(src.background, FR16[0])
    assert src.attrs["setup"]["cylinder"]["radius_mm"] == 85.3


def test_zarr_entry_point_reader(tmp_path, monkeypatch):
    # a real (fake) installed distribution advertising a rollfric.zarr_readers entry point
    site = tmp_path / "site"
    (site / "fakereader-0.1.dist-info").mkdir(parents=True)
    (site / "fakereader-0.1.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: fakereader\nVersion: 0.1\n")
    (site / "fakereader-0.1.dist-info" / "entry_points.txt").write_text(
        "[rollfric.zarr_readers]\nfake = fakereader_mod:open_frames\n")
    (site / "fakereader_mod.py").write_text(textwrap.dedent("""
        import numpy as np

        class Src:
            def __init__(self, group):
                self.clean = group["clean"]
                self.shape = self.clean.shape
                self.dtype = np.dtype(np.uint8)
                self.fps = 500.0
                self.background = None
                self.attrs = {"from": "fake"}
            def __len__(self):
                return self.shape[0]
            def __getitem__(self, i):
                return (np.asarray(self.clean[i]) // 2).astype(np.uint8)

        def open_frames(group):
            return Src(group) if "clean" in group else None
        """))
    monkeypatch.syspath_prepend(str(site))
    p = tmp_path / "rec.zarr"
    g = zarr.open_group(str(p), mode="w")
    g.create_array("clean", data=FR8)
    src = open_recording(p)
    assert src.shape == FR8.shape and src.fps == 500.0 and src.attrs["from"] == "fake"
    np.testing.assert_array_equal(src[1], FR8[1] // 2)
    # a store neither has frames nor is accepted by any reader
    p2 = tmp_path / "other.zarr"
    zarr.open_group(str(p2), mode="w").create_array("x", data=np.zeros(3))
    with pytest.raises(RecordingError, match="without an array 'frames'.*tried: .*fake"):
        open_recording(p2)
    sys.modules.pop("fakereader_mod", None)


def test_median_background_streams_a_subsample():
    class Counting:
        shape = (200, 8, 8)
        dtype = np.dtype(np.uint8)

        def __init__(self):
            self.reads = 0

        def __len__(self):
            return 200

        def __getitem__(self, i):
            self.reads += 1
            f = np.full((8, 8), 100, np.uint8)
            f[i % 8, :] = 250  # a 'ball' that moves: never in the median
            return f

    from rollfric.io.background import median_background

    src = Counting()
    bg, notes = median_background(src, 1.0, max_frames=21)
    assert src.reads == 21 and notes == []
    np.testing.assert_array_equal(bg, 100)


def test_bad_inputs(tmp_path):
    with pytest.raises(RecordingError, match="no such file"):
        open_recording(tmp_path / "missing.tif")
    junk = tmp_path / "junk.tif"
    junk.write_bytes(b"this is not a tiff file at all" * 10)
    with pytest.raises(RecordingError, match="junk.tif"):
        open_recording(junk)
    # truncated TIFF: the last pages' data cut off
    p = tmp_path / "trunc.tif"
    big = np.random.default_rng(1).integers(0, 255, (6, 64, 64), dtype=np.uint8)
    with tifffile.TiffWriter(p) as tw:
        for f in big:
            tw.write(f, contiguous=False)
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(RecordingError, match="trunc.tif"):
        src = open_recording(p)
        for i in range(len(src)):
            src[i]
    # mixed sizes in a folder
    d = tmp_path / "mixed"
    d.mkdir()
    cv2.imwrite(str(d / "a.png"), FR8[0])
    cv2.imwrite(str(d / "b.png"), np.zeros((10, 10), np.uint8))
    src = open_recording(d)
    with pytest.raises(RecordingError, match="mixed sizes"):
        src[1]
    # a corrupt image in a folder
    d2 = tmp_path / "corrupt"
    d2.mkdir()
    cv2.imwrite(str(d2 / "a.png"), FR8[0])
    (d2 / "b.png").write_bytes(b"\x89PNG broken")
    with pytest.raises(RecordingError, match="b.png"):
        open_recording(d2)[1]
    # an empty folder, an unknown format, a broken video
    (tmp_path / "empty").mkdir()
    with pytest.raises(RecordingError, match="no image files"):
        open_recording(tmp_path / "empty")
    (tmp_path / "x.xyz").write_text("?")
    with pytest.raises(RecordingError, match="unknown recording format"):
        open_recording(tmp_path / "x.xyz")
    (tmp_path / "v.avi").write_bytes(os.urandom(300))
    with pytest.raises(RecordingError, match="v.avi"):
        open_recording(tmp_path / "v.avi")
    # a background of another size
    tifffile.imwrite(tmp_path / "rec.tif", FR8)
    src = open_recording(tmp_path / "rec.tif")
    with pytest.raises(RecordingError, match="background is 10x12 px but the frames are 32x24"):
        check_background(np.zeros((12, 10), np.uint8), src)
    with pytest.raises(RecordingError, match="unsupported pixel type"):
        check_background(np.zeros((24, 32), np.float32), src)
    with pytest.raises(RecordingError, match="no such file"):
        read_image(tmp_path / "nope.png")
    assert math.isfinite(float(read_image(tmp_path / "rec.tif").mean()))


@pytest.mark.parametrize("contiguous", [False, True])
def test_tiff_cut_between_two_pages_is_refused(tmp_path, contiguous):
    # audit 2026-11-24: a stack cut right after a page's data read as a shorter recording
    # (tifffile stops at the next directory beyond the end of the file with a log line only),
    # and rollfric measure reported mu from the pages before the cut with status 0
    p = tmp_path / "rec.tif"
    big = np.random.default_rng(2).integers(0, 255, (6, 64, 64), dtype=np.uint8)
    if contiguous:  # tifffile's one shaped series: the later directories after all the data
        tifffile.imwrite(p, big)
    else:
        with tifffile.TiffWriter(p) as tw:
            for f in big:
                tw.write(f, contiguous=False)
    end = _end_of_page(p, 3)
    assert len(open_recording(p)) == 6
    cut = tmp_path / "cut.tif"
    cut.write_bytes(p.read_bytes()[:end])
    with pytest.raises(RecordingError, match=r"cut.tif: the directory of page \d+ lies beyond "
                                             r"the end of the file"):
        open_recording(cut)


def test_measure_of_a_tiff_cut_between_pages_writes_nothing(tmp_path, capsys):
    from measure_data import write_lab

    from rollfric.cli.main import main

    lab = write_lab(tmp_path, n=60)
    with tifffile.TiffFile(lab / "rec.tif") as tif:
        assert len(tif.pages) == 60
    # the same frames, one directory a page, cut after page 40's data
    frames = tifffile.imread(lab / "rec.tif")
    with tifffile.TiffWriter(lab / "pages.tif") as tw:
        for f in frames:
            tw.write(f, contiguous=False)
    with tifffile.TiffFile(lab / "pages.tif") as tif:
        page = tif.pages[39]
        end = int(page.dataoffsets[0] + page.databytecounts[0])
    (lab / "cut.tif").write_bytes((lab / "pages.tif").read_bytes()[:end])
    code = main(["measure", str(lab / "cut.tif"), "--setup", str(lab / "setup.toml"),
                 "--background", str(lab / "bg.tif"), "--out", str(lab / "out"),
                 "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "cut.tif" in err and "only 40 whole page(s)" in err and "Traceback" not in err
    assert not (lab / "out").exists()


def test_a_background_of_another_bit_depth_is_refused(tmp_path):
    # audit 2026-11-24: a 16-bit background for 8-bit frames (or the reverse) ended in "the
    # ball was found in none of the frames" after tracking them all
    tifffile.imwrite(tmp_path / "rec8.tif", FR8)
    tifffile.imwrite(tmp_path / "rec16.tif", FR16)
    src8, src16 = open_recording(tmp_path / "rec8.tif"), open_recording(tmp_path / "rec16.tif")
    with pytest.raises(RecordingError, match="is 16-bit but the frames are 8-bit"):
        check_background(FR16[0], src8)
    with pytest.raises(RecordingError, match="is 8-bit but the frames are 16-bit"):
        check_background(FR8[0], src16)
    # the byte order is no bit depth: a big-endian stack with a native background
    tifffile.imwrite(tmp_path / "be.tif", FR16.astype(">u2"), byteorder=">")
    check_background(FR16[0], open_recording(tmp_path / "be.tif"))
