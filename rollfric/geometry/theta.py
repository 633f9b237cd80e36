"""Ball centres -> theta, the ball's angle about the trough's axis.

:func:`angles` is the formula (atan2, or the thesis's arcsin); :func:`centre_angles` is the
whole way from centres located in the recorded image: undistorted with the setup's lens
calibration (the bent outline's correction), moved by a tilted camera's map, then the angles.
The measurement (:mod:`rollfric.track.tracker`) and the uncertainty budget's re-evaluations
(:mod:`rollfric.uncertainty.budget`) both go through it.
"""

from __future__ import annotations

import numpy as np

from rollfric.errors import InputError
from rollfric.geometry.pathshape import mapped_centres

ANGLES = ("atan2", "arcsin")


def angles(x, y, center, *, method: str = "atan2", track_radius_px: float | None = None):
    """theta (rad) of ball centres about the cylinder centre.

    "atan2": atan2(x - xc, y - yc) (image y down: y > yc below the axis). "arcsin": the
    thesis's arcsin((x - xc) / L_px), L_px = (R - r) / pixel size.

    Parameters
    ----------
    x, y : array_like
        Ball centres (px).
    center : tuple of float
        (xc, yc), the cylinder axis (px).
    method : {"atan2", "arcsin"}, optional
        The formula.
    track_radius_px : float, optional
        L_px, needed by "arcsin".

    Returns
    -------
    numpy.ndarray
        theta, > 0 right of the bottom.

    Raises
    ------
    InputError
        An unknown method.
    ValueError
        "arcsin" without ``track_radius_px``.

    Examples
    --------
    A ball 100 px straight below the axis, and one 0.1 rad to its right:

    >>> import numpy as np
    >>> from rollfric import angles
    >>> x = [100.0, 100.0 + 100.0 * np.sin(0.1)]
    >>> y = [200.0, 100.0 + 100.0 * np.cos(0.1)]
    >>> angles(x, y, (100.0, 100.0)).round(6)
    array([0. , 0.1])
    >>> angles(x, y, (100.0, 100.0), method="arcsin", track_radius_px=100.0).round(6)
    array([0. , 0.1])
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    xc, yc = center
    if method == "atan2":
        return np.arctan2(x - xc, y - yc)
    if method == "arcsin":
        if not track_radius_px:
            raise ValueError("arcsin angles need track_radius_px")
        return np.arcsin(np.clip((x - xc) / track_radius_px, -1.0, 1.0))
    raise InputError(f"unknown angle method {method!r} (known: {', '.join(ANGLES)})")


def centre_angles(x, y, center, setup, *, method: str = "atan2", distorted: bool = True,
                  angle_map=None):
    """theta of ball centres located in the recorded image, and the centres it was taken from.

    With ``distorted`` and a lens calibration in ``setup``, the centres are undistorted first
    (:meth:`rollfric.setup.lens.Calibration.undistort_ball`, the ball's radius from the setup);
    with ``angle_map`` they are then moved about ``center`` by it
    (:func:`rollfric.geometry.pathshape.mapped_centres`); the angles follow (:func:`angles`,
    L_px from the setup for "arcsin").

    Parameters
    ----------
    x, y : array_like
        Ball centres (px); NaN where no ball.
    center : tuple of float
        The cylinder axis (px, in the undistorted image when there is a lens calibration).
    setup : rollfric.setup.model.Setup
        Ball and track radius, pixel size, lens calibration.
    method : {"atan2", "arcsin"}, optional
        The formula.
    distorted : bool, optional
        ``x``, ``y`` are in the recorded (distorted) image.
    angle_map : array_like or None, optional
        A 2 x 2 map about ``center`` applied before the angles (a tilted camera's compression
        undone); None: none.

    Returns
    -------
    theta : numpy.ndarray
        Angles (rad), NaN where no ball.
    x, y : numpy.ndarray
        The centres the angles were taken from (undistorted, mapped), NaN where no ball.

    Examples
    --------
    Without a lens calibration or a map, the angles of :func:`angles`:

    >>> import numpy as np
    >>> from rollfric import thesis_setup
    >>> theta, xu, yu = centre_angles([100.0, np.nan], [200.0, np.nan], (100.0, 100.0),
    ...                               thesis_setup("10mm"))
    >>> theta
    array([ 0., nan])
    """
    x = np.array(x, dtype=float)
    y = np.array(y, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y)
    lens = setup.calibration
    if distorted and lens is not None:
        # the lens bends the round outline: the fitted circle's centre is not the bent
        # image of the ball's centre
        und = lens.undistort_ball(np.stack([x[ok], y[ok]], axis=1),
                                  setup.ball_radius / setup.pixel_size)
        x[ok], y[ok] = und[:, 0], und[:, 1]
    if angle_map is not None:
        x, y = mapped_centres(x, y, center, angle_map)
    theta = np.full(x.shape, np.nan)
    theta[ok] = angles(x[ok], y[ok], center, method=method,
                       track_radius_px=setup.track_radius / setup.pixel_size)
    return theta, x, y
