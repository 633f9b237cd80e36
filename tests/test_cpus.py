"""Independent computations on threads (rollfric.parallel): the results of the plain loop.

The fits that run on threads when CPUs are free (the least-squares fit's coarse starts, the
dropped-frame search's refits at turning points, the uncertainty budget's refits) are compared
bit for bit with the same fits made one after another in the calling thread."""

from __future__ import annotations

import dataclasses
import math
import threading

import numpy as np
import pytest
from test_timing import FPS, SETUP, angles_of, camera_track
from test_uncertainty import LAB, _lab_track, write

from rollfric import parallel as cpus
from rollfric.fit.estimate import fit_mu
from rollfric.setup.model import load_setup
from rollfric.track.dropped_frames import find_gaps, turning_gaps
from rollfric.uncertainty.budget import budget
from rollfric.uncertainty.measured import Measurement


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_map_ordered_gives_the_loop_s_results_in_order(workers):
    names = set()

    def square(x):
        names.add(threading.current_thread().name)
        return x * x

    assert cpus.map_ordered(square, range(7), workers=workers, name="sq") == \
        [x * x for x in range(7)]
    if workers == 1:
        assert names == {threading.current_thread().name}  # the plain loop
    else:
        assert names and all(n.startswith("sq") for n in names)


def test_map_ordered_raises_the_first_error_in_order_and_leaves_no_thread():
    def f(x):
        if x in (2, 4):
            raise ValueError(f"item {x}")
        return x

    with pytest.raises(ValueError, match="item 2"):
        cpus.map_ordered(f, range(6), workers=2, name="rollfric-test-err")
    assert not [t for t in threading.enumerate() if t.name.startswith("rollfric-test-err")]


@pytest.mark.parametrize("workers", [1, 2])
def test_first_ordered_finds_what_the_loop_that_stops_finds(workers):
    def accept(x, r):
        return r % 3 == 0

    assert cpus.first_ordered(lambda x: x + 1, [4, 7, 8, 11], accept, workers=workers) == \
        (8, 9)
    assert cpus.first_ordered(lambda x: x + 1, [4, 7], accept, workers=workers) is None
    with pytest.raises(ZeroDivisionError):  # an error before the first accepted is raised
        cpus.first_ordered(lambda x: 1 // x, [0, 1], lambda x, r: True, workers=workers)
    # one after the first accepted is not: the loop would not have made it
    assert cpus.first_ordered(lambda x: 1 // x, [1, 0], lambda x, r: True,
                              workers=workers) == (1, 1)


def _fields(result):
    return {k: v for k, v in dataclasses.asdict(result).items() if k != "seconds"}


def _same(a, b):
    """Equal to the bit, arrays included (NaN where NaN)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(a, b, equal_nan=True)
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return a == b


def _both(monkeypatch, run):
    """run() with one CPU free (the plain loops) and with two (threads)."""
    out = []
    for free in (1, 2):
        monkeypatch.setattr(cpus, "free_cpus", lambda free=free, **_: free)
        out.append(run())
    return out


def test_the_fit_on_threads_is_the_fit_in_one_thread(monkeypatch):
    x, y, _ = camera_track(np.arange(2500), seed=4)
    th = angles_of(x, y)
    one, two = _both(monkeypatch, lambda: fit_mu(np.arange(2500) / FPS, th, SETUP,
                                                  offset=True))
    assert one.extra["n_starts"] > 2  # the starts ran on two threads
    assert _same(_fields(one), _fields(two))


def test_the_turning_point_refits_on_threads_find_the_same_lost_frame(monkeypatch):
    omega = math.sqrt(5 * 9.80665 / (7 * SETUP.track_radius))
    turn = 3 * int(round(math.pi / omega * FPS))
    x, y, _ = camera_track(np.setdiff1d(np.arange(3000), [turn]), seed=1)
    gaps = find_gaps(x, y, np.ones(x.size, bool))
    th = angles_of(x, y)

    def run():
        first = fit_mu(gaps.pos / FPS, th, SETUP)
        return first, turning_gaps(gaps.pos / FPS, th, first, SETUP, False)

    (f1, (t1, r1, found1)), (f2, (t2, r2, found2)) = _both(monkeypatch, run)
    assert len(found1) == 1 and found1 == found2
    assert np.array_equal(t1, t2)
    assert _same(_fields(f1), _fields(f2)) and _same(_fields(r1), _fields(r2))


def test_the_budget_s_refits_on_threads_are_the_refits_in_one_thread(monkeypatch, tmp_path):
    lab = load_setup(write(tmp_path, LAB.replace("642.0", "640.0")))
    frames, x, y = _lab_track(seconds=2.0)
    meas = Measurement(setup=lab, frames=frames, x=x, y=y, center=lab.center_px)
    result = fit_mu(*meas.series(lab), lab)
    one, two = _both(monkeypatch, lambda: budget(meas, result))
    assert one.n_refits == two.n_refits > 8  # 5 inputs act: their 10 refits, and the nominal
    assert _same(_fields(one), _fields(two))


def test_measure_on_threads_is_measure_in_one_thread_and_times_its_stages(monkeypatch):
    # 1000 frames: the recording's halves on two threads too, the fits on two
    from measure_data import MemorySource, make_recording

    from rollfric import measurement as track

    rec = make_recording(1000, mu=0.01, theta0=0.5, fps=200.0, noise=1.0, seed=2)
    src = MemorySource(rec.frames, concurrent=True)
    (df1, info1, r1), (df2, info2, r2) = _both(
        monkeypatch, lambda: track.measure(src, rec.setup, rec.background))
    assert len(src.threads) > 1  # the second run read from two threads
    assert df1.equals(df2) and _same(_fields(r1), _fields(r2))
    assert dataclasses.replace(info1, seconds={}) == dataclasses.replace(info2, seconds={})
    for info in (info1, info2):
        assert set(info.seconds) == {"open", "background", "trough centre", "tracking", "fit",
                                     "turning points", "ellipse check", "path check", "checks",
                                     "locator precision"}
        assert all(v >= 0.0 for v in info.seconds.values())
        assert info.seconds["tracking"] > 0.0 and info.seconds["fit"] > 0.0
