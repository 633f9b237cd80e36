"""Frames drawn analytically with known sub-pixel truth (no renderer): for locator tests and
the locator benchmark.

A scene is a bright backdrop with a gentle gradient, the trough seen end-on (a dark annulus
below and beside its axis whose inner contour is the circle of radius R_px about ``center``),
and a dark steel ball with two specular spots, optionally a soft shadow beside it and an
occluding bar. The ball's silhouette is drawn with exact area coverage (edge pixels
supersampled 16 x 16); pixel coordinates have x right, y down, origin at the centre of the
top-left pixel.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


@dataclasses.dataclass(frozen=True)
class Scene:
    """An analytically drawn scene in the thesis geometry (defaults: 1280 x 1024, 0.1343 mm/px).

    Attributes
    ----------
    width, height : int
        Frame size (px).
    center : tuple of float
        The trough's axis (px).
    R_px, r_px : float
        Trough bore and ball radius (px).
    wall_px : float
        Thickness of the trough's wall (px).
    backdrop, trough, ball : float
        Levels in [0, 1] of the backdrop, the trough and the ball.
    spot : float
        Amplitude of the two specular spots (0: none).
    shadow : float
        Darkening of the soft shadow beside the ball (0: none).
    bit_depth : int
        8 or 16.
    noise : float
        Gaussian pixel noise (DN).
    """
    width: int = 1280
    height: int = 1024
    center: tuple[float, float] = (640.0, 380.0)  # trough axis (px)
    R_px: float = 635.14  # 85.3 mm / 0.1343 mm per px
    r_px: float = 37.23  # ball radius (px): 5 mm / 0.1343
    wall_px: float = 60.0
    backdrop: float = 0.78
    trough: float = 0.35
    ball: float = 0.12
    spot: float = 0.85  # amplitude of the specular spots (0 = none)
    shadow: float = 0.0  # darkening of the soft shadow beside the ball (0 = none)
    bit_depth: int = 8
    noise: float = 0.0  # Gaussian pixel noise (DN)

    @property
    def full_scale(self) -> float:
        """The largest pixel value: 255 for 8 bit, 65535 for 16."""
        return 255.0 if self.bit_depth == 8 else 65535.0

    @property
    def dtype(self):
        """The frames' NumPy dtype: uint8 for 8 bit, uint16 for 16."""
        return np.uint8 if self.bit_depth == 8 else np.uint16

    def ball_center(self, theta: float) -> tuple[float, float]:
        """Ball centre at angle theta on the track (image y down).

        Parameters
        ----------
        theta : float
            Angle from the trough bottom (rad, > 0 right of it).

        Returns
        -------
        tuple of float
            (x, y) in px.
        """
        L = self.R_px - self.r_px
        return (self.center[0] + L * math.sin(theta), self.center[1] + L * math.cos(theta))


def disk_coverage(h: int, w: int, cx: float, cy: float, r: float, ss: int = 16,
                  x_off: int = 0, y_off: int = 0) -> np.ndarray:
    """Area fraction of each pixel of an (h, w) tile covered by a disk.

    Edge pixels are supersampled ss x ss (error ~ 1/ss^2 of a pixel).

    Parameters
    ----------
    h, w : int
        Tile size (px).
    cx, cy : float
        Disk centre in frame pixels.
    r : float
        Disk radius (px).
    ss : int, optional
        Supersampling of the edge pixels per axis.
    x_off, y_off : int, optional
        Frame position of the tile's top-left pixel.

    Returns
    -------
    numpy.ndarray
        (h, w) coverage in [0, 1].
    """
    yy, xx = np.mgrid[0:h, 0:w]
    d = np.hypot(xx + x_off - cx, yy + y_off - cy)
    cov = (d < r).astype(np.float64)
    edge = np.abs(d - r) < 0.75
    ey, ex = np.nonzero(edge)
    if len(ey):
        sub = (np.arange(ss) + 0.5) / ss - 0.5
        sx, sy = np.meshgrid(sub, sub)
        px = ex[:, None] + x_off + sx.ravel()[None, :] - cx
        py = ey[:, None] + y_off + sy.ravel()[None, :] - cy
        cov[ey, ex] = ((px * px + py * py) < r * r).mean(axis=1)
    return cov


def background(scene: Scene) -> np.ndarray:
    """The background image: backdrop and trough, no ball.

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    numpy.ndarray
        (height, width) float64 in [0, 1].
    """
    h, w = scene.height, scene.width
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    img = scene.backdrop + 0.05 * (xx / w - 0.5) - 0.04 * (yy / h - 0.5)
    d = np.hypot(xx - scene.center[0], yy - scene.center[1])
    # trough wall: R < d < R + wall, below the axis minus a little; soft 1-px contour
    inner = np.clip(d - scene.R_px + 0.5, 0.0, 1.0)
    outer = np.clip(scene.R_px + scene.wall_px - d + 0.5, 0.0, 1.0)
    below = yy > scene.center[1] - 0.25 * scene.R_px
    wall = inner * outer * below
    return img * (1 - wall) + scene.trough * wall


def to_dtype(img: np.ndarray, scene: Scene, rng: np.random.Generator | None = None):
    """An image in [0, 1] as the scene's integer frames, with its pixel noise.

    Parameters
    ----------
    img : numpy.ndarray
        Float image in [0, 1].
    scene : Scene
        Gives the bit depth and the noise (DN).
    rng : numpy.random.Generator, optional
        Needed when ``scene.noise`` > 0.

    Returns
    -------
    numpy.ndarray
        Rounded and clipped, ``scene.dtype``.

    Raises
    ------
    ValueError
        Noise without an ``rng``.
    """
    out = img * scene.full_scale
    if scene.noise > 0:
        if rng is None:
            raise ValueError("noise needs an rng")
        out = out + rng.normal(0.0, scene.noise, out.shape)
    return np.clip(np.rint(out), 0, scene.full_scale).astype(scene.dtype)


def draw_ball(bg: np.ndarray, scene: Scene, cx: float, cy: float, *,
              occluder: tuple[float, float, float, float] | None = None) -> np.ndarray:
    """The background with the ball drawn in.

    The ball at (cx, cy), its specular spots, its soft shadow and an occluding bar; only a tile
    around the ball is touched.

    Parameters
    ----------
    bg : numpy.ndarray
        Float background in [0, 1] (not modified).
    scene : Scene
    cx, cy : float
        Ball centre (px).
    occluder : tuple of float, optional
        (x0, y0, x1, y1) of a bar drawn over the ball.

    Returns
    -------
    numpy.ndarray
        A copy of ``bg`` with the ball.
    """
    img = bg.copy()
    r = scene.r_px
    m = int(math.ceil(2.2 * r + 4))
    x0, y0 = max(0, int(cx) - m), max(0, int(cy) - m)
    x1, y1 = min(scene.width, int(cx) + m + 1), min(scene.height, int(cy) + m + 1)
    if x1 <= x0 or y1 <= y0:
        return img
    tile = img[y0:y1, x0:x1]
    th, tw = tile.shape
    yy, xx = np.mgrid[0:th, 0:tw].astype(np.float64)
    xx += x0
    yy += y0
    if scene.shadow > 0:  # soft shadow beside the ball, away from the trough axis side
        side = 1.0 if cx >= scene.center[0] else -1.0
        sd = np.hypot(xx - (cx + side * 0.45 * r), yy - (cy - 0.1 * r))
        soft = np.clip((1.05 * r - sd) / (0.3 * r) + 0.5, 0.0, 1.0)
        tile *= 1.0 - scene.shadow * soft
    cov = disk_coverage(th, tw, cx, cy, r, x_off=x0, y_off=y0)
    tex = np.full_like(tile, scene.ball)
    if scene.spot > 0:
        s2 = (0.1 * r) ** 2 + 0.5
        for dx in (-0.3 * r, 0.3 * r):
            tex += scene.spot * np.exp(-((xx - cx - dx) ** 2 + (yy - cy + 0.2 * r) ** 2) / (2 * s2))
    tile[:] = tile * (1 - cov) + np.minimum(tex, 1.0) * cov
    if occluder is not None:
        ox0, oy0, ox1, oy1 = occluder
        occ = (xx >= ox0) & (xx <= ox1) & (yy >= oy0) & (yy <= oy1)
        tile[occ] = 0.5
    return img


def make_frames(scene: Scene, centers, *, seed: int = 0, occluder=None):
    """Integer frames with the ball at each of ``centers``.

    Parameters
    ----------
    scene : Scene
    centers : iterable of tuple
        (x, y) per frame in px; (None, None) for a frame without the ball.
    seed : int, optional
        Seed of the pixel noise.
    occluder : tuple of float, optional
        As in :func:`draw_ball`.

    Returns
    -------
    background : numpy.ndarray
        The noiseless background frame.
    frames : list of numpy.ndarray
        One frame per centre.
    """
    rng = np.random.default_rng(seed)
    bgf = background(scene)
    bg = to_dtype(bgf, dataclasses.replace(scene, noise=0.0))
    frames = []
    for cx, cy in centers:
        if cx is None:
            frames.append(to_dtype(bgf, scene, rng))
        else:
            frames.append(to_dtype(draw_ball(bgf, scene, cx, cy, occluder=occluder), scene, rng))
    return bg, frames
