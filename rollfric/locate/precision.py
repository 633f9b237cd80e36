"""The locator's attainable precision: the Cramér-Rao lower bound on the centre error of a
disc of known radius and levels (:func:`centre_crb`)."""

from __future__ import annotations

import math

import numpy as np
from scipy import special


def centre_crb(r_px: float, contrast: float, noise: float, edge_sigma: float = 0.0) -> float:
    """Cramér-Rao lower bound on the rms centre error (px, both axes together) of an unbiased
    estimator for a disc seen in one frame.

    The disc of radius ``r_px`` has an edge that is a step of ``contrast`` (DN) blurred by a
    Gaussian of ``edge_sigma`` px; pixels are area-sampled and carry independent Gaussian
    noise of std ``noise`` (DN); the levels and the radius are known.

    Parameters
    ----------
    r_px : float
        The disc's radius (px).
    contrast : float
        The edge step, disc minus background (DN; its sign does not matter).
    noise : float
        The pixel noise's standard deviation (DN).
    edge_sigma : float, optional
        The Gaussian edge blur's standard deviation (px); 0: a sharp edge.

    Returns
    -------
    float
        sqrt(var_x + var_y) of the bound (px); inf when the contrast is 0, nan for invalid input.

    Notes
    -----
    Fisher information I_xx = (C / noise)^2 sum over pixels of g_x^2, where g_x, the change of
    a pixel's disc coverage per px of centre shift, is the integral over the rim of the
    outward normal's x component times the chance that the blurred rim point falls in that
    pixel (the product of two Gaussian-box integrals; for a sharp edge: whether it lies in it).
    The bound is sqrt(1 / I_xx + 1 / I_yy).
    """
    r, c, s, e = float(r_px), abs(float(contrast)), float(noise), max(float(edge_sigma), 0.0)
    if not (r > 0 and s > 0 and math.isfinite(c) and math.isfinite(e)):
        return math.nan
    if c == 0:
        return math.inf
    n_theta = int(min(max(2000, 64 * 2 * math.pi * r), 400000))
    phi = (np.arange(n_theta) + 0.5) * (2 * math.pi / n_theta)
    dl = r * 2 * math.pi / n_theta
    x = 0.37 + r * np.cos(phi)  # an arbitrary sub-pixel centre
    y = 0.61 + r * np.sin(phi)
    half = int(math.ceil(4.0 * e)) + 1 if e > 0 else 0
    i0 = int(math.floor(-r - half)) - 1
    size = int(math.ceil(2 * r + 2 * half)) + 4
    gx = np.zeros((size, size))
    gy = np.zeros((size, size))
    px, py = np.rint(x).astype(np.int64), np.rint(y).astype(np.int64)
    wx_cos, wy_sin = np.cos(phi) * dl, np.sin(phi) * dl
    for dx in range(-half, half + 1):
        ix = px + dx
        fx = _box(ix, x, e)
        for dy in range(-half, half + 1):
            iy = py + dy
            w = fx * _box(iy, y, e)
            np.add.at(gx, (ix - i0, iy - i0), w * wx_cos)
            np.add.at(gy, (ix - i0, iy - i0), w * wy_sin)
    ixx = (c / s) ** 2 * float(np.sum(gx * gx))
    iyy = (c / s) ** 2 * float(np.sum(gy * gy))
    return math.sqrt(1.0 / ixx + 1.0 / iyy)


def _box(i, u, e):
    """The chance that a point at ``u`` blurred by a Gaussian of std ``e`` falls in pixel ``i``
    (the pixel spans i - 0.5 .. i + 0.5); for ``e`` 0, whether ``u`` rounds to ``i``."""
    if e <= 0:
        return np.ones_like(u)
    k = 1.0 / (math.sqrt(2.0) * e)
    return 0.5 * (special.erf((i + 0.5 - u) * k) - special.erf((i - 0.5 - u) * k))
