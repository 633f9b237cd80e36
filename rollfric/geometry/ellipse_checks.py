"""The measured mu checked against the ellipses the images show: the trough's contour and the
ball's path.

A trough contour that is an ellipse (a tilted camera, an out-of-round bore) implies a mu bias
either way (:func:`contour_check`); the ball's path as an ellipse tells the two apart by the
period (:func:`path_check`) and, for a tilted camera, corrects the angles. A path read either
way replaces the contour's two readings (:func:`path_replaces_contour`).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from rollfric.errors import InputError
from rollfric.fit import estimate as fitmod
from rollfric.geometry import ellipse as ell
from rollfric.geometry import pathreading
from rollfric.geometry.theta import angles

logger = logging.getLogger(__name__)

ELLIPSE_WARNING_START = "the trough's contour is an ellipse"


def contour_check(ellipse, info, t_s, th, setup, result, offset, fit_method, fit_kwargs):
    """The mu bias the contour's ellipse implies (:mod:`rollfric.geometry.ellipse`).

    Parameters
    ----------
    ellipse : rollfric.geometry.ellipse.ContourEllipse
        The trough's contour as an ellipse.
    info : rollfric.track.track_info.TrackInfo
        The track's (its ``ball_radius_px`` and ``warnings``).
    t_s, th : numpy.ndarray
        The fitted times (s) and angles (rad; NaN where left out).
    setup : rollfric.setup.model.Setup
        The setup.
    result : rollfric.fit.estimate.FitResult
        The fit of mu.
    offset : bool
        Whether the fit has the angle offset.
    fit_method : str
        The fitting method (the refit with the bottom's radius uses it).
    fit_kwargs : dict or None
        More keywords of :func:`rollfric.fit.estimate.fit_mu`.

    Returns
    -------
    info : rollfric.track.track_info.TrackInfo
        With ``contour_ellipse`` set and, when the bias exceeds ``BIAS_WARN``, its warning
        (logged too).
    coded : list of (str, str)
        The quality reason ``contour_ellipse`` when the bias exceeds ``BIAS_SUSPECT``.
    """
    out = ellipse.to_dict()
    # the swing's turning points (of the fitted curve): where the amplitude loss is measured
    swing = np.asarray(result.curve, dtype=float) - result.offset
    k = np.flatnonzero(np.diff(np.sign(np.diff(swing))) != 0) + 1
    amp = float(np.median(np.abs(swing[k]))) if len(k) else float(np.nanmax(np.abs(swing)))
    cam = ell.camera_bias(ellipse, amp)
    r_eff, f_b = ell.trough_scale(ellipse, info.ball_radius_px, amp)
    try:
        refit = fitmod.fit_mu(t_s, th, setup.replace(cylinder_radius=setup.cylinder_radius
                                                     * r_eff),
                              method=fit_method, offset=offset, **(fit_kwargs or {}))
        trough = ell.trough_bias(result.mu, refit.mu, f_b)
    except (InputError, ValueError):
        trough = math.nan
    out.update(mu_bias_if_camera=cam, mu_bias_if_trough=trough, swing_amplitude_rad=amp,
               bottom_radius_over_mean=r_eff, trough_angle_scale=f_b)
    worst = max(abs(cam), abs(trough) if math.isfinite(trough) else 0.0)
    coded, warns = [], ()
    if ellipse.significant and worst > ell.BIAS_WARN:
        msg = ell.warning_text(ellipse, cam, trough)
        logger.warning(msg)
        warns = (msg,)
        if worst > ell.BIAS_SUSPECT:
            coded.append(("contour_ellipse", msg))
    return dataclasses.replace(info, contour_ellipse=out,
                               warnings=info.warnings + warns), coded


def path_check(df, info, center, setup, result, offset, fit_method, fit_kwargs, angle):
    """The ball's path as an ellipse (:mod:`rollfric.geometry.pathreading`).

    A tilted camera that the period singles out is corrected: the angles in ``df``
    (``theta_rad``) and the fit are replaced.

    Parameters
    ----------
    df : pandas.DataFrame
        The track (its centres, times and angles).
    info : rollfric.track.track_info.TrackInfo
        The track's.
    center : tuple of float
        The trough's centre the angles are taken about (px).
    setup : rollfric.setup.model.Setup
        The setup.
    result : rollfric.fit.estimate.FitResult
        The fit of mu.
    offset : bool
        Whether the fit has the angle offset.
    fit_method : str
        The fitting method of the refits.
    fit_kwargs : dict or None
        More keywords of :func:`rollfric.fit.estimate.fit_mu`.
    angle : str
        The angle formula (:func:`rollfric.geometry.theta.angles`).

    Returns
    -------
    info : rollfric.track.track_info.TrackInfo
        With ``path_ellipse`` set, ``angle_map`` for a corrected camera, and the reading's
        warning (logged too).
    result : rollfric.fit.estimate.FitResult
        The fit, replaced for a corrected camera.
    coded : list of (str, str)
        The quality reason ``camera_orientation`` when the readings cannot be told apart and
        differ by more than ``BIAS_WARN`` of mu.
    """
    found = df["found"].to_numpy() == 1
    cx_col, cy_col = ("xu_px", "yu_px") if "xu_px" in df.columns else ("x_px", "y_px")
    x = np.where(found, df[cx_col].to_numpy(float), np.nan)
    y = np.where(found, df[cy_col].to_numpy(float), np.nan)
    t_s, th = df["t_s"].to_numpy(float), df["theta_rad"].to_numpy(float)
    L_px = setup.track_radius / setup.pixel_size

    def refit(t, theta, s):
        return fitmod.fit_mu(t, theta, s, method=fit_method, offset=offset,
                             **(fit_kwargs or {}))

    def angle_of(xx, yy):
        return angles(xx, yy, center, method=angle, track_radius_px=L_px)

    # the centre's uncertainty: the lab's center_px_u, else the contour's
    u_c = setup.u("center_px") if setup.center_px is not None else info.center_u_px
    try:
        reading = pathreading.read_path(x, y, center, t_s, th, setup, result, offset=offset,
                                      refit=refit, ball_radius_px=info.ball_radius_px,
                                      angle_of=angle_of, center_u=u_c)
    except (InputError, ValueError, np.linalg.LinAlgError) as exc:
        logger.info(f"the ball's path was not fitted as an ellipse: {exc}")
        return info, result, []
    msg = reading.message()
    coded, warns, amap = [], (), None
    if reading.verdict == "camera":
        df["theta_rad"] = np.where(found & np.isfinite(th), reading.theta_camera, th)
        result = reading.result_camera
        amap = tuple(map(tuple, reading.path.round_map(L_px)))
    elif reading.verdict == "undecided" and reading.spread > ell.BIAS_WARN:
        coded.append(("camera_orientation", msg))
    if msg is not None and (reading.verdict != "undecided" or reading.spread > ell.BIAS_WARN):
        logger.warning(msg)
        warns = (msg,)
    return dataclasses.replace(info, path_ellipse=reading.to_dict(), angle_map=amap,
                               warnings=info.warnings + warns), result, coded


def path_replaces_contour(info, coded):
    """The path's reading, decided by the period, in place of the contour's two readings.

    Parameters
    ----------
    info : rollfric.track.track_info.TrackInfo
        After :func:`path_check`.
    coded : list of (str, str)
        The quality reasons so far.

    Returns
    -------
    info : rollfric.track.track_info.TrackInfo
        Without the contour's warning when the path was read as "camera" or "trough".
    coded : list of (str, str)
        Without the reason ``contour_ellipse`` then.
    """
    if info.path_ellipse is None or info.path_ellipse["verdict"] not in ("camera", "trough"):
        return info, coded
    coded = [c for c in coded if c[0] != "contour_ellipse"]
    return dataclasses.replace(info, warnings=tuple(
        w for w in info.warnings if not w.startswith(ELLIPSE_WARNING_START))), coded
