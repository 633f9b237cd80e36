"""Locators on analytically drawn balls with known sub-pixel centres (exact area coverage)."""

import math

import numpy as np
import pytest

from rollfric.locate import (
    SubpixelOptions,
    coarse_find,
    locate_large_thesis,
    locate_small_thesis,
    locate_subpixel,
)
from synth.drawn.frames import Scene, disk_coverage, make_frames

R10, R12, R158 = 5.0 / 0.1343, 6.345 / 0.1343, 0.79 / 0.1343  # thesis balls in px


def _scene(r_px, **kw):
    # a 200 x 200 window of backdrop with the trough axis far above: the ball alone
    return Scene(width=200, height=200, center=(100.0, -500.0), R_px=640.0, r_px=r_px, **kw)


def _errors(scene, n=8, seed=0, guess_err=1.2, occluder=None, **kw):
    rng = np.random.default_rng(seed)
    errs, found = [], []
    for i in range(n):
        cx, cy = 100 + rng.uniform(-0.5, 0.5), 100 + rng.uniform(-0.5, 0.5)
        occ = occluder(cx, cy) if occluder else None
        bg, (frame,) = make_frames(scene, [(cx, cy)], seed=seed * 100 + i, occluder=occ)
        loc = locate_subpixel(frame, bg, scene.r_px, guess=(cx + guess_err, cy - guess_err),
                              **kw)
        found.append(loc.found)
        errs.append((loc.x - cx, loc.y - cy))
    e = np.array(errs)
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1)))), np.array(found)


def test_disk_coverage_is_exact_area():
    cov = disk_coverage(40, 40, 19.3, 20.7, 11.0)
    assert cov.sum() == pytest.approx(math.pi * 11.0 ** 2, rel=2e-4)
    yy, xx = np.mgrid[0:40, 0:40]
    assert (cov * xx).sum() / cov.sum() == pytest.approx(19.3, abs=2e-3)
    assert (cov * yy).sum() / cov.sum() == pytest.approx(20.7, abs=2e-3)


@pytest.mark.parametrize("r_px,tol", [(R10, 0.01), (R12, 0.01), (R158, 0.05)])
def test_subpixel_clean(r_px, tol):
    rms, found = _errors(_scene(r_px))
    assert found.all()
    assert rms < tol


def test_subpixel_known_radius_and_quality():
    rms, found = _errors(_scene(R10), opts=SubpixelOptions(radius="known"))
    assert found.all() and rms < 0.02
    bg, (frame,) = make_frames(_scene(R10), [(100.3, 99.6)])
    loc = locate_subpixel(frame, bg, R10, guess=(101, 99))
    assert loc.r == pytest.approx(R10, abs=0.05)
    assert 0 < loc.sigma < 0.02 and loc.inlier_frac > 0.8


def test_subpixel_noise_8_and_16_bit():
    rms8, found8 = _errors(_scene(R10, noise=3.0))
    assert found8.all() and rms8 < 0.02
    rms16, found16 = _errors(_scene(R10, noise=3.0 * 257, bit_depth=16))
    assert found16.all() and rms16 < 0.02


def test_subpixel_rejects_shadow_and_occluded_arcs():
    rms, found = _errors(_scene(R10, shadow=0.5))
    assert found.all() and rms < 0.03
    # a bar hiding the top 30 % of the ball
    rms, found = _errors(_scene(R10), occluder=lambda cx, cy: (0, 0, 200, cy - 0.4 * R10))
    assert found.all() and rms < 0.05


def test_subpixel_without_guess_searches_the_frame():
    bg, (frame,) = make_frames(_scene(R10), [(63.4, 128.9)])
    loc = locate_subpixel(frame, bg, R10)
    assert loc.found
    assert math.hypot(loc.x - 63.4, loc.y - 128.9) < 0.05
    assert coarse_find(frame, bg, R10) is not None


def test_missing_ball_is_not_found():
    bg, (frame,) = make_frames(_scene(R10, noise=2.0), [(None, None)], seed=4)
    assert not locate_subpixel(frame, bg, R10).found
    assert not locate_subpixel(frame, bg, R10, guess=(100, 100)).found
    assert coarse_find(frame, bg, R10) is None


def test_wrong_radius_is_not_found():
    bg, (frame,) = make_frames(_scene(R10), [(100.2, 100.1)])
    loc = locate_subpixel(frame, bg, 0.6 * R10, guess=(100, 100))
    assert not loc.found


def test_thesis_large_locator_to_a_pixel():
    scene = _scene(R10)
    rng = np.random.default_rng(5)
    for side in (1, -1):
        cx, cy = 100 + rng.uniform(-0.5, 0.5), 100 + rng.uniform(-0.5, 0.5)
        bg, (frame,) = make_frames(scene, [(cx, cy)])
        loc = locate_large_thesis(frame, bg, R10, side=side, guess=(cx + 2, cy - 2))
        assert loc.found
        assert math.hypot(loc.x - cx, loc.y - cy) < 1.5


def test_thesis_small_locator_brightest_point():
    # the thesis takes the brightest point (the specular spot) in the best 15 x 15 window: the
    # drawn ball's spots sit at (cx -+ 0.3 r, cy - 0.2 r)
    scene = _scene(R158)
    cx, cy = 87.3, 112.6
    bg, (frame,) = make_frames(scene, [(cx, cy)])
    loc = locate_small_thesis(frame, bg, roi=(40, 60, 140, 160))
    assert loc.found
    assert loc.x == int(loc.x) and loc.y == int(loc.y)  # integer pixels, as in the thesis
    spots = [(cx - 0.3 * R158, cy - 0.2 * R158), (cx + 0.3 * R158, cy - 0.2 * R158)]
    assert min(math.hypot(loc.x - sx, loc.y - sy) for sx, sy in spots) <= 1.0
    # nothing brighter than the background: nothing found
    assert not locate_small_thesis(bg, bg).found
