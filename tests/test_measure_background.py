"""The median background when the ball rests in one place for most of the recording."""

import logging
import re

import numpy as np
from measure_data import make_recording, messages
from test_measure_roi import _Plain

from rollfric.io.background import median, median_background, sample
from rollfric.measurement import measure


def _errors(df, rec):
    found = df["found"].to_numpy() == 1
    err = np.hypot(df["x_px"] - rec.centers[:, 0], df["y_px"] - rec.centers[:, 1])
    return found, err[found]


def test_a_ball_resting_in_most_frames_is_taken_out_of_the_median(caplog):
    # mu 0.1 from 0.25 rad: the ball rests from frame ~70 of 240 on (71 % of the frames)
    rec = make_recording(240, mu=0.1, theta0=0.25, noise=1.0)
    rest = np.abs(np.diff(rec.theta)) < 1e-12
    assert rest.mean() > 0.6
    src = _Plain([np.asarray(f) for f in rec.frames])
    # the plain median holds the ball at its rest place
    _, stack = sample(src, 41)
    plain = median(stack).astype(int)
    xr, yr = rec.centers[-1]
    yy, xx = np.mgrid[0:plain.shape[0], 0:plain.shape[1]]
    disc = np.hypot(xx - xr, yy - yr) < 0.8 * rec.scene.r_px
    assert np.abs(plain - rec.background.astype(int))[disc].mean() > 20
    with caplog.at_level(logging.INFO, logger="rollfric"):
        df, info, _ = measure(src, rec.setup, None, fit=False)
    logs = messages(caplog)
    found, err = _errors(df, rec)
    assert found.all()
    assert np.sqrt(np.mean(err ** 2)) < 0.05 and err.max() < 0.1
    # the sampled frames at rest (from frame ~70, sampled every 6th) are left out of the
    # median; the median background repairs what is left of a resting ball otherwise (below)
    assert "repaired" in info.background
    said = [re.match(r"the median background is made from the (\d+) sampled frames in which "
                     r"the ball moves, not the last (\d+) \(the ball at rest from frame (\d+)\)",
                     m) for m in info.warnings]
    (m,) = [m for m in said if m]
    moving, still, start = (int(v) for v in m.groups())
    assert moving + still == 41 and 70 <= start <= 84
    assert any(x.startswith("warning: " + m.group(0)) for x in logs)
    # the median of all the sampled frames, repaired: the disc is the backdrop again
    bg, _ = median_background(src, rec.scene.r_px)
    assert np.abs(bg.astype(int) - rec.background.astype(int))[disc].max() <= 4


def test_a_moving_ball_leaves_the_median_alone():
    rec = make_recording(160, noise=1.0, missing=[20, 21, 22])
    src = _Plain([np.asarray(f) for f in rec.frames])
    bg, notes = median_background(src, rec.scene.r_px)
    _, stack = sample(src, 41)
    assert notes == []
    np.testing.assert_array_equal(bg, median(stack))


def test_a_ball_that_never_moves_is_reported():
    rec = make_recording(60, mu=0.1, theta0=0.0, noise=1.0)
    src = _Plain([np.asarray(f) for f in rec.frames])
    _, notes = median_background(src, rec.scene.r_px)
    assert len(notes) == 1 and "give a background image" in notes[0]


def test_still_runs_at_the_start_and_end_are_left_out_of_the_median():
    # sampled frames of a held start (the ball at x 40 in samples 0-9), a swing and a rest
    # (x 150 from sample 30 on), 41 in all, with noise and a 5 % flicker on every frame
    from rollfric.io.background_choice import _moving

    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:80, 0:200]
    xs = np.r_[np.full(10, 40.0), 100 + 60 * np.sin(np.arange(20)), np.full(11, 150.0)]
    stack = np.stack([(100.0 * (1 + 0.05 * rng.uniform(-1, 1))
                       - 60.0 * (np.hypot(xx - x, yy - 40) < 10)
                       + rng.normal(0, 2.0, xx.shape)) for x in xs]).astype(np.float32)
    idx = np.arange(41) * 30
    moving, note = _moving(idx, stack, 10.0)
    assert moving[9:31].all() and not moving[:9].any() and not moving[31:].any()
    assert "not the first 9 (a held start, frames 0-240) or the last 10 (the ball at rest " \
           "from frame 930)" in note
    # a ball that moves throughout: nothing left out
    moving, note = _moving(idx[:20], stack[10:30], 10.0)
    assert moving.all() and note == ""
