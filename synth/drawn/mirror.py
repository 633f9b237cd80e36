"""A polished steel ball drawn as a curved mirror (no renderer): frames with an exact centre
whose rim looks like a real steel ball's.

A real steel ball reflects its surroundings, and at grazing angles (Fresnel) its rim mirrors
what lies beyond it: the bright backdrop where that is behind the ball (its upper side and
flanks), the dark trough where that is (its lower side). The silhouette is then not a clean
step of the ball's own level, and an edge found from the step moves inwards where the rim is
bright. These frames are drawn independently of ``synth``'s renderers, from the geometry:

- the camera is orthographic along -z (world: x right, y up, z towards the camera, mm; the
  trough's axis is the z axis); a pixel is sampled on a grid of sub-pixel points (16 x 16 on
  the rim, ``ss`` x ``ss`` elsewhere), so the disk's area coverage is exact to ~1/256 px;
- inside the disk each sample reflects the view ray exactly about the sphere's normal
  (optionally jittered by a roughness), weighted by the exact unpolarised Fresnel reflectance of
  a conductor (iron, complex index ``eta + i k``);
- the reflected ray is traced through a simple world: the trough's bore (a cylinder of radius
  R, ``trough_len`` long, covering ``opening`` either side of the bottom; dark), the paper
  backdrop (a plane ``backdrop_mm`` behind the ball plane, bright, a gentle gradient), two
  spherical lamps in front beside the camera, and a dark room elsewhere;
- outside the disk each sample sees what the camera sees without the ball (the background:
  the backdrop through the bore, the trough's front face as an annulus);
- the pixel image is blurred by a Gaussian point spread function (``psf_px``, also the
  background), then noise and rounding.

The ball's centre in the image is its sphere's centre (orthographic: the silhouette is a circle
of the ball's radius about it), so every frame's truth is exact. Pixels: x right, y down,
origin at the centre of the top-left pixel.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np


@dataclasses.dataclass(frozen=True)
class MirrorScene:
    """The thesis geometry seen end-on, with a mirror ball (defaults: 10 mm ball, 0.1343 mm/px).

    Attributes
    ----------
    width, height : int
        Frame size (px).
    center : tuple of float
        The trough's axis in the image (px).
    pixel_mm : float
        Pixel size in the ball plane (mm).
    R_mm, r_mm : float
        Bore and ball radius (mm).
    wall_mm : float
        Thickness of the trough's wall seen on its front face (mm).
    trough_len_mm : float
        Trough length along the axis, centred on the ball plane (mm).
    opening : float
        Half-angle (rad) of the bore covered by the trough, from the bottom.
    backdrop_mm : float
        Distance of the backdrop behind the ball plane (mm).
    backdrop_half_mm : float
        Half-size of the square backdrop (mm); beyond it the room.
    backdrop_top_mm : float
        Height of the backdrop's top edge above the trough's axis (mm): a low top edge leaves
        the rim's steeper reflections to the dark room (a narrower bright crescent).
    backdrop, face, bore, room : float
        Radiances (1 = full scale) of the backdrop, the trough's front face, its bore, the room.
    lamp : float
        Radiance of the lamps (values above 1 clip).
    lamps_mm : tuple of tuple of float
        Lamp centres (x, y, z) in mm.
    lamp_radius_mm : float
        Lamp radius (mm).
    eta, k : float
        The ball's complex refractive index (iron, green: 2.95 + 2.93 i).
    roughness : float
        Standard deviation (rad) of the normal's jitter per sample (0: a perfect mirror).
    psf_px : float
        Gaussian PSF sigma (px; 0: none, the pixels integrate the scene exactly).
    ss : int
        Sub-pixel samples per axis away from the rim (16 within 1.5 px of it).
    bit_depth : int
        8 or 16.
    noise : float
        Gaussian pixel noise (DN).
    """
    width: int = 1280
    height: int = 1024
    center: tuple[float, float] = (640.0, 380.0)
    pixel_mm: float = 0.1343
    R_mm: float = 85.3
    r_mm: float = 5.0
    wall_mm: float = 8.0
    trough_len_mm: float = 30.0
    opening: float = math.radians(110.0)
    backdrop_mm: float = 50.0
    backdrop_half_mm: float = 250.0
    backdrop_top_mm: float = 250.0
    backdrop: float = 0.80
    face: float = 0.14
    bore: float = 0.06
    room: float = 0.05
    lamp: float = 40.0
    lamps_mm: tuple[tuple[float, float, float], ...] = ((60.0, 0.0, 400.0),
                                                        (-60.0, 0.0, 400.0))
    lamp_radius_mm: float = 12.0
    eta: float = 2.95
    k: float = 2.93
    roughness: float = 0.0
    psf_px: float = 0.5
    ss: int = 6
    bit_depth: int = 8
    noise: float = 0.0

    @property
    def r_px(self) -> float:
        """The ball's radius in pixels."""
        return self.r_mm / self.pixel_mm

    @property
    def full_scale(self) -> float:
        """The largest pixel value: 255 for 8 bit, 65535 for 16."""
        return 255.0 if self.bit_depth == 8 else 65535.0

    def ball_center(self, theta: float) -> tuple[float, float]:
        """The ball's centre (px) at angle ``theta`` (rad, > 0 right of the trough's bottom).

        Parameters
        ----------
        theta : float

        Returns
        -------
        tuple of float
            (x, y) in px.
        """
        L = (self.R_mm - self.r_mm) / self.pixel_mm
        return (self.center[0] + L * math.sin(theta), self.center[1] + L * math.cos(theta))


def fresnel_conductor(cos_i: np.ndarray, eta: float, k: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a conductor of complex index ``eta + i k`` in air.

    Parameters
    ----------
    cos_i : numpy.ndarray
        Cosine of the angle of incidence (from the normal), in [0, 1].
    eta, k : float
        Real and imaginary parts of the refractive index.

    Returns
    -------
    numpy.ndarray
        (R_s + R_p) / 2.
    """
    c = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    n2 = complex(eta, k) ** 2
    root = np.sqrt(n2 - (1.0 - c * c))
    rs = (c - root) / (c + root)
    rp = (n2 * c - root) / (n2 * c + root)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def _world(scene: MirrorScene, x, y):
    """World x, y (mm) of image points (px)."""
    p = scene.pixel_mm
    return (x - scene.center[0]) * p, -(y - scene.center[1]) * p


def direct_view(scene: MirrorScene, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Radiance the camera sees at image points (px) without the ball: the trough's front face
    (an annulus R < d < R + wall within ``opening`` of the bottom), else the backdrop."""
    wx, wy = _world(scene, x, y)
    d = np.hypot(wx, wy)
    ang = np.abs(np.arctan2(wx, -wy))  # from the bottom
    face = (d > scene.R_mm) & (d < scene.R_mm + scene.wall_mm) & (ang <= scene.opening)
    return np.where(face, scene.face, _backdrop(scene, wx, wy))


def _backdrop(scene: MirrorScene, wx, wy):
    """The backdrop's radiance at world (x, y) on its plane: lit from the front, a gentle
    gradient, the room beyond its edges."""
    h = scene.backdrop_half_mm
    val = scene.backdrop * (1.0 + 0.04 * wx / h - 0.06 * wy / h)
    inside = (np.abs(wx) <= h) & (wy >= -h) & (wy <= min(h, scene.backdrop_top_mm))
    return np.where(inside, val, scene.room)


def trace(scene: MirrorScene, px, py, pz, dx, dy, dz) -> np.ndarray:
    """Radiance along rays from points (mm) on the ball in unit directions (world frame).

    Forward rays (dz > 0) see the lamps or the room; backward rays the trough's bore (within
    its length and opening), else the backdrop, else the room.
    """
    out = np.full(np.shape(px), scene.room, float)
    fwd = dz > 0
    for lx, ly, lz in scene.lamps_mm:
        ox, oy, oz = px - lx, py - ly, pz - lz
        b = ox * dx + oy * dy + oz * dz
        c = ox * ox + oy * oy + oz * oz - scene.lamp_radius_mm ** 2
        hit = fwd & (b * b - c > 0) & (b < 0)
        out = np.where(hit, scene.lamp, out)
    back = dz < 0
    # the bore: |(p + t d)_xy| = R, the exit point of a ray from inside
    a = dx * dx + dy * dy
    b = px * dx + py * dy
    c = px * px + py * py - scene.R_mm ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(a > 1e-15, (-b + np.sqrt(np.maximum(b * b - a * c, 0.0)))
                     / np.maximum(a, 1e-15), 0.0)
    hz = pz + t * dz
    hx, hy = px + t * dx, py + t * dy
    ang = np.abs(np.arctan2(hx, -hy))
    on_bore = (back & (a > 1e-15) & (hz >= -0.5 * scene.trough_len_mm)
               & (ang <= scene.opening))
    # the backdrop plane z = -backdrop_mm
    with np.errstate(invalid="ignore", divide="ignore"):
        tb = np.where(back, (-scene.backdrop_mm - pz) / np.where(back, dz, -1.0), 0.0)
    bx, by = px + tb * dx, py + tb * dy
    on_back = back & ~on_bore
    out = np.where(on_bore, scene.bore, out)
    out = np.where(on_back, _backdrop(scene, bx, by), out)
    return out


def _samples(n: int) -> np.ndarray:
    return (np.arange(n) + 0.5) / n - 0.5


def background(scene: MirrorScene, ss: int = 4) -> np.ndarray:
    """The frame without the ball (float, full scale 1), area-sampled ss x ss and blurred.

    Parameters
    ----------
    scene : MirrorScene
    ss : int, optional
        Samples per pixel and axis.

    Returns
    -------
    numpy.ndarray
        (height, width) float64.
    """
    yy, xx = np.mgrid[0:scene.height, 0:scene.width].astype(np.float64)
    acc = np.zeros_like(xx)
    for sy in _samples(ss):
        for sx in _samples(ss):
            acc += direct_view(scene, xx + sx, yy + sy)
    img = acc / (ss * ss)
    return _blur(img, scene.psf_px)


def _blur(img: np.ndarray, sigma: float) -> np.ndarray:
    if sigma <= 0:
        return img
    return cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)


def _ball_radiance(scene: MirrorScene, cx: float, cy: float, x: np.ndarray, y: np.ndarray,
                   rng: np.random.Generator) -> np.ndarray:
    """Radiance of sample points (px) inside the disk about (cx, cy): the mirror's reflection."""
    p = scene.pixel_mm
    r = scene.r_mm
    u = (x - cx) * p
    v = -(y - cy) * p
    w = np.sqrt(np.maximum(r * r - u * u - v * v, 0.0))
    nx, ny, nz = u / r, v / r, w / r
    if scene.roughness > 0:
        j = rng.normal(0.0, scene.roughness, (3,) + np.shape(x))
        nx, ny, nz = nx + j[0], ny + j[1], nz + j[2]
        nn = np.sqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = nx / nn, ny / nn, nz / nn
    # view ray d = (0, 0, -1): reflected d - 2 (d.n) n = (2 nz nx, 2 nz ny, 2 nz^2 - 1)
    cos_i = np.clip(nz, 0.0, 1.0)
    rx, ry, rz = 2 * cos_i * nx, 2 * cos_i * ny, 2 * cos_i * nz - 1.0
    bx, by = _world(scene, cx, cy)
    rad = trace(scene, bx + u, by + v, w, rx, ry, rz)
    return fresnel_conductor(cos_i, scene.eta, scene.k) * rad


def draw_ball(bg_sharp: np.ndarray, scene: MirrorScene, cx: float, cy: float,
              rng: np.random.Generator) -> tuple[np.ndarray, int, int]:
    """The ball's tile: the unblurred scene with the ball, and its top-left corner (px).

    Every pixel of the tile is the mean of its sub-pixel samples (16 x 16 within 1.5 px of the
    rim, ``scene.ss`` x ``scene.ss`` elsewhere inside; the background's own value outside).
    """
    r = scene.r_px
    m = int(math.ceil(r + 4 + 4 * scene.psf_px))
    x0, y0 = max(0, int(cx) - m), max(0, int(cy) - m)
    x1, y1 = min(scene.width, int(cx) + m + 2), min(scene.height, int(cy) + m + 2)
    tile = bg_sharp[y0:y1, x0:x1].copy()
    yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    d = np.hypot(xx - cx, yy - cy)
    for sel, n in (((d < r + 1.5) & (d >= r - 1.5), 16), (d < r - 1.5, scene.ss)):
        iy, ix = np.nonzero(sel)
        if not len(iy):
            continue
        s = _samples(n)
        sx, sy = np.meshgrid(s, s)
        X = xx[iy, ix][:, None] + sx.ravel()[None, :]
        Y = yy[iy, ix][:, None] + sy.ravel()[None, :]
        inside = (X - cx) ** 2 + (Y - cy) ** 2 < r * r
        val = np.empty_like(X)
        val[inside] = _ball_radiance(scene, cx, cy, X[inside], Y[inside], rng)
        val[~inside] = direct_view(scene, X[~inside], Y[~inside])
        tile[iy, ix] = val.mean(axis=1)
    return tile, x0, y0


def _to_dtype(img, scene: MirrorScene, rng, noise: float):
    out = img * scene.full_scale
    if noise > 0:
        out = out + rng.normal(0.0, noise, out.shape)
    dt = np.uint8 if scene.bit_depth == 8 else np.uint16
    return np.clip(np.rint(out), 0, scene.full_scale).astype(dt)


def make_mirror_frames(scene: MirrorScene, centers, *, seed: int = 0):
    """Integer frames of the mirror ball at each of ``centers``, and their background.

    Parameters
    ----------
    scene : MirrorScene
    centers : iterable of tuple
        (x, y) per frame in px.
    seed : int, optional
        Seed of the noise and the roughness's jitter (same seed, same bytes).

    Returns
    -------
    background : numpy.ndarray
        The noiseless frame without the ball.
    frames : list of numpy.ndarray
        One frame per centre.
    """
    rng = np.random.default_rng(seed)
    # the background's only edge is the trough face's contour, away from the ball's rim
    sharp = background(dataclasses.replace(scene, psf_px=0.0), ss=2)
    blurred = _blur(sharp, scene.psf_px)
    bg = _to_dtype(blurred, scene, rng, 0.0)
    frames = []
    for cx, cy in centers:
        tile, x0, y0 = draw_ball(sharp, scene, float(cx), float(cy), rng)
        img = blurred.copy()
        if scene.psf_px > 0:
            # blur the tile in its context; the tile holds the ball plus 4 sigma of margin
            m = int(math.ceil(4 * scene.psf_px)) + 1
            ya, yb = max(0, y0 - m), min(scene.height, y0 + tile.shape[0] + m)
            xa, xb = max(0, x0 - m), min(scene.width, x0 + tile.shape[1] + m)
            ctx = sharp[ya:yb, xa:xb].copy()
            ctx[y0 - ya:y0 - ya + tile.shape[0], x0 - xa:x0 - xa + tile.shape[1]] = tile
            ctx = _blur(ctx, scene.psf_px)
            img[y0:y0 + tile.shape[0], x0:x0 + tile.shape[1]] = \
                ctx[y0 - ya:y0 - ya + tile.shape[0], x0 - xa:x0 - xa + tile.shape[1]]
        else:
            img[y0:y0 + tile.shape[0], x0:x0 + tile.shape[1]] = tile
        frames.append(_to_dtype(img, scene, rng, scene.noise))
    return bg, frames
