"""Verdicts that name the real cause (issue 33, item 1): the fault study's misses, each on the
drawn recordings of :mod:`validation.faults.recordings` or on a track with a known truth."""

import logging

import numpy as np

from rollfric.measurement import measure
from rollfric.track import plausibility
from validation.faults.recordings import Family, clean

logging.getLogger("rollfric").setLevel(logging.ERROR)


def _track(n=400):
    t = np.arange(n) / 200.0
    th = 0.3 * np.cos(2 * np.pi * t / 0.85)
    return 240 + 193 * np.sin(th), 20 + 193 * np.cos(th)


def test_a_small_balls_scattered_rim_share_is_no_occlusion_but_a_real_one_is():
    # a ball of 3.5 px: the rim's share that fits a circle is k of 48 rays, k ~ binomial
    # (48, 0.42), frame to frame (as located on the drawn 3 mm ball); a 7 px ball's k of 128
    # ~ binomial(128, 0.73), and a bar across it for 4 frames leaves 0.3 of its rim
    x, y = _track()
    rng = np.random.default_rng(1)
    found = np.ones(x.size, bool)
    small = rng.binomial(48, 0.42, x.size) / 48.0
    flags = plausibility.flag_frames(x, y, found, inlier_frac=small)
    assert not (flags == "occluded").any()
    big = rng.binomial(128, 0.73, x.size) / 128.0
    assert not (plausibility.flag_frames(x, y, found, inlier_frac=big) == "occluded").any()
    big[200:204] = 0.3
    flags = plausibility.flag_frames(x, y, found, inlier_frac=big)
    assert set(np.flatnonzero(flags == "occluded")) == set(range(200, 204))


def test_a_clean_3_mm_ball_loses_no_frames_to_the_plausibility_checks():
    # the fault study's clean 3 mm ball (3.5 px radius): 54 of 400 frames were "occluded",
    # the measurement suspect (flagged_frames, swing_coverage) with mu right
    rec = clean(Family(ball_mm=3.0), seed=1000)
    df, info, res = measure(rec.source, rec.setup, rec.background)
    codes = {r.code for r in res.quality_reasons}
    assert not codes & {"flagged_frames", "swing_coverage"}
    assert info.flags.get("occluded", 0) == 0
    assert abs(res.mu / rec.mu - 1) < 3e-3
