"""The median background when the ball rests in one place for most of the recording."""

import logging

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
    assert "repaired" in info.background
    assert any("resting ball" in m for m in info.warnings)
    assert any(m.startswith("warning: the median background held a resting ball") for m in logs)
    # the repaired disc is the backdrop again (noise aside)
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
