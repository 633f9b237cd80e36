"""The cylinder (trough) centre from its contour in the background image (thesis, ch. 4).

The thesis takes the centre as the intersection of the horizontal line of maximum width of the
contour circle with the vertical line through its lowest point: the centre of the contour's
circle. Here that circle is found from the whole visible contour: the background's edge pixels
(Canny), the contour's circle among them by a RANSAC search (radius near R / pixel size when
known), then sub-pixel edge points along that circle's normals (the area-centre of each
profile's step) fitted by a robust circle, with the centre's uncertainty (the fit's scatter and
the edge's definition), the saturated share of the contour and its ellipse.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
from scipy.optimize import least_squares

from rollfric.errors import InputError
from rollfric.fit.hac import hac_covariance
from rollfric.geometry.ellipse import ContourEllipse, fit_ellipse


class ContourError(InputError):
    """The cylinder contour cannot be found in the background image."""


EDGE_HALF_PX = 4.0  # the transition window either side of an edge point, along the normal
PLATEAU_PX = 4.0  # beyond it, each side: the levels' straight-line fit
_STEP = 0.25  # px between samples of a profile
EDGE_LEVELS = (0.25, 0.75)  # the other edge definitions: crossings of these fractions
MAX_RECENTRE = 30  # re-centrings of the profiles' windows


@dataclasses.dataclass(frozen=True)
class CylinderContour:
    """The trough's contour circle found in a background image.

    Attributes
    ----------
    center : tuple of float
        (xc, yc), the cylinder axis in pixels.
    radius : float
        Radius of the contour circle (px).
    n_points : int
        Edge points used.
    arc_deg : float
        Angular extent of the edge points (deg).
    center_u : tuple of float
        Standard uncertainty of (xc, yc) in px: the root sum of squares of ``center_u_fit``
        and ``center_u_edge``.
    center_u_fit : tuple of float
        Type A: the circle fit's standard errors of (xc, yc) from the edge points' scatter
        (a HAC covariance over the points in their order along the contour, which neighbouring
        profiles' shared pixels correlate).
    center_u_edge : tuple of float
        Type B: what the fit cannot see, the edge's definition. The centres from the
        crossings of 25 % and 75 % of the step (:data:`EDGE_LEVELS`) instead of its
        area-centre; the largest difference taken as the half-width of a rectangular
        distribution (u = max |difference| / sqrt 3). Zero for a symmetric edge profile.
    rms_px : float
        Rms distance of the edge points from the circle (px).
    saturated_fraction : float
        Fraction of the edge points with a saturated pixel (the camera's full scale)
        within their profile: a clipped step is not a linear image of the edge, and its edge
        points move with the local contrast (by up to the blur's width); the uncertainty
        above does not cover that.
    ellipse : rollfric.geometry.ellipse.ContourEllipse or None
        The same edge points fitted as an ellipse (camera yaw/pitch or an out-of-round
        trough make the contour one).
    """
    center: tuple[float, float]
    radius: float
    n_points: int
    arc_deg: float
    center_u: tuple[float, float] = (0.0, 0.0)
    center_u_fit: tuple[float, float] = (0.0, 0.0)
    center_u_edge: tuple[float, float] = (0.0, 0.0)
    rms_px: float = 0.0
    saturated_fraction: float = 0.0
    # the same edge points fitted as an ellipse (rollfric.geometry.ellipse)
    ellipse: ContourEllipse | None = None


def _profiles(img, px, py, nx, ny, s):
    """Bilinear samples of ``img`` at (px + s nx, py + s ny): (N, len(s)); NaN off the image."""
    h, w = img.shape
    X = px[:, None] + s[None, :] * nx[:, None]
    Y = py[:, None] + s[None, :] * ny[:, None]
    out = cv2.remap(img, X.astype(np.float32), Y.astype(np.float32), cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    off = (X < 0) | (X > w - 1) | (Y < 0) | (Y > h - 1)
    return np.where(off, np.nan, out.astype(float))


def _line_fit(s, v):
    """Row-wise straight lines v = a + b s (s shared): (a, b)."""
    sm = s.mean()
    ds = s - sm
    b = (v - v.mean(axis=1, keepdims=True)) @ ds / (ds @ ds)
    a = v.mean(axis=1) - b * sm
    return a, b


def _edges(img, px, py, nx, ny, levels=()):
    """Sub-pixel edge offsets along the normals (nx, ny) from (px, py), each profile's window
    centred on (px, py): the area-centre of the normalised step (exact for any symmetric
    blur of a straight step, and for a pixel's area coverage) and, for each of ``levels``, the
    crossing of that fraction of the step nearest to it. Returns (offset, {level: offset},
    contrast, valid)."""
    a, p = EDGE_HALF_PX, PLATEAU_PX
    s = np.arange(-a - p, a + p + _STEP / 2, _STEP)
    prof = _profiles(img, px, py, nx, ny, s)
    valid = np.isfinite(prof).all(axis=1)
    prof = np.where(valid[:, None], prof, 0.0)
    inner, outer, mid = s <= -a + 1e-9, s >= a - 1e-9, np.abs(s) <= a + 1e-9
    ai, bi = _line_fit(s[inner], prof[:, inner])
    ao, bo = _line_fit(s[outer], prof[:, outer])
    sm = s[mid]
    lin = ai[:, None] + bi[:, None] * sm[None]
    lout = ao[:, None] + bo[:, None] * sm[None]
    contrast = ai - ao
    with np.errstate(divide="ignore", invalid="ignore"):
        q = (prof[:, mid] - lout) / (lin - lout)
    area = -a + (0.5 * (q[:, 1:] + q[:, :-1])).sum(axis=1) * _STEP
    out = {}
    for lev in levels:
        sgn = np.sign(q - lev)
        cross = (sgn[:, :-1] != sgn[:, 1:]) & np.isfinite(q[:, :-1]) & np.isfinite(q[:, 1:])
        # the crossing nearest the area-centre
        k = np.argmin(np.where(cross, np.abs(sm[None, :-1] + 0.5 * _STEP - area[:, None]),
                               np.inf), axis=1)
        r = np.arange(len(k))
        q0, q1 = q[r, k], q[r, k + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            off = sm[k] + _STEP * (lev - q0) / (q1 - q0)
        out[lev] = np.where(cross[r, k], off, np.nan)
    valid &= np.isfinite(area) & (np.abs(area) < a)
    return area, out, contrast, valid


def _ransac_circle(xs, ys, r_expected, rng, iters=400, tol=2.0):
    """The circle through 3 of the points (drawn ``iters`` times) with the most points within
    ``tol`` px, weighted by a prior on ``r_expected``: (x, y, r), or None. The candidates are
    drawn one by one (the generator's stream) and scored together, each with the arithmetic
    of one at a time, so the circle is that of a loop over them (the first of equal scores)."""
    n = len(xs)
    tri = np.array([rng.choice(n, 3, replace=False) for _ in range(iters)]).reshape(-1, 3)
    ax, ay, bx, by, cx_, cy_ = xs[tri[:, 0]], ys[tri[:, 0]], xs[tri[:, 1]], ys[tri[:, 1]], \
        xs[tri[:, 2]], ys[tri[:, 2]]
    d = 2 * (ax * (by - cy_) + bx * (cy_ - ay) + cx_ * (ay - by))
    ok = np.abs(d) >= 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = ((ax * ax + ay * ay) * (by - cy_) + (bx * bx + by * by) * (cy_ - ay)
              + (cx_ * cx_ + cy_ * cy_) * (ay - by)) / d
        uy = ((ax * ax + ay * ay) * (cx_ - bx) + (bx * bx + by * by) * (ax - cx_)
              + (cx_ * cx_ + cy_ * cy_) * (bx - ax)) / d
    cands = []  # (index, x, y, r, prior) of the circles scored, in the order drawn
    for m in np.flatnonzero(ok):
        x, y = float(ux[m]), float(uy[m])
        r = math.hypot(float(ax[m]) - x, float(ay[m]) - y)
        if r_expected is not None:
            if abs(r - r_expected) > 0.3 * r_expected:
                continue
            prior = math.exp(-0.5 * ((r - r_expected) / (0.05 * r_expected)) ** 2)
        else:
            prior = 1.0
        cands.append((x, y, r, prior))
    best = (-1.0, None)
    for k in range(0, len(cands), 64):  # 64 circles' distances at a time
        part = cands[k:k + 64]
        cx = np.array([c[0] for c in part])[:, None]
        cy = np.array([c[1] for c in part])[:, None]
        r = np.array([c[2] for c in part])[:, None]
        count = (np.abs(np.hypot(xs[None, :] - cx, ys[None, :] - cy) - r) < tol).sum(axis=1)
        for c, m in zip(part, count, strict=True):
            score = m * c[3]
            if score > best[0]:
                best = (score, c[:3])
    return best[1]


def find_cylinder_center(background: np.ndarray, *, radius_px: float | None = None,
                         seed: int = 0, min_arc_deg: float = 60.0,
                         undistort=None, full_scale: float | None = None) -> CylinderContour:
    """Centre (px) of the trough's contour circle in ``background``.

    Parameters
    ----------
    background : numpy.ndarray
        Background image (H, W), without the ball.
    radius_px : float, optional
        The expected contour radius (cylinder radius / pixel size), used to pick the right
        circle among the edges.
    seed : int, optional
        Seed of the RANSAC circle search.
    min_arc_deg : float, optional
        Smallest angular extent of contour points accepted (deg).
    undistort : callable, optional
        Image pixels (N, 2) -> undistorted pixels (a lens calibration's
        :meth:`rollfric.setup.lens.Calibration.undistort`): the chords' end points are undistorted
        and the centre and radius are those of the circle through them (least squares on the
        distances), in the undistorted image.
    full_scale : float, optional
        The camera's full scale, 2**bit_depth - 1 (DN): a pixel at it is saturated (4095 for
        a 12-bit camera's frames in 16-bit words); default the image type's largest value.

    Returns
    -------
    CylinderContour
        The centre, radius and support of the contour.

    Raises
    ------
    ContourError
        When no circular contour with a visible lowest point and enough arc is found.
    """
    xs, ys = _edge_pixels(background)
    ux, uy, ur, px, py = _contour_circle(xs, ys, background.shape, radius_px, seed, min_arc_deg)
    bx, by, nx, ny, off, area, level_off, ok = _subpixel_edges(background, ux, uy, ur, px, py)

    def points(o):
        pts = np.stack([bx + o * nx, by + o * ny], axis=1)
        return np.asarray(undistort(pts), dtype=float) if undistort is not None else pts

    pts = points(off + area)
    fit = _robust_circle(pts, ok)
    if fit is None:
        raise ContourError("the sub-pixel edge points of the cylinder contour do not lie on a "
                           "circle; give [cylinder] center_px in the setup")
    (xc, yc), radius, keep, res = fit
    arc_used = float(np.degrees(np.ptp(np.arctan2(nx[keep], ny[keep]))))  # 0 at the bottom
    u_fit = _fit_uncertainty(pts[keep], res[keep], xc, yc)
    # Type B: the centre with the edge defined by other crossings of the step
    diffs = []
    for lev in EDGE_LEVELS:
        o = level_off[lev]
        use = keep & np.isfinite(o)
        if use.sum() < 30:
            continue
        (xl, yl), _ = fit_circle(points(off + np.where(np.isfinite(o), o, 0.0))[use])
        diffs.append((xl - xc, yl - yc))
    dmax = np.max(np.abs(diffs), axis=0) if diffs else np.zeros(2)
    u_edge = tuple(float(v / math.sqrt(3.0)) for v in dmax)
    u = tuple(float(math.hypot(a, b)) for a, b in zip(u_fit, u_edge, strict=True))
    saturated = _saturated_fraction(background, full_scale, (bx + off * nx)[keep],
                                    (by + off * ny)[keep], nx[keep], ny[keep])
    # the kept edge points, in their order along the contour, fitted as an ellipse
    order = np.argsort(np.arctan2(nx[keep], ny[keep]))
    ellipse = fit_ellipse(pts[keep][order])
    return CylinderContour(center=(float(xc), float(yc)), radius=float(radius),
                           n_points=int(keep.sum()), arc_deg=arc_used, center_u=u,
                           center_u_fit=u_fit, center_u_edge=u_edge,
                           rms_px=float(np.sqrt(np.mean(res[keep] ** 2))),
                           saturated_fraction=saturated, ellipse=ellipse)


def _edge_pixels(background):
    """The background's edge pixels (x, y): Canny on the image blurred by 1.5 px and
    stretched to 8 bits between its 0.5th and 99.5th percentiles, the thresholds a quarter
    and half of the gradient's 99.9th percentile."""
    img = background.astype(np.float32)
    img = cv2.GaussianBlur(img, (0, 0), 1.5)
    lo, hi = (float(v) for v in np.percentile(img, [0.5, 99.5]))  # one partition, the same
    if hi - lo <= 0:
        raise ContourError("background image is flat: no cylinder contour visible; give "
                           "[cylinder] center_px in the setup")
    img8 = np.clip((img - lo) * (255.0 / (hi - lo)), 0, 255).astype(np.uint8)
    gx = cv2.Sobel(img8, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(img8, cv2.CV_32F, 0, 1)
    mag = cv2.magnitude(gx, gy)
    gmax = float(np.percentile(mag, 99.9))
    if gmax < 8:
        raise ContourError("background image has no clear edges: no cylinder contour visible; "
                           "give [cylinder] center_px in the setup")
    edges = cv2.Canny(img8, 0.25 * gmax, 0.5 * gmax, L2gradient=True)
    ys, xs = np.nonzero(edges)
    if len(xs) < 50:
        raise ContourError("too few edge points in the background image to find the cylinder "
                           "contour; give [cylinder] center_px in the setup")
    return xs, ys


def _contour_circle(xs, ys, shape, radius_px, seed, min_arc_deg):
    """The contour's circle among the edge pixels (xs, ys): a RANSAC search (at most 20000 of
    them drawn with ``seed``), then the edge pixels within 2 px of it. Returns its centre,
    radius and those pixels; :class:`ContourError` where it spans less than ``min_arc_deg``
    or its lowest point is outside the frame (of ``shape``) or hidden."""
    rng = np.random.default_rng(seed)
    if len(xs) > 20000:
        pick = rng.choice(len(xs), 20000, replace=False)
        xs_s, ys_s = xs[pick].astype(float), ys[pick].astype(float)
    else:
        xs_s, ys_s = xs.astype(float), ys.astype(float)
    circ = _ransac_circle(xs_s, ys_s, radius_px, rng)
    if circ is None:
        raise ContourError("no circular contour of the expected radius "
                           f"({radius_px:.0f} px) in the background image; give [cylinder] "
                           "center_px in the setup" if radius_px else
                           "no circular contour in the background image; give [cylinder] "
                           "center_px in the setup")
    ux, uy, ur = circ
    d = np.hypot(xs - ux, ys - uy)
    inl = np.abs(d - ur) < 2.0
    px, py = xs[inl].astype(float), ys[inl].astype(float)
    h, w = shape
    ang = np.degrees(np.arctan2(px - ux, py - uy))  # 0 at the bottom
    arc = float(np.ptp(ang)) if len(ang) else 0.0
    if len(px) < 30 or arc < min_arc_deg:
        raise ContourError(f"the cylinder contour is not visible enough in the background "
                           f"image ({len(px)} points over {arc:.0f} deg); give [cylinder] "
                           "center_px in the setup")
    if not (uy + ur <= h - 0.5 + 2.0 and np.any(np.abs(ang) < 5.0)):
        raise ContourError("the lowest point of the cylinder contour is outside the frame or "
                           "hidden; give [cylinder] center_px in the setup")
    return ux, uy, ur, px, py


def _subpixel_edges(background, ux, uy, ur, px, py):
    """Sub-pixel edge points along the normals of the circle (ux, uy, ur), one per px of arc
    where the edge pixels (px, py) lie: the base points and normals (bx, by, nx, ny), each
    profile's window offset, the edge's offset in it, the offsets of the other crossings
    (:data:`EDGE_LEVELS`) and which points have a step of the contour's polarity."""
    smooth = cv2.GaussianBlur(background.astype(np.float32), (0, 0), 1.0)
    step = 1.0 / ur
    k = np.unique(np.round(np.arctan2(py - uy, px - ux) / step).astype(int))
    phi = k * step
    nx, ny = np.cos(phi), np.sin(phi)
    bx, by = ux + ur * nx, uy + ur * ny
    off = np.zeros_like(phi)
    # each profile's window re-centred on its own edge until it sits on it (a window off
    # centre sees the blurred step's tails unequally and finds only part of the offset)
    for _ in range(MAX_RECENTRE):
        area, _, _, ok = _edges(smooth, bx + off * nx, by + off * ny, nx, ny)
        off = np.where(ok, off + area, off)
        if not ok.any() or np.max(np.abs(area[ok])) < 1e-4:
            break
    area, level_off, contrast, ok = _edges(smooth, bx + off * nx, by + off * ny, nx, ny,
                                           EDGE_LEVELS)
    sign = np.sign(np.median(contrast[ok])) if ok.any() else 1.0
    ok &= sign * contrast >= 0.3 * np.median(np.abs(contrast[ok])) if ok.any() else ok
    if ok.sum() < 30:
        raise ContourError("too few sub-pixel edge points of the cylinder contour; give "
                           "[cylinder] center_px in the setup")
    return bx, by, nx, ny, off, area, level_off, ok


def _fit_uncertainty(pts, res, xc, yc):
    """Type A: the standard errors of the centre (xc, yc) of the circle fitted to ``pts`` (in
    their order along the contour, residuals ``res``), from the points' scatter: the larger of
    the ordinary and the HAC covariance (neighbouring points share pixels)."""
    d = np.hypot(pts[:, 0] - xc, pts[:, 1] - yc)
    jac = np.stack([-(pts[:, 0] - xc) / d, -(pts[:, 1] - yc) / d,
                    -np.ones_like(d)], axis=1)
    ordinary, hac, _, _ = hac_covariance(jac, res)
    var = np.maximum(np.diag(hac)[:2], np.diag(ordinary)[:2])
    return tuple(float(math.sqrt(v)) if math.isfinite(v) else math.inf for v in var)


def _saturated_fraction(background, full_scale, bx, by, nx, ny):
    """The fraction of the edge points (bx, by; normals nx, ny) with a pixel at the camera's
    ``full_scale`` (default the image type's largest value) within their profile."""
    if full_scale is None and np.issubdtype(background.dtype, np.integer):
        full_scale = float(np.iinfo(background.dtype).max)
    if full_scale is None:
        return 0.0
    top = (background >= full_scale).astype(np.float32)
    if not top.any():
        return 0.0
    a = EDGE_HALF_PX + PLATEAU_PX
    prof = _profiles(top, bx, by, nx, ny, np.arange(-a, a + 0.5, 1.0))
    return float(np.mean(np.nan_to_num(prof).max(axis=1) > 0))


def _robust_circle(pts, ok):
    """The circle through ``pts[ok]`` with outliers (beyond 5 robust sigmas of the distances,
    at least 0.05 px) left out: ((xc, yc), radius, kept mask, residuals) or None."""
    keep = ok.copy()
    for _ in range(4):
        if keep.sum() < 30:
            return None
        (xc, yc), r = fit_circle(pts[keep])
        res = np.hypot(pts[:, 0] - xc, pts[:, 1] - yc) - r
        res = np.where(ok, res, np.inf)
        mad = 1.4826 * np.median(np.abs(res[keep] - np.median(res[keep])))
        new = ok & (np.abs(res) < max(5.0 * mad, 0.05))
        if np.array_equal(new, keep):
            break
        keep = new
    if keep.sum() < 30:
        return None
    (xc, yc), r = fit_circle(pts[keep])
    res = np.hypot(pts[:, 0] - xc, pts[:, 1] - yc) - r
    return (xc, yc), r, keep, res


def fit_circle(points: np.ndarray) -> tuple[tuple[float, float], float]:
    """Centre and radius of the circle through ``points`` (N, 2): the algebraic (Kasa) fit,
    polished by least squares on the points' distances to the circle.

    Parameters
    ----------
    points : numpy.ndarray
        (N, 2) points (px), N >= 3.

    Returns
    -------
    tuple
        ((xc, yc), radius) in px.
    """
    x, y = points[:, 0], points[:, 1]
    a = np.column_stack([2 * x, 2 * y, np.ones_like(x)])
    (xc, yc, c), *_ = np.linalg.lstsq(a, x * x + y * y, rcond=None)
    r0 = math.sqrt(max(c + xc * xc + yc * yc, 0.0))
    sol = least_squares(lambda p: np.hypot(x - p[0], y - p[1]) - p[2], [xc, yc, r0],
                        xtol=1e-12, ftol=1e-12)
    return (float(sol.x[0]), float(sol.x[1])), float(sol.x[2])
