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
