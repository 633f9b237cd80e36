"""Full-frame search: where in a frame a ball of known radius may be (no prediction needed)."""

from __future__ import annotations

import math

import cv2
import numpy as np

from rollfric.locate.regions import _crop, _full_scale, as_array


def _ring_template(r: float, width: float) -> np.ndarray:
    """A ring of radius r (px) with a Gaussian cross-section of sigma ``width`` px: the
    matched filter for the gradient magnitude of a smoothed disk edge."""
    half = int(math.ceil(r + 3.0 * width)) + 1
    yy, xx = np.mgrid[-half:half + 1, -half:half + 1].astype(np.float32)
    d = np.hypot(xx, yy)
    return np.exp(-0.5 * ((d - r) / width) ** 2).astype(np.float32)


def _refine_candidate(frame, background, r_px: float, cx: float, cy: float, reach: float):
    """Full-resolution matched filter around a coarse candidate: the normalised correlation of
    a ring of the known radius with the gradient magnitude of the smoothed frame - background
    (a circular Hough transform of known radius), over shifts within ``reach`` px. Each edge
    point votes on the circle around it, so the peak sits at the centre whatever the contrast
    along the rim (part of the ball in front of the trough, shading); pixels outside the
    frame count as edge-free, so a ball partly outside peaks at its centre too. Returns
    (x, y, disk-likeness: the correlation, <= 1) or None."""
    s = max(0.7, 0.08 * r_px)  # smoothing before differentiation: the noise averages down
    tpl = _ring_template(r_px, max(1.0, s))
    th = tpl.shape[0] // 2
    half = th + int(math.ceil(reach)) + 1
    ix, iy = int(round(cx)), int(round(cy))
    m = int(math.ceil(3 * s)) + 1  # context for the smoothing
    sub, x0, y0 = _crop(frame, ix - half - m, iy - half - m, ix + half + m + 1,
                        iy + half + m + 1)
    if sub is None:
        return None
    rel = cv2.subtract(sub, background[y0:y0 + sub.shape[0], x0:x0 + sub.shape[1]],
                       dtype=cv2.CV_32F)
    rel = cv2.GaussianBlur(rel, (0, 0), s, borderType=cv2.BORDER_REPLICATE)
    gx = cv2.Sobel(rel, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.Sobel(rel, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
    mag = cv2.magnitude(gx, gy)
    # place it in the full window, the median (edge-free) level outside the frame
    win = np.full((2 * half + 1, 2 * half + 1), float(np.median(mag)), np.float32)
    wx0, wy0 = ix - half, iy - half
    ax0, ay0 = max(x0, wx0), max(y0, wy0)
    ax1 = min(x0 + mag.shape[1], wx0 + win.shape[1])
    ay1 = min(y0 + mag.shape[0], wy0 + win.shape[0])
    if ax1 <= ax0 or ay1 <= ay0:
        return None
    win[ay0 - wy0:ay1 - wy0, ax0 - wx0:ax1 - wx0] = mag[ay0 - y0:ay1 - y0, ax0 - x0:ax1 - x0]
    ncc = cv2.matchTemplate(win, tpl, cv2.TM_CCOEFF_NORMED)
    _, vmax, _, (px, py) = cv2.minMaxLoc(ncc)
    # sub-pixel peak: a parabola through the neighbours
    dx = dy = 0.0
    nh, nw = ncc.shape
    if 0 < px < nw - 1:
        a, b, c = ncc[py, px - 1], ncc[py, px], ncc[py, px + 1]
        den = a - 2 * b + c
        dx = 0.5 * (a - c) / den if den < 0 else 0.0
    if 0 < py < nh - 1:
        a, b, c = ncc[py - 1, px], ncc[py, px], ncc[py + 1, px]
        den = a - 2 * b + c
        dy = 0.5 * (a - c) / den if den < 0 else 0.0
    # the template centred on result (px, py) sits at window pixel (px + th, py + th)
    return float(wx0 + px + th + dx), float(wy0 + py + th + dy), float(vmax)


def coarse_find(frame: np.ndarray, background: np.ndarray, r_px: float, *,
                min_contrast: float | None = None,
                full_scale: float | None = None,
                n_candidates: int = 3) -> tuple[float, float] | None:
    """Full-frame search: a rough centre of the ball, good to about a pixel.

    The most disk-like of :func:`coarse_candidates`.

    Parameters
    ----------
    frame, background : numpy.ndarray
        The frame and the background image (same shape).
    r_px : float
        The ball's radius (px).
    min_contrast : float, optional
        Mean |frame - background| over the ball that counts as a ball (DN); default 1 % of
        full scale.
    full_scale : float, optional
        The camera's full scale, 2**bit_depth - 1 (DN; :mod:`rollfric.io.bitdepth`); default the
        frame's word's (255 or 65535).
    n_candidates : int, optional
        Candidates compared.

    Returns
    -------
    tuple of float or None
        (x, y) in px, or None when nothing ball-like differs from the background.
    """
    cands = coarse_candidates(frame, background, r_px, min_contrast=min_contrast,
                              full_scale=full_scale, n_candidates=n_candidates)
    return (cands[0][0], cands[0][1]) if cands else None


def coarse_candidates(frame: np.ndarray, background: np.ndarray, r_px: float, *,
                      min_contrast: float | None = None,
                      full_scale: float | None = None,
                      n_candidates: int = 3) -> list[tuple[float, float, float]]:
    """Full-frame search: up to ``n_candidates`` places where a ball of radius ``r_px`` may be.

    The most disk-like first (a harsh lamp's cast shadow of the ball on the backdrop is a disk
    too: :func:`locate_subpixel` tries them in turn).

    1. Detection at reduced resolution: frame - background (signed) averaged over cells of
       about r/3 px (the noise averages down before it is rectified), |.|, then the mean over a
       ball-sized box minus the mean over the ring around it (pixels outside the frame left
       out); the strongest few separated peaks are candidates. A candidate must exceed 10 x
       the score's noise (from the cells' median |difference|) and half ``min_contrast``.
    2. Each candidate is refined at full resolution by a matched filter (normalised
       correlation of a disk-minus-ring template of the known radius with the smoothed
       |frame - background|); the most disk-like candidate wins.

    Parameters
    ----------
    frame, background : numpy.ndarray
        The frame and the background image (same shape).
    r_px : float
        The ball's radius (px).
    min_contrast : float, optional
        Mean |frame - background| over the ball that counts as a ball (DN); default 1 % of
        full scale.
    full_scale : float, optional
        The camera's full scale, 2**bit_depth - 1 (DN; :mod:`rollfric.io.bitdepth`); default the
        frame's word's (255 or 65535).
    n_candidates : int, optional
        Most candidates returned.

    Returns
    -------
    list of tuple of float
        (x, y, disk-likeness) per candidate, the most disk-like first; empty when nothing
        ball-like differs from the background.
    """
    frame = as_array(frame)
    h, w = frame.shape
    if min_contrast is None:
        min_contrast = 0.01 * (_full_scale(frame.dtype) if full_scale is None else full_scale)
    f = max(1, int(r_px // 3))
    hs, ws = h // f, w // f
    if hs < 1 or ws < 1:
        return []
    diff = cv2.subtract(frame[:hs * f, :ws * f], background[:hs * f, :ws * f],
                        dtype=cv2.CV_32F)
    small = cv2.resize(diff, (ws, hs), interpolation=cv2.INTER_AREA) if f > 1 else diff
    a = np.abs(small)
    rc = r_px / f
    k_in = max(1, int(round(1.6 * rc)))
    k_out = max(k_in + 2, int(round(3.0 * rc)))
    ones = np.ones_like(a)
    n_in = cv2.boxFilter(ones, -1, (k_in, k_in), normalize=False,
                         borderType=cv2.BORDER_CONSTANT)
    n_out = cv2.boxFilter(ones, -1, (k_out, k_out), normalize=False,
                          borderType=cv2.BORDER_CONSTANT)
    s_in = cv2.boxFilter(a, -1, (k_in, k_in), normalize=False, borderType=cv2.BORDER_CONSTANT)
    s_out = cv2.boxFilter(a, -1, (k_out, k_out), normalize=False,
                          borderType=cv2.BORDER_CONSTANT)
    score = s_in / n_in - (s_out - s_in) / np.maximum(n_out - n_in, 1.0)
    # the noise of a cell from the median |cell| (most cells see no ball), that of the score
    # from it (|N(0, s)| has a standard deviation of 0.6 s)
    sig_c = 1.4826 * float(np.median(a))
    sig_score = 0.6 * sig_c * math.sqrt(1.0 / k_in ** 2 + 1.0 / (k_out ** 2 - k_in ** 2))
    thr = max(10.0 * sig_score, 0.5 * min_contrast)
    sep = max(1, int(round(2.0 * rc)))
    work = score.copy()
    cands = []
    for _ in range(max(1, n_candidates)):
        _, vmax, _, (px, py) = cv2.minMaxLoc(work)
        if vmax < thr:
            break
        cands.append(((px + 0.5) * f - 0.5, (py + 0.5) * f - 0.5))
        work[max(0, py - sep):py + sep + 1, max(0, px - sep):px + sep + 1] = -np.inf
    out = []
    for cx, cy in cands:
        # a ball cut by the frame's border can be centred up to ~r beyond where the cut part
        # peaks: search further there
        border = min(cx, cy, w - 1 - cx, h - 1 - cy)
        reach = f + 2.0 + max(0.0, r_px - border)
        got = _refine_candidate(frame, background, r_px, cx, cy, reach=reach)
        if got is not None and all(math.hypot(got[0] - o[0], got[1] - o[1]) > 0.5 * r_px
                                   for o in out):
            out.append(got)
    out.sort(key=lambda c: -c[2])
    return out
