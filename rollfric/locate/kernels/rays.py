"""The ray profiles of the sub-pixel locator: bilinear samples of frame - background along rays
from the current centre, and the background's own step along a ray."""

from __future__ import annotations

import numpy as np

from rollfric.jit import njit


@njit(nogil=True)
def profiles(rel, cx, cy, s0, ds, ns, n):
    """Bilinear samples of rel along n rays from (cx, cy) at s0 + j ds; NaN outside rel."""
    h, w = rel.shape
    prof = np.empty((n, ns), np.float64)
    te = s0 + (ns - 1) * ds
    for i in range(n):
        phi = (i + 0.5) * (2.0 * np.pi / n)
        c, sn = np.cos(phi), np.sin(phi)
        # x and y of the samples are monotone along the ray (each rounding is): a ray whose
        # first and last samples lie inside rel lies inside it all along, and its samples need
        # no test (the same values, less work)
        xa, ya, xb, yb = cx + c * s0, cy + sn * s0, cx + c * te, cy + sn * te
        test = not (0.0 <= xa <= w - 1 and 0.0 <= ya <= h - 1 and 0.0 <= xb <= w - 1
                    and 0.0 <= yb <= h - 1)
        for j in range(ns):
            t = s0 + j * ds
            x = cx + c * t
            y = cy + sn * t
            if test and (x < 0.0 or y < 0.0 or x > w - 1 or y > h - 1):
                prof[i, j] = np.nan
                continue
            ix = min(int(x), w - 2)
            iy = min(int(y), h - 2)
            fx = x - ix
            fy = y - iy
            prof[i, j] = ((1 - fy) * ((1 - fx) * rel[iy, ix] + fx * rel[iy, ix + 1])
                          + fy * ((1 - fx) * rel[iy + 1, ix] + fx * rel[iy + 1, ix + 1]))
    return prof


@njit(nogil=True)
def _bilinear(img, x, y):
    """img at (x, y) by bilinear interpolation; NaN outside."""
    h, w = img.shape
    if not (0.0 <= x <= w - 1 and 0.0 <= y <= h - 1):
        return np.nan
    ix = min(int(x), w - 2)
    iy = min(int(y), h - 2)
    fx = x - ix
    fy = y - iy
    return ((1 - fy) * ((1 - fx) * img[iy, ix] + fx * img[iy, ix + 1])
            + fy * ((1 - fx) * img[iy + 1, ix] + fx * img[iy + 1, ix + 1]))


@njit(nogil=True)
def background_step(bgr, cx, cy, phi, s_in, s_out, nl, ds):
    """The background's own change along a ray at angle phi from (cx, cy): the mean over nl
    samples ending at s_in (inwards) minus the mean over nl samples from s_out outwards."""
    c, sn = np.cos(phi), np.sin(phi)
    a = 0.0
    b = 0.0
    for j in range(nl):
        a += _bilinear(bgr, cx + c * (s_in - j * ds), cy + sn * (s_in - j * ds))
        b += _bilinear(bgr, cx + c * (s_out + j * ds), cy + sn * (s_out + j * ds))
    return (a - b) / nl
