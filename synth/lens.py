"""A real lens in the rendering: OpenCV's Brown-Conrady distortion applied to the ideal image.

The lens is OpenCV's camera model: camera matrix K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
(px) and distortion [k1, k2, p1, p2, k3]. An ideal (undistorted) pixel (u, v) has normalised
coordinates x = (u - cx) / fx, y = (v - cy) / fy; the lens moves it to

    r2 = x^2 + y^2,  radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
    xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
    yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y

and the recorded pixel is (cx + fx xd, cy + fy yd): what ``cv2.projectPoints`` gives for the
point (x, y, 1) with no rotation and translation. The distorted frame is made from the ideal
render by sampling it, at every output pixel, at that pixel's undistorted position (bilinear):
the ideal render covers the frame's undistorted footprint (a margin around it for a barrel
lens). The ground truth is the distorted position of the ideal projection.

Written apart from :mod:`rollfric.lens` (which calls OpenCV) on purpose: the truth must not share
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


@dataclasses.dataclass(frozen=True)
class IdealWindow:
    """Where the ideal render lies: frame pixel (u, v) undistorts to ideal-render pixel
    (map_x, map_y); the ideal render is ``width`` x ``height`` px with its origin at ideal
    frame pixel (x0, y0)."""

    x0: int
    y0: int
    width: int
    height: int
    map_x: np.ndarray  # (H, W) float32, in ideal-render pixels
    map_y: np.ndarray


def ideal_window(lens: Lens, width: int, height: int, margin: int = 3) -> IdealWindow:
    """The ideal render a ``width`` x ``height`` distorted frame samples (every frame pixel's
    undistorted position, with ``margin`` px for the bilinear kernel)."""
    v, u = np.mgrid[0:height, 0:width].astype(float)
    ideal = lens.undistort(np.stack([u, v], axis=-1))
    x0 = int(math.floor(ideal[..., 0].min())) - margin
    y0 = int(math.floor(ideal[..., 1].min())) - margin
    x1 = int(math.ceil(ideal[..., 0].max())) + margin + 1
    y1 = int(math.ceil(ideal[..., 1].max())) + margin + 1
    return IdealWindow(x0=x0, y0=y0, width=x1 - x0, height=y1 - y0,
                       map_x=(ideal[..., 0] - x0).astype(np.float32),
                       map_y=(ideal[..., 1] - y0).astype(np.float32))


@functools.lru_cache(maxsize=4)
def cached_window(lens: Lens, width: int, height: int) -> IdealWindow:
    """:func:`ideal_window`, kept per lens and frame size (it undistorts every pixel)."""
    return ideal_window(lens, width, height)


def distort_image(ideal: np.ndarray, win: IdealWindow) -> np.ndarray:
    """The recorded frame (float64) from the ideal render: each pixel samples it bilinearly
    at its undistorted position."""
    import cv2

    return cv2.remap(np.asarray(ideal, dtype=np.float32), win.map_x, win.map_y,
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0
                     ).astype(np.float64)


def distort_tile(tile: np.ndarray, box: tuple[int, int, int, int], win: IdealWindow,
                 lens: Lens, frame_shape: tuple[int, int]):
    """A tile of the ideal render (``box`` = (x0, y0, w, h) in ideal-render pixels, zero
    outside) as seen through the lens: (frame box (x0, y0, w, h), values) of the frame pixels
    that sample it, or None when none does."""
    import cv2

    bx, by, bw, bh = box
    # the tile's outline in ideal frame pixels -> frame pixels
    t = np.linspace(0.0, 1.0, 33)
    xs = np.concatenate([bx + t * bw, np.full_like(t, bx + bw), bx + t * bw, np.full_like(t, bx)])
    ys = np.concatenate([np.full_like(t, by), by + t * bh, np.full_like(t, by + bh), by + t * bh])
    q = lens.distort(np.stack([xs + win.x0 - 0.5, ys + win.y0 - 0.5], axis=-1))
    H, W = frame_shape
    fx0 = max(int(math.floor(q[:, 0].min())) - 2, 0)
    fy0 = max(int(math.floor(q[:, 1].min())) - 2, 0)
    fx1 = min(int(math.ceil(q[:, 0].max())) + 3, W)
    fy1 = min(int(math.ceil(q[:, 1].max())) + 3, H)
    if fx1 <= fx0 or fy1 <= fy0:
        return None
    mx = win.map_x[fy0:fy1, fx0:fx1] - np.float32(bx)
    my = win.map_y[fy0:fy1, fx0:fx1] - np.float32(by)
    out = cv2.remap(np.asarray(tile, dtype=np.float32), mx, my, cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return (fx0, fy0, fx1 - fx0, fy1 - fy0), out.astype(np.float64)
