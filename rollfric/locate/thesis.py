"""The thesis's two locators.

- ``locate_small_thesis`` (thesis paper 1, sec. 3): background subtraction, a 15 x 15 window
  summed over a sub-image, the brightest pixel inside the best window. Integer pixels.
- ``locate_large_thesis`` (thesis paper 2, sec. 4, steps 1-7): sub-image around the specular
  spots, the quarter of the ball chosen by the side, binarisation and Canny, a rough centre from
  the edge and the known diameter (eq. 12), then the candidate in the 15 x 15 neighbourhood
  whose circle of the known radius crosses most radial intensity jumps (eqs. 13-15).
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np

from rollfric.locate.location import Location
from rollfric.locate.regions import _crop, _full_scale, relative_image
from rollfric.locate.search import coarse_find

# --------------------------------------------------------------------------------------------
# thesis, paper 1: the small-ball locator


def locate_small_thesis(frame: np.ndarray, background: np.ndarray, *,
                        roi: tuple[int, int, int, int] | None = None, window: int = 15,
                        polarity: str = "abs", full_scale: float | None = None) -> Location:
    """Thesis paper 1: the brightest pixel of the window of largest summed relative image.

    A ``window`` x ``window`` window traverses the sub-image ``roi``; the centre is the
    brightest pixel (largest frame - background) in the window of largest sum. It finds the
    specular spot, not the geometric centre.

    Parameters
    ----------
    frame, background : numpy.ndarray or LazyFrame
        The frame and the background image (same size).
    roi : tuple of int, optional
        (x0, y0, x1, y1) of the sub-image searched (default: the whole frame).
    window : int, optional
        Side of the summing window (px).
    polarity : {"abs", "bright", "dark"}, optional
        What is summed: |frame - background| (default: finds a dark ball with a bright spot as
        well as a bright one), frame - background (as for the thesis's bright spot) or
        background - frame.
    full_scale : float, optional
        The camera's full scale, 2**bit_depth - 1 (DN): a spot whose window sums to less than
        10 % of it is none; default the frame's word's (255 or 65535).

    Returns
    -------
    Location
        Integer-pixel centre; ``found`` False when the region lies outside the frame, holds no
        spot, or the brightest pixel does not stand out from the ball around it (a uniformly
        dark, backlit ball has no spot to locate by).
    """
    h, w = frame.shape
    x0, y0, x1, y1 = (0, 0, w, h) if roi is None else roi
    fr, x0, y0 = _crop(frame, x0, y0, x1, y1)
    if fr is None:
        return Location.missing("search region outside the frame")
    bg = background[y0:y0 + fr.shape[0], x0:x0 + fr.shape[1]]
    rel = relative_image(fr, bg)
    if polarity == "dark":
        summed = -rel
    elif polarity == "abs":
        summed = np.abs(rel)
    elif polarity == "bright":
        summed = rel
    else:
        raise ValueError(f"polarity must be bright, dark or abs, got {polarity!r}")
    sums = cv2.boxFilter(summed, -1, (window, window), normalize=False,
                         borderType=cv2.BORDER_CONSTANT)
    _, smax, _, (bx, by) = cv2.minMaxLoc(sums)
    if full_scale is None:
        full_scale = _full_scale(frame.dtype)
    if smax < 0.1 * full_scale:  # 25 DN summed over the window (8 bit)
        return Location.missing("no spot in the search region")
    half = window // 2
    sub, sx0, sy0 = _crop(rel, bx - half, by - half, bx + half + 1, by + half + 1)
    _, vmax, _, (px, py) = cv2.minMaxLoc(sub)
    sx, sy = px + sx0, py + sy0
    # the spot must stand out from the ball around it: its height above the median of the
    # ring 3..7 px about it (for the 15 px window) at least a quarter of the window's mean
    # |frame - background|. The brightest pixel of a uniformly dark (backlit) ball is no spot,
    # and reporting it would be a wrong place
    r_in, r_out = max(2, window // 4), max(3, half)
    ring, rx0, ry0 = _crop(rel, sx - r_out, sy - r_out, sx + r_out + 1, sy + r_out + 1)
    yy, xx = np.mgrid[ry0:ry0 + ring.shape[0], rx0:rx0 + ring.shape[1]]
    d = np.hypot(xx - sx, yy - sy)
    around = ring[(d >= r_in) & (d <= r_out)]
    if around.size and vmax - float(np.median(around)) < 0.25 * smax / window ** 2:
        return Location.missing("no spot standing out on the ball (a uniformly dark ball, "
                                "backlit?): thesis-small locates by the specular spot")
    return Location(x=float(sx + x0), y=float(sy + y0), found=True)


# --------------------------------------------------------------------------------------------
# thesis, paper 2: the large-ball locator


def _circle_known_radius(xs, ys, r, cx, cy, iters=20):
    """Least-squares centre of points on a circle of known radius r (eq. 12), Gauss-Newton."""
    for _ in range(iters):
        dx, dy = xs - cx, ys - cy
        d = np.hypot(dx, dy)
        d[d == 0] = 1e-9
        res = d - r
        jac = np.stack([-dx / d, -dy / d], axis=1)
        step, *_ = np.linalg.lstsq(jac, -res, rcond=None)
        cx, cy = cx + step[0], cy + step[1]
        if abs(step[0]) + abs(step[1]) < 1e-6:
            break
    return cx, cy


def locate_large_thesis(frame: np.ndarray, background: np.ndarray, r_px: float, *,
                        side: int = 1, guess: tuple[float, float] | None = None,
                        threshold: float | None = None, neighbourhood: int = 15,
                        step: float = 0.025, full_scale: float | None = None) -> Location:
    """Thesis paper 2, steps 1-7, for a ball of radius ``r_px`` (px).

    Parameters
    ----------
    frame, background : numpy.ndarray or LazyFrame
        The frame and the background image (same size).
    r_px : float
        The ball's radius (px).
    side : {1, -1}, optional
        The sign of theta: +1 (right of the bottom) uses the upper-left quarter of the ball,
        -1 the upper-right.
    guess : tuple of float, optional
        Where to look for the specular spots (default: the whole frame via
        :func:`coarse_find`).
    threshold : float, optional
        The binarisation threshold on |frame - background| (default: Otsu's threshold on the
        quarter), also the intensity jump that counts in step 6.
    neighbourhood : int, optional
        Side of the square of candidate centres tried in step 6 (px; 15 in the thesis).
    step : float, optional
        Angular step (rad) around the candidate circles of step 6.
    full_scale : float, optional
        The camera's full scale, 2**bit_depth - 1 (DN), for the full-frame search
        (:func:`coarse_find`) and the highlight (at least 1 % of it above the background);
        default the frame's word's.

    Returns
    -------
    Location
        Integer-pixel centre (ties in step 6 averaged); ``found`` False when no ball-like
        change is found, or no specular highlight brighter than the background lies on the
        ball (a dark ball on a bright backlight: the method has nothing to locate by).
    """
    if guess is None:
        guess = coarse_find(frame, background, r_px, full_scale=full_scale)
        if guess is None:
            return Location.missing("no ball-like change in the frame")
    try:
        scx, scy = _highlight(frame, background, r_px, guess, full_scale)
        half = int(round(r_px + 13))  # 50 for the 10 mm ball: the thesis's 101 x 101
        # step 2: background subtraction on the sub-image
        fr, x0, y0 = _crop(frame, scx - half, scy - half, scx + half + 1, scy + half + 1)
        if fr is None or min(fr.shape) < half:
            raise _NotFound("ball too close to the frame border")
        rel = relative_image(fr, background[y0:y0 + fr.shape[0], x0:x0 + fr.shape[1]])
        cxl, cyl = scx - x0, scy - y0
        ex, ey, threshold = _quarter_edge(np.abs(rel), cxl, cyl, half, r_px, side, threshold)
        # step 5: rough centre from the edge and the known diameter (eq. 12)
        rcx, rcy = _circle_known_radius(ex.astype(float), ey.astype(float), r_px, float(cxl),
                                        float(cyl))
        if not (np.isfinite(rcx) and np.isfinite(rcy)):
            raise _NotFound("rough centre fit failed")
        cand_x, cand_y, jumps, n_rho = _jump_counts(rel, rcx, rcy, r_px, neighbourhood, step,
                                                    threshold)
    except _NotFound as why:
        return Location.missing(str(why))
    best = jumps.max()
    if best == 0:
        return Location.missing("no intensity jumps around the rough centre")
    win = jumps == best
    # step 7: back to frame coordinates
    return Location(x=float(cand_x[win].mean() + x0), y=float(cand_y[win].mean() + y0),
                    r=float(r_px), found=True, inlier_frac=float(best) / n_rho)


class _NotFound(Exception):
    """A step of :func:`locate_large_thesis` found nothing to go on (the message says what)."""


def _highlight(frame, background, r_px, guess, full_scale) -> tuple[int, int]:
    """Step 1: the specular spot near ``guess`` (frame pixels), the brightest 3 x 3 mean of the
    relative image within 1.3 r of it; :class:`_NotFound` where none is brighter than the
    background or it lies off the ball."""
    half_s = int(round(1.3 * r_px))
    fr, x0, y0 = _crop(frame, int(round(guess[0])) - half_s, int(round(guess[1])) - half_s,
                       int(round(guess[0])) + half_s + 1, int(round(guess[1])) + half_s + 1)
    if fr is None:
        raise _NotFound("search region outside the frame")
    rel = relative_image(fr, background[y0:y0 + fr.shape[0], x0:x0 + fr.shape[1]])
    spots = cv2.blur(rel, (3, 3))
    _, smax, _, (sx, sy) = cv2.minMaxLoc(spots)
    scx, scy = sx + x0, sy + y0
    # the method stands on the highlight: one no brighter than the background (a dark ball on
    # a bright backlight) or off the ball is not found, never a wrong place
    # the pixel noise from neighbours' differences (edges are few), a third of it after the
    # 3 x 3 mean
    noise = 1.4826 * float(np.median(np.abs(np.diff(rel, axis=1)))) / math.sqrt(2.0) / 3.0
    fs = _full_scale(fr.dtype) if full_scale is None else float(full_scale)
    if smax < max(8.0 * noise, 0.01 * fs):
        raise _NotFound("no specular highlight brighter than the background on the "
                        "ball (a dark ball on a bright backlight?): thesis-large "
                        "locates by the highlight; use the subpixel locator")
    if math.hypot(scx - guess[0], scy - guess[1]) > r_px:
        raise _NotFound("the brightest spot near the ball lies off the ball: no "
                        "specular highlight to locate by")
    return scx, scy


def _quarter_edge(rel_abs, cxl, cyl, half, r_px, side, threshold):
    """Steps 3-4: the ball's edge points in its upper-left (``side`` >= 0) or upper-right
    quarter about the spot (cxl, cyl) of ``rel_abs`` (|frame - background|): the quarter
    binarised at ``threshold`` (None: Otsu's) with the part near the centre masked, its Canny
    edges at 0.6-1.5 r from the spot. Returns their x, y and the threshold."""
    # step 3: the upper-left quarter when theta > 0, the upper-right one when theta < 0
    qy0, qy1 = max(0, cyl - half), cyl + 1
    if side >= 0:
        qx0, qx1 = max(0, cxl - half), cxl + 1
    else:
        qx0, qx1 = cxl, min(rel_abs.shape[1], cxl + half + 1)
    quarter = rel_abs[qy0:qy1, qx0:qx1]
    if quarter.size < 16:
        raise _NotFound("ball quarter outside the frame")
    # step 4: mask the (dark) part near the centre, binarise, Canny
    yy, xx = np.mgrid[qy0:qy1, qx0:qx1]
    inner = np.hypot(xx - cxl, yy - cyl) < 0.7 * r_px
    if threshold is None:
        q8 = cv2.normalize(quarter, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
        t8, _ = cv2.threshold(q8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        qmin, qmax = float(quarter.min()), float(quarter.max())
        threshold = qmin + (t8 + 0.5) / 255.0 * (qmax - qmin)
    binary = ((quarter > threshold) | inner).astype(np.uint8) * 255
    edges = cv2.Canny(binary, 50, 150)
    ey, ex = np.nonzero(edges)
    # keep edge points that can belong to the ball (not the quarter's cut lines)
    d = np.hypot(ex + qx0 - cxl, ey + qy0 - cyl)
    keep = (d > 0.6 * r_px) & (d < 1.5 * r_px)
    ex, ey = ex[keep] + qx0, ey[keep] + qy0
    if len(ex) < 5:
        raise _NotFound("no ball edge in the chosen quarter")
    return ex, ey, threshold


def _jump_counts(rel, rcx, rcy, r_px, neighbourhood, step, threshold):
    """Step 6: for each candidate centre in the ``neighbourhood`` x ``neighbourhood`` square
    about (rcx, rcy), the radial intensity jumps above ``threshold`` on its circle of radius
    ``r_px`` every ``step`` rad. Returns the candidates' x, y, their counts and the number of
    angles."""
    nh = neighbourhood // 2
    c0x, c0y = int(round(rcx)), int(round(rcy))
    offs = np.arange(-nh, nh + 1)
    cand_x = (c0x + offs)[None, :].repeat(len(offs), 0).ravel()
    cand_y = (c0y + offs)[:, None].repeat(len(offs), 1).ravel()
    rho = np.arange(0.0, 2 * math.pi, step)
    cos, sin = np.cos(rho), np.sin(rho)
    hh, ww = rel.shape
    x1 = np.rint(cand_x[:, None] + r_px * cos).astype(int)
    y1 = np.rint(cand_y[:, None] + r_px * sin).astype(int)
    x2 = np.rint(cand_x[:, None] + (r_px + 1) * cos).astype(int)
    y2 = np.rint(cand_y[:, None] + (r_px + 1) * sin).astype(int)
    same = (x1 == x2) & (y1 == y2)
    x2 = np.where(same, np.rint(cand_x[:, None] + (r_px + 2) * cos).astype(int), x2)
    y2 = np.where(same, np.rint(cand_y[:, None] + (r_px + 2) * sin).astype(int), y2)
    inside = (x1 >= 0) & (x1 < ww) & (y1 >= 0) & (y1 < hh) & (x2 >= 0) & (x2 < ww) \
        & (y2 >= 0) & (y2 < hh)
    i1 = rel[np.clip(y1, 0, hh - 1), np.clip(x1, 0, ww - 1)]
    i2 = rel[np.clip(y2, 0, hh - 1), np.clip(x2, 0, ww - 1)]
    jumps = ((np.abs(i1 - i2) > threshold) & inside).sum(axis=1)
    return cand_x, cand_y, jumps, len(rho)


# --------------------------------------------------------------------------------------------
# as the tracking loop calls them (rollfric.locate.Locator)


def thesis_large_locator(frame, background, r_px: float, guess: tuple[float, float] | None,
                         center: tuple[float, float], **unused: Any) -> Location:
    """The :class:`rollfric.locate.Locator` ``"thesis-large"``.

    :func:`locate_large_thesis` around ``guess`` (the full-frame search of :func:`coarse_find`
    without one), on the quarter of the ball on the side of the trough's axis ``center`` where
    the ball is. Of the sub-pixel locator's options (``unused``) only ``opts.full_scale`` (the
    camera's full scale) applies.

    Parameters
    ----------
    frame, background : numpy.ndarray or LazyFrame
    r_px : float
        The ball's radius (px).
    guess : tuple of float or None
        The predicted centre (px).
    center : tuple of float
        The cylinder axis (px).
    **unused
        Ignored.

    Returns
    -------
    Location
    """
    fs = getattr(unused.get("opts"), "full_scale", None)
    if guess is None:
        guess = coarse_find(frame, background, r_px, full_scale=fs)
        if guess is None:
            return Location.missing("no ball-like change in the frame")
    side = 1 if guess[0] >= center[0] else -1
    return locate_large_thesis(frame, background, r_px, side=side, guess=guess, full_scale=fs)


def thesis_small_locator(frame, background, r_px: float, guess: tuple[float, float] | None,
                         center: tuple[float, float], **unused: Any) -> Location:
    """The :class:`rollfric.locate.Locator` ``"thesis-small"``.

    :func:`locate_small_thesis` in a window of 2 r + 20 px a side around ``guess``, then over the
    whole frame when the spot is not found there. ``center`` and the sub-pixel locator's options
    (``unused``) do not apply, but ``opts.full_scale`` (the camera's full scale).

    Parameters
    ----------
    frame, background : numpy.ndarray or LazyFrame
    r_px : float
        The ball's radius (px).
    guess : tuple of float or None
        The predicted centre (px).
    center : tuple of float
        Not used.
    **unused
        Ignored.

    Returns
    -------
    Location
    """
    roi = None
    if guess is not None:
        m = int(math.ceil(2 * r_px + 20))
        roi = (int(guess[0]) - m, int(guess[1]) - m, int(guess[0]) + m + 1,
               int(guess[1]) + m + 1)
    fs = getattr(unused.get("opts"), "full_scale", None)
    loc = locate_small_thesis(frame, background, roi=roi, full_scale=fs)
    if roi is not None and not loc.found:
        loc = locate_small_thesis(frame, background, full_scale=fs)
    return loc
