"""Per-frame plausibility: a located "ball" stuck at one place while the motion goes on."""

import numpy as np

from rollfric.track import plausibility


def _noisy(x, y, seed=0, s=0.02):
    rng = np.random.default_rng(seed)
    return x + rng.normal(0, s, x.size), y + rng.normal(0, s, y.size)


def test_a_place_the_track_sticks_to_at_full_speed_is_flagged():
    # the ball rolls 3 px a frame; frames 20-27 are located at one place (a ghost) meanwhile
    i = np.arange(60, dtype=float)
    x, y = 100.0 + 3.0 * i, 50.0 + 0.5 * i
    x[20:28], y[20:28] = 130.0, 60.0
    x, y = _noisy(x, y)
    flags = plausibility.flag_frames(x, y, np.ones(60, bool))
    assert (flags[20:28] == "stuck").all()
    assert not np.isin(flags[:20], ["stuck"]).any() and not np.isin(flags[28:], ["stuck"]).any()
    # a ghost at the start, left at full speed, too
    x2, y2 = 100.0 + 3.0 * i, 50.0 + 0.0 * i
    x2[:10] = 95.0
    x2, y2 = _noisy(x2, y2, seed=1)
    assert (plausibility.stuck(x2, y2, np.ones(60, bool))[:10]).all()


def test_a_ball_that_slows_to_rest_turns_or_is_released_is_not_stuck():
    t = np.arange(200, dtype=float)
    a = 0.2  # px / frame^2
    # slows to a halt at frame 40 and rests
    stop = np.where(t < 40, 12.0 * t - 0.15 * t ** 2, 12.0 * 40 - 0.15 * 40 ** 2)
    # held for 50 frames, then released
    held = np.where(t < 50, 0.0, 0.5 * a * (t - 50) ** 2)
    # swings with turning points, fast and slow
    for amp, period in ((300.0, 80.0), (40.0, 120.0), (5.0, 60.0)):
        sw = amp * np.sin(2 * np.pi * t / period)
        assert not plausibility.stuck(*_noisy(sw, 0 * t), np.ones(200, bool)).any()
    for xs in (stop, held):
        assert not plausibility.stuck(*_noisy(xs, 0 * t), np.ones(200, bool)).any()


def test_two_swapped_frames_near_a_turning_point_make_no_stuck_run():
    # the rendered fault study: frames 1147 and 1149 swapped with later ones put the located
    # ball 17 px away and back, three steps of 17 px that read as a steady motion "at full
    # speed"; the slow frames at the turning point beside them (steps below 1.7 px) were
    # flagged stuck, 212 of 1201 frames, the fit then suspect for its period
    t = np.arange(1201) / 1000.0
    x = 100.0 + 55.0 * np.cos(2 * np.pi * t / 0.68)
    y = 30.0 + 0.002 * (x - 100.0) ** 2
    x, y = _noisy(x, y, seed=3)
    for i in (1147, 1149):
        x[i], y[i] = x[i] + 17.0, y[i] + 1.0
    assert not plausibility.stuck(x, y, np.ones(x.size, bool)).any()
