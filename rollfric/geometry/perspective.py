"""A pinhole camera's depth: the trough centre found on a contour outside the ball's plane,
moved to the ball's plane along the line of sight.

A pinhole (entrance pupil) at the working distance D from the ball's plane, its optical axis
parallel to the trough's axis and meeting the image at the principal point p: a point of the
trough's axis at depth z (in front of the ball's plane: towards the camera) is seen at

    p + (c - p) D / (D - z)

where c is where the axis is seen in the ball's plane. The trough's contour lies on an edge of
the bore (its front or back face), not in the ball's plane, so the centre of the contour's
circle is not c unless the camera looks along the trough's axis (c = p): for c - p = 131.5 px
(the thesis's framing, the axis above the frame centre), D = 0.5 m and the back edge 15 mm
behind the ball, the contour's centre is 3.9 px below c. :func:`ball_plane_center` undoes it;
the contour's radius also says the edge's depth, z = D (1 - R_px / rho), when it is not
stated (rho the contour's radius, R_px the bore radius over the pixel size at the ball: a
0.5 % error of the pixel size moves z by 0.5 % of D).
"""

from __future__ import annotations

import numpy as np


def contour_depth_from_radius(radius_px: float, bore_radius_px: float,
                              working_distance: float) -> float:
    """The depth of the edge a contour of radius ``radius_px`` is seen on.

    Parameters
    ----------
    radius_px : float
        The contour circle's radius (px).
    bore_radius_px : float
        The bore's radius at the ball's plane (cylinder radius / pixel size, px).
    working_distance : float
        Pinhole to the ball's plane (m).

    Returns
    -------
    float
        z (m): in front of (+, towards the camera) or behind (-) the ball's plane.
    """
    return float(working_distance) * (1.0 - float(bore_radius_px) / float(radius_px))


def ball_plane_center(center_px, principal_px, working_distance: float,
                      contour_depth: float) -> tuple[float, float]:
    """The trough axis in the ball's plane from the centre of a contour at depth
    ``contour_depth``.

    Parameters
    ----------
    center_px : sequence of 2 floats
        The contour circle's centre (px).
    principal_px : sequence of 2 floats
        Where the optical axis meets the image (px).
    working_distance : float
        Pinhole to the ball's plane, D (m).
    contour_depth : float
        The contour's edge in front of (+) or behind (-) the ball's plane, z (m).

    Returns
    -------
    tuple of float
        p + (center - p) (D - z) / D (px).
    """
    c = np.asarray(center_px, dtype=float)
    p = np.asarray(principal_px, dtype=float)
    out = p + (c - p) * (working_distance - contour_depth) / working_distance
    return float(out[0]), float(out[1])
