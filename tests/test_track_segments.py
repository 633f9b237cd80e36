"""A long recording tracked in segments (rollfric.track.tracker.track_segments): the split itself,
the
track against one pass through the recording (the same but at the first frames of a later
segment, which start from a full-frame search), the same track on threads and one after
another, a repeated frame at a segment's start, and an error in one segment."""

import threading

import numpy as np
import pandas as pd
import pytest
from measure_data import MemorySource, make_recording

from rollfric import parallel as cpus
from rollfric.errors import InputError
from rollfric.io.readers import RecordingError
from rollfric.track.tracker import SEGMENT_MIN_FRAMES, track_recording, track_segments


def test_the_segments_cover_the_recording_in_order():
    assert track_segments(2 * SEGMENT_MIN_FRAMES - 1) == [(0, 2 * SEGMENT_MIN_FRAMES - 1)]
    assert track_segments(2 * SEGMENT_MIN_FRAMES) == [(0, SEGMENT_MIN_FRAMES),
                                                      (SEGMENT_MIN_FRAMES,
                                                       2 * SEGMENT_MIN_FRAMES)]
    assert track_segments(4001) == [(0, 2001), (2001, 4001)]
    assert track_segments(10, 3) == [(0, 4), (4, 7), (7, 10)]
    assert track_segments(4001, 1) == [(0, 4001)]
    assert track_segments(2, 5) == [(0, 1), (1, 2)]  # never an empty segment
    for bad in (0, -1, 2.5, True, "two", None):
        with pytest.raises(InputError, match="segments"):
            track_segments(100, bad)


def _recording(fps=1000.0):
    # noise and a stretch without the ball: a segment's start and a loss both search the frame
    rec = make_recording(90, noise=2.0, missing=[70, 71, 72], ball_mm=6.0, fps=fps)
    return rec, [np.asarray(f) for f in rec.frames]


def _track(rec, frames, segments, **kw):
    source = MemorySource(frames, **{"concurrent": True, **kw})
    return track_recording(source, rec.setup, rec.background, progress=False,
                           center=rec.scene.center, segments=segments)


def test_two_segments_give_one_pass_s_track():
    # a ball moving under a px a frame: the second segment's warm-up frames lock the
    # prediction on as one pass has it, and the track is the same to the bit
    rec, frames = _recording()
    one, info1 = _track(rec, frames, 1)
    two, info2 = _track(rec, frames, 2)
    pd.testing.assert_frame_equal(two, one, check_exact=True)
    assert info2 == info1


def test_a_fast_ball_s_second_segment_differs_in_the_locator_s_last_digits_only():
    # 4 px a frame on a 7 px ball: a new start's prediction (from one centre) misses by more
    # than the tracker's gate, so a start locks on only where the ball slows; one pass and the
    # second segment then locate some frames from other guesses
    rec, frames = _recording(fps=200.0)
    one, info1 = _track(rec, frames, 1)
    two, info2 = _track(rec, frames, 2)
    (_, m), _ = track_segments(len(frames), 2)
    # the first segment is one pass's first half, to the bit
    pd.testing.assert_frame_equal(two.iloc[:m], one.iloc[:m], check_exact=True)
    for col in ("x_px", "y_px", "r_px"):
        d = np.abs(two[col].to_numpy() - one[col].to_numpy())
        assert np.nanmax(d) < 0.01  # measured: 0.0027 px (x), 0.0076 px (r)
    assert (two["flag"] == one["flag"]).all() and (two["found"] == one["found"]).all()
    assert info2.n_found == info1.n_found and info2.flags == info1.flags
    # against the drawn centres: as good as one pass
    found = two["found"].to_numpy() == 1
    err = np.hypot(two["x_px"].to_numpy() - rec.centers[:, 0],
                   two["y_px"].to_numpy() - rec.centers[:, 1])[found]
    assert np.max(err) < 0.05


def test_segments_on_threads_and_one_after_another_give_the_same_track(monkeypatch):
    rec, frames = _recording()
    monkeypatch.setattr(cpus, "free_cpus", lambda **_: 2)
    runs, threads = [], []
    for concurrent in (False, True):
        src = MemorySource(frames, concurrent=concurrent)
        runs.append(track_recording(src, rec.setup, rec.background, progress=False,
                                    center=rec.scene.center, segments=2))
        threads.append(src.threads)
    pd.testing.assert_frame_equal(runs[1][0], runs[0][0], check_exact=True)
    assert runs[1][1] == runs[0][1]
    # one after another in the caller's thread; concurrently on two others
    assert threads[0] == {threading.get_ident()}
    assert len(threads[1] - {threading.get_ident()}) == 2
    # no CPU free: one after another, the same track
    monkeypatch.setattr(cpus, "free_cpus", lambda **_: 1)
    src = MemorySource(frames, concurrent=True)
    busy = track_recording(src, rec.setup, rec.background, progress=False,
                           center=rec.scene.center, segments=2)
    pd.testing.assert_frame_equal(busy[0], runs[0][0], check_exact=True)
    assert src.threads == {threading.get_ident()}


def test_the_free_cpus_are_the_process_s_less_the_threads_running_elsewhere(monkeypatch,
                                                                            tmp_path):
    import builtins

    real_open = builtins.open
    loadavg = tmp_path / "loadavg"

    def fake_open(path, *a, **k):
        return real_open(loadavg if path == "/proc/loadavg" else path, *a, **k)

    monkeypatch.setattr(builtins, "open", fake_open)
    monkeypatch.setattr(cpus, "cpus", lambda: 2)
    for line, free in (("0.5 0.4 0.3 1/300 77", 2), ("1.9 1.0 0.8 2/300 77", 1),
                       ("11.0 9.0 8.0 13/500 77", 1)):
        loadavg.write_text(line + "\n")
        assert cpus.free_cpus() == free
    loadavg.write_text("garbled\n")  # unreadable: every CPU of the process
    assert cpus.free_cpus() == 2


def test_a_thread_running_for_an_instant_does_not_take_the_free_cpu(monkeypatch):
    import builtins
    import io

    lines = iter(["1.9 1.0 0.8 2/300 77", "1.9 1.0 0.8 2/300 77", "1.9 1.0 0.8 1/300 77",
                  "1.9 1.0 0.8 2/300 77", "1.9 1.0 0.8 2/300 77"])
    real_open = builtins.open
    reads = []

    def fake_open(path, *a, **k):
        if path == "/proc/loadavg":
            reads.append(path)
            return io.StringIO(next(lines) + "\n")
        return real_open(path, *a, **k)

    monkeypatch.setattr(builtins, "open", fake_open)
    monkeypatch.setattr(cpus, "cpus", lambda: 2)
    # one reading of five saw the other CPU free
    assert cpus.free_cpus(samples=5, interval=0.0) == 2
    assert len(reads) == 3  # it stops reading once nothing else runs
    lines = iter(["1.9 1.0 0.8 2/300 77"] * 5)
    reads.clear()
    assert cpus.free_cpus(samples=5, interval=0.0) == 1  # busy in every reading
    assert len(reads) == 5
    lines = iter(["1.9 1.0 0.8 2/300 77"] * 5)
    reads.clear()
    assert cpus.free_cpus() == 1  # by default one reading (a short computation's choice)
    assert len(reads) == 1


def test_a_repeated_frame_at_a_segment_s_start_is_flagged_as_in_one_pass():
    rec, frames = _recording()
    (_, m), _ = track_segments(len(frames), 2)
    frames = list(frames)
    frames[m] = frames[m - 1].copy()  # the camera sent frame m - 1 twice
    one, _ = _track(rec, frames, 1)
    two, _ = _track(rec, frames, 2)
    assert one["flag"].iloc[m] == "duplicate"
    assert (two["flag"] == one["flag"]).all()


def _track_threads():
    return [t for t in threading.enumerate() if t.name.startswith("rollfric-track")]


def test_an_error_in_one_segment_is_raised_and_no_thread_is_left(monkeypatch):
    rec, frames = _recording()
    monkeypatch.setattr(cpus, "free_cpus", lambda **_: 2)
    before = set(_track_threads())
    with pytest.raises(RecordingError, match="frame 60 is corrupt"):
        _track(rec, frames, 2, bad={60: 0})
    for t in set(_track_threads()) - before:
        t.join(timeout=10.0)
        assert not t.is_alive()
