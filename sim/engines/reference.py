"""The exact reference: the equation of motion integrated by DOP853 to 1e-10 (rollfric.eom).

With losses the fitter does not assume (speed-dependent rolling friction, air drag: the
scenario's ``mu_speed``, ``air_density``), the equation of :mod:`sim.losses` instead, integrated
the same way; without them rollfric.eom's, unchanged.

Orientation and spin follow from rolling without slipping: the contact point
c = centre + r n_out (n_out = (sin theta, -cos theta, 0)) is at rest, so
v + w x (r n_out) = 0 with v = L theta' (cos theta, sin theta, 0) gives w = (0, 0, -(L/r) theta').
The ball starts with the identity orientation and turns about +z by phi = -(L/r)(theta - theta0).
"""

from __future__ import annotations

import time

import numpy as np
import scipy

from rollfric.eom import solve_reference
from sim.engines.common import centre_from_theta, losses_meta, rolling_spin
from sim.losses import losses_of
from sim.losses import solve as solve_losses

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
    from sim.trajectory import Trajectory

    opts = scenario.options()
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
        version = f"scipy {scipy.__version__} solve_ivp DOP853 (rollfric.eom)"
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
