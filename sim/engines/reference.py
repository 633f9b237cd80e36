"""The exact reference: the equation of motion integrated by DOP853 to 1e-10 (rollfric.fit.eom).

With losses the fitter does not assume (speed-dependent rolling friction, air drag: the
scenario's ``mu_speed``, ``air_density``), the equation of :mod:`sim.losses` instead, integrated
the same way; without them rollfric.fit.eom's, unchanged.

Orientation and spin follow from rolling without slipping: the contact point
c = centre + r n_out (n_out = (sin theta, -cos theta, 0)) is at rest, so
v + w x (r n_out) = 0 with v = L theta' (cos theta, sin theta, 0) gives w = (0, 0, -(L/r) theta').
The ball starts with the identity orientation and turns about +z by phi = -(L/r)(theta - theta0).

An out-of-round trough (:mod:`sim.section`, an ellipse) is integrated in the normal angle phi
of the contact (the slope of the ball centre's path; arc length ds = (rho - r) dphi), see
:func:`solve_section` and docs/how/trough.md. A trough tilted along its length is refused by
the scenario (a 3D motion).
"""

from __future__ import annotations

import math
import time

import numpy as np
import scipy
from scipy.integrate import solve_ivp

from rollfric.fit.eom import solve_reference, sticks
from sim.engines.common import centre_from_theta, losses_meta, rolling_spin, theta_from_centre
from sim.losses import losses_of
from sim.losses import solve as solve_losses
from sim.trajectory import Trajectory

DEFAULTS: dict = {"rtol": 1e-10}


def run(scenario, progress: bool = False):
    """Simulate ``scenario`` with the exact equation of motion (SciPy DOP853, exact turning points).

    Parameters
    ----------
    scenario : sim.Scenario
        The scenario (engine ``reference``; option ``rtol``, default 1e-10).
    progress : bool, optional
        Unused (the integration takes milliseconds); kept for the engines' common signature.

    Returns
    -------
    sim.Trajectory
        The ground truth at the camera rate: rolling without slipping, the normal force
        m g cos(theta) + m L theta'^2, slip 0, and the time the ball came to rest in ``meta``.
    """
    opts = scenario.options()
    if not scenario.section.round:
        return _run_section(scenario, opts)
    t = scenario.times()
    start = time.perf_counter()
    L, r = scenario.track_radius, scenario.ball_radius
    losses = losses_of(scenario)
    if losses.active:
        theta, theta_dot, t_stop = solve_losses(
            scenario.theta0, scenario.theta_dot0, scenario.mu, t, losses, track_radius=L,
            ball_radius=r, ball_mass=scenario.ball_mass, gravity=scenario.gravity,
            rtol=opts["rtol"])
        version = f"scipy {scipy.__version__} solve_ivp DOP853 (sim.losses)"
    else:
        theta, theta_dot, t_stop = solve_reference(
            scenario.theta0, scenario.theta_dot0, scenario.mu, t, track_radius=L,
            gravity=scenario.gravity, rtol=opts["rtol"])
        version = f"scipy {scipy.__version__} solve_ivp DOP853 (rollfric.fit.eom)"
    phi = -(L / r) * (theta - scenario.theta0)
    quat = np.column_stack([np.cos(phi / 2), np.zeros_like(phi), np.zeros_like(phi),
                            np.sin(phi / 2)])
    omega = np.zeros((len(t), 3))
    omega[:, 2] = rolling_spin(theta_dot, L, r)
    m, g = scenario.ball_mass, scenario.gravity
    normal = m * g * np.cos(theta) + m * L * theta_dot**2
    meta = {
        "engine": "reference",
        "engine_version": version,
        "surface": scenario.surface,
        "settings": opts,
        "t_stop_s": None if not np.isfinite(t_stop) else float(t_stop),
        "wall_time_s": time.perf_counter() - start,
        **losses_meta(scenario, theta_dot),
    }
    return Trajectory(t=t, theta=theta, theta_dot=theta_dot, position=centre_from_theta(theta, L),
                      quaternion=quat, angular_velocity=omega, normal_force=normal,
                      slip_speed=np.zeros_like(t), scenario=scenario, meta=meta)


def solve_section(section, ball_radius: float, phi0: float, phi_dot0: float, mu: float, t, *,
                  gravity: float, rtol: float = 1e-10, atol: float = 1e-13):
    """Integrate the rolling ball in a trough of any convex cross-section (DOP853, events).

    The coordinate is phi, the angle of the contact normal from straight down (the slope of
    the ball centre's path); the centre moves at speed v = rho_c phi' with rho_c = rho(phi) - r
    the path's radius of curvature. Rolling without slipping (spin v / r, kinetic energy
    (7/10) m v^2) and the rolling-resistance torque M = mu r N, N = m g cos(phi) + m rho_c phi'^2,
    give (7/5) s'' = -g sin(phi) - mu sign(phi') N / m along the arc length s, i.e.::

        phi'' = [-(5/7) (g sin phi + mu sign(phi') (g cos phi + rho_c phi'^2))
                 - rho_c'(phi) phi'^2] / rho_c(phi)

    which for a circle (rho_c = L constant) is the equation of :mod:`rollfric.fit.eom`. The ball
    sticks at a turning point where |tan phi| <= mu.

    Parameters
    ----------
    section : sim.section.Section
        The cross-section.
    ball_radius : float
        r, m.
    phi0, phi_dot0 : float
        Normal angle (rad) and its rate (rad/s) at ``t[0]``.
    mu : float
        Rolling-resistance coefficient.
    t : array_like
        Strictly increasing sample times, s.
    gravity : float
        m/s^2.
    rtol, atol : float
        Tolerances of :func:`scipy.integrate.solve_ivp`.

    Returns
    -------
    phi, phi_dot, s : numpy.ndarray
        The normal angle, its rate and the arc length run by the centre (m, from 0) at ``t``.
    t_stop : float
        Time the ball came to rest for good (inf if it did not).
    """
    t = np.asarray(t, dtype=float)
    r, g = float(ball_radius), float(gravity)

    def rc(p):
        return float(section.curvature_radius(p)) - r

    phi_out, om_out, s_out = np.empty_like(t), np.empty_like(t), np.empty_like(t)
    t_now, ph, om, arc = float(t[0]), float(phi0), float(phi_dot0), 0.0
    t_end, t_stop = float(t[-1]), math.inf
    while True:
        if om == 0.0:
            if sticks(ph, mu):
                t_stop = t_now
                sel = t >= t_now
                phi_out[sel], om_out[sel], s_out[sel] = ph, 0.0, arc
                break
            sgn = -1.0 if math.sin(ph) > 0 else 1.0
        else:
            sgn = math.copysign(1.0, om)

        def rhs(_t, y, sgn=sgn):
            rho = rc(y[0])
            normal = g * math.cos(y[0]) + rho * y[1] ** 2
            acc = (-(5.0 / 7.0) * (g * math.sin(y[0]) + sgn * mu * normal)
                   - float(section.curvature_radius_slope(y[0])) * y[1] ** 2) / rho
            return (y[1], acc, rho * y[1])

        def turning(_t, y):
            return y[1]

        turning.terminal = True
        turning.direction = -sgn
        if t_now >= t_end:
            phi_out[-1], om_out[-1], s_out[-1] = ph, om, arc
            break
        sol = solve_ivp(rhs, (t_now, t_end), [ph, om, arc], method="DOP853", rtol=rtol,
                        atol=atol, events=turning, dense_output=True)
        if not sol.success:
            raise RuntimeError(f"section equation of motion: integration failed: {sol.message}")
        sel = (t >= t_now) & (t <= sol.t[-1])
        if np.any(sel):
            y = sol.sol(t[sel])
            phi_out[sel], om_out[sel], s_out[sel] = y[0], y[1], y[2]
        if sol.status == 1 and sol.t_events[0].size:
            t_now = float(sol.t_events[0][0])
            ph, om, arc = float(sol.y_events[0][0][0]), 0.0, float(sol.y_events[0][0][2])
        else:
            break
    return phi_out, om_out, s_out, t_stop


def _run_section(scenario, opts):
    """The reference run of an out-of-round trough (:func:`solve_section`)."""
    t = scenario.times()
    start = time.perf_counter()
    sec, r = scenario.section, scenario.ball_radius
    phi0 = sec.phi_of_theta(scenario.theta0, r)
    phid0 = scenario.theta_dot0 / sec.dtheta_dphi(phi0, r)
    phi, phid, arc, t_stop = solve_section(sec, r, phi0, phid0, scenario.mu, t,
                                           gravity=scenario.gravity, rtol=opts["rtol"])
    c = sec.centre(phi, r)
    rho_c = sec.curvature_radius(phi) - r
    speed = rho_c * phid
    position = np.column_stack([c[:, 0], c[:, 1], np.zeros_like(phi)])
    velocity = np.column_stack([speed * np.cos(phi), speed * np.sin(phi), np.zeros_like(phi)])
    theta, theta_dot = theta_from_centre(position, velocity)
    spin = -arc / r  # rolling without slipping: turned by -s / r about +z
    quat = np.column_stack([np.cos(spin / 2), np.zeros_like(spin), np.zeros_like(spin),
                            np.sin(spin / 2)])
    omega = np.zeros((len(t), 3))
    omega[:, 2] = -speed / r
    m, g = scenario.ball_mass, scenario.gravity
    normal = m * g * np.cos(phi) + m * rho_c * phid**2
    a, b = sec.semi_axes
    meta = {
        "engine": "reference",
        "engine_version": f"scipy {scipy.__version__} solve_ivp DOP853 "
                          "(sim.engines.reference.solve_section)",
        "surface": scenario.surface,
        "settings": opts,
        "section": {"semi_axes_m": [a, b], "angle_rad": sec.angle,
                    "bottom_curvature_radius_m": sec.bottom_curvature_radius()},
        "t_stop_s": None if not np.isfinite(t_stop) else float(t_stop),
        "wall_time_s": time.perf_counter() - start,
    }
    return Trajectory(t=t, theta=theta, theta_dot=theta_dot, position=position,
                      quaternion=quat, angular_velocity=omega, normal_force=normal,
                      slip_speed=np.zeros_like(t), scenario=scenario, meta=meta)
