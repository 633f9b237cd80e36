"""The cylinder (trough) centre from its contour in the background image (thesis, ch. 4).

The thesis takes the centre as the intersection of the horizontal line of maximum width of the
contour circle with the vertical line through its lowest point. Here the contour is found as
the edge points (Canny) that a RANSAC circle search (radius near R / pixel size when known)
picks out; then the thesis's rule is applied to those points, with sub-pixel averaging:

- the horizontal chords of the contour (in each row crossed steeply enough, the left and right
  contour x to sub-pixel precision, where the smoothed intensity crosses the mean of the
  levels either side): for a circle, (half-width)^2 + y^2 is linear in y and the widest chord
  lies at its vertex: yc is fitted from every chord, the exact generalisation of "the widest
  chord" that still works when only the lower half of the trough is visible;
- the vertical line through the lowest point: xc is the chords' common midpoint (median), the
  circle's axis of symmetry; the lowest point itself must be in the frame.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from rollfric.errors import InputError


class ContourError(InputError):
    """The cylinder contour cannot be found in the background image."""


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
        Contour points used.
    arc_deg : float
        Angular extent of the contour points seen (deg).
    """
    center: tuple[float, float]  # (xc, yc) px
    radius: float  # px, of the contour circle
    n_points: int  # contour points used
    arc_deg: float  # angular extent of the contour points seen


def _ransac_circle(xs, ys, r_expected, rng, iters=400, tol=2.0):
    n = len(xs)
    best = (-1.0, None)
    for _ in range(iters):
        i, j, k = rng.choice(n, 3, replace=False)
        ax, ay, bx, by, cx_, cy_ = xs[i], ys[i], xs[j], ys[j], xs[k], ys[k]
        d = 2 * (ax * (by - cy_) + bx * (cy_ - ay) + cx_ * (ay - by))
        if abs(d) < 1e-9:
            continue
        ux = ((ax * ax + ay * ay) * (by - cy_) + (bx * bx + by * by) * (cy_ - ay)
              + (cx_ * cx_ + cy_ * cy_) * (ay - by)) / d
        uy = ((ax * ax + ay * ay) * (cx_ - bx) + (bx * bx + by * by) * (ax - cx_)
              + (cx_ * cx_ + cy_ * cy_) * (bx - ax)) / d
        r = math.hypot(ax - ux, ay - uy)
        if r_expected is not None:
            if abs(r - r_expected) > 0.3 * r_expected:
                continue
            prior = math.exp(-0.5 * ((r - r_expected) / (0.05 * r_expected)) ** 2)
        else:
            prior = 1.0
        inl = np.abs(np.hypot(xs - ux, ys - uy) - r) < tol
        score = inl.sum() * prior
        if score > best[0]:
            best = (score, (ux, uy, r))
    return best[1]


def find_cylinder_center(background: np.ndarray, *, radius_px: float | None = None,
                         seed: int = 0, min_arc_deg: float = 60.0,
                         undistort=None) -> CylinderContour:
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
        :meth:`rollfric.lens.Calibration.undistort`): the chords' end points are undistorted
        and the centre and radius are those of the circle through them (least squares on the
        distances), in the undistorted image.

    Returns
    -------
    CylinderContour
        The centre, radius and support of the contour.

    Raises
    ------
    ContourError
        When no circular contour with a visible lowest point and enough arc is found.
    """
    img = background.astype(np.float32)
    img = cv2.GaussianBlur(img, (0, 0), 1.5)
    lo, hi = float(np.percentile(img, 0.5)), float(np.percentile(img, 99.5))
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
    # keep one contour (the inner side of a 2-px band may hold both sides of a thick line):
    # per row the outermost points left and right of the centre
    h, w = background.shape
    ang = np.degrees(np.arctan2(px - ux, py - uy))  # 0 at the bottom
    arc = float(np.ptp(ang)) if len(ang) else 0.0
    if len(px) < 30 or arc < min_arc_deg:
        raise ContourError(f"the cylinder contour is not visible enough in the background "
                           f"image ({len(px)} points over {arc:.0f} deg); give [cylinder] "
                           "center_px in the setup")
    if not (uy + ur <= h - 0.5 + 2.0 and np.any(np.abs(ang) < 5.0)):
        raise ContourError("the lowest point of the cylinder contour is outside the frame or "
                           "hidden; give [cylinder] center_px in the setup")
    # sub-pixel chords: in each row crossed by the contour steeply enough (tangent more than
    # 25 deg from horizontal), the left and right contour x where the smoothed intensity
    # crosses the mean of the levels 4 px either side
    chords = []
    smooth = cv2.GaussianBlur(background.astype(np.float32), (0, 0), 1.0)
    for y in np.unique(py.astype(int)):
        dy = y - uy
        if abs(dy) > ur * math.cos(math.radians(25)) or not 0 <= y < h:
            continue
        dx = math.sqrt(max(ur * ur - dy * dy, 0.0))
        xs_sub = []
        for x_guess in (ux - dx, ux + dx):
            xi = int(round(x_guess))
            if xi - 6 < 0 or xi + 6 >= w:
                break
            row = smooth[y, xi - 6:xi + 7].astype(float)
            level = 0.5 * (row[:3].mean() + row[-3:].mean())
            if abs(row[:3].mean() - row[-3:].mean()) < 4.0:
                break
            sgn = np.sign(row - level)
            k = np.flatnonzero(sgn[:-1] != sgn[1:])
            if len(k) == 0:
                break
            k = k[np.argmin(np.abs(k - 5.5))]
            xs_sub.append(xi - 6 + k + (level - row[k]) / (row[k + 1] - row[k]))
        if len(xs_sub) == 2:
            chords.append((y, xs_sub[0], xs_sub[1]))
    if len(chords) < 10:
        raise ContourError("too few horizontal chords of the cylinder contour; give "
                           "[cylinder] center_px in the setup")
    ch = np.array(chords, dtype=float)
    if undistort is not None:
        ends = np.concatenate([ch[:, [1, 0]], ch[:, [2, 0]]])
        (xc, yc), radius = fit_circle(np.asarray(undistort(ends), dtype=float))
        return CylinderContour(center=(xc, yc), radius=radius, n_points=int(len(px)),
                               arc_deg=arc)
    cy_rows, half, mid = ch[:, 0], 0.5 * (ch[:, 2] - ch[:, 1]), 0.5 * (ch[:, 1] + ch[:, 2])
    # widest chord: (half-width)^2 + y^2 = (R^2 - yc^2) + 2 yc y
    a = np.stack([np.ones_like(cy_rows), 2 * cy_rows], axis=1)
    sol, *_ = np.linalg.lstsq(a, half ** 2 + cy_rows ** 2, rcond=None)
    yc = float(sol[1])
    radius = math.sqrt(max(sol[0] + yc * yc, 0.0))
    # the vertical line through the lowest point: the chords' common midpoint
    xc = float(np.median(mid))
    return CylinderContour(center=(xc, yc), radius=radius, n_points=int(len(px)), arc_deg=arc)


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
    from scipy.optimize import least_squares

    x, y = points[:, 0], points[:, 1]
    a = np.column_stack([2 * x, 2 * y, np.ones_like(x)])
    (xc, yc, c), *_ = np.linalg.lstsq(a, x * x + y * y, rcond=None)
    r0 = math.sqrt(max(c + xc * xc + yc * yc, 0.0))
    sol = least_squares(lambda p: np.hypot(x - p[0], y - p[1]) - p[2], [xc, yc, r0],
                        xtol=1e-12, ftol=1e-12)
    return (float(sol.x[0]), float(sol.x[1])), float(sol.x[2])
