"""The trough's axis in the image: the centre the ball's angles are taken about.

The setup's ``[cylinder] center_px`` when it gives one; else the trough's contour in the
background (:func:`rollfric.geometry.trough.find_cylinder_center`), checked against the setup's
radius, at its ellipse's centre when the contour is an ellipse, and moved into the ball's plane
when the setup gives the working distance (:mod:`rollfric.geometry.perspective`).
"""

from __future__ import annotations

import dataclasses
import logging

from rollfric.geometry.ellipse import ContourEllipse
from rollfric.geometry.perspective import ball_plane_center, contour_depth_from_radius
from rollfric.geometry.trough import find_cylinder_center
from rollfric.setup.model import Setup, SetupError

logger = logging.getLogger(__name__)

# a contour whose edge points are saturated beyond this share gets a warning
SATURATED_WARN = 0.1


@dataclasses.dataclass(frozen=True)
class TroughCenter:
    """The trough's centre in the image and where it came from.

    Attributes
    ----------
    center : tuple of float
        (xc, yc) in px.
    center_u : tuple of float or None
        Its standard uncertainty (px) when found from the contour; None from the setup.
    source : str
        Where it came from, for the user ("setup center_px", or the contour's fit).
    ellipse : rollfric.geometry.ellipse.ContourEllipse or None
        The contour as an ellipse; None from the setup.
    notes : tuple of str
        Warnings about the contour (not logged here: the caller logs them after its checks).
    """

    center: tuple
    center_u: tuple | None = None
    source: str = "setup center_px"
    ellipse: ContourEllipse | None = None
    notes: tuple = ()


def trough_center(background, setup: Setup, shape, *, full_scale: float | None = None
                  ) -> TroughCenter:
    """The centre the angles are taken about: the setup's, else the background's contour.

    Parameters
    ----------
    background : numpy.ndarray
        The background image without the ball.
    setup : Setup
        The setup (center_px, cylinder radius, pixel size, lens, working distance).
    shape : tuple of int
        (T, H, W) of the recording (the principal point without a lens calibration).
    full_scale : float or None
        The camera's full scale (DN), for the contour's thresholds.

    Returns
    -------
    TroughCenter

    Raises
    ------
    rollfric.setup.model.SetupError
        The contour's radius is more than 10 % off the setup's.
    """
    if setup.center_px is not None:
        return TroughCenter(center=setup.center_px)
    R_px = setup.cylinder_radius / setup.pixel_size
    lens = setup.calibration
    contour = find_cylinder_center(background, radius_px=R_px,
                                   undistort=None if lens is None else lens.undistort,
                                   full_scale=full_scale)
    if abs(contour.radius - R_px) > 0.1 * R_px:
        raise SetupError(
            f"the setup does not fit the images: the trough contour in the background has a "
            f"radius of {contour.radius:.1f} px, the setup says {R_px:.1f} px "
            "(cylinder.radius_mm / camera.pixel_size_mm); fix those or give "
            "[cylinder] center_px")
    ellipse = contour.ellipse
    center, desc = contour.center, (
        f"contour in the background ({contour.n_points} points over "
        f"{contour.arc_deg:.0f} deg, radius {contour.radius:.1f} px, u = "
        f"({contour.center_u[0]:.2g}, {contour.center_u[1]:.2g}) px)")
    if ellipse is not None and ellipse.significant:
        # an elliptic contour (a tilted camera, an out-of-round bore) has its axis at the
        # ellipse's centre; a circle fitted to its arc sits off it (2 px low at 8 deg yaw)
        center = ellipse.center
        desc += (f", the centre of its ellipse ({center[0]:.2f}, {center[1]:.2f}) "
                 "px: the contour is an ellipse")
    if setup.working_distance is not None:
        # the contour's edge is not in the ball's plane (rollfric.geometry.perspective)
        D = setup.working_distance
        z, how = setup.contour_depth, "stated"
        if z is None:
            z, how = contour_depth_from_radius(contour.radius, R_px, D), \
                "from the contour's radius"
        h, w = shape[1:]
        pp = (lens.K[0, 2], lens.K[1, 2]) if lens is not None else \
            ((w - 1) / 2.0, (h - 1) / 2.0)
        center = ball_plane_center(center, pp, D, z)
        desc += (f", moved to the ball's plane (edge {z * 1e3:+.1f} mm, {how}; "
                 f"working distance {D * 1e3:g} mm)")
    logger.info(f"cylinder centre from the background contour: ({center[0]:.2f}, "
                f"{center[1]:.2f}) px")
    notes = ()
    if contour.saturated_fraction > SATURATED_WARN:
        notes = (f"the trough contour is saturated at {100 * contour.saturated_fraction:.0f} "
                 "% of its edge points: a clipped edge moves with the local contrast, the "
                 "contour centre may be off by a few tenths of a px beyond its uncertainty; "
                 "expose the background less or give [cylinder] center_px",)
    return TroughCenter(center=center, center_u=contour.center_u, source=desc, ellipse=ellipse,
                        notes=notes)
