"""Regions of interest: every reader's read(i, roi) is the crop of the full frame, and the
tracking loop reading only ROIs gives the same track as reading whole frames."""

import logging

import cv2
import numpy as np
import pandas as pd
import pytest
import tifffile
import zarr
from measure_data import make_recording, messages

from rollfric.io import readers as io
from rollfric.io.formats.zarrstore import EntryPointSource
from rollfric.locate import LazyFrame, locate_subpixel
from rollfric.measurement import measure

rng = np.random.default_rng(1)
FR8 = rng.integers(0, 255, (4, 37, 53), dtype=np.uint8)
FR16 = rng.integers(0, 65535, (4, 37, 53), dtype=np.uint16)


def _rois(h, w, k=25, seed=0):
    """Random regions plus the whole frame, single pixels at the corners and edge strips."""
    r = np.random.default_rng(seed)
    out = [(0, h, 0, w), (0, 1, 0, 1), (h - 1, h, w - 1, w), (0, h, w - 3, w), (h - 2, h, 0, w)]
    for _ in range(k):
        y0 = int(r.integers(0, h))
        x0 = int(r.integers(0, w))
        out.append((y0, int(r.integers(y0 + 1, h + 1)), x0, int(r.integers(x0 + 1, w + 1))))
    return out


def _check_reads(src, frames):
    t, h, w = frames.shape
    for i in range(t):
        for roi in _rois(h, w, seed=i):
            y0, y1, x0, x1 = roi
            got = src.read(i, roi)
            assert got.dtype == frames.dtype
            np.testing.assert_array_equal(got, frames[i, y0:y1, x0:x1])
            np.testing.assert_array_equal(got, src[i][y0:y1, x0:x1])
    np.testing.assert_array_equal(src.read(-1, (1, 5, 2, 9)), frames[-1, 1:5, 2:9])


@pytest.mark.parametrize("frames", [FR8, FR16])
@pytest.mark.parametrize("kind", ["pages", "pages-big-endian", "pages-zlib", "stack", "zarr",
                                  "folder"])
def test_read_roi_is_the_crop_of_the_frame(tmp_path, frames, kind):
    if kind.startswith("pages"):
        p = tmp_path / "rec.tif"
        kw = {"compression": "zlib"} if kind == "pages-zlib" else {}
        with tifffile.TiffWriter(p, byteorder=">" if kind == "pages-big-endian" else "<") as tw:
            for f in frames:
                tw.write(f, contiguous=False, **kw)
    elif kind == "stack":  # one page holding the (T, H, W) stack
        p = tmp_path / "rec.tif"
        tifffile.imwrite(p, frames, photometric="minisblack", planarconfig="separate")
    elif kind == "zarr":
        p = tmp_path / "rec.zarr"
        zarr.open_group(str(p), mode="w").create_array("frames", data=frames,
                                                       chunks=(1, 16, 16))
    else:
        p = tmp_path / "png"
        p.mkdir()
        for i, f in enumerate(frames):
            cv2.imwrite(str(p / f"f{i:03d}.png"), f)
    src = io.open_recording(p)
    assert src.shape == frames.shape
    _check_reads(src, frames)
    if kind in ("pages", "pages-big-endian"):  # plain pages are memory-mapped, not decoded
        assert src._mmap is not None
    if kind == "pages-zlib":
        assert src._mmap is None
    if kind.startswith("pages") or kind == "stack":
        assert (src._stack is not None) == (kind == "stack")


def test_read_roi_refuses_bad_regions(tmp_path):
    p = tmp_path / "rec.tif"
    tifffile.imwrite(p, FR8, photometric="minisblack")
    src = io.open_recording(p)
    for roi in [(0, 0, 0, 5), (5, 3, 0, 5), (0, 38, 0, 5), (-1, 3, 0, 5), (0, 3, 10, 54)]:
        with pytest.raises(IndexError, match="roi"):
            src.read(0, roi)
    with pytest.raises(TypeError, match="roi"):
        src.read(0, (0, 3))
    with pytest.raises(IndexError):
        src.read(4, (0, 3, 0, 3))


class _Group:
    attrs = {"fps": 100.0}


class _Plain:
    """A FrameSource without read(): an entry-point reader's object."""

    def __init__(self, frames, background=None):
        self.frames = frames
        self.shape = (len(frames),) + frames[0].shape
        self.dtype = frames[0].dtype
        self.fps = None
        self.background = background
        self.attrs = {}
        self.full_reads = 0

    def __len__(self):
        return self.shape[0]

    def __getitem__(self, i):
        self.full_reads += 1
        return self.frames[i].copy()


class _WithRead(_Plain):
    def __init__(self, frames, background=None):
        super().__init__(frames, background)
        self.rois = []

    def read(self, i, roi):
        y0, y1, x0, x1 = roi
        self.rois.append(roi)
        return self.frames[i][y0:y1, x0:x1].copy()


def test_entry_point_source_forwards_read():
    inner = _WithRead(list(FR16))
    src = EntryPointSource(inner, "fake", _Group())
    _check_reads(src, FR16)
    assert len(inner.rois) == 4 * 30 + 1  # every region asked of the reader itself
    n_full = inner.full_reads
    src.read(1, (2, 9, 3, 20))
    assert inner.rois[-1] == (2, 9, 3, 20) and inner.full_reads == n_full
    # without read(): the crop of the full frame
    plain = _Plain(list(FR16))
    src = EntryPointSource(plain, "fake", _Group())
    _check_reads(src, FR16)

    class _Bad(_WithRead):
        def read(self, i, roi):
            return super().read(i, roi)[:-1]

    with pytest.raises(io.RecordingError, match="read"):
        EntryPointSource(_Bad(list(FR16)), "fake", _Group()).read(0, (0, 5, 0, 5))


def test_lazy_frame_crops_equal_the_full_frame():
    frame = FR16[0]
    reads = []

    def read(roi):
        reads.append(roi)
        y0, y1, x0, x1 = roi
        return frame[y0:y1, x0:x1].copy()

    lf = LazyFrame(read, lambda: frame.copy(), frame.shape, frame.dtype, margin=3)
    from rollfric.locate import _crop

    for x0, y0, x1, y1 in [(10, 10, 20, 20), (11, 12, 19, 21), (-5, -5, 4, 4), (50, 30, 60, 40),
                           (60, 40, 70, 50), (0, 0, 53, 37)]:
        a, ax, ay = _crop(lf, x0, y0, x1, y1)
        b, bx, by = _crop(frame, x0, y0, x1, y1)
        assert (ax, ay) == (bx, by)
        if b is None:
            assert a is None
        else:
            np.testing.assert_array_equal(a, b)
    # the second box lies inside the first read grown by the margin: no new read
    assert reads[0] == (7, 23, 7, 23) and len(reads) == 4
    np.testing.assert_array_equal(lf.full(), frame)


@pytest.mark.parametrize("method", ["subpixel", "thesis-large", "thesis-small"])
def test_measure_reading_rois_gives_the_same_track(method):
    # noise, and frames without the ball (the tracker loses it and searches whole frames)
    missing = [30, 31, 32, 33, 34, 50]
    rec = make_recording(70, noise=2.0, missing=missing,
                         ball_mm=16.0 if method == "thesis-large" else 6.0)
    frames = [np.asarray(f) for f in rec.frames]
    plain, roi = _Plain(frames), _WithRead(frames)
    df_full, _, _ = measure(plain, rec.setup, rec.background, method=method, fit=False)
    df_roi, _, _ = measure(roi, rec.setup, rec.background, method=method, fit=False)
    pd.testing.assert_frame_equal(df_roi, df_full, check_exact=True)
    assert df_full["found"].sum() >= 70 - len(missing) - 2
    # tracked frames were read as regions, far smaller than the frame
    h, w = frames[0].shape
    assert len(roi.rois) >= 40
    area = sum((y1 - y0) * (x1 - x0) for y0, y1, x0, x1 in roi.rois)
    assert roi.full_reads < 25
    assert area + roi.full_reads * h * w < 0.5 * plain.full_reads * h * w


def test_subpixel_on_a_lazy_frame_reads_one_region():
    rec = make_recording(3, noise=2.0)
    frame = np.asarray(rec.frames[1])
    reads = []

    def read(roi):
        reads.append(roi)
        y0, y1, x0, x1 = roi
        return frame[y0:y1, x0:x1].copy()

    r_px = rec.scene.r_px
    guess = (rec.centers[1, 0] + 1.3, rec.centers[1, 1] - 0.8)
    a = locate_subpixel(LazyFrame(read, lambda: frame, frame.shape, frame.dtype),
                        rec.background, r_px, guess=guess, search=3.0)
    b = locate_subpixel(frame, rec.background, r_px, guess=guess, search=3.0)
    assert a == b and a.found
    assert 1 <= len(reads) <= 2


def test_a_recording_frame_rate_other_than_the_setup_is_reported(caplog):
    rec = make_recording(12, noise=1.0)
    frames = [np.asarray(f) for f in rec.frames]
    src = _Plain(frames)
    src.fps = 30.0  # a video export's playback rate
    with caplog.at_level(logging.INFO, logger="rollfric"):
        df, info, _ = measure(src, rec.setup, rec.background, fit=False)
    logs = messages(caplog)
    assert any("30 frames/s" in m and "setup" in m for m in info.warnings)
    assert any(m.startswith("warning: the recording says 30") for m in logs)
    # times still come from the setup's rate
    np.testing.assert_allclose(df["t_s"].to_numpy(), np.arange(12) / rec.setup.fps)
    src.fps = rec.setup.fps
    _, info, _ = measure(src, rec.setup, rec.background, fit=False)
    assert not any("frames/s" in m for m in info.warnings)
