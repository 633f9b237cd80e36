"""Per-frame figures of the ball's tile: the light around the ball and a repeated frame.

:func:`ring_gain` (the frame's brightness against the background in a ring about the ball: a
flash or a dropped exposure moves it) and :func:`same_pixels` (the ball's tile the same as the
previous frame's: a repeated frame) feed the tracker's plausibility checks
(:mod:`rollfric.track.plausibility`); both run on the locator's kernels.
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.locate.kernels.crops import ring_sums, same_values
from rollfric.locate.regions import _crop


def ring_gain(frame, background, x: float, y: float, r: float) -> float:
    """Brightness of the frame against the background in a ring 2-6 px outside the ball at
    (x, y) of radius r: sum(frame) / sum(background) over the ring (NaN when the ring is off
    the frame or dark). A flash or a dropped exposure moves it; the ball does not."""
    m = int(math.ceil(r + 7))
    x0, y0 = int(math.floor(x)) - m, int(math.floor(y)) - m
    fr, x0c, y0c = _crop(frame, x0, y0, x0 + 2 * m + 2, y0 + 2 * m + 2)
    if fr is None:
        return math.nan
    bg = background[y0c:y0c + fr.shape[0], x0c:x0c + fr.shape[1]]
    num, den, count = ring_sums(np.asarray(fr), np.asarray(bg), x0c, y0c, float(x), float(y),
                                 r + 2, r + 6)
    if count < 8 or den <= 0:
        return math.nan
    return num / den


def same_pixels(frame, prev, x: float, y: float, r: float) -> bool:
    """True when the ball's tile (the box of the ball at (x, y) of radius r, 4 px more a side)
    holds the same pixels in ``frame`` and ``prev``: a repeated frame (two exposures always
    differ by the sensor's noise)."""
    m = int(math.ceil(r + 4))
    x0, y0 = int(math.floor(x)) - m, int(math.floor(y)) - m
    a, _, _ = _crop(frame, x0, y0, x0 + 2 * m + 2, y0 + 2 * m + 2)
    b, _, _ = _crop(prev, x0, y0, x0 + 2 * m + 2, y0 + 2 * m + 2)
    return (a is not None and b is not None and a.shape == b.shape
            and same_values(np.asarray(a), np.asarray(b)))
