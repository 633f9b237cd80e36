"""Ball locators: the thesis's two, and the sub-pixel silhouette-circle fit (the default).

All work on one frame and its background (same size), in pixels with x right, y down and the
origin at the centre of the top-left pixel. Each returns a :class:`Location`. The frame may be
a :class:`LazyFrame`, which reads only the regions a locator crops (the tracking loop's ROI).

- ``locate_small_thesis`` (thesis paper 1, sec. 3): background subtraction, a 15 x 15 window
  summed over a sub-image, the brightest pixel inside the best window. Integer pixels.
- ``locate_large_thesis`` (thesis paper 2, sec. 4, steps 1-7): sub-image around the specular
  spots, the quarter of the ball chosen by the side, binarisation and Canny, a rough centre from
  the edge and the known diameter (eq. 12), then the candidate in the 15 x 15 neighbourhood
  whose circle of the known radius crosses most radial intensity jumps (eqs. 13-15).
- ``locate_subpixel`` (beyond the thesis): sub-pixel edge points of the ball silhouette along
  rays from the current centre (the integral of the normalised edge profile: exact for an
  area-sampled step), a robust geometric circle fit (Tukey-weighted, known or free radius) that
  drops rays whose edge contrast or background is spoiled (shadows, specular spots, contact
  with the trough, occluders), then a Gauss-Newton fit of an exact area-coverage edge model to
  the edge pixels of the kept rays (contrast taken against the background pixel by pixel),
  and a per-frame quality: the estimated standard error of the centre in pixels.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numba
import numpy as np

METHODS = ("subpixel", "thesis-large", "thesis-small")


@dataclasses.dataclass(frozen=True)
class Location:
    """One frame's answer: centre (px), fitted radius (px), found flag and quality."""

    x: float = math.nan
    y: float = math.nan
    r: float = math.nan
    found: bool = False
    sigma: float = math.nan  # estimated standard error of the centre (px); nan if unknown
    inlier_frac: float = math.nan  # fraction of edge rays kept by the robust fit
    reason: str = ""  # why not found
    radius_free: bool = False  # r fitted (most of the rim); False: the known radius was used

    @staticmethod
    def missing(reason: str) -> Location:
        return Location(reason=reason)


# --------------------------------------------------------------------------------------------
# helpers


def _full_scale(dtype) -> float:
    return 65535.0 if np.dtype(dtype) == np.uint16 else 255.0


class LazyFrame:
    """A frame read by regions: the locators' crops read only what they need.

    ``read(roi)`` returns the region roi = (y0, y1, x0, x1) of the frame (a FrameSource's
    ``read(i, roi)``), ``full()`` the whole frame; ``shape`` (H, W) and ``dtype`` are the
    frame's. A crop outside the region read so far reads that crop grown by ``margin`` px a side
    (the sub-pixel locator's later passes move a little), clipped to the frame. Every crop holds
    the same pixels as the same crop of the full frame, so the locators give the same answers.
    """

    ndim = 2

    def __init__(self, read, full, shape, dtype, *, margin: int = 8) -> None:
        self._read = read
        self._full = full
        self.shape = (int(shape[0]), int(shape[1]))
        self.dtype = np.dtype(dtype)
        self.margin = int(margin)
        self._box = None  # (y0, y1, x0, x1) of the region held in self._data
        self._data = None
        self.reads = 0  # region reads made (for benchmarks)

    def full(self) -> np.ndarray:
        """The whole frame (read once, then every crop is sliced from it)."""
        h, w = self.shape
        if self._box != (0, h, 0, w):
            self._data = np.asarray(self._full())
            self._box = (0, h, 0, w)
        return self._data

    def crop(self, x0: int, y0: int, x1: int, y1: int):
        """As :func:`_crop`: (frame[y0:y1, x0:x1] clipped to the frame, x0, y0 of the clip)."""
        h, w = self.shape
        x0c, y0c, x1c, y1c = max(0, x0), max(0, y0), min(w, x1), min(h, y1)
        if x1c <= x0c or y1c <= y0c:
            return None, x0c, y0c
        b = self._box
        if b is None or not (b[0] <= y0c and y1c <= b[1] and b[2] <= x0c and x1c <= b[3]):
            m = self.margin
            b = (max(0, y0c - m), min(h, y1c + m), max(0, x0c - m), min(w, x1c + m))
            data = np.asarray(self._read(b))
            if data.shape != (b[1] - b[0], b[3] - b[2]) or data.dtype != self.dtype:
                raise ValueError(f"read({b}) gave a {data.dtype} array of shape {data.shape}, "
                                 f"not {self.dtype} {(b[1] - b[0], b[3] - b[2])}")
            self._box, self._data = b, data
            self.reads += 1
        return self._data[y0c - b[0]:y1c - b[0], x0c - b[2]:x1c - b[2]], x0c, y0c


def as_array(img) -> np.ndarray:
    """The whole frame as an array (a :class:`LazyFrame` reads it)."""
    return img.full() if isinstance(img, LazyFrame) else img


def _crop(img, x0: int, y0: int, x1: int, y1: int):
    """img[y0:y1, x0:x1] clipped to the image; returns (crop, x0, y0) of the clipped box."""
    if isinstance(img, LazyFrame):
        return img.crop(x0, y0, x1, y1)
    h, w = img.shape
    x0c, y0c, x1c, y1c = max(0, x0), max(0, y0), min(w, x1), min(h, y1)
    if x1c <= x0c or y1c <= y0c:
        return None, x0c, y0c
    return img[y0c:y1c, x0c:x1c], x0c, y0c


def relative_image(frame: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Background subtraction: frame - background as float32 (signed; the thesis's relative
    image up to its sign)."""
    return frame.astype(np.float32) - background.astype(np.float32)


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
                n_candidates: int = 3) -> tuple[float, float] | None:
    """Full-frame search: a rough centre (px, good to about a pixel) of the ball of radius
    ``r_px``, or None when nothing ball-like differs from the background: the most disk-like
    of :func:`coarse_candidates`."""
    cands = coarse_candidates(frame, background, r_px, min_contrast=min_contrast,
                              n_candidates=n_candidates)
    return (cands[0][0], cands[0][1]) if cands else None


def coarse_candidates(frame: np.ndarray, background: np.ndarray, r_px: float, *,
                      min_contrast: float | None = None,
                      n_candidates: int = 3) -> list[tuple[float, float, float]]:
    """Full-frame search: up to ``n_candidates`` places (x, y, disk-likeness) where a ball of
    radius ``r_px`` may be, the most disk-like first (a harsh lamp's cast shadow of the ball on
    the backdrop is a disk too: :func:`locate_subpixel` tries them in turn).

    1. Detection at reduced resolution: frame - background (signed) averaged over cells of
       about r/3 px (the noise averages down before it is rectified), |.|, then the mean over a
       ball-sized box minus the mean over the ring around it (pixels outside the frame left
       out); the strongest few separated peaks are candidates. A candidate must exceed 10 x
       the score's noise (from the cells' median |difference|) and half ``min_contrast``.
    2. Each candidate is refined at full resolution by a matched filter (normalised
       correlation of a disk-minus-ring template of the known radius with the smoothed
       |frame - background|); the most disk-like candidate wins.

    ``min_contrast`` (DN): the mean |frame - background| over the ball that counts as a ball;
    default 1 % of full scale.
    """
    frame = as_array(frame)
    h, w = frame.shape
    if min_contrast is None:
        min_contrast = 0.01 * _full_scale(frame.dtype)
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


# --------------------------------------------------------------------------------------------
# thesis, paper 1: the small-ball locator


def locate_small_thesis(frame: np.ndarray, background: np.ndarray, *,
                        roi: tuple[int, int, int, int] | None = None, window: int = 15,
                        polarity: str = "abs") -> Location:
    """Thesis paper 1: sum the relative image over a ``window`` x ``window`` window traversing
    the sub-image ``roi`` = (x0, y0, x1, y1) (default: the whole frame); the centre is the
    brightest pixel (largest frame - background) in the window of largest sum.

    ``polarity`` of the summed relative image: "abs" (|frame - background|, default: finds a
    dark ball with a bright spot as well as a bright one), "bright" (frame - background, as
    for the thesis's bright spot) or "dark" (background - frame).
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
    if smax < 0.1 * _full_scale(frame.dtype):  # 25 DN summed over the window (8 bit)
        return Location.missing("no spot in the search region")
    half = window // 2
    sub, sx0, sy0 = _crop(rel, bx - half, by - half, bx + half + 1, by + half + 1)
    _, vmax, _, (px, py) = cv2.minMaxLoc(sub)
    return Location(x=float(px + sx0 + x0), y=float(py + sy0 + y0), found=True)


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
                        step: float = 0.025) -> Location:
    """Thesis paper 2, steps 1-7, for a ball of radius ``r_px`` (px).

    ``side`` is the sign of theta (+1 right of the bottom: the upper-left quarter is used,
    -1: the upper-right). ``guess`` is where to look for the specular spots (default: the whole
    frame via :func:`coarse_find`). ``threshold`` is the binarisation threshold on
    |frame - background| (default: Otsu's threshold on the quarter) and also the intensity jump
    that counts in step 6. Ties in step 6 are averaged.
    """
    rel_full_abs = None
    if guess is None:
        guess = coarse_find(frame, background, r_px)
        if guess is None:
            return Location.missing("no ball-like change in the frame")
    # step 1: the specular spots near the guess -> 101 x 101 (for the 10 mm ball) sub-image
    half_s = int(round(1.3 * r_px))
    fr, x0, y0 = _crop(frame, int(round(guess[0])) - half_s, int(round(guess[1])) - half_s,
                       int(round(guess[0])) + half_s + 1, int(round(guess[1])) + half_s + 1)
    if fr is None:
        return Location.missing("search region outside the frame")
    rel = relative_image(fr, background[y0:y0 + fr.shape[0], x0:x0 + fr.shape[1]])
    spots = cv2.blur(rel, (3, 3))
    _, _, _, (sx, sy) = cv2.minMaxLoc(spots)
    scx, scy = sx + x0, sy + y0
    half = int(round(r_px + 13))  # 50 for the 10 mm ball: the thesis's 101 x 101
    # step 2: background subtraction on the sub-image
    fr, x0, y0 = _crop(frame, scx - half, scy - half, scx + half + 1, scy + half + 1)
    if fr is None or min(fr.shape) < half:
        return Location.missing("ball too close to the frame border")
    rel = relative_image(fr, background[y0:y0 + fr.shape[0], x0:x0 + fr.shape[1]])
    rel_full_abs = np.abs(rel)
    # step 3: the upper-left quarter when theta > 0, the upper-right one when theta < 0
    cxl, cyl = scx - x0, scy - y0
    qy0, qy1 = max(0, cyl - half), cyl + 1
    if side >= 0:
        qx0, qx1 = max(0, cxl - half), cxl + 1
    else:
        qx0, qx1 = cxl, min(rel.shape[1], cxl + half + 1)
    quarter = rel_full_abs[qy0:qy1, qx0:qx1]
    if quarter.size < 16:
        return Location.missing("ball quarter outside the frame")
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
        return Location.missing("no ball edge in the chosen quarter")
    # step 5: rough centre from the edge and the known diameter (eq. 12)
    rcx, rcy = _circle_known_radius(ex.astype(float), ey.astype(float), r_px, float(cxl),
                                    float(cyl))
    if not (np.isfinite(rcx) and np.isfinite(rcy)):
        return Location.missing("rough centre fit failed")
    # step 6: count radial intensity jumps on circles centred in the 15 x 15 neighbourhood
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
    best = jumps.max()
    if best == 0:
        return Location.missing("no intensity jumps around the rough centre")
    win = jumps == best
    # step 7: back to frame coordinates
    return Location(x=float(cand_x[win].mean() + x0), y=float(cand_y[win].mean() + y0),
                    r=float(r_px), found=True, inlier_frac=float(best) / len(rho))


# --------------------------------------------------------------------------------------------
# the sub-pixel locator


@dataclasses.dataclass(frozen=True)
class SubpixelOptions:
    """Tuning of :func:`locate_subpixel` (defaults suit balls of 3-60 px radius)."""

    radius: str = "auto"  # "free": fit the radius too; "known": use r_px; "auto": free when
    # r_px >= 12 (enough edge points to afford it), known below
    ds: float = 0.25  # sample step along a ray (px)
    edge_half: float = 1.5  # half-width of the window integrated across the edge (px)
    level_len: float = 2.0  # length of the inside/outside level windows (px)
    min_rays: int = 12
    min_inlier_frac: float = 0.35
    max_radius_dev: float = 0.15  # fitted radius within this fraction of r_px
    tukey_c: float = 4.685
    sigma_floor: float = 0.03  # px: residual scale floor of the robust fit
    passes: int = 3
    ray_spacing: float = 1.0  # px between rays along the rim
    max_rays: int = 360
    pixel_fit: bool = True  # final Gauss-Newton fit on the edge pixels themselves
    level_smooth: int = 3  # levels averaged over 2 k + 1 neighbouring rays
    contrast_bands: tuple[float, ...] = (0.15, 0.3, 0.5)  # |contrast - median| / median kept
    min_contrast_rel: float = 0.3  # rays with a step below this x the strong rays' carry no edge
    min_arc_frac: float = 0.2  # fraction of the rim that must fit (known radius, partial arc)
    free_min_frac: float = 0.45  # free radius only when at least this fraction of the rim fits
    radius_sigma: float = 0.003  # relative uncertainty of r_px (centre error on partial arcs)
    max_sigma: float = 0.5  # px: a centre less certain than this is reported not found


def _n_rays(r_px: float, spacing: float = 2.5, most: int = 128) -> int:
    """Rays around a ball of radius r_px: about ``spacing`` px apart along the rim."""
    return int(min(most, max(48, round(2 * math.pi * r_px / spacing))))


@numba.njit(cache=True)
def _profiles(rel, cx, cy, s0, ds, ns, n):
    """Bilinear samples of rel along n rays from (cx, cy) at s0 + j ds; NaN outside rel."""
    h, w = rel.shape
    prof = np.empty((n, ns), np.float64)
    for i in range(n):
        phi = (i + 0.5) * (2.0 * np.pi / n)
        c, sn = np.cos(phi), np.sin(phi)
        for j in range(ns):
            t = s0 + j * ds
            x = cx + c * t
            y = cy + sn * t
            if x < 0.0 or y < 0.0 or x > w - 1 or y > h - 1:
                prof[i, j] = np.nan
                continue
            ix = min(int(x), w - 2)
            iy = min(int(y), h - 2)
            fx = x - ix
            fy = y - iy
            prof[i, j] = ((1 - fy) * ((1 - fx) * rel[iy, ix] + fx * rel[iy, ix + 1])
                          + fy * ((1 - fx) * rel[iy + 1, ix] + fx * rel[iy + 1, ix + 1]))
    return prof


@numba.njit(cache=True)
def _edges(prof, s0, ds, r, w, ne, nl, ksm, min_rel):
    """Per ray: the steepest step of the ball's polarity in [r - w, r + w], then the edge
    position from the integral of the normalised profile across a window of 2 ne + 2 samples
    (exact for a sampled step), with the inside/outside levels from nl samples either side.

    Rays whose step is below ``min_rel`` x the 75th percentile of the rays' steps have no
    usable contrast and are not valid.

    Returns s_edge, contrast (inside - outside, signed by polarity), outside std, valid,
    and the inside and outside levels used."""
    n, ns = prof.shape
    # polarity: inside minus outside at the ends of the band, median over rays
    diffs = np.empty(n)
    m = 0
    for i in range(n):
        a = 0.0
        b = 0.0
        for j in range(nl):
            a += prof[i, j]
            b += prof[i, ns - 1 - j]
        if np.isfinite(a) and np.isfinite(b):
            diffs[m] = (a - b) / nl
            m += 1
    s_edge = np.full(n, np.nan)
    a_used = np.full(n, np.nan)
    b_used = np.full(n, np.nan)
    con = np.full(n, np.nan)
    osd = np.full(n, np.nan)
    valid = np.zeros(n, np.bool_)
    if m < 3:
        return s_edge, con, osd, valid, a_used, b_used
    # polarity: the majority sign among the rays with a clear step (rays where the ball sits
    # in front of a region of its own level -- a cast shadow, the trough -- have none and
    # must not outvote the arc that has contrast)
    absd = np.sort(np.abs(diffs[:m]))
    tpol = 0.3 * absd[int(0.9 * (m - 1))]
    npos = 0
    nneg = 0
    for i in range(m):
        if diffs[i] > tpol:
            npos += 1
        elif diffs[i] < -tpol:
            nneg += 1
    sgn = 1.0 if npos >= nneg else -1.0
    lo = max(ne + nl, int(np.floor((r - w - s0) / ds)))
    hi = min(ns - ne - nl - 3, int(np.ceil((r + w - s0) / ds)))
    kbs = np.full(n, -1)
    a_in = np.full(n, np.nan)
    b_out = np.full(n, np.nan)
    for i in range(n):
        best = -np.inf
        kb = -1
        for k in range(lo, hi + 1):
            g = sgn * ((prof[i, k - 1] + prof[i, k]) - (prof[i, k + 1] + prof[i, k + 2]))
            if g > best:  # NaN never wins
                best = g
                kb = k
        if kb < 0:
            continue
        a = 0.0
        b = 0.0
        b2 = 0.0
        for j in range(nl):
            a += prof[i, kb - ne - 1 - j]
            v = prof[i, kb + ne + 2 + j]
            b += v
            b2 += v * v
        a /= nl
        b /= nl
        kbs[i] = kb
        a_in[i] = a
        b_out[i] = b
        osd[i] = np.sqrt(max(b2 / nl - b * b, 0.0))
    # rays with contrast: a step of at least min_rel x the typical strong ray's (the 75th
    # percentile); the others (the ball in front of a cast shadow or of anything of its own
    # level) carry no edge and are left out of the level statistics below
    fin = np.isfinite(a_in) & np.isfinite(b_out)
    if fin.sum() < 3:
        return s_edge, con, osd, valid, a_used, b_used
    cr = np.sort(sgn * (a_in[fin] - b_out[fin]))
    cref = cr[int(0.75 * (len(cr) - 1))]
    for i in range(n):
        if fin[i] and sgn * (a_in[i] - b_out[i]) < min_rel * cref:
            fin[i] = False
    if fin.sum() < 3:
        return s_edge, con, osd, valid, a_used, b_used
    # the ball's inside level: per ray, unless a spot or shading spoils it (then the median)
    a_med = np.median(a_in[fin])
    c_med = np.median(np.abs(a_in[fin] - b_out[fin]))
    sd_med = np.median(osd[fin])
    spoiled = np.abs(a_in - a_med) > 0.08 * c_med + 3.0 * sd_med
    # drop those rays when enough clean ones remain, else use the median inside level
    drop = (fin & ~spoiled).sum() >= 0.5 * fin.sum()
    # levels averaged over neighbouring rays (2 ksm + 1, clean ones only): less noise
    a_sm = np.full(n, np.nan)
    b_sm = np.full(n, np.nan)
    for i in range(n):
        sa = 0.0
        sb = 0.0
        na = 0
        nb = 0
        for j in range(-ksm, ksm + 1):
            q = (i + j) % n
            if fin[q]:
                sb += b_out[q]
                nb += 1
                if not spoiled[q]:
                    sa += a_in[q]
                    na += 1
        if na > 0:
            a_sm[i] = sa / na
        if nb > 0:
            b_sm[i] = sb / nb
    for i in range(n):
        kb = kbs[i]
        if kb < 0 or not fin[i]:
            continue
        a = a_sm[i] if np.isfinite(a_sm[i]) else a_med
        if spoiled[i]:
            if drop:
                continue
            a = a_med
        b = b_sm[i]
        c = a - b
        if c * sgn <= 0:
            continue
        acc = 0.0
        nw = 2 * ne + 2
        for j in range(nw):
            f = (prof[i, kb - ne + j] - b) / c
            acc += 0.5 * f if (j == 0 or j == nw - 1) else f
        se = s0 + (kb - ne) * ds + ds * acc
        if not np.isfinite(se) or se <= s0 + (kb - ne) * ds or se >= s0 + (kb + ne + 1) * ds:
            continue
        s_edge[i] = se
        con[i] = abs(c)
        valid[i] = True
        a_used[i] = a
        b_used[i] = b
    return s_edge, con, osd, valid, a_used, b_used


@numba.njit(cache=True)
def _solve3(m, v):
    det = (m[0, 0] * (m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1])
           - m[0, 1] * (m[1, 0] * m[2, 2] - m[1, 2] * m[2, 0])
           + m[0, 2] * (m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]))
    out = np.empty(3)
    if det == 0.0 or not np.isfinite(det):
        out[:] = np.nan
        return out
    for c in range(3):
        mm = m.copy()
        for r in range(3):
            mm[r, c] = v[r]
        out[c] = (mm[0, 0] * (mm[1, 1] * mm[2, 2] - mm[1, 2] * mm[2, 1])
                  - mm[0, 1] * (mm[1, 0] * mm[2, 2] - mm[1, 2] * mm[2, 0])
                  + mm[0, 2] * (mm[1, 0] * mm[2, 1] - mm[1, 1] * mm[2, 0])) / det
    return out


@numba.njit(cache=True)
def _fit_circle(xs, ys, r_known, free, tukey_c, sigma_floor):
    """Robust geometric circle fit: algebraic (Kasa) start, then Gauss-Newton on the
    point-to-circle distances with Tukey biweights (scale from the MAD, floored at
    sigma_floor). Returns cx, cy, r, weights, residuals."""
    n = len(xs)
    ata = np.zeros((3, 3))
    atb = np.zeros(3)
    for i in range(n):
        row = (xs[i], ys[i], 1.0)
        z = xs[i] * xs[i] + ys[i] * ys[i]
        for p in range(3):
            atb[p] += row[p] * z
            for q in range(3):
                ata[p, q] += row[p] * row[q]
    sol = _solve3(ata, atb)
    cx = 0.5 * sol[0]
    cy = 0.5 * sol[1]
    r = np.sqrt(max(sol[2] + cx * cx + cy * cy, 1e-12)) if free else r_known
    wts = np.ones(n)
    res = np.zeros(n)
    d = np.zeros(n)
    if not (np.isfinite(cx) and np.isfinite(cy)):
        return np.nan, np.nan, np.nan, wts, res
    for it in range(30):
        for i in range(n):
            d[i] = max(np.hypot(xs[i] - cx, ys[i] - cy), 1e-9)
            res[i] = d[i] - r
        good = res[wts > 0]
        if len(good) < 3:
            return np.nan, np.nan, np.nan, wts, res
        med = np.median(good)
        scale = max(1.4826 * np.median(np.abs(good - med)), sigma_floor)
        jtj = np.zeros((3, 3))
        jtr = np.zeros(3)
        wsum = 0.0
        for i in range(n):
            u = (res[i] - med) / (tukey_c * scale)
            wi = (1.0 - u * u) ** 2 if abs(u) < 1.0 else 0.0
            wts[i] = wi
            wsum += wi
            j0 = -(xs[i] - cx) / d[i]
            j1 = -(ys[i] - cy) / d[i]
            jj = (j0, j1, -1.0)
            for p in range(3):
                jtr[p] += wi * jj[p] * res[i]
                for q in range(3):
                    jtj[p, q] += wi * jj[p] * jj[q]
        if wsum < 3.0:
            return np.nan, np.nan, np.nan, wts, res
        if not free:  # 2 x 2 system
            det = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
            if det == 0.0:
                return np.nan, np.nan, np.nan, wts, res
            s0 = -(jtj[1, 1] * jtr[0] - jtj[0, 1] * jtr[1]) / det
            s1 = -(-jtj[1, 0] * jtr[0] + jtj[0, 0] * jtr[1]) / det
            s2 = 0.0
        else:
            st = _solve3(jtj, -jtr)
            s0, s1, s2 = st[0], st[1], st[2]
        if not (np.isfinite(s0) and np.isfinite(s1) and np.isfinite(s2)):
            return np.nan, np.nan, np.nan, wts, res
        cx += s0
        cy += s1
        r += s2
        if abs(s0) + abs(s1) + abs(s2) < 1e-6 and it > 1:
            break
    for i in range(n):
        res[i] = np.hypot(xs[i] - cx, ys[i] - cy) - r
    return cx, cy, r, wts, res


@numba.njit(cache=True)
def _edge_cdf(t, a, b):
    """Area of a unit pixel on the inner side of a straight edge at signed distance t from its
    centre, for an edge normal (cos, sin) with |cos| = a >= |sin| = b: the CDF of the sum of
    two uniform variables of widths a and b. Returns (coverage, density)."""
    if b < 1e-6:
        if t <= -0.5 * a:
            return 0.0, 0.0
        if t >= 0.5 * a:
            return 1.0, 0.0
        return t / a + 0.5, 1.0 / a
    lo, mid = -0.5 * (a + b), 0.5 * (a - b)
    if t <= lo:
        return 0.0, 0.0
    if t <= -mid:
        return (t - lo) ** 2 / (2 * a * b), (t - lo) / (a * b)
    if t <= mid:
        return (t + 0.5 * a) / a, 1.0 / a
    if t < -lo:
        return 1.0 - (-lo - t) ** 2 / (2 * a * b), (-lo - t) / (a * b)
    return 1.0, 0.0


@numba.njit(cache=True)
def _pixel_fit(rel, bgr, cx, cy, r, free, ray_ok, a_lv, b_lv, inset, iters):
    """Refine the circle on the pixels themselves: each pixel within 1.5 px of the rim, on a
    ray kept by the robust fit, is modelled as b + (a - b) * (area of the pixel inside the
    disk) with a straight-edge area model, levels a, b of its ray; Gauss-Newton on the centre
    (and radius). The contrast is taken pixel by pixel against the background ``bgr``: where
    the ball covers a background that changes (the trough's contour at the contact, texture),
    frame - background = b + (a + B_in - B - b) * area, B_in the background ``inset`` px
    inside the rim where the level a was measured. Uses every edge pixel once with its own
    weight, which is what the noise allows (Cramer-Rao). Rays whose pixels do not fit are
    dropped after the first pass. Returns cx, cy, r, centre standard error (px), pixels used."""
    h, w = rel.shape
    n = len(ray_ok)
    npar = 3 if free else 2
    sig = np.nan
    npix = 0
    ray_ok = ray_ok.copy()
    ray_ss = np.zeros(n)
    ray_n = np.zeros(n)
    for it in range(iters):
        jtj = np.zeros((3, 3))
        jtr = np.zeros(3)
        ss = 0.0
        npix = 0
        ray_ss[:] = 0.0
        ray_n[:] = 0.0
        x0 = max(0, int(cx - r - 2))
        x1 = min(w - 1, int(cx + r + 3))
        y0 = max(0, int(cy - r - 2))
        y1 = min(h - 1, int(cy + r + 3))
        for iy in range(y0, y1 + 1):
            for ix in range(x0, x1 + 1):
                dx = ix - cx
                dy = iy - cy
                d = np.sqrt(dx * dx + dy * dy)
                u = d - r
                if abs(u) > 1.5 or d == 0.0:
                    continue
                phi = np.arctan2(dy, dx)
                if phi < 0:
                    phi += 2 * np.pi
                k = int(phi / (2 * np.pi / n)) % n
                if not ray_ok[k]:
                    continue
                b = b_lv[k]
                jx = int(np.rint(cx + dx * (r - inset) / d))
                jy = int(np.rint(cy + dy * (r - inset) / d))
                jx = min(max(jx, 0), w - 1)
                jy = min(max(jy, 0), h - 1)
                a = a_lv[k] + bgr[jy, jx] - bgr[iy, ix]
                c = abs(dx) / d
                s_ = abs(dy) / d
                if s_ > c:
                    c, s_ = s_, c
                cov, dens = _edge_cdf(-u, c, s_)
                res = rel[iy, ix] - (b + (a - b) * cov)
                # d model / d (cx, cy, r): (a - b) * dens * (dx/d, dy/d, 1)
                g0 = (a - b) * dens * dx / d
                g1 = (a - b) * dens * dy / d
                g2 = (a - b) * dens
                gg = (g0, g1, g2)
                for p in range(3):
                    jtr[p] += gg[p] * res
                    for q in range(3):
                        jtj[p, q] += gg[p] * gg[q]
                ss += res * res
                npix += 1
                ray_ss[k] += res * res
                ray_n[k] += 1
        if npix < 20:
            return np.nan, np.nan, np.nan, np.nan, npix
        if it == 0:
            # drop rays whose pixels do not fit (shadow edges, spots): rms residual above
            # 2.5 x the typical ray's, then start again from the same circle
            used = ray_n > 0
            rr = np.sqrt(ray_ss[used] / ray_n[used])
            thr = 2.5 * np.median(rr)
            drop = 0
            for q in range(n):
                if used[q] and np.sqrt(ray_ss[q] / ray_n[q]) > thr:
                    ray_ok[q] = False
                    drop += 1
            if drop > 0:
                continue
        if free:
            st = _solve3(jtj, jtr)
            s0, s1, s2 = st[0], st[1], st[2]
        else:
            det = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
            if det == 0.0:
                return np.nan, np.nan, np.nan, np.nan, npix
            s0 = (jtj[1, 1] * jtr[0] - jtj[0, 1] * jtr[1]) / det
            s1 = (-jtj[1, 0] * jtr[0] + jtj[0, 0] * jtr[1]) / det
            s2 = 0.0
        if not (np.isfinite(s0) and np.isfinite(s1) and np.isfinite(s2)):
            return np.nan, np.nan, np.nan, np.nan, npix
        cx += s0
        cy += s1
        r += s2
        # centre standard error from the residual variance and the 2 x 2 block of J^T J
        var = ss / max(npix - npar, 1)
        det2 = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
        sig = np.sqrt(var * (jtj[0, 0] + jtj[1, 1]) / det2) if det2 > 0 else np.nan
        if abs(s0) + abs(s1) + abs(s2) < 1e-4:
            break
    return cx, cy, r, sig, npix


def _arc_leverage(rays: np.ndarray, n: int) -> float:
    """|(N^T N)^-1 N^T 1| for the unit normals N of rays ``rays`` (of n around the rim): how
    far a known-radius fit's centre moves per pixel of radius error (0 for the full rim, about
    1.3 for half of it; large for a short arc)."""
    if len(rays) < 3:
        return math.inf
    phi = (rays + 0.5) * (2.0 * math.pi / n)
    c, s = np.cos(phi), np.sin(phi)
    m = np.array([[c @ c, c @ s], [c @ s, s @ s]])
    v = np.array([c.sum(), s.sum()])
    try:
        b = np.linalg.solve(m, v)
    except np.linalg.LinAlgError:
        return math.inf
    return float(math.hypot(b[0], b[1]))


_SELECT_FAIL = {
    1: "too few edge points (ball missing, occluded or at the border)",
    2: "ball edge contrast below the noise",
    3: "too few clean edge points (shadows or occlusion)",
}


@numba.njit(cache=True)
def _select(s_edge, con, out_sd, valid, lcx, lcy, bands, min_rays, noise, floor):
    """Edge points of the clean rays: the ball's typical contrast (a tight band first, widened
    only when too few rays pass: real balls vary around the rim) and a flat outside (shadow
    gradients, spots, the trough contact and occluders fail). Returns status, xs, ys, ray index."""
    n = len(s_edge)
    empty = np.empty(0)
    iempty = np.empty(0, np.int64)
    nv = valid.sum()
    if nv < min_rays:
        return 1, empty, empty, iempty
    cmed = np.median(con[valid])
    nz = noise if noise >= 0 else np.median(out_sd[valid])
    if cmed < max(4.0 * nz, floor):
        return 2, empty, empty, iempty
    keep = np.zeros(n, np.bool_)
    for tol in bands:
        cnt = 0
        for i in range(n):
            keep[i] = (valid[i] and out_sd[i] < 0.02 * cmed + 2.5 * nz
                       and abs(con[i] - cmed) < tol * cmed + 3.0 * nz)
            cnt += keep[i]
        if cnt >= max(min_rays, 0.4 * nv):
            break
    m = keep.sum()
    if m < min_rays:
        return 3, empty, empty, iempty
    xs = np.empty(m)
    ys = np.empty(m)
    idx = np.empty(m, np.int64)
    j = 0
    for i in range(n):
        if keep[i]:
            phi = (i + 0.5) * (2.0 * np.pi / n)
            xs[j] = lcx + np.cos(phi) * s_edge[i]
            ys[j] = lcy + np.sin(phi) * s_edge[i]
            idx[j] = i
            j += 1
    return 0, xs, ys, idx


@numba.njit(cache=True)
def _fit_stats(wts, res):
    """Inliers, their median residual and weighted rms residual."""
    inl = wts > 0
    n_in = inl.sum()
    if n_in == 0:
        return 0, np.nan, np.nan
    sw = wts.sum()
    return n_in, np.median(res[inl]), np.sqrt((wts * res * res).sum() / max(sw, 1e-12))


def locate_subpixel(frame: np.ndarray, background: np.ndarray, r_px: float, *,
                    guess: tuple[float, float] | None = None, search: float | None = None,
                    opts: SubpixelOptions = SubpixelOptions(),
                    noise: float | None = None, r_known: float | None = None,
                    r_known_sigma: float | None = None) -> Location:
    """Sub-pixel centre of the ball of radius about ``r_px`` px.

    ``guess``: where the ball centre is expected (from tracking); ``search``: how far (px) the
    edge may be from the guessed circle (default 0.3 r + 2). Without a guess, a full-frame
    search (:func:`coarse_candidates`) comes first; its candidates are fitted in turn, the
    most disk-like first, and the first the fit accepts is the answer. ``noise``: pixel noise
    (DN) used to reject low-contrast rays (default: estimated from the rays).
    ``r_known``: the radius (px) a partial arc is fitted with (default ``r_px``; the tracker
    passes the ball's apparent radius calibrated from its full-rim frames), ``r_known_sigma``
    its relative uncertainty (default ``opts.radius_sigma``), which adds the arc's leverage
    times it to the centre's sigma. ``r_px`` still sets the search and the radius check.
    """
    rk = (float(r_px) if r_known is None else float(r_known),
          opts.radius_sigma if r_known_sigma is None else float(r_known_sigma))
    if guess is None:
        cands = coarse_candidates(frame, background, r_px)
        if not cands:
            return Location.missing("no ball-like change in the frame")
        # the most disk-like candidate that the fit accepts (a cast shadow may look more
        # disk-like than the ball; the fit checks the radius and the edge)
        first = None
        for cx, cy, _ in cands:
            # no prediction to check a partial arc against: the full search accepts only a
            # ball whose rim mostly fits (a cast shadow's arc would pass a partial-arc fit)
            loc = _locate_guess(frame, background, r_px, (cx, cy),
                                max(search or 0.0, 0.5 * r_px + 2), opts, noise, False, rk)
            if loc.found:
                return loc
            first = first or loc
        return first
    return _locate_guess(frame, background, r_px, guess, search, opts, noise, True, rk)


def _locate_guess(frame, background, r_px, guess, search, opts, noise, partial,
                  rk) -> Location:
    """:func:`locate_subpixel` from a guess; ``partial``: accept a known-radius fit of a
    partial arc (at least ``opts.min_arc_frac`` of the rim) near the guess; ``rk``: (radius
    of the known-radius fits, its relative uncertainty)."""
    r_kn, r_kn_sig = rk
    w = search if search is not None else 0.3 * r_px + 2.0
    w = max(w, 1.5)
    w0 = w
    h, wd = frame.shape
    cx, cy = float(guess[0]), float(guess[1])
    if not (-r_px < cx < wd - 1 + r_px and -r_px < cy < h - 1 + r_px):
        return Location.missing("predicted centre outside the frame")
    r = float(r_px)
    # window sizes scale down for small balls
    edge_half = min(opts.edge_half, max(1.5, 0.25 * r_px))
    level_len = min(opts.level_len, max(0.75, 0.2 * r_px))
    # coarse passes (rays ~2.5 px apart) until the centre settles, then one fine pass
    n_coarse = _n_rays(r_px)
    n_fine = max(n_coarse, _n_rays(r_px, opts.ray_spacing, opts.max_rays))
    fine = False
    if opts.radius not in ("auto", "free", "known"):
        raise ValueError(f"radius must be auto, free or known, got {opts.radius!r}")
    free = opts.radius == "free" or (opts.radius == "auto" and r_px >= 12)
    loc = Location.missing("no edge found")
    for p in range(opts.passes + 1):
        n = n_fine if fine else n_coarse
        ds = opts.ds if w <= 3.0 else 2 * opts.ds  # coarse sampling while the search is wide
        ne = max(2, int(round(edge_half / ds)))
        nl = max(2, int(round(level_len / ds)))
        m = (ne + nl + 3) * ds
        s0 = max(0.5, r - w - m)
        ns = int(math.ceil((r + w + m - s0) / ds)) + 1
        half = int(math.ceil(s0 + ns * ds)) + 2
        x0, y0 = int(math.floor(cx)) - half, int(math.floor(cy)) - half
        fr, x0c, y0c = _crop(frame, x0, y0, x0 + 2 * half + 2, y0 + 2 * half + 2)
        if fr is None:
            return Location.missing("ball outside the frame")
        bg = background[y0c:y0c + fr.shape[0], x0c:x0c + fr.shape[1]]
        rel = cv2.subtract(fr, bg, dtype=cv2.CV_32F)
        lcx, lcy = cx - x0c, cy - y0c
        prof = _profiles(rel, lcx, lcy, s0, ds, ns, n)
        s_edge, con, out_sd, valid, a_lv, b_lv = _edges(prof, s0, ds, r, w, ne, nl,
                                                        opts.level_smooth, opts.min_contrast_rel)
        status, xs, ys, idx = _select(s_edge, con, out_sd, valid, lcx, lcy,
                                      opts.contrast_bands, opts.min_rays,
                                      -1.0 if noise is None else float(noise),
                                      0.004 * _full_scale(frame.dtype))
        if status:
            return Location.missing(_SELECT_FAIL[status])
        # a free radius only on most of the rim: on a partial arc (the rest of the rim without
        # contrast against a shadow or the trough) the radius and the centre are confounded,
        # and the known radius is what makes the arc usable
        free_p = free and len(xs) >= opts.free_min_frac * n
        fcx, fcy, fr_, wts, res = _fit_circle(xs, ys, r_kn, free_p, opts.tukey_c,
                                              opts.sigma_floor)
        n_in, med_res, rms = _fit_stats(wts, res)
        if free_p and (n_in < opts.free_min_frac * n or not math.isfinite(fcx)):
            free_p = False
            fcx, fcy, fr_, wts, res = _fit_circle(xs, ys, r_kn, False, opts.tukey_c,
                                                  opts.sigma_floor)
            n_in, med_res, rms = _fit_stats(wts, res)
        if n_in < opts.min_rays or not math.isfinite(fcx):
            return Location.missing("robust circle fit failed")
        # the ball's radius as seen: the fitted one, or (known radius) the known one plus the
        # median offset of the edge points from that circle
        r_seen = fr_ if free_p else r_kn + med_res
        if abs(r_seen - r_px) > opts.max_radius_dev * r_px:
            return Location.missing(f"the ball's edge lies on a circle of {r_seen:.2f} px "
                                    f"radius, not {r_px:.2f} px")
        sigma = rms * math.sqrt(2.0 / n_in)
        inl = idx[wts > 0]
        if fine and opts.pixel_fit:
            ray_ok = np.zeros(n, np.bool_)
            ray_ok[inl] = True
            bgr = bg.astype(np.float32)
            pcx, pcy, pr, psig, npix = _pixel_fit(rel, bgr, fcx, fcy, fr_ if free_p else r_kn,
                                                  free_p, ray_ok, a_lv, b_lv,
                                                  (ne + 0.5 * nl + 1) * ds, 5)
            if math.isfinite(pcx) and math.hypot(pcx - fcx, pcy - fcy) < 0.5:
                fcx, fcy, sigma = pcx, pcy, psig
                if free_p:
                    r_seen = pr
        if not free_p:
            # a known radius that is off by dr moves the centre of a partial arc by |b| dr,
            # b = (N^T N)^-1 N^T 1 over the arc's unit normals N (0 on the full rim)
            sigma = math.hypot(sigma, _arc_leverage(inl, n) * r_kn_sig * r_kn)
        shift = math.hypot(fcx - lcx, fcy - lcy)
        cx, cy, r = fcx + x0c, fcy + y0c, float(r_seen)
        frac = n_in / n
        need = opts.min_inlier_frac if free_p or not partial else min(opts.min_inlier_frac,
                                                                        opts.min_arc_frac)
        if frac < need:
            ok, why = False, f"only {100 * frac:.0f} % of the edge fits a circle"
        elif not sigma <= opts.max_sigma:
            ok, why = False, f"centre uncertain ({sigma:.2f} px)"
        elif math.hypot(cx - guess[0], cy - guess[1]) > w0 + 1.0:
            ok, why = False, "the fitted circle lies outside the searched band"
        else:
            ok, why = True, ""
        loc = Location(x=cx, y=cy, r=r, found=ok, sigma=sigma, inlier_frac=frac, reason=why,
                       radius_free=bool(free_p))
        if fine:
            break
        w = min(w, max(1.5, 2.0 * shift + 1.0))
        if shift < 0.1 or p >= opts.passes - 1:
            fine = True
    return loc
