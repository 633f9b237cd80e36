"""A ball's silhouette seen by a pinhole camera: an ellipse stretched away from the principal
point (:func:`silhouette_stretch`), squeezed back to a circle about its centre
(:func:`squeeze`) for the sub-pixel locator, and a point of the squeezed image taken back
(:func:`unsqueeze`)."""

from __future__ import annotations

import math

import cv2
import numpy as np


def silhouette_stretch(center_px, r_px: float, pinhole) -> tuple[float, float, float]:
    """How a pinhole camera stretches a sphere's silhouette: the ellipse's direction of
    elongation and its axis ratio.

    A sphere seen by a pinhole is bounded by the cone of sight lines tangent to it (half-angle
    beta about the line to its centre, which makes the angle alpha with the optical axis); the
    image plane cuts it in an ellipse whose major axis points away from the principal point,
    a / b = cos(beta) / sqrt(cos(alpha)^2 - sin(beta)^2), about 1 / cos(alpha) (1.3 % for a
    ball 600 px from the principal point at a focal length of 3700 px). For a ball in the
    plane parallel to the image at the working distance, sin(beta) = r_px cos(alpha) / f with
    r_px its radius over the pixel size at that plane, and b = r_px (1 + O(sin(beta)^2)).

    Parameters
    ----------
    center_px : sequence of 2 floats
        Where the ball is seen (px; the silhouette's centre will do: alpha changes by
        1e-4 rad a pixel).
    r_px : float
        The ball's radius (px) at its plane.
    pinhole : sequence of 3 floats
        Principal point x, y and focal length (px).

    Returns
    -------
    tuple of float
        The unit vector (ux, uy) from the principal point to the ball and a / b (>= 1); (1,
        0, 1) at the principal point.
    """
    px, py, f = (float(v) for v in pinhole)
    vx, vy = float(center_px[0]) - px, float(center_px[1]) - py
    rho = math.hypot(vx, vy)
    if rho < 1e-9:
        return 1.0, 0.0, 1.0
    cos2a = 1.0 / (1.0 + (rho / f) ** 2)
    sin2b = float(r_px) ** 2 * cos2a / f ** 2
    k = math.sqrt((1.0 - sin2b) / (cos2a - sin2b))
    return vx / rho, vy / rho, k


def unsqueeze(x, y, o, u, k):
    """The point (x, y) of an image squeezed by :func:`squeeze` (about ``o``, along ``u``, by
    ``k``) in the image before."""
    along = (k - 1.0) * ((x - o[0]) * u[0] + (y - o[1]) * u[1])
    return x + along * u[0], y + along * u[1]


def squeeze(img, o, u, k):
    """img resampled so that the stretch k along u about o (px, in img) is undone: the value
    at p' is img's at o + A^-1 (p' - o), A = I + (1 / k - 1) u u^T (bilinear; NaN outside)."""
    ux, uy = u
    g = k - 1.0  # A^-1 = I + (k - 1) u u^T
    m = np.array([[1.0 + g * ux * ux, g * ux * uy, 0.0],
                  [g * ux * uy, 1.0 + g * uy * uy, 0.0]])
    m[:, 2] = np.asarray(o) - m[:, :2] @ np.asarray(o)
    return cv2.warpAffine(img, m, (img.shape[1], img.shape[0]),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
