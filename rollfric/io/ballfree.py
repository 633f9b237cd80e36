"""Backgrounds made from the frames themselves, checked to be free of the ball where it goes.

A background made from the frames holds the ball wherever the ball does not move clear of a
place in enough of them: the per-pixel median where it covers a pixel in half the frames or
more (a short clip, a slow ball, a ball at rest), the per-pixel maximum of a backlit rig (a dark
ball on a bright field) where it covers a pixel in every frame. The tracker would then find
the "hole" the ball's ghost leaves in the difference of frame and background, at the ghost's
place, with a small stated error. :func:`check_ball_free` looks at every place the ball (or
something ball-like) is seen in the sampled frames, rebuilds the background there from the
frames in which the ball is clear of it, and refuses the background where too few are.

Backlit rigs have two backgrounds of their own: :func:`clip_background`, a flat field at the
backlight's level, and :func:`max_background`, the per-pixel maximum over the frames less its
upward noise bias (the maximum of k noisy samples exceeds their mean by about
sigma * E[max of k standard normals]).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from rollfric import locate
from rollfric.errors import InputError
from rollfric.io.background import HOLE_SHARE, MIN_FRAMES_SHOWING, median, only_about

# the backgrounds `rollfric measure --background-from` offers
KINDS = ("median", "clip", "max")
# a place is held clear by at least this many frames before the background there is rebuilt
# from them (the median of fewer is one frame's noise)
MIN_CLEAR = 3
# rebuilds before a background that still holds the ball is refused (each finds the ball's
# places better: the first may see only the ghost's hole)
ATTEMPTS = 3
# the pixels a frame's ball (or its cast shadow, its blur) may touch: within this many radii
# (+ CLEAR_PAD px) of where it is seen, as the median's repair takes them
CLEAR_RADII = 1.5
CLEAR_PAD_PX = 3.0
# the level of a backlit field: this percentile of the median image (the field fills most of
# a backlit frame; a clipped field sits at full scale)
CLIP_PERCENTILE = 99.0

REMEDIES = {"median": "give a ball-free frame or a recording of the empty scene (--background "
                       "FILE), or, for a backlit rig (a dark ball on a bright field), "
                       "--background-from clip (a flat field at the backlight's level) or "
                       "--background-from max",
            "max": "give a ball-free frame or a recording of the empty scene (--background "
                   "FILE), or --background-from clip (a flat field at the backlight's level)"}


@functools.lru_cache(maxsize=64)
def expected_max_normal(k: int) -> float:
    """E[max of k independent standard normals] (0 for k = 1).

    Parameters
    ----------
    k : int
        Number of samples (>= 1).

    Returns
    -------
    float
        The expected maximum, in standard deviations above the mean.
    """
    from scipy import integrate, stats

    if k <= 1:
        return 0.0
    # E[max] = int x k phi(x) Phi(x)^(k-1) dx
    val, _ = integrate.quad(lambda x: x * k * stats.norm.pdf(x) * stats.norm.cdf(x) ** (k - 1),
                            -12.0, 12.0, limit=200)
    return float(val)


def noise_sigma(stack: np.ndarray) -> float:
    """The frames' temporal noise (DN, one frame): from the differences of successive frames.

    The robust standard deviation (1.4826 x median |d|) of the differences, over 2; pixels at
    the stack's lowest or highest value in either frame (clipped) are left out, and so are the
    few the moving ball changes (the median ignores them).

    Parameters
    ----------
    stack : numpy.ndarray
        Frames, shape (k, H, W), k >= 2.

    Returns
    -------
    float
        The noise's standard deviation (0 when no pixel is unclipped).
    """
    f = stack.astype(np.float32)
    lo, hi = float(f.min()), float(f.max())
    d = f[1:] - f[:-1]
    ok = (f[1:] > lo) & (f[1:] < hi) & (f[:-1] > lo) & (f[:-1] < hi)
    if not ok.any():
        return 0.0
    return float(1.4826 * np.median(np.abs(d[ok])) / math.sqrt(2.0))


def clip_background(stack: np.ndarray) -> tuple[np.ndarray, float]:
    """A flat field at the backlight's level: the CLIP_PERCENTILE of the median image.

    Parameters
    ----------
    stack : numpy.ndarray
        Sampled frames, shape (k, H, W).

    Returns
    -------
    background : numpy.ndarray
        (H, W), every pixel the level, the frames' dtype.
    level : float
        The level (DN).
    """
    level = float(np.percentile(median(stack), CLIP_PERCENTILE))
    bg = np.full(stack.shape[1:], level)
    return np.rint(bg).astype(stack.dtype), level


def max_background(stack: np.ndarray, sigma: float | None = None) -> tuple[np.ndarray, float]:
    """The per-pixel maximum over frames, less its upward noise bias.

    The maximum of k samples of a pixel with noise sigma exceeds their mean by about
    sigma * E[max of k standard normals] (:func:`expected_max_normal`); that is taken off
    where the maximum exceeds the median (a clipped pixel, whose maximum is its median, keeps
    it).

    Parameters
    ----------
    stack : numpy.ndarray
        Frames, shape (k, H, W): a dark ball on a bright field, clear of every pixel in at least
        one of them.
    sigma : float, optional
        The noise (DN); default :func:`noise_sigma` of the frames.

    Returns
    -------
    background : numpy.ndarray
        (H, W), the frames' dtype.
    sigma : float
        The noise used.
    """
    if sigma is None:
        sigma = noise_sigma(stack) if len(stack) > 1 else 0.0
    top = stack.max(axis=0).astype(np.float64)
    med = np.median(stack, axis=0)
    bias = np.where(top > med, sigma * expected_max_normal(len(stack)), 0.0)
    return np.rint(top - bias).astype(stack.dtype), float(sigma)


def seen_places(stack: np.ndarray, background: np.ndarray, r_px: float, *,
                full_scale: float | None = None) -> tuple[list, list]:
    """Where the ball is seen against ``background`` in each frame, and the background's holes.

    A hole is a place where something ball-like is seen in nearly every frame that shows a
    change (HOLE_SHARE of them, as the median's repair finds a resting ball): the backdrop
    revealed where the background holds the ball, or the ball resting there. What is seen
    within a radius of a hole is not taken for the frame's ball.

    Returns
    -------
    places : list of list of (x, y)
        Per frame, where its ball (or its cast shadow) may be; empty: unknown (no change, or
        only at a hole).
    holes : list of (x, y)
        The holes.
    """
    seen = [[(c[0], c[1]) for c in locate.coarse_candidates(f, background, r_px,
                                                            n_candidates=3,
                                                            full_scale=full_scale)]
            for f in stack]
    showing = sum(1 for ps in seen if ps)
    holes = []
    for x0, y0 in (p for ps in seen for p in ps):
        if any(math.hypot(x0 - hx, y0 - hy) < r_px for hx, hy in holes):
            continue
        n = sum(1 for ps in seen if any(math.hypot(x - x0, y - y0) <= 0.5 * r_px
                                        for x, y in ps))
        n_eff = showing - only_about(seen, x0, y0, r_px)
        if n >= max(MIN_FRAMES_SHOWING, HOLE_SHARE * n_eff):
            holes.append((x0, y0))
    places = [[(x, y) for x, y in ps
               if all(math.hypot(x - hx, y - hy) > r_px for hx, hy in holes)] for ps in seen]
    return places, holes


def _discs(shape, points, r: float) -> np.ndarray:
    """(H, W) bool: the pixels within ``r`` of any of ``points`` (x, y)."""
    import cv2

    mask = np.zeros(shape, dtype=np.uint8)
    for x, y in points:
        # 4 fractional bits: the discs' centres and radius to 1/16 px
        cv2.circle(mask, (int(round(x * 16)), int(round(y * 16))), int(round(r * 16)), 1, -1,
                   lineType=cv2.LINE_8, shift=4)
    return mask.astype(bool)


def _near(ys, xs, points, r: float) -> np.ndarray:
    """Bool per pixel (ys, xs): within ``r`` of any of ``points``."""
    out = np.zeros(len(ys), dtype=bool)
    for x, y in points:
        out |= (xs - x) ** 2 + (ys - y) ** 2 <= r * r
    return out


def check_ball_free(stack: np.ndarray, background: np.ndarray, r_px: float, *,
                    kind: str = "median", sources=(), sigma: float = 0.0,
                    what: str = "the background",
                    full_scale: float | None = None) -> tuple[np.ndarray, list]:
    """``background`` (made from ``stack`` by ``kind``) made free of the ball where it goes.

    Every place something ball-like is seen against the background in a sampled frame is
    checked: the frames the background there was made from (all, or a repaired disc's
    ``sources``) must leave it clear of the ball in more than half of them (median) or in at
    least one (max). Where they do not, the background there is rebuilt from the frames in which
    the ball is clear of it (at least MIN_CLEAR), and checked again against the new background;
    where too few are, it is refused.

    Parameters
    ----------
    stack : numpy.ndarray
        The sampled frames (k, H, W) the background was made from.
    background : numpy.ndarray
        The background (H, W).
    r_px : float
        The ball's radius (px).
    kind : {"median", "max"}
        How the background was made.
    sources : sequence of (mask, frame numbers)
        Pixels made from only some of the frames (the median's repaired discs).
    sigma : float
        The frames' noise (DN), for the "max" rebuild.
    what : str
        The background's name in messages.
    full_scale : float, optional
        The camera's full scale (DN) the ball is searched with (rollfric.io.bitdepth).

    Returns
    -------
    background : numpy.ndarray
        The background, rebuilt where it held the ball (the same array when it did not).
    notes : list of str
        What was rebuilt.

    Raises
    ------
    rollfric.errors.InputError
        The ball does not move clear of where it is seen in enough frames: no background free
        of it can be made from the frames (the message names the place, how far the ball
        moves, and the remedies).
    """
    k = len(stack)
    shape = background.shape
    r_clear = CLEAR_RADII * r_px + CLEAR_PAD_PX
    # each pixel's frames: all, a repaired disc's (``sources``), or, once rebuilt, those clear
    # of it (column own[p] of own_use, (k, n))
    own = np.full(shape, -1, dtype=np.int64)
    own_use = np.zeros((k, 0), dtype=bool)
    worst_on, where = 0, None
    for attempt in range(ATTEMPTS):
        places, holes = seen_places(stack, background, r_px, full_scale=full_scale)
        if not any(places) and not holes:
            break
        # a frame whose ball is not seen may have it where the background holds a ball
        unknown = holes or [p for ps in places for p in ps]
        n_from = np.zeros(shape, dtype=np.int32)
        n_on = np.zeros(shape, dtype=np.int32)
        seen = np.zeros(shape, dtype=bool)
        mine = own >= 0
        for j in range(k):
            on = _discs(shape, places[j] or unknown, r_px + 2.0)  # the ball's own pixels
            member = np.ones(shape, dtype=bool)
            for mask, use in sources:
                if j not in use:
                    member[mask] = False
            member[mine] = own_use[j, own[mine]]
            n_from += member
            n_on += on & member
            seen |= on
        bad = ((2 * n_on >= n_from) if kind != "max" else (n_on >= n_from)) & seen
        if not bad.any():
            break
        ys, xs = np.nonzero(bad)
        # frames whose ball is clear of each bad pixel
        use = np.stack([~_near(ys, xs, places[j] or unknown, r_clear) for j in range(k)])
        n_clear = use.sum(axis=0)
        cx, cy = float(xs.mean()), float(ys.mean())
        short = n_clear < (MIN_CLEAR if kind != "max" else 1)
        if attempt == ATTEMPTS - 1 or short.any():
            worst = int(n_on[bad].max())
            few = ", and too few frames leave it clear to rebuild it" if short.any() else ""
            raise InputError(
                f"{what} holds the ball around ({cx:.0f}, {cy:.0f}) px: the ball does not move "
                f"clear of where it is (a ball {2 * r_px:.0f} px across, on that place in "
                f"{worst} of the {k} sampled frames{few}: a short clip, a slow ball or one at "
                f"rest), so it would be found at its ghost; {REMEDIES[kind]}")
        vals = stack[:, ys, xs].astype(np.float64)
        vals[~use] = np.nan
        med = np.nanmedian(vals, axis=0)
        if kind == "max":
            top = np.nanmax(vals, axis=0)
            e = np.array([expected_max_normal(int(n)) for n in n_clear])
            new = np.where(top > med, top - sigma * e, top)
        else:
            new = med
        background = background.copy()
        background[ys, xs] = np.rint(new).astype(stack.dtype)
        own[ys, xs] = own_use.shape[1] + np.arange(len(ys))
        own_use = np.concatenate([own_use, use], axis=1)
        worst_on = max(worst_on, int(n_on[bad].max()))
        where = where or (cx, cy)
    n_rebuilt = int((own >= 0).sum())
    notes = [] if not n_rebuilt else [
        f"{what} held the ball around ({where[0]:.0f}, {where[1]:.0f}) px ({n_rebuilt} px, the "
        f"ball on them in up to {worst_on} of {k} sampled frames); they were rebuilt from the "
        "frames in which the ball is clear of them"]
    return background, notes
