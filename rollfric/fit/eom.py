"""The Lagrange equation of motion of a ball rolling in a horizontal cylindrical trough.

theta is the angle of the ball centre about the cylinder axis, measured from the bottom,
positive to the right. With L = R - r the radius of the ball centre's circle, rolling
without slipping and a rolling-resistance torque M = mu r N opposing the rolling, where
N = m g cos(theta) + m L theta'^2 is the normal force::

    theta'' = -(5 / (7 L)) [g sin(theta) + mu sign(theta') (g cos(theta) + L theta'^2)]

(thesis, paper 2). The ball sticks for good at a turning point where |tan(theta)| <= mu
(static rolling resistance holds it). Both integrators here treat the sign of theta' exactly:
they stop at every turning point (theta' = 0), apply the sticking rule, and restart with the
new sign, so there is no smoothed sign function and no chattering.

Room air (:mod:`rollfric.fit.air`: drag on the centre, buoyancy, added mass) enters through the
``air`` coefficients of :func:`solve` and :func:`solve_reference`; without them (None) the
equation is the one above.

The velocity-dependent variant ``mu(theta') = mu0 + mu1 |theta'|`` (a model the thesis cites
for ball bearings) is selected with ``mu1 != 0``; sticking then uses mu0.

Two integrators with one meaning:

- :func:`solve_reference`: SciPy's DOP853 with events, to a relative tolerance of 1e-10
  (the ground truth of the validation suite). Its segment-and-stick loop is
  :func:`rollfric.fit.segments.solve_segments` (importable from here too), which takes any
  right-hand side theta'' = f(theta, theta', s) (the validation suite's equation with losses
  the fitter does not assume uses it), with the sticking rule :func:`sticks`.
- :func:`solve`: a compiled fixed-step RK4 with exact turning-point location, about
  100x faster, for fitting (agreement with the reference is a test).
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.fit.segments import (
    check_times,
    solve_segments,
    sticks,  # noqa: F401  (the sticking rule, importable from here as before)
)
from rollfric.jit import njit

STANDARD_GRAVITY = 9.81


def omega_squared(track_radius: float, gravity: float = STANDARD_GRAVITY) -> float:
    """Small-angle gravity parameter omega^2 = 5 g / (7 (R - r)) in 1/s^2.

    Parameters
    ----------
    track_radius : float
        Radius L = R - r of the ball centre's circle, m.
    gravity : float
        Gravitational acceleration, m/s^2.

    Returns
    -------
    float
        omega^2, 1/s^2.
    """
    return 5.0 * gravity / (7.0 * track_radius)


def theta_ddot(theta, theta_dot, mu, track_radius, gravity=STANDARD_GRAVITY, mu1=0.0):
    """Right-hand side of the equation of motion (vectorised; sign(0) = 0).

    Parameters
    ----------
    theta : float or array_like
        Angle of the ball centre from the bottom, rad.
    theta_dot : float or array_like
        Angular velocity, rad/s.
    mu : float
        Rolling-resistance coefficient (mu0 of the velocity-dependent model).
    track_radius : float
        L = R - r, m.
    gravity : float
        Gravitational acceleration, m/s^2.
    mu1 : float
        Velocity coefficient of mu(theta') = mu + mu1 |theta'|, s/rad.

    Returns
    -------
    numpy.ndarray
        theta'', rad/s^2, broadcast over the inputs.
    """
    theta = np.asarray(theta, dtype=float)
    theta_dot = np.asarray(theta_dot, dtype=float)
    k = 5.0 / (7.0 * track_radius)
    mu_v = mu + mu1 * np.abs(theta_dot)
    normal = gravity * np.cos(theta) + track_radius * theta_dot**2
    return -k * (gravity * np.sin(theta) + mu_v * np.sign(theta_dot) * normal)


def energy(theta, theta_dot, track_radius, gravity=STANDARD_GRAVITY):
    """Mechanical energy per unit mass (J/kg) of the rolling ball, zero at rest at the bottom.

    Kinetic: (1/2) v^2 + (1/2) I w^2 / m = (7/10) L^2 theta'^2; potential g L (1 - cos theta).

    Parameters
    ----------
    theta : float or array_like
        Angle from the bottom, rad.
    theta_dot : float or array_like
        Angular velocity, rad/s.
    track_radius : float
        L = R - r, m.
    gravity : float
        Gravitational acceleration, m/s^2.

    Returns
    -------
    numpy.ndarray
        Energy per unit mass, J/kg.
    """
    theta = np.asarray(theta, dtype=float)
    theta_dot = np.asarray(theta_dot, dtype=float)
    return 0.7 * track_radius**2 * theta_dot**2 + gravity * track_radius * (1 - np.cos(theta))


def _check_inputs(t, track_radius, gravity, mu, mu1, signed=False):
    t = check_times(t)
    if not track_radius > 0:
        raise ValueError(f"track_radius (R - r) must be positive, got {track_radius}")
    if not gravity > 0:
        raise ValueError(f"gravity must be positive, got {gravity}")
    if mu < 0 or (mu1 < 0 and not signed):
        raise ValueError(f"mu and mu1 must not be negative, got mu={mu}, mu1={mu1}")
    return t


def solve_reference(theta0: float, omega0: float, mu: float, t, *, track_radius: float,
                    gravity: float = STANDARD_GRAVITY, mu1: float = 0.0,
                    rtol: float = 1e-10, atol: float = 1e-13, air=None):
    """Integrate the equation of motion with DOP853 and turning-point events.

    The state at ``t[0]`` is (theta0, omega0). Returns ``(theta, theta_dot, t_stop)`` sampled at
    ``t``; ``t_stop`` is the time the ball came to rest for good (inf if it never did). The
    loop is :func:`solve_segments` with this module's right-hand side.

    Parameters
    ----------
    theta0 : float
        Angle at ``t[0]``, rad.
    omega0 : float
        Angular velocity at ``t[0]``, rad/s.
    mu : float
        Rolling-resistance coefficient (mu0 when ``mu1 != 0``); also the sticking threshold.
    t : array_like
        Strictly increasing sample times, s.
    track_radius : float
        L = R - r, m.
    gravity : float
        Gravitational acceleration, m/s^2.
    mu1 : float
        Velocity coefficient of mu(theta') = mu + mu1 |theta'|, s/rad.
    rtol, atol : float
        Tolerances passed to :func:`scipy.integrate.solve_ivp`.
    air : array_like or None
        The air's coefficients (:meth:`rollfric.fit.air.Air.coefficients`); None: no air.

    Returns
    -------
    theta : numpy.ndarray
        Angle at ``t``, rad.
    theta_dot : numpy.ndarray
        Angular velocity at ``t``, rad/s.
    t_stop : float
        Time of coming to rest for good, s (inf if it never did within ``t``).

    Raises
    ------
    ValueError
        If ``t`` is empty, not 1-D or not strictly increasing, ``track_radius`` or ``gravity``
        is not positive, or ``mu`` or ``mu1`` is negative.
    RuntimeError
        If the integrator fails.
    """
    t = _check_inputs(t, track_radius, gravity, mu, mu1)
    a = _air_array(air)
    if not np.any(a):
        k = 5.0 / (7.0 * track_radius)

        def accel(th, om, s):
            mu_v = mu + mu1 * abs(om)
            return -k * (gravity * math.sin(th) + s * mu_v * (gravity * math.cos(th)
                                                              + track_radius * om**2))
    else:
        def accel(th, om, s):
            return float(_accel(th, om, s, mu, mu1, track_radius, gravity, a))

    return solve_segments(theta0, omega0, t, accel, mu_static=mu, rtol=rtol, atol=atol)


@njit
def drag_accel(v, kd, re_per_speed, cd_fixed, wall):
    """Drag deceleration per unit mass k Cd v^2 (m/s^2) at the centre's speed ``v`` >= 0
    (:mod:`rollfric.fit.air`; its coefficients k, rho d / eta, a given Cd, the wall factor).

    ``cd_fixed`` > 0: that Cd; else ``wall`` x the Schiller-Naumann law at Re =
    ``re_per_speed`` v, written so that v -> 0 gives 0 (Cd v^2 = 24 v / re_per_speed (...)).
    """
    if kd == 0.0 or v <= 0.0:
        return 0.0
    if cd_fixed > 0.0:
        return kd * cd_fixed * v * v
    re = re_per_speed * v
    return kd * wall * 24.0 / re_per_speed * v * (1.0 + 0.15 * re ** 0.687)


@njit
def _accel(th, om, s, mu0, mu1, L, g, air):
    # air: rollfric.fit.air.Air.coefficients (zeros: no air): buoyancy, added mass, drag
    cab = air[1]
    k = 5.0 / (7.0 * L) if cab == 0.0 else 1.0 / (L * (1.4 + cab))
    gb = g * (1.0 - air[0])
    drag = drag_accel(L * abs(om), air[2], air[3], air[4], air[5])
    return -k * (gb * math.sin(th) + s * ((mu0 + mu1 * abs(om))
                                          * (gb * math.cos(th) + (1.0 + cab) * L * om * om)
                                          + drag))


@njit
def _rk4(th, om, h, s, mu0, mu1, L, g, air):
    a1 = _accel(th, om, s, mu0, mu1, L, g, air)
    th2 = th + 0.5 * h * om
    om2 = om + 0.5 * h * a1
    a2 = _accel(th2, om2, s, mu0, mu1, L, g, air)
    th3 = th + 0.5 * h * om2
    om3 = om + 0.5 * h * a2
    a3 = _accel(th3, om3, s, mu0, mu1, L, g, air)
    th4 = th + h * om3
    om4 = om + h * a3
    a4 = _accel(th4, om4, s, mu0, mu1, L, g, air)
    th_n = th + h / 6.0 * (om + 2.0 * om2 + 2.0 * om3 + om4)
    om_n = om + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return th_n, om_n


@njit
def _advance(th, om, s, h, mu0, mu1, L, g, air):
    """Advance by h with friction sign s, stopping at a turning point if one comes first.

    Returns (theta, omega, used_h, turned).
    """
    th_n, om_n = _rk4(th, om, h, s, mu0, mu1, L, g, air)
    if om_n * s > 0.0:
        return th_n, om_n, h, False
    # theta' reached zero inside the step: Newton on tau for omega(tau) = 0
    a0 = _accel(th, om, s, mu0, mu1, L, g, air)
    tau = -om / a0 if a0 != 0.0 else 0.5 * h
    if tau <= 0.0 or tau > h:
        tau = 0.5 * h
    for _ in range(30):
        th_t, om_t = _rk4(th, om, tau, s, mu0, mu1, L, g, air)
        a_t = _accel(th_t, om_t, s, mu0, mu1, L, g, air)
        if a_t == 0.0:
            break
        step = om_t / a_t
        tau_new = tau - step
        if tau_new <= 0.0:
            tau_new = 0.5 * tau
        elif tau_new > h:
            tau_new = 0.5 * (tau + h)
        if abs(tau_new - tau) <= 1e-15 * (1.0 + h):
            tau = tau_new
            break
        tau = tau_new
    th_t, om_t = _rk4(th, om, tau, s, mu0, mu1, L, g, air)
    return th_t, 0.0, tau, True


@njit
def _sticks(th, mu0):
    # as sticks(): gravity along the track does not beat the rolling resistance at rest
    return abs(math.sin(th)) <= mu0 * math.cos(th) or math.sin(th) == 0.0


@njit(nogil=True)  # nogil: independent fits run on threads (rollfric.parallel)
def _solve_rk4(t, theta0, omega0, mu0, mu1, L, g, h_max, air):
    n = t.shape[0]
    theta = np.empty(n)
    omega = np.empty(n)
    th = theta0
    om = omega0
    stuck = False
    t_stop = np.inf
    s = 1.0
    if om == 0.0:
        if _sticks(th, mu0):
            stuck = True
            t_stop = t[0]
        else:
            s = -1.0 if math.sin(th) > 0.0 else 1.0
    else:
        s = 1.0 if om > 0.0 else -1.0
    theta[0] = th
    omega[0] = om
    for i in range(1, n):
        remaining = t[i] - t[i - 1]
        idle = 0  # turning points in a row that took no time (a ball that cannot move on)
        while remaining > 0.0 and not stuck:
            h = remaining
            if h > h_max:
                nsub = math.ceil(remaining / h_max)
                h = remaining / nsub
            th, om, used, turned = _advance(th, om, s, h, mu0, mu1, L, g, air)
            remaining -= used
            if turned:
                idle = idle + 1 if used <= 1e-15 * (1.0 + h) else 0
                if _sticks(th, mu0) or idle > 8:
                    stuck = True
                    t_stop = t[i] - remaining
                else:
                    s = -1.0 if math.sin(th) > 0.0 else 1.0
            if remaining < 1e-15:
                remaining = 0.0
        theta[i] = th
        omega[i] = om
    return theta, omega, t_stop


def solve(theta0: float, omega0: float, mu: float, t, *, track_radius: float,
          gravity: float = STANDARD_GRAVITY, mu1: float = 0.0, steps_per_radian: float = 200.0,
          air=None, signed_mu1: bool = False):
    """Fast integration of the equation of motion (compiled RK4, exact turning points).

    Same arguments and results as :func:`solve_reference`. The step is at most
    ``1 / (steps_per_radian * omega)`` with omega the small-angle frequency, so the local
    error per step is about (1/steps_per_radian)^5; the default agrees with the reference to
    about 1e-9 rad over 4 s.

    Parameters
    ----------
    theta0 : float
        Angle at ``t[0]``, rad.
    omega0 : float
        Angular velocity at ``t[0]``, rad/s.
    mu : float
        Rolling-resistance coefficient (mu0 when ``mu1 != 0``); also the sticking threshold.
    t : array_like
        Strictly increasing sample times, s.
    track_radius : float
        L = R - r, m.
    gravity : float
        Gravitational acceleration, m/s^2.
    mu1 : float
        Velocity coefficient of mu(theta') = mu + mu1 |theta'|, s/rad.
    steps_per_radian : float
        Integration steps per radian of small-angle phase (sets the largest step).
    air : array_like or None
        The air's coefficients (:meth:`rollfric.fit.air.Air.coefficients`: buoyancy, added mass,
        drag); None: no air.
    signed_mu1 : bool
        Accept a negative ``mu1`` (a resistance that falls with speed: the two-sided fit of the
        friction law's test, :mod:`rollfric.uncertainty.law`).

    Returns
    -------
    theta : numpy.ndarray
        Angle at ``t``, rad.
    theta_dot : numpy.ndarray
        Angular velocity at ``t``, rad/s.
    t_stop : float
        Time of coming to rest for good, s (inf if it never did within ``t``).

    Raises
    ------
    ValueError
        If ``t`` is empty, not 1-D or not strictly increasing, ``track_radius`` or ``gravity``
        is not positive, or ``mu`` or (without ``signed_mu1``) ``mu1`` is negative.
    """
    t = _check_inputs(t, track_radius, gravity, mu, mu1, signed_mu1)
    w = math.sqrt(omega_squared(track_radius, gravity))
    h_max = 1.0 / (steps_per_radian * w)
    return _solve_rk4(t, float(theta0), float(omega0), float(mu), float(mu1),
                      float(track_radius), float(gravity), h_max, _air_array(air))


def _air_array(air) -> np.ndarray:
    if air is None:
        return np.zeros(6)
    a = np.asarray(air, dtype=float)
    if a.shape != (6,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ValueError(f"air must be 6 finite numbers >= 0 (rollfric.fit.air), got {air!r}")
    return a
