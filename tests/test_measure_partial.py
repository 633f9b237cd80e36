"""locate_subpixel with part of the ball's rim against a region of the ball's own level (a
harsh lamp's cast shadow): the arcs with contrast must give the centre within the stated
uncertainty, or the frame is reported not found; and the full search falls through to the next
coarse candidate when the first is rejected."""

import math

import numpy as np
import pytest

from rollfric.locate import locate_subpixel
from validation.drawn_frames import disk_coverage

R = 37.2


def _frame(cx, cy, shadow_frac, noise=2.0, seed=0):
    """A dark ball (20 DN) on a 120 DN backdrop whose lower right is a shadow of the ball's
    level, cut by a straight line so that ``shadow_frac`` of the rim lies in the shadow."""
    h, w = 200, 240
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    # shadow half-plane: points whose projection on (1, 1)/sqrt2 from the centre exceeds t;
    # the rim fraction beyond t is acos(t / R) / pi
    t = R * math.cos(math.pi * shadow_frac)
    shade = np.clip(((xx - cx) + (yy - cy)) / math.sqrt(2) - t + 0.5, 0.0, 1.0)
    bg = 120.0 * (1 - shade) + 20.0 * shade
    cov = disk_coverage(h, w, cx, cy, R)
    img = bg * (1 - cov) + 20.0 * cov
    rng = np.random.default_rng(seed)
    f = np.clip(np.rint(img + rng.normal(0, noise, img.shape)), 0, 255).astype(np.uint8)
    return f, np.clip(np.rint(bg), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("shadow_frac", [0.33, 0.5, 0.6])
def test_partial_arc_within_stated_uncertainty_or_not_found(shadow_frac):
    rng = np.random.default_rng(int(100 * shadow_frac))
    for k in range(6):
        cx, cy = rng.uniform(100, 140), rng.uniform(85, 115)
        f, bg = _frame(cx, cy, shadow_frac, seed=k)
        guess = (cx + rng.uniform(-2, 2), cy + rng.uniform(-2, 2))
        loc = locate_subpixel(f, bg, R, guess=guess)
        if shadow_frac <= 0.5:
            assert loc.found, loc.reason
        if loc.found:
            err = math.hypot(loc.x - cx, loc.y - cy)
            assert err < 4.0 * loc.sigma + 0.02, (err, loc.sigma)
            assert loc.sigma < 0.5

