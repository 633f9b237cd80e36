"""The locator's precision: the centre's Cramér-Rao bound (rollfric.locate.precision)."""

import math

import numpy as np
import pytest
from scipy import ndimage

from rollfric.locate.precision import centre_crb
from validation.bench.locate import cramer_rao_rms


@pytest.mark.parametrize("r", [6.0, 17.5, 40.0])
def test_sharp_edge_matches_the_bench_reference(r):
    # the bench's bound adds the 8-bit rounding (1/12 DN^2): the same total variance here
    ref = cramer_rao_rms(r, 80.0, math.sqrt(4.0 - 1.0 / 12.0))
    assert centre_crb(r, 80.0, 2.0) == pytest.approx(ref, rel=0.02)


def test_scales_as_noise_over_contrast_and_grows_with_blur():
    base = centre_crb(15.0, 100.0, 2.0)
    assert centre_crb(15.0, 50.0, 2.0) == pytest.approx(2 * base, rel=1e-9)
    assert centre_crb(15.0, 100.0, 6.0) == pytest.approx(3 * base, rel=1e-9)
    assert centre_crb(15.0, -100.0, 2.0) == pytest.approx(base, rel=1e-9)
    blurred = [centre_crb(15.0, 100.0, 2.0, e) for e in (0.0, 0.5, 1.0, 2.0)]
    assert np.all(np.diff(blurred) > 0)
    assert math.isinf(centre_crb(15.0, 0.0, 2.0))


def _model(cx, cy, r, e, size, ss=16):
    """A disc's area-sampled coverage blurred by a Gaussian of std e px: drawn on a grid ss
    times finer, blurred there and averaged over each pixel."""
    u = (np.arange(size * ss) + 0.5) / ss - 0.5
    xx, yy = np.meshgrid(u, u)
    fine = ((xx - cx) ** 2 + (yy - cy) ** 2 <= r * r).astype(float)
    if e > 0:
        fine = ndimage.gaussian_filter(fine, e * ss, mode="constant", truncate=5.0)
    return fine.reshape(size, ss, size, ss).mean(axis=(1, 3))


@pytest.mark.parametrize("e", [0.0, 1.2])
def test_matches_a_brute_force_fisher_sum_on_a_drawn_image(e):
    # Fisher information from the finite-difference derivative of a drawn model image
    r, c, s, size, h = 9.0, 60.0, 3.0, 32, 0.05
    cx, cy = 15.37, 15.61
    dx = (_model(cx + h, cy, r, e, size) - _model(cx - h, cy, r, e, size)) / (2 * h)
    dy = (_model(cx, cy + h, r, e, size) - _model(cx, cy - h, r, e, size)) / (2 * h)
    ixx = (c / s) ** 2 * np.sum(dx * dx)
    iyy = (c / s) ** 2 * np.sum(dy * dy)
    brute = math.sqrt(1 / ixx + 1 / iyy)
    assert centre_crb(r, c, s, e) == pytest.approx(brute, rel=0.05)
