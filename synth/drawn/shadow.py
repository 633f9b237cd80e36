"""Shadowgraph frames drawn with known sub-pixel truth: a backlit ball, a dark disc with a bright
central spot on a bright diffuse field, as a lab's backlit rig records it (the real Photron clip
``tests/data/real/ball_12bit.cihx``: the ball's limb shades from about a third of the backlight at
the silhouette to its dark inside over a few pixels, the edge blurred by the optics).

The image is radially symmetric about the ball's centre, so the centre is exact whatever the
profile: each pixel is the mean of ``ss`` x ``ss`` samples of the blurred radial profile (the
blur a Gaussian across the edge; its curvature term, of order blur^2 / r, changes the radius
only). Pixel coordinates: x right, y down, origin at the centre of the top-left pixel.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.ndimage import gaussian_filter1d


@dataclasses.dataclass(frozen=True)
class ShadowScene:
    """A backlit ball (defaults: about the real 12-bit clip's, r = 63.6 px).

    Attributes
    ----------
    width, height : int
        Frame size (px).
    r_px : float
        The ball's radius (px).
    bright : float
        The backlight's level (DN).
    dark : float
        The ball's dark inside (DN).
    limb : float
        How much brighter than ``dark`` the limb is at the silhouette (DN); it fades inwards
        exponentially over ``limb_px``.
    limb_px : float
        The limb's fall-off length (px).
    blur_px : float
        Standard deviation of the Gaussian blur across the edge (px).
    spot : float
        Excess of the bright central spot (DN) over ``dark``; 0 none.
    spot_px : float
        The spot's radius (px, a Gaussian's standard deviation).
    noise : float
        Gaussian pixel noise (DN).
    bit_depth : int
        The sensor's bit depth: values are clipped to 2**bit_depth - 1 and stored as uint16
        (uint8 for 8).
    ss : int
        Samples per pixel side.
    """
    width: int = 240
    height: int = 240
    r_px: float = 63.6
    bright: float = 3900.0
    dark: float = 480.0
    limb: float = 1000.0
    limb_px: float = 2.5
    blur_px: float = 0.6
    spot: float = 3000.0
    spot_px: float = 8.0
    noise: float = 0.0
    bit_depth: int = 12
    ss: int = 8

    @property
    def full_scale(self) -> int:
        """The largest value the sensor gives: 2**bit_depth - 1."""
        return 2 ** int(self.bit_depth) - 1

    @property
    def dtype(self):
        """uint8 for 8 bits, uint16 for more."""
        return np.uint8 if self.bit_depth <= 8 else np.uint16


def radial_profile(scene: ShadowScene, step: float = 0.01):
    """The ball's blurred radial profile (DN) as a function of the distance from its centre.

    Parameters
    ----------
    scene : ShadowScene
    step : float, optional
        Sampling step (px) of the table it interpolates.

    Returns
    -------
    callable
        d (px, array) -> level (DN).
    """
    d = np.arange(0.0, scene.r_px + 12.0 * max(scene.blur_px, 0.5) + 4.0, step)
    inside = scene.dark + scene.limb * np.exp(-(scene.r_px - d) / scene.limb_px)
    if scene.spot:
        inside = inside + scene.spot * np.exp(-0.5 * (d / scene.spot_px) ** 2)
    f = np.where(d < scene.r_px, inside, scene.bright)
    if scene.blur_px > 0:
        f = gaussian_filter1d(f, scene.blur_px / step, mode="nearest")
    return lambda x: np.interp(x, d, f, right=scene.bright)


def background(scene: ShadowScene) -> np.ndarray:
    """The ball-free frame: the backlight's level everywhere (no noise), in the scene's dtype."""
    v = min(round(scene.bright), scene.full_scale)
    return np.full((scene.height, scene.width), v, scene.dtype)


def draw(scene: ShadowScene, cx: float, cy: float, *, seed: int = 0) -> np.ndarray:
    """One frame with the ball's centre at (cx, cy) px.

    Parameters
    ----------
    scene : ShadowScene
    cx, cy : float
        The ball's centre (px).
    seed : int, optional
        Seed of the pixel noise.

    Returns
    -------
    numpy.ndarray
        (height, width) frame, rounded and clipped to [0, 2**bit_depth - 1].
    """
    prof = radial_profile(scene)
    img = np.full((scene.height, scene.width), float(scene.bright))
    # only the pixels near the ball differ from the backlight
    reach = scene.r_px + 8.0 * max(scene.blur_px, 0.5) + 2.0
    x0, x1 = max(0, int(cx - reach)), min(scene.width, int(cx + reach) + 2)
    y0, y1 = max(0, int(cy - reach)), min(scene.height, int(cy + reach) + 2)
    k = scene.ss
    sub = (np.arange(k) + 0.5) / k - 0.5
    yy, xx = np.mgrid[y0:y1, x0:x1].astype(float)
    acc = np.zeros_like(xx)
    for dy in sub:
        for dx in sub:
            acc += prof(np.hypot(xx + dx - cx, yy + dy - cy))
    img[y0:y1, x0:x1] = acc / (k * k)
    if scene.noise > 0:
        img = img + np.random.default_rng(seed).normal(0.0, scene.noise, img.shape)
    return np.clip(np.rint(img), 0, scene.full_scale).astype(scene.dtype)
