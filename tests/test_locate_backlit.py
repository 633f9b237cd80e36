"""Backlit (shadowgraph) balls: a dark disc with a bright central spot on a bright field, its
limb shading into the dark inside and its edge blurred (drawn with exact centres, and the real
12-bit Photron clip of pyMRAW's test data), located by the default sub-pixel locator and by the
bench's plain edge-point circle fit."""

from pathlib import Path

import numpy as np
import pytest

from rollfric.io.readers import open_recording
from rollfric.locate import locate_subpixel
from synth.drawn.shadow import ShadowScene, background, draw
from validation.bench.locate import edge_point_locator

REAL = Path(__file__).parent / "data" / "real" / "ball_12bit.cihx"

SCENES = {
    # about the real clip: r 63.6 px, limb a quarter of the contrast fading over 2.5 px
    "real-like, noise 8 DN": ShadowScene(noise=8.0),
    "37 px ball, short limb": ShadowScene(r_px=37.2, limb_px=1.5, width=160, height=160),
    "uniform disc, blur 0.8 px": ShadowScene(limb=0.0, blur_px=0.8),
}


def _drawn(scene, n=6, seed=0):
    rng = np.random.default_rng(seed)
    c0 = 0.5 * (scene.width - 1)
    truth = c0 + rng.uniform(-0.5, 0.5, (n, 2))
    frames = [draw(scene, x, y, seed=seed * 100 + i) for i, (x, y) in enumerate(truth)]
    guesses = truth + rng.normal(0.0, 0.7, truth.shape)
    return background(scene), frames, truth, guesses


def _rms(locs, truth):
    assert all(loc.found for loc in locs)
    e = np.array([(loc.x, loc.y) for loc in locs]) - truth
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))


@pytest.mark.parametrize("name", list(SCENES))
def test_subpixel_on_drawn_shadowgraph(name):
    # the pixel fit's sharp-step model locked such an edge to the pixel grid (0.012-0.028 px);
    # a graded edge is integrated across a window that holds it all
    scene = SCENES[name]
    bg, frames, truth, guesses = _drawn(scene)
    locs = [locate_subpixel(f, bg, scene.r_px, guess=tuple(g))
            for f, g in zip(frames, guesses, strict=True)]
    assert _rms(locs, truth) <= 0.01
    # and from a full-frame search
    assert _rms([locate_subpixel(frames[0], bg, scene.r_px)], truth[:1]) <= 0.01


@pytest.mark.parametrize("name", list(SCENES))
def test_edge_point_baseline_on_drawn_shadowgraph(name):
    scene = SCENES[name]
    bg, frames, truth, guesses = _drawn(scene)
    locs = [edge_point_locator(f, bg, scene.r_px, tuple(g))
            for f, g in zip(frames, guesses, strict=True)]
    assert _rms(locs, truth) <= 0.01


def _quadratic_residuals(xy):
    # the ball falls freely over the 15 frames (0.5 ms): x and y are quadratics in time
    t = np.arange(len(xy))
    res = [xy[:, k] - np.polyval(np.polyfit(t, xy[:, k], 2), t) for k in (0, 1)]
    return np.sqrt(np.sum(np.square(res), axis=1) / (len(t) - 3))


def test_real_backlit_clip_no_noisier_than_the_edge_point_fit():
    src = open_recording(REAL)
    frames = [np.asarray(src[i]) for i in range(len(src))]
    # the clip has no ball-free frame; its backlight is saturated (4095) above the trough's
    # strip at the bottom (rows 300 on), which the ball never reaches: there the frames' maximum
    bg = np.full(frames[0].shape, 4095, frames[0].dtype)
    bg[300:] = np.max([f[300:] for f in frames], axis=0)
    ours = [locate_subpixel(f, bg, 63.6) for f in frames]
    assert all(loc.found for loc in ours)
    xy = np.array([(loc.x, loc.y) for loc in ours])
    ref = np.array([(loc.x, loc.y) for loc in (edge_point_locator(f, bg, 63.6, tuple(p))
                                                for f, p in zip(frames, xy, strict=True))])
    r_ours, r_ref = _quadratic_residuals(xy), _quadratic_residuals(ref)
    # (before: y 0.0100 px against 0.0036, and 0.023 px right of the edge-point fit)
    assert np.hypot(*r_ours) <= np.hypot(*r_ref)
    assert np.all(r_ours <= 0.005)
    assert np.all(np.abs(np.mean(xy - ref, axis=0)) <= 0.01)
    assert np.max(np.hypot(*(xy - ref).T)) <= 0.05


def test_bench_shadowgraph_case_rows():
    # the bench's shadowgraph case: the default locator and the edge-point baseline both
    # within 0.01 px of the exact centres; RANSAC's Canny edges are not
    from validation.bench.locate import run_case, shadow_case

    rows = {r["locator"]: r for r in run_case(shadow_case(4, seed=1))}
    assert rows["subpixel (ROI)"]["found"] == 1.0
    assert rows["subpixel (ROI)"]["rms_px"] <= 0.01
    assert rows["edge points (find_contours + CircleModel)"]["rms_px"] <= 0.01
    assert "skimage CircleModel+RANSAC" in rows
