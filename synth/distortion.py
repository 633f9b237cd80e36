"""A real lens in the rendering: OpenCV's Brown-Conrady distortion applied to the ideal image.

The lens is OpenCV's camera model: camera matrix K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
(px) and distortion [k1, k2, p1, p2, k3]. An ideal (undistorted) pixel (u, v) has normalised
coordinates x = (u - cx) / fx, y = (v - cy) / fy; the lens moves it to

    r2 = x^2 + y^2,  radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
    xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
    yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y

and the recorded pixel is (cx + fx xd, cy + fy yd): what ``cv2.projectPoints`` gives for the
point (x, y, 1) with no rotation and translation. The ground truth is the distorted position of
the ideal projection.

The distorted frame is made from an ideal render that covers the frame's undistorted footprint
(a margin around it for a barrel lens) at FACTOR x FACTOR render pixels per frame pixel: each
recorded pixel is the mean of the ideal image over its own area mapped back through the lens
(SAMPLES x SAMPLES points spread over the pixel, each undistorted through the local Jacobian
of the inverse and sampled bilinearly). One bilinear sample a pixel of a frame-resolution
render is not a lens: its kernel (1 - f, f) follows the fractional
part f of the lens's displacement, and the locator's edge-model fit read that as up to
0.06 px of ball centre; rendered finer and integrated over the footprint, the ball is where an
exactly bent drawing of it is to 0.003 px (tests/test_lens.py).

Written apart from :mod:`rollfric.setup.lens` (which calls OpenCV) on purpose: the truth must not
share
the measurement's code, so an error in either shows up; the tests hold both to
``cv2.projectPoints``.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from rollfric.errors import InputError


@dataclasses.dataclass(frozen=True)
class Lens:
    """OpenCV camera matrix (3 x 3, px) and distortion coefficients (k1, k2, p1, p2, k3)."""

    matrix: tuple
    distortion: tuple

    def __post_init__(self) -> None:
        k = np.asarray(self.matrix, dtype=float)
        if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0 \
                or k[2, 2] != 1 or k[1, 0] or k[2, 0] or k[2, 1]:
            raise InputError(f"lens matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] "
                             f"with fx, fy > 0, got {self.matrix!r}")
        d = tuple(float(v) for v in self.distortion)
        if len(d) != 5 or not all(math.isfinite(v) for v in d):
            raise InputError(f"lens distortion must be [k1, k2, p1, p2, k3], got "
                             f"{self.distortion!r}")
        object.__setattr__(self, "matrix", tuple(tuple(float(v) for v in row) for row in k))
        object.__setattr__(self, "distortion", d)

    @property
    def K(self) -> np.ndarray:
        return np.asarray(self.matrix, dtype=float)

    @property
    def is_identity(self) -> bool:
        return not any(self.distortion)

    @property
    def _intrinsics(self) -> tuple[float, float, float, float, float]:
        K = self.K
        return K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]

    def _normalised(self, uv) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (..., 2) -> normalised coordinates x, y (K^-1 applied)."""
        uv = np.asarray(uv, dtype=float)
        fx, s, cx, fy, cy = self._intrinsics
        y = (uv[..., 1] - cy) / fy
        return (uv[..., 0] - cx - s * y) / fx, y

    def distort(self, uv) -> np.ndarray:
        """Ideal pixels (..., 2) -> where the lens puts them (..., 2)."""
        x, y = self._normalised(uv)
        fx, s, cx, fy, cy = self._intrinsics
        k1, k2, p1, p2, k3 = self.distortion
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.stack([cx + fx * xd + s * yd, cy + fy * yd], axis=-1)

    def undistort(self, uv) -> np.ndarray:
        """Recorded pixels (..., 2) -> their ideal positions: the inverse of :meth:`distort`,
        by fixed-point iteration on the normalised coordinates until they move less than
        1e-13 (1e-9 px at fx = 10000 px)."""
        xd, yd = self._normalised(uv)
        fx, s, cx, fy, cy = self._intrinsics
        k1, k2, p1, p2, k3 = self.distortion
        x, y = xd.copy(), yd.copy()
        for _ in range(200):
            r2 = x * x + y * y
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            xn = (xd - 2 * p1 * x * y - p2 * (r2 + 2 * x * x)) / radial
            yn = (yd - p1 * (r2 + 2 * y * y) - 2 * p2 * x * y) / radial
            step = max(float(np.max(np.abs(xn - x), initial=0.0)),
                       float(np.max(np.abs(yn - y), initial=0.0)))
            x, y = xn, yn
            if step < 1e-13:
                break
        else:
            raise InputError("the lens model does not invert over this frame: its distortion "
                             "folds the image (check lens_distortion)")
        return np.stack([cx + fx * x + s * y, cy + fy * y], axis=-1)


def lens_of(camera) -> Lens | None:
    """The camera's lens (None when it has no distortion)."""
    if not any(camera.lens_distortion):
        return None
    m = camera.lens_matrix
    if m is None:
        f = camera.focal_px
        m = ((f, 0.0, (camera.width - 1) / 2), (0.0, f, (camera.height - 1) / 2),
             (0.0, 0.0, 1.0))
    return Lens(matrix=m, distortion=camera.lens_distortion)


FACTOR = 4  # the ideal render's pixels per recorded pixel (per axis) behind a lens
SAMPLES = 4  # sub-samples per recorded pixel (per axis) of its footprint in the ideal render


@dataclasses.dataclass(frozen=True)
class IdealWindow:
    """Where the ideal render lies and how each frame pixel's area maps into it.

    The ideal render has ``factor`` x ``factor`` pixels per ideal frame pixel: its pixel (i, j)
    is centred on ideal frame pixel (x0 + (i + 0.5) / factor - 0.5, y0 + (j + 0.5) / factor
    - 0.5), and it is ``width`` x ``height`` render pixels. Frame pixel (u, v) undistorts to
    render pixel (map_x, map_y); ``jac`` (H, W, 4: d map_x / du, d map_x / dv, d map_y / du,
    d map_y / dv, render px per frame px) maps a point of the frame pixel's square around its
    centre (the lens is affine over a pixel to 1e-5 px for the target's lens)."""

    x0: int
    y0: int
    width: int
    height: int
    map_x: np.ndarray  # (H, W) float32, in ideal-render pixels
    map_y: np.ndarray
    factor: int = 1
    jac: np.ndarray | None = None  # (H, W, 4) float32

    def to_render(self, p) -> np.ndarray:
        """Ideal frame pixels (..., 2) -> ideal-render pixels."""
        p = np.asarray(p, dtype=float)
        return (p - (self.x0, self.y0) + 0.5) * self.factor - 0.5

    def to_frame(self, q) -> np.ndarray:
        """Ideal-render pixels (..., 2) -> ideal frame pixels."""
        q = np.asarray(q, dtype=float)
        return (q + 0.5) / self.factor - 0.5 + (self.x0, self.y0)


def ideal_window(lens: Lens, width: int, height: int, margin: int = 3,
                 factor: int = 1) -> IdealWindow:
    """The ideal render a ``width`` x ``height`` distorted frame samples: every frame pixel's
    undistorted position and its area's, with ``margin`` ideal px around them, rendered at
    ``factor`` x ``factor`` pixels per ideal frame pixel.

    Parameters
    ----------
    lens : Lens
        The lens.
    width, height : int
        The recorded frame (px).
    margin : int, optional
        Ideal frame pixels kept around the frame's undistorted footprint.
    factor : int, optional
        Render pixels per ideal frame pixel, per axis (1: the ideal render is at the frame's
        resolution; :data:`FACTOR` behind a lens in synth's recordings).

    Returns
    -------
    IdealWindow
    """
    if not isinstance(factor, (int, np.integer)) or factor < 1:
        raise InputError(f"the ideal render's factor must be a positive integer, got {factor!r}")
    v, u = np.mgrid[0:height, 0:width].astype(float)
    uv = np.stack([u, v], axis=-1)
    ideal = lens.undistort(uv)
    x0 = int(math.floor(ideal[..., 0].min())) - margin
    y0 = int(math.floor(ideal[..., 1].min())) - margin
    x1 = int(math.ceil(ideal[..., 0].max())) + margin + 1
    y1 = int(math.ceil(ideal[..., 1].max())) + margin + 1
    # the Jacobian by central differences over the pixel (its second-order error is the
    # lens's third derivative times 1/24 px^2: < 1e-7)
    h = 0.5
    du = (lens.undistort(uv + (h, 0.0)) - lens.undistort(uv - (h, 0.0))) * (factor / (2 * h))
    dv = (lens.undistort(uv + (0.0, h)) - lens.undistort(uv - (0.0, h))) * (factor / (2 * h))
    jac = np.stack([du[..., 0], dv[..., 0], du[..., 1], dv[..., 1]], axis=-1).astype(np.float32)
    q = (ideal - (x0, y0) + 0.5) * factor - 0.5
    return IdealWindow(x0=x0, y0=y0, width=(x1 - x0) * factor, height=(y1 - y0) * factor,
                       map_x=q[..., 0].astype(np.float32), map_y=q[..., 1].astype(np.float32),
                       factor=int(factor), jac=jac)


@functools.lru_cache(maxsize=4)
def cached_window(lens: Lens, width: int, height: int, factor: int = FACTOR) -> IdealWindow:
    """:func:`ideal_window`, kept per lens, frame size and factor (it undistorts every
    pixel)."""
    return ideal_window(lens, width, height, factor=factor)


def _footprint(img: np.ndarray, map_x: np.ndarray, map_y: np.ndarray, jac: np.ndarray | None,
               samples: int) -> np.ndarray:
    """Each frame pixel's mean of ``img`` (ideal render pixels, zero outside) over its area
    mapped back through the lens: ``samples`` x ``samples`` points spread evenly over the
    pixel's square, each sampled bilinearly at its undistorted position (the pixel's centre
    mapped and the square by the local Jacobian)."""
    import cv2

    src = np.asarray(img, dtype=np.float32)
    if jac is None or samples == 1:
        return cv2.remap(src, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                         borderValue=0.0).astype(np.float64)
    offs = (np.arange(samples) + 0.5) / samples - 0.5
    out = np.zeros(map_x.shape, dtype=np.float64)
    jxu, jxv, jyu, jyv = (jac[..., k] for k in range(4))
    for b in offs:
        bx, by = map_x + np.float32(b) * jxv, map_y + np.float32(b) * jyv
        for a in offs:
            out += cv2.remap(src, bx + np.float32(a) * jxu, by + np.float32(a) * jyu,
                             cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return out / (samples * samples)


def distort_image(ideal: np.ndarray, win: IdealWindow, samples: int = SAMPLES) -> np.ndarray:
    """The recorded frame (float64) from the ideal render: each pixel is the mean of the ideal
    render over its area mapped back through the lens (``samples`` x ``samples`` bilinear
    samples; with ``samples`` = 1 or a window without a Jacobian, one bilinear sample at the
    pixel's undistorted centre).

    Parameters
    ----------
    ideal : numpy.ndarray
        The ideal render (``win.height`` x ``win.width``).
    win : IdealWindow
        Where it lies (:func:`ideal_window`).
    samples : int, optional
        Sub-samples per frame pixel, per axis.

    Returns
    -------
    numpy.ndarray
        The recorded frame, float64, in the ideal render's units.
    """
    return _footprint(ideal, win.map_x, win.map_y, win.jac, samples)


def distort_tile(tile: np.ndarray, box: tuple[int, int, int, int], win: IdealWindow,
                 lens: Lens, frame_shape: tuple[int, int], samples: int = SAMPLES):
    """A tile of the ideal render (``box`` = (x0, y0, w, h) in ideal-render pixels, zero
    outside) as seen through the lens: (frame box (x0, y0, w, h), values) of the frame pixels
    whose area reaches it, or None when none does. Each pixel as in :func:`distort_image`."""
    bx, by, bw, bh = box
    # the tile's outline (render pixel edges) in ideal frame pixels -> frame pixels
    t = np.linspace(0.0, 1.0, 33)
    xs = np.concatenate([bx + t * bw, np.full_like(t, bx + bw), bx + t * bw, np.full_like(t, bx)])
    ys = np.concatenate([np.full_like(t, by), by + t * bh, np.full_like(t, by + bh), by + t * bh])
    q = lens.distort(win.to_frame(np.stack([xs - 0.5, ys - 0.5], axis=-1)))
    H, W = frame_shape
    fx0 = max(int(math.floor(q[:, 0].min())) - 2, 0)
    fy0 = max(int(math.floor(q[:, 1].min())) - 2, 0)
    fx1 = min(int(math.ceil(q[:, 0].max())) + 3, W)
    fy1 = min(int(math.ceil(q[:, 1].max())) + 3, H)
    if fx1 <= fx0 or fy1 <= fy0:
        return None
    mx = win.map_x[fy0:fy1, fx0:fx1] - np.float32(bx)
    my = win.map_y[fy0:fy1, fx0:fx1] - np.float32(by)
    jac = None if win.jac is None else win.jac[fy0:fy1, fx0:fx1]
    out = _footprint(tile, mx, my, jac, samples)
    return (fx0, fy0, fx1 - fx0, fy1 - fy0), out
