"""The trough and the camera as built: the budget's rows for what the fit assumes ideal.

The fit takes the trough as a level circular bore filmed square-on. Four ways a real rig
differs, none corrected by these rows (each is one bias of unknown size within a tolerance,
or seen by the images and read two ways):

- **the axis tilted along its length** (``cylinder.tilt_deg`` with ``tilt_deg_u``): the ball
  also rolls along the axis and the rolling resistance, opposing the whole velocity, acts in
  the swing's plane only with the share |v_theta| / |v|: mu is biased low, about as tilt^2
  and growing with the record's length (:func:`tilted_motion`, :func:`tilt_bias`). The images
  show nothing of it with a camera looking along the axis, so only a stated tolerance enters.
- **an out-of-round bore**: seen in the trough's contour or the ball's path (then read below),
  else a stated tolerance ``cylinder.ovality_mm_u``, orientation unknown: the worse of the
  major axis horizontal and vertical, by re-fitting with R at the bottom's radius of
  curvature and the bore's angle slope (as :func:`rollfric.geometry.ellipse_checks.contour_check`
  does; a diagonal axis moves only the bottom, which the offset takes).
- **the camera yawed or pitched** against the trough's axis: seen as the same ellipse, else a
  stated tolerance ``camera.yaw_deg_u`` / ``pitch_deg_u``: the angles seen through the
  compressed image fitted again (:func:`camera_tilt_bias`; quadratic and one-signed). Where
  the lab states neither (``yaw_deg_u = 0`` states a camera square on, exactly) and the
  ball's path (or the trough's contour) is round within its noise, the tilt it cannot
  exclude (:meth:`rollfric.geometry.pathshape.PathEllipse.tilt_bound_deg`) enters instead,
  the worse of a yaw and a pitch (:data:`TURN`): a short arc tells a few degrees from none
  only weakly, and a 4 deg yaw moves mu by -0.24 %.
- **an ellipse seen** in the path (:mod:`rollfric.geometry.pathreading`) or the contour: the
  camera's and the bore's readings. Where the data cannot tell them apart, both enter: the two
  readings equally likely, u(mu) is the root mean square of mu's differences from them (a
  single reading: the whole difference). A camera the period singled out is corrected; its
  row is the correction's own uncertainty.

A stated value beside the tolerance (``tilt_deg = 0.02``) is not corrected either: the row
takes the bias at |value| + u. A quantity without value and ``_u`` is listed among the
budget's exact inputs (the trough level, round, the camera square on it).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.integrate import solve_ivp

from rollfric.fit import eom
from rollfric.fit.air import coefficients_of
from rollfric.fit.eom import drag_accel
from rollfric.geometry import ellipse as ell
from rollfric.geometry.pathreading import swing_amplitude
from rollfric.setup.model import LAB_KEYS, Setup
from rollfric.uncertainty.measured import Measurement
from rollfric.uncertainty.sensitivity import Refitter

TILT = "cylinder.tilt_deg"
OVALITY = "cylinder.ovality_mm"
YAW = "camera.yaw_deg"
PITCH = "camera.pitch_deg"
PATH = "as built: path ellipse"  # the ball's path read as a camera's tilt or a bore
CONTOUR = "as built: contour ellipse"  # the trough's contour read alike
TURN = "as built: camera turn"  # the yaw or pitch a round path cannot exclude
SOURCES = (TILT, OVALITY, YAW, PITCH, PATH, CONTOUR, TURN)

# a path's bound beyond this is no bound: the budget's row takes the bias at this tilt
MAX_TURN_DEG = 45.0

TILT_NOTE = ("the ball also rolls along the tilted axis (from rest at the record's start); "
             "mu biased low, as tilt^2 and the record's length: not corrected, u(mu) the bias "
             "at |tilt| + u")


# speed (m/s) below which the resistance grows linearly with the speed instead of keeping its
# full size: a thousandth of the swing's speeds, a fraction of a millisecond near each turning
# point
V_EPS = 1e-4


def tilted_motion(theta0: float, omega0: float, mu: float, t, *, track_radius: float,
                  gravity: float, tilt: float, mu1: float = 0.0, air=None):
    """The swing in a trough whose axis is tilted by ``tilt``: (theta, axial speed) at ``t``.

    In the trough's frame gravity is g (0, -cos tilt, sin tilt). The ball's centre moves on
    the cylinder of radius L = ``track_radius``: theta about the axis and z along it, both
    rolling (inertia 7/5 m, plus the air's added mass), the rolling resistance mu N (N the
    normal force, m g cos(tilt) cos(theta) + m L theta'^2) and the air's drag opposing the
    centre's whole velocity v = (L theta', z'): the swing feels the share L theta' / |v| of
    them. It starts at ``t[0]`` at rest along the axis (z' = 0). Left out: the ball's spin
    about the contact normal, which couples the two motions (MuJoCo and PyBullet drift 1.8 %
    less). At ``tilt`` = 0 this is :func:`rollfric.fit.eom.solve`'s motion.

    Parameters
    ----------
    theta0, omega0 : float
        Angle (rad) and angular speed (rad/s) at ``t[0]``.
    mu : float
        The rolling-resistance coefficient (M = mu r N).
    t : array_like
        Increasing times, s.
    track_radius : float
        L = R - r, m.
    gravity : float
        m/s^2.
    tilt : float
        The axis's tilt along its length, rad.
    mu1 : float
        Speed coefficient, mu + mu1 |v| / L (as the fit's velocity model).
    air : array_like or None
        The air's coefficients (:func:`rollfric.fit.air.coefficients_of`); None: no air.

    Returns
    -------
    theta : numpy.ndarray
        The angle about the axis, rad.
    axial_speed : numpy.ndarray
        z', m/s (towards the lower end).

    Raises
    ------
    RuntimeError
        If the integrator fails.
    """
    t = np.asarray(t, dtype=float)
    if tilt == 0.0:  # the level trough: the fit's own motion, exact at its turning points
        theta, _, _ = eom.solve_reference(theta0, omega0, mu, t, track_radius=track_radius,
                                          gravity=gravity, mu1=mu1, air=air)
        return theta, np.zeros_like(theta)
    a = np.zeros(6) if air is None else np.asarray(air, dtype=float)
    L, g = float(track_radius), float(gravity)
    gb = g * (1.0 - a[0])  # buoyancy
    inertia = 1.4 + a[1]  # (7/5 + added mass) m
    ct, st = math.cos(tilt), math.sin(tilt)

    def rhs(_, y):
        th, om, w = y
        v_th = L * om
        v = math.hypot(v_th, w)
        n = gb * ct * math.cos(th) + (1.0 + a[1]) * L * om * om
        loss = (mu + mu1 * v / L) * n + drag_accel(v, a[2], a[3], a[4], a[5])
        # the resistance's direction, regularised below V_EPS: a Coulomb law's sign flips
        # where the axial drift stops at a turning point, or where the ball comes to rest,
        # made the integrator's steps vanish
        vr = max(v, V_EPS)
        s_th, s_z = v_th / vr, w / vr
        return [om, (-gb * ct * math.sin(th) - loss * s_th) / (inertia * L),
                (gb * st - loss * s_z) / inertia]

    sol = solve_ivp(rhs, (t[0], t[-1]), [theta0, omega0, 0.0], method="DOP853", t_eval=t,
                    rtol=1e-10, atol=1e-12)
    if not sol.success:
        raise RuntimeError(f"the tilted trough's motion was not integrated: {sol.message}")
    return sol.y[0], sol.y[2]


def tilt_bias(meas: Measurement, result, setup: Setup, params: dict, tilt: float, *,
              fit_length: bool = False) -> tuple[float, int]:
    """The relative mu bias a trough tilted by ``tilt`` (rad) gives this measurement.

    The fitted motion (``params``: the nominal re-fit's mu, start, offset, L) is made again
    with the tilt (:func:`tilted_motion`, from rest along the axis at the first fitted sample)
    at the fitted samples' times and fitted again as the budget fits (a
    :class:`rollfric.uncertainty.sensitivity.Refitter`, level trough).

    Parameters
    ----------
    meas : Measurement
        The measurement.
    result : FitResult
        Its least-squares fit.
    setup : Setup
        The setup the budget uses.
    params : dict
        The nominal re-fit's parameters.
    tilt : float
        rad.
    fit_length : bool
        L is fitted (then ``params["length"]`` is the motion's L).

    Returns
    -------
    bias : float
        mu fitted to the tilted motion / mu - 1 (negative).
    n_refits : int
        Re-fits made (1).
    """
    t, th = meas.series(setup)
    refit = Refitter(meas, result, fit_length=fit_length)
    mask = refit.mask
    L = params.get("length", setup.track_radius)
    off = params.get("offset", 0.0)
    th_tilt, _ = tilted_motion(params["theta0"] - off, params["omega0"], params["mu"],
                               t[mask], track_radius=L, gravity=setup.gravity, tilt=tilt,
                               mu1=params.get("mu1", 0.0), air=coefficients_of(setup))
    syn = np.full(t.shape, np.nan)
    syn[mask] = th_tilt + off
    tilted = Refitter(Measurement(setup=setup, t=t, theta=syn), result, fit_length=fit_length)
    mu_tilt = tilted.mu(setup)
    return mu_tilt / params["mu"] - 1.0, tilted.count


def ovality_bias(refit: Refitter, setup: Setup, mu: float, ovality: float,
                 amplitude: float) -> tuple[float, float]:
    """The relative mu bias of a bore ``ovality`` out of round, major axis horizontal and
    vertical: each a re-fit with R at the bottom's radius of curvature, divided by the bore's
    angle slope (:func:`rollfric.geometry.ellipse.trough_scale`).

    Parameters
    ----------
    refit : Refitter
        The budget's re-fitter.
    setup : Setup
        The setup the budget uses (its R the bore's mean radius).
    mu : float
        The nominal mu.
    ovality : float
        D_max - D_min, m.
    amplitude : float
        The swing's typical turning-point angle, rad.

    Returns
    -------
    tuple of float
        The biases (mu as measured / the bore's reading - 1) with the major axis horizontal
        and vertical.
    """
    R, r = setup.cylinder_radius, setup.ball_radius
    out = []
    for angle in (0.0, 90.0):
        bore = ell.ContourEllipse(center=(0.0, 0.0), semi_axes=(R + ovality / 4,
                                                                R - ovality / 4),
                                  angle_deg=angle, rms_px=0.0, n_points=0)
        r_eff, f_b = ell.trough_scale(bore, r, amplitude)
        mu_refit = refit.mu(setup.replace(cylinder_radius=R * r_eff))
        out.append(ell.trough_bias(mu, mu_refit, f_b))
    return out[0], out[1]


def camera_tilt_bias(meas: Measurement, result, setup: Setup, params: dict, angle: float, *,
                     pitch: bool, fit_length: bool = False) -> tuple[float, int]:
    """The relative mu bias of a camera pitched (``pitch``) or yawed by ``angle`` (rad)
    against the trough's axis, orthographic: the measured angles seen through the image
    compressed by cos(angle) across the tilt axis (about the fitted bottom) and fitted again
    (the compression's slope at the turning points, :func:`rollfric.geometry.ellipse.camera_bias`,
    and its change of the swing's shape).

    Parameters
    ----------
    meas : Measurement
        The measurement.
    result : FitResult
        Its least-squares fit.
    setup : Setup
        The setup the budget uses.
    params : dict
        The nominal re-fit's parameters (its ``offset`` is the bottom's angle).
    angle : float
        The camera's yaw or pitch, rad.
    pitch : bool
        A pitch (the image compressed vertically), else a yaw (horizontally).
    fit_length : bool
        L is fitted.

    Returns
    -------
    bias : float
        mu fitted to the compressed angles / mu - 1 (+ for a pitch, - for a yaw).
    n_refits : int
        Re-fits made (1).
    """
    t, th = meas.series(setup)
    off = params.get("offset", 0.0)
    c = math.cos(angle)
    seen = np.arctan2(np.sin(th - off) * (1.0 if pitch else c),
                      np.cos(th - off) * (c if pitch else 1.0)) + off
    refit = Refitter(Measurement(setup=setup, t=t, theta=seen), result, fit_length=fit_length)
    return refit.mu(setup) / params["mu"] - 1.0, refit.count


def two_readings_u(mu: float, readings) -> float:
    """u of mu when the truth is one of ``readings``, equally likely: the root mean square of
    mu's differences from them (one reading: the whole difference).

    Parameters
    ----------
    mu : float
        mu as reported.
    readings : iterable of float or None
        The possible values of the truth (None or NaN: left out).

    Returns
    -------
    float
        u(mu); 0 without a reading.

    Examples
    --------
    >>> from rollfric.uncertainty.asbuilt import two_readings_u
    >>> round(two_readings_u(1.0, [0.97, 1.04]), 6)  # sqrt((0.03^2 + 0.04^2) / 2)
    0.035355
    """
    d = [mu - m for m in readings if m is not None and math.isfinite(m)]
    return float(math.sqrt(sum(x * x for x in d) / len(d))) if d else 0.0


@dataclasses.dataclass(frozen=True)
class AsBuilt:
    """The as-built rows of one budget: ``rows`` (budget Rows as tuples (source, value, u,
    sensitivity, u_mu, note)), ``exact`` (the keys taken as exact), ``n_refits``."""

    rows: tuple
    exact: tuple
    n_refits: int


def _stated(setup: Setup, field: str) -> tuple[float, float, float]:
    """(value, u, bound |value| + u) of an as-built field, in its lab unit."""
    _, _, scale = LAB_KEYS[field]
    value = getattr(setup, field) * scale
    u = (setup.u(field) or 0.0) * scale
    return value, u, abs(value) + u


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


def _text(v) -> str:
    """A reading of mu as text, "?" where it could not be made."""
    return f"{v:.6g}" if _finite(v) else "? (not made)"


def _seen_rows(meas: Measurement, mu: float):
    """The row of an ellipse the measurement saw (path first, then contour), or None."""
    seen = meas.as_built or {}
    pe = seen.get("path_ellipse")
    if pe is not None and pe.get("verdict") in ("camera", "trough", "undecided"):
        m0, cam, tr = pe.get("mu_as_measured"), pe.get("mu_if_camera"), pe.get("mu_if_trough")
        if not m0:
            return None
        readings = [v for v in (cam, tr) if _finite(v)]
        if pe["verdict"] == "camera":
            # corrected: mu is the camera's reading; the correction scales with the path's
            # anisotropy, which the conic fit knows to 1 / sqrt(chi2) of itself
            u = abs(cam - m0) / math.sqrt(max(pe.get("chi2") or 0.0, 1.0)) * mu / cam
            note = (f"camera yawed/pitched by {pe['tilt_deg_if_camera']:.2g} deg, singled out "
                    "by the period and corrected; u: the correction over sqrt(chi2) of the "
                    "path's anisotropy")
        elif pe["verdict"] == "trough" and _finite(tr):
            u = two_readings_u(m0, [tr]) * mu / m0
            note = ("the bore is out of round (the period agrees with the path's bottom "
                    f"curvature): mu left as measured, the bore's reading {tr:.6g}; u: the "
                    "whole difference")
        elif readings:  # undecided, or a bore whose own reading could not be made
            u = two_readings_u(m0, readings) * mu / m0
            note = (f"both readings: {_text(cam)} if the camera is yawed/pitched, {_text(tr)} "
                    "if the bore is out of round (the period cannot tell which), equally "
                    "likely; u: the rms of mu's differences from them")
        else:
            return None
        return (PATH, None, u, None, u, note)
    ce = seen.get("contour_ellipse")
    if ce is not None and ce.get("significant"):
        cam, tr = ce.get("mu_bias_if_camera"), ce.get("mu_bias_if_trough")
        readings = [mu / (1.0 + b) for b in (cam, tr) if b is not None and math.isfinite(b)]
        u = two_readings_u(mu, readings)
        note = ("both readings of the trough's elliptic contour: mu biased "
                f"{100 * cam:+.3g} % if the camera is yawed/pitched, "
                + (f"{100 * tr:+.3g} %" if tr is not None and math.isfinite(tr) else "?")
                + " if the bore is out of round, equally likely; u: the rms of mu's "
                "differences from them")
        return (CONTOUR, None, u, None, u, note)
    return None


def _turn_row(meas: Measurement, result, setup: Setup, params: dict, fit_length: bool):
    """The row of the camera's yaw or pitch that a round path or contour cannot exclude (the
    tighter of their bounds), and the re-fits made; None without one (neither fitted, or an
    ellipse seen)."""
    seen = meas.as_built or {}
    pe, ce = seen.get("path_ellipse"), seen.get("contour_ellipse")
    bounds = {}
    if pe is not None and pe.get("verdict") == "round" and _finite(pe.get("tilt_deg_bound")):
        bounds["ball's path"] = pe["tilt_deg_bound"]
    if ce is not None and not ce.get("significant") and _finite(ce.get("tilt_deg_bound")):
        bounds["trough's contour"] = ce["tilt_deg_bound"]  # a long arc: often the tighter
    if not bounds:
        return None
    by = min(bounds, key=bounds.get)
    bound = bounds[by]
    angle = math.radians(min(bound, MAX_TURN_DEG))
    biases = []
    for pitch in (False, True):
        try:
            biases.append(camera_tilt_bias(meas, result, setup, params, angle, pitch=pitch,
                                           fit_length=fit_length)[0])
        except (ValueError, RuntimeError):
            biases.append(math.nan)
    worst = max(abs(b) for b in biases) if all(map(math.isfinite, biases)) else math.inf
    at = "" if bound <= MAX_TURN_DEG else f" (taken at {MAX_TURN_DEG:g} deg)"
    note = (f"the {by} is round within its noise, so the camera may be yawed or pitched up "
            f"to {bound:.2g} deg (its ellipse at one standard uncertainty): the worse of a yaw "
            f"({100 * biases[0]:+.3g} %) and a pitch ({100 * biases[1]:+.3g} %){at}, not "
            "corrected; state camera.yaw_deg_u and pitch_deg_u to replace it")
    return (TURN, None, bound, None, worst * params["mu"], note), 2


def as_built_rows(meas: Measurement, result, refit: Refitter, setup: Setup, params: dict, *,
                  fit_length: bool = False) -> AsBuilt:
    """The budget's rows of the trough and camera as built (the module's docstring).

    Parameters
    ----------
    meas : Measurement
        The measurement (its ``as_built``: the ellipses the measurement saw).
    result : FitResult
        Its least-squares fit.
    refit : Refitter
        The budget's re-fitter (the ovality's re-fits are made with it).
    setup : Setup
        The setup the budget uses.
    params : dict
        The nominal re-fit's parameters.
    fit_length : bool
        L is fitted.

    Returns
    -------
    AsBuilt
        The rows, the keys taken as exact, the re-fits made outside ``refit``.
    """
    mu = params["mu"]
    amp = swing_amplitude(result)
    rows, exact, n = [], [], 0
    value, u, bound = _stated(setup, "cylinder_tilt")
    if bound == 0.0:
        exact.append(TILT)
    else:
        bias, n = tilt_bias(meas, result, setup, params, math.radians(bound),
                            fit_length=fit_length)
        rows.append((TILT, value, u, bias * mu / u if u else None, abs(bias) * mu,
                     TILT_NOTE))
    seen = _seen_rows(meas, mu)
    if seen is not None:
        rows.append(seen)
    value, u, bound = _stated(setup, "cylinder_ovality")
    if seen is None and bound > 0.0:
        hor, ver = ovality_bias(refit, setup, mu, bound * 1e-3, amp)
        worst = max(abs(hor), abs(ver)) if math.isfinite(hor) and math.isfinite(ver) \
            else math.nan
        rows.append((OVALITY, value, u, worst * mu / u if u else None, worst * mu,
                     f"orientation unknown: the worse of the major axis horizontal "
                     f"({100 * hor:+.3g} %) and vertical ({100 * ver:+.3g} %), not corrected"))
    elif seen is None:
        exact.append(OVALITY)
    # the lab's word on its camera, even 0 +- 0 (square on, exactly), replaces the path's bound
    stated = [setup.u(f) is not None for f in ("camera_yaw", "camera_pitch")]
    turn = None if seen is not None or any(stated) else _turn_row(meas, result, setup, params,
                                                                  fit_length)
    if turn is not None:
        rows.append(turn[0])
        n += turn[1]
    for field, source, pitch in (("camera_yaw", YAW, False), ("camera_pitch", PITCH, True)):
        value, u, bound = _stated(setup, field)
        if seen is not None or turn is not None:
            continue  # the ellipse seen, or the round path's bound, holds the camera's tilt
        if bound == 0.0:
            exact.append(source)
            continue
        bias, k = camera_tilt_bias(meas, result, setup, params, math.radians(bound),
                                   pitch=pitch, fit_length=fit_length)
        n += k
        rows.append((source, value, u, bias * mu / u if u else None, abs(bias) * mu,
                     f"quadratic, one-signed ({'+' if bias > 0 else '-'}): not corrected, "
                     "u(mu) the bias at |angle| + u"))
    return AsBuilt(rows=tuple(rows), exact=tuple(exact), n_refits=n)
