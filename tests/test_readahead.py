"""Reading one frame ahead on a second thread (rollfric.track.readahead): the same bytes as plain
reads, in order, every read on the one worker thread, errors raised where they were asked for,
and a measurement that is the same with and without it."""

import gc
import threading

import numpy as np
import pandas as pd
import pytest
from measure_data import MemorySource as _Source
from measure_data import make_recording

from rollfric.io.readers import RecordingError
from rollfric.measurement import measure
from rollfric.track.readahead import ReadAhead
from rollfric.track.tracker import track_recording


def _frames(n=12, h=40, w=50, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 65535, (h, w), dtype=np.uint16) for _ in range(n)]


def test_regions_are_the_bytes_of_plain_reads_in_order():
    frames = _frames()
    src = _Source(frames)
    rng = np.random.default_rng(1)
    with ReadAhead(src) as ra:
        for i in range(len(frames)):
            ra.prefetch(i + 1, (5 + i, 30 + i, -3, 20 + 2 * i))  # clipped to the frame
            for _ in range(4):  # inside the region read ahead of frame i, and outside it
                y0, x0 = rng.integers(0, 30), rng.integers(0, 40)
                roi = (int(y0), int(y0 + rng.integers(1, 11)), int(x0),
                       int(x0 + rng.integers(1, 11)))
                got = ra.read(i, roi)
                want = frames[i][roi[0]:roi[1], roi[2]:roi[3]]
                assert got.dtype == want.dtype and got.flags.c_contiguous
                np.testing.assert_array_equal(got, want)
            np.testing.assert_array_equal(ra.frame(i), frames[i])
        assert ra.hits > 0 and ra.misses > 0
        # a region inside the one read ahead is sliced from it, not read again
        n = len(src.reads)
        ra.prefetch(3, (0, 40, 0, 50))
        for _ in range(5):
            np.testing.assert_array_equal(ra.read(3, (2, 9, 4, 33)), frames[3][2:9, 4:33])
        assert len(src.reads) == n + 1
    # every read of the source was made on the one worker thread, never the caller's
    assert src.threads and threading.get_ident() not in src.threads and len(src.threads) == 1


def test_errors_are_raised_where_a_region_is_asked_for():
    frames = _frames()
    src = _Source(frames, bad={4: 40, 6: 0})
    with ReadAhead(src) as ra:
        # the region read ahead reaches the bad columns, the region asked for does not: no error
        ra.prefetch(4, (0, 40, 0, 50))
        np.testing.assert_array_equal(ra.read(4, (0, 10, 0, 30)), frames[4][:10, :30])
        # a region that is bad itself raises the reader's own error, in the caller's thread
        with pytest.raises(RecordingError, match="frame 4's columns from 40"):
            ra.read(4, (0, 10, 30, 45))
        ra.prefetch(6, (0, 20, 0, 20))
        with pytest.raises(RecordingError, match="frame 6"):
            ra.read(6, (1, 5, 1, 5))
        with pytest.raises(RecordingError, match="frame 6 is corrupt"):
            ra.frame(6)
        # and the reader goes on
        np.testing.assert_array_equal(ra.read(7, (0, 3, 0, 3)), frames[7][:3, :3])
    # closed: the worker thread has ended
    assert not [t for t in threading.enumerate() if t.name.startswith("rollfric-read-ahead")]


def test_tracking_with_and_without_read_ahead_is_the_same():
    # noise, and frames without the ball (the tracker loses it and searches whole frames)
    rec = make_recording(70, noise=2.0, missing=[30, 31, 32, 33, 34, 50], ball_mm=6.0)
    frames = [np.asarray(f) for f in rec.frames]
    runs = []
    for read_ahead in (False, True):
        src = _Source(frames)
        runs.append(track_recording(src, rec.setup, rec.background, progress=False,
                                    read_ahead=read_ahead, center=rec.scene.center))
    pd.testing.assert_frame_equal(runs[1][0], runs[0][0], check_exact=True)
    assert runs[1][1] == runs[0][1]


def _read_ahead_threads():
    return [t for t in threading.enumerate() if t.name.startswith("rollfric-read-ahead")]


def test_a_bad_frame_stops_the_measurement_with_its_error_and_no_thread_is_left():
    rec = make_recording(40, noise=2.0, ball_mm=6.0)
    frames = [np.asarray(f) for f in rec.frames]
    before = set(_read_ahead_threads())
    with pytest.raises(RecordingError, match="frame 25"):
        measure(_Source(frames, bad={25: 0}), rec.setup, rec.background, fit=False,
                read_ahead=True)
    gc.collect()
    for t in set(_read_ahead_threads()) - before:
        t.join(timeout=10.0)
        assert not t.is_alive()
