"""The static scene's shift between a frame and the background, to a hundredth of a pixel.

The trough and the backdrop do not move; a bumped or drifting camera moves all of them in the
image. :func:`frame_shift` compares a frame with the background over the static scene (the
ball's square and its shadow left out): a masked normalised cross-correlation on reduced
images finds the shift to a pixel, the enhanced correlation coefficient refines it, and the
shift's standard error (:func:`shift_precision`) says whether the scene can tell it at all (a
plain or evenly shaded backdrop cannot). :mod:`rollfric.track.camera_motion` makes the
camera's motion over a recording of it.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import cv2
import numpy as np
from skimage.registration import phase_cross_correlation

logger = logging.getLogger(__name__)

BALL_MARGIN = 2.0  # the ball's disc and its shadow: this many ball radii masked
ECC_STEPS = 30  # iterations of the ECC refinement at most
# the whole-scene search (and the quick look): images halved up to this many times
QUICK_LEVEL = 2
# a shift is measured where its standard error (shift_precision) is at most this: 0.001-0.005
# px on drawn scenes with the trough's walls in view, 0.02-0.06 px on small rendered frames,
# 0.23 px on the dim lighting's (its trough edge barely above the noise: where the ball is
# biases its shifts by up to 0.7 px, which camera_motion's tests of a motion stand against),
# none on a plain or evenly shaded backdrop with noise
SHIFT_MAX_SE_PX = 0.3
# the ball's square filled in from the background is searched by the phase correlation while
# it is at most this share of the image (the thesis camera's 10 mm ball: 2 %; a small
# rendered frame's: 30-40 %, where the filled square held the peak at no shift)
SQUARE_SHARE_MAX = 0.05


@dataclasses.dataclass(frozen=True)
class Reference:
    """The background prepared for :func:`frame_shift` (once for all of a recording's samples):
    its greyscale image halved 0, 1, ... times, and at each size its gradients
    (:func:`_gradient`) and the energy per pixel its own noise puts into each of them."""

    images: tuple
    gradients: tuple
    noise_energy: tuple


def reference(background, levels: int) -> Reference:
    """``background`` prepared for :func:`frame_shift` at sizes halved up to ``levels``
    times."""
    b = np.asarray(background, dtype=np.float32)
    if b.ndim == 3:
        b = b.mean(axis=2)
    images = [b]
    for _ in range(levels):
        images.append(cv2.pyrDown(images[-1]))
    delta = np.zeros((7, 7), dtype=np.float32)
    delta[3, 3] = 1.0
    # white noise of the image's level puts sigma^2 sum(k^2) per pixel into a gradient's
    # square (k: the gradient filter's coefficients)
    k2 = [float(np.sum(_gradient(delta, dx, dy) ** 2)) for dx, dy in ((1, 0), (0, 1))]
    return Reference(tuple(images),
                     tuple((_gradient(im, 1, 0), _gradient(im, 0, 1)) for im in images),
                     tuple(tuple(_noise(im) ** 2 * k for k in k2) for im in images))


def _scene(frame, shape, ball, r_px: float):
    """The frame as float32 greyscale and the static scene's mask (uint8, 1 outside the
    ball's square of half-width BALL_MARGIN radii + 2 px)."""
    f = np.asarray(frame, dtype=np.float32)
    if f.ndim == 3:
        f = f.mean(axis=2)
    mask = np.ones(shape, dtype=np.uint8)
    if ball is not None and np.all(np.isfinite(ball)):
        h, w = shape
        rad = BALL_MARGIN * r_px + 2
        y0, y1 = max(0, int(ball[1] - rad)), min(h, int(ball[1] + rad) + 1)
        x0, x1 = max(0, int(ball[0] - rad)), min(w, int(ball[0] + rad) + 1)
        mask[y0:y1, x0:x1] = 0
    return f, mask


def _halved(f, mask):
    f = cv2.pyrDown(f)
    # a halved pixel is static only where all it was made of is
    mask = (cv2.resize(mask.astype(np.float32), (f.shape[1], f.shape[0]),
                       interpolation=cv2.INTER_AREA) > 0.999).astype(np.uint8)
    return f, mask


def _inside(mask, warp):
    """``mask`` less the frame's border that a shift by ``warp`` moves in (and a pixel)."""
    bx, by = (math.ceil(abs(float(v))) + 1 for v in warp[:, 2])
    out = mask.copy()
    out[:by] = out[out.shape[0] - by:] = 0
    out[:, :bx] = out[:, out.shape[1] - bx:] = 0
    return out


def search_level(shape) -> int:
    """How many times a frame of ``shape`` is halved for the whole-scene search (and the
    quick look): up to QUICK_LEVEL, the halved frame at least 64 px on its short side."""
    level = 0
    while level < QUICK_LEVEL and min(shape[:2]) >= 64 * 2 ** (level + 1):
        level += 1
    return level


def shift_precision(f, b, mask, warp, *, gradients=None, noise_energy=None) -> float:
    """The standard error (px) of the shift ``warp`` found between ``b`` and ``f`` over
    ``mask``: the frame moved back by it regressed on the background (gain and offset, as
    the ECC leaves free) and the background's gradients (the shift's linear effect), the
    larger of the two gradients' standard errors. The gradients' energy that the background's
    own noise makes (its level from neighbouring pixels' differences) is no structure and is
    taken out. A scene whose only structure is a gain or an offset (a plain or evenly shaded
    backdrop: a shift along a linear shading is an offset) has an infinite one.
    ``gradients``, ``noise_energy``: the background's (:class:`Reference`), made here when
    not given."""
    h, w = f.shape
    back = cv2.warpAffine(f, warp, (w, h), flags=cv2.INTER_LINEAR + cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)
    inside = cv2.warpAffine(mask, warp, (w, h), flags=cv2.INTER_NEAREST + cv2.WARP_INVERSE_MAP,
                            borderValue=0)
    m = (mask > 0) & (inside > 0)
    m[:2] = m[-2:] = False
    m[:, :2] = m[:, -2:] = False
    n = int(m.sum())
    if n < 16:
        return math.inf
    if gradients is None:
        gradients = (_gradient(b, 1, 0), _gradient(b, 0, 1))
    if noise_energy is None:
        noise_energy = reference(b, 0).noise_energy[0]
    x = np.column_stack([b[m], np.ones(n), gradients[0][m], gradients[1][m]]).astype(float)
    y = back[m].astype(float)
    xtx = x.T @ x
    try:
        coef = np.linalg.solve(xtx, x.T @ y)
    except np.linalg.LinAlgError:
        return math.inf
    res = y - x @ coef
    s2 = float(res @ res) / max(1, n - 4)
    xtx[2, 2] -= n * noise_energy[0]
    xtx[3, 3] -= n * noise_energy[1]
    if not np.all(np.linalg.eigvalsh(xtx) > 0):
        return math.inf
    cov = s2 * np.linalg.inv(xtx)
    return math.sqrt(max(cov[2, 2], cov[3, 3]))


def _noise(img) -> float:
    """The image's pixel noise: the rms of neighbouring pixels' differences over root 2,
    the differences beyond 4 robust sigmas (an edge) left out (a MAD alone reads 8-bit data
    of 0.7 counts as 1.05: its differences are whole counts)."""
    d = np.diff(np.asarray(img, dtype=np.float64), axis=1).ravel()
    s0 = 1.4826 * float(np.median(np.abs(d)))
    d = d[np.abs(d) <= max(4.0 * s0, 2.0)]
    return math.sqrt(float(np.mean(d * d)) / 2.0) if d.size else 0.0


def _gradient(img, dx: int, dy: int):
    """The image's gradient along x (dx 1) or y (dy 1), per px, smoothed by a pixel."""
    return cv2.Sobel(cv2.GaussianBlur(img, (0, 0), 1.0), cv2.CV_32F, dx, dy, ksize=3) / 8.0


def _search(f, b, mask) -> tuple[float, float]:
    """The scene's shift in ``f`` against ``b`` over the whole image, to about a pixel:
    where the ball's square is a small share of the image, the phase correlation
    (``cv2.phaseCorrelate``) of the frame with the square filled in from the background;
    where it is more, the masked normalised cross-correlation
    (``skimage.registration.phase_cross_correlation`` with masks), which leaves the square
    out (filled in, it is the same in both images and pulls the peak to no shift) but costs
    several FFTs of twice the image's size."""
    if np.mean(mask == 0) <= SQUARE_SHARE_MAX:
        filled = np.where(mask > 0, f, b).astype(np.float64)
        window = cv2.createHanningWindow((f.shape[1], f.shape[0]), cv2.CV_64F)
        (dx, dy), _ = cv2.phaseCorrelate(b.astype(np.float64), filled, window)
        return float(dx), float(dy)
    # the shift that moves the frame onto the background: the scene's shift, negated
    found = phase_cross_correlation(b, f, reference_mask=np.ones(b.shape, dtype=bool),
                                    moving_mask=mask > 0)
    dy, dx = -np.asarray(found[0] if isinstance(found, tuple) else found, dtype=float)
    return float(dx), float(dy)


def frame_shift(frame, background, ball=None, r_px: float = 0.0, *, level: int = 0):
    """The scene's shift (dx, dy) px in ``frame`` against ``background``, the ball at
    ``ball`` = (x, y) px masked (NaN where the scene cannot tell it: a standard error above
    SHIFT_MAX_SE_PX, :func:`shift_precision`).

    A whole-scene search on the images halved :func:`search_level` times (:func:`_search`),
    refined by the enhanced correlation coefficient's translation (``cv2.findTransformECC``)
    over the static scene at each level down to ``level`` (0: full size; more, a quick look,
    the shift still given in the full images' pixels). ``background``: an image, or a
    :class:`Reference` made of it once for many frames.
    """
    ref = background if isinstance(background, Reference) else None
    shape = (ref.images[0] if ref is not None else np.asarray(background)).shape[:2]
    top = max(level, search_level(shape))
    if ref is None or len(ref.images) <= top:
        ref = reference(ref.images[0] if ref is not None else background, top)
    pyramid = [_scene(frame, shape, ball, r_px)]
    while len(pyramid) <= top:
        pyramid.append(_halved(*pyramid[-1]))
    (f, mask), b = pyramid[top], ref.images[top]
    if mask.sum() < 16:
        return math.nan, math.nan
    dx, dy = _search(f, b, mask)
    warp = np.array([[1, 0, dx], [0, 1, dy]], dtype=np.float32)
    # the rho increment ends it: from the search's pixel it is small at once, so a tiny one
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, ECC_STEPS, 1e-7)
    for lv in range(top, level - 1, -1):
        (f, mask), b = pyramid[lv], ref.images[lv]
        if lv < top:
            warp[:, 2] *= 2.0
        # where the frame's edge moved in, it holds no scene of the background's
        mask = _inside(mask, warp)
        try:
            _, warp = cv2.findTransformECC(b, f, warp, cv2.MOTION_TRANSLATION, crit, mask, 1)
        except cv2.error as exc:  # a featureless scene
            logger.debug(f"ECC failed: {exc}")
            return math.nan, math.nan
    scale = float(2 ** level)
    if not shift_precision(f, b, mask, warp, gradients=ref.gradients[level],
                           noise_energy=ref.noise_energy[level]) * scale <= SHIFT_MAX_SE_PX:
        return math.nan, math.nan
    return float(warp[0, 2]) * scale, float(warp[1, 2]) * scale
