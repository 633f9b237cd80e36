"""Kinematics shared by the engines (world frame of the team contract, SI units)."""

from __future__ import annotations

import math

import numpy as np

from sim.losses import ROOM_AIR_DENSITY, losses_of, reynolds


def centre_from_theta(theta, track_radius):
    """Ball centre (N, 3) at angle theta: (L sin theta, -L cos theta, 0)."""
    theta = np.asarray(theta, dtype=float)
    return np.column_stack([track_radius * np.sin(theta), -track_radius * np.cos(theta),
                            np.zeros_like(theta)])


def theta_from_centre(position, velocity):
    """(theta, theta_dot) of the ball centre projected on the x-y plane."""
    x, y = position[:, 0], position[:, 1]
    vx, vy = velocity[:, 0], velocity[:, 1]
    theta = np.arctan2(x, -y)
    theta_dot = (x * vy - y * vx) / (x * x + y * y)
    return theta, theta_dot


def slip_speed(position, velocity, angular_velocity, ball_radius, section=None):
    """Speed of the ball's contact point in m/s: on the cylinder, outward from the axis, or on
    an out-of-round ``section`` (:class:`sim.section.Section`) along its contact normal."""
    n_out = np.zeros_like(position)
    if section is None or section.round:
        rho = np.linalg.norm(position[:, :2], axis=1)
        n_out[:, 0] = position[:, 0] / rho
        n_out[:, 1] = position[:, 1] / rho
    else:
        phi = contact_angles(section, position)
        n_out[:, 0], n_out[:, 1] = np.sin(phi), -np.cos(phi)
    v_contact = velocity + np.cross(angular_velocity, ball_radius * n_out)
    return np.linalg.norm(v_contact, axis=1)


def rolling_spin(theta_dot, track_radius, ball_radius):
    """Angular velocity about +z of a ball rolling without slipping: -(L / r) theta'."""
    return -(track_radius / ball_radius) * np.asarray(theta_dot, dtype=float)


def losses_meta(scenario, theta_dot) -> dict:
    """The trajectory's meta entries of the losses the fitter does not assume (sim.losses):
    ``losses`` (their settings) and the ball's largest speed and Reynolds number; empty
    without losses (the meta of such a trajectory stays what it was)."""
    losses = losses_of(scenario)
    if not losses.active:
        return {}
    vmax = float(np.nanmax(np.abs(theta_dot))) * scenario.track_radius if len(theta_dot) \
        else 0.0
    return {"losses": {"mu_speed_s_m": losses.mu_speed,
                       "air_density_kg_m3": losses.air_density, "air_cd": losses.air_cd,
                       **({"air_drag": "law"} if losses.law else {}),
                       "max_speed_m_s": vmax,
                       "max_reynolds": float(reynolds(vmax, scenario.ball_diameter,
                                                      losses.air_density or ROOM_AIR_DENSITY))}}


def contact_angles(section, position) -> np.ndarray:
    """Normal angle phi of the bore point nearest each ball centre (N, 3) of an out-of-round
    ``section`` (:meth:`sim.section.Section.phi_of_point`, each sample started from the last)."""
    phi = np.empty(len(position))
    guess = float(np.arctan2(position[0, 0], -position[0, 1]))
    for i, (x, y) in enumerate(position[:, :2]):
        guess = phi[i] = section.phi_of_point(float(x), float(y), guess)
    return phi


def initial_state(scenario):
    """Ball centre (x, y) and velocity (vx, vy) at release, and the spin about +z, for the
    scenario's theta0 and theta_dot0 (round trough: L (sin, -cos) theta0 and L theta_dot0
    (cos, sin) theta0; out-of-round: on the offset curve of :mod:`sim.section`)."""
    th0, w0, r = scenario.theta0, scenario.theta_dot0, scenario.ball_radius
    sec = scenario.section
    if sec.round:
        L = scenario.track_radius
        return ((L * math.sin(th0), -L * math.cos(th0)),
                (L * w0 * math.cos(th0), L * w0 * math.sin(th0)), -(L / r) * w0)
    phi0 = sec.phi_of_theta(th0, r)
    v = (float(sec.curvature_radius(phi0)) - r) * w0 / sec.dtheta_dphi(phi0, r)
    x, y = sec.centre(phi0, r)
    return ((float(x), float(y)), (v * math.cos(phi0), v * math.sin(phi0)), -v / r)
