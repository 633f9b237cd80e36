"""The small-angle analytic model of the thesis's first paper, and its conversions.

With sin(theta) ~ theta and a constant rolling-resistance torque M, the equation of motion is

    theta'' + omega^2 theta + eps sign(theta') = 0,
    omega^2 = 5 g / (7 L),   eps = 5 M / (7 m r L),   L = R - r.

Each half-swing is a cosine about the offset -sign(theta') eps / omega^2, so the amplitude
drops linearly, by 2 eps / omega^2 per half-swing (Coulomb damping). With M = mu r m g (our
convention, N ~ m g for small angles) eps = mu omega^2.

The first paper splits a half-swing into a roll-down stage (from rest at theta_0 to the bottom,
its eq. 7) and a climb stage (from the bottom with angular speed omega_m, its eq. 11), and
defines its own coefficient (its eq. 13), which for small angles is 5/7 of ours: see
:func:`paper1_mu_from_eps`.
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.fit.eom import STANDARD_GRAVITY, omega_squared

__all__ = [
    "omega_squared", "eps_from_mu", "mu_from_eps", "paper1_mu_from_eps", "paper1_mu_from_mu",
    "mu_from_paper1_mu", "roll_down", "climb", "solve_small_angle", "decay_per_half_swing",
]


def eps_from_mu(mu: float, track_radius: float, gravity: float = STANDARD_GRAVITY) -> float:
    """Friction parameter eps of the small-angle model for mu in our convention.

    With M = mu r N and N ~ m g at small angles, eps = mu omega^2.

    Parameters
    ----------
    mu : float
        Rolling friction coefficient (M = mu r N).
    track_radius : float
        L = R - r, radius of the circle the ball's centre moves on (m).
    gravity : float, optional
        Gravitational acceleration (m/s^2).

    Returns
    -------
    float
        eps (1/s^2).
    """
    return mu * omega_squared(track_radius, gravity)


def mu_from_eps(eps: float, track_radius: float, gravity: float = STANDARD_GRAVITY) -> float:
    """mu in our convention (M = mu r N) from the friction parameter eps.

    Parameters
    ----------
    eps : float
        Friction parameter of the small-angle model (1/s^2).
    track_radius : float
        L = R - r (m).
    gravity : float, optional
        Gravitational acceleration (m/s^2).

    Returns
    -------
    float
        mu = eps / omega^2.
    """
    return eps / omega_squared(track_radius, gravity)


def paper1_mu_from_eps(eps: float, theta0: float, track_radius: float,
                       gravity: float = STANDARD_GRAVITY) -> float:
    """The first paper's coefficient (its eq. 13): tangential over normal force at the bottom.

    mu_1 = 7 eps L / (g (17 - 10 cos theta0) - 14 eps theta0 L), theta0 the release angle.
    For theta0 -> 0 this is eps L / g = (5/7) mu.

    Parameters
    ----------
    eps : float
        Friction parameter (1/s^2).
    theta0 : float
        Release angle (rad); its sign is ignored.
    track_radius : float
        L = R - r (m).
    gravity : float, optional
        Gravitational acceleration (m/s^2).

    Returns
    -------
    float
        The first paper's coefficient mu_1.
    """
    theta0 = abs(theta0)
    L = track_radius
    return 7 * eps * L / (gravity * (17 - 10 * math.cos(theta0)) - 14 * eps * theta0 * L)


def paper1_mu_from_mu(mu: float, theta0: float, track_radius: float,
                      gravity: float = STANDARD_GRAVITY) -> float:
    """The first paper's coefficient for a ball released at theta0, given our mu.

    Parameters
    ----------
    mu : float
        Rolling friction coefficient in our convention (M = mu r N).
    theta0 : float
        Release angle (rad).
    track_radius : float
        L = R - r (m).
    gravity : float, optional
        Gravitational acceleration (m/s^2).

    Returns
    -------
    float
        mu_1 of the first paper's eq. 13.
    """
    return paper1_mu_from_eps(eps_from_mu(mu, track_radius, gravity), theta0, track_radius,
                              gravity)


def mu_from_paper1_mu(mu_1: float, theta0: float, track_radius: float,
                      gravity: float = STANDARD_GRAVITY) -> float:
    """Our mu from the first paper's coefficient (the inverse of its eq. 13).

    Parameters
    ----------
    mu_1 : float
        The first paper's coefficient.
    theta0 : float
        Release angle (rad); its sign is ignored.
    track_radius : float
        L = R - r (m).
    gravity : float, optional
        Gravitational acceleration (m/s^2).

    Returns
    -------
    float
        mu in our convention (M = mu r N).
    """
    theta0 = abs(theta0)
    L = track_radius
    # solve mu_1 (g (17 - 10 cos) - 14 eps theta0 L) = 7 eps L for eps
    eps = mu_1 * gravity * (17 - 10 * math.cos(theta0)) / (7 * L + 14 * mu_1 * theta0 * L)
    return mu_from_eps(eps, track_radius, gravity)


def decay_per_half_swing(eps: float, omega2: float) -> float:
    """Amplitude lost per half-swing in the small-angle model.

    Parameters
    ----------
    eps : float
        Friction parameter (1/s^2).
    omega2 : float
        omega^2 = 5 g / (7 L) (1/s^2).

    Returns
    -------
    float
        2 eps / omega^2 (rad).
    """
    return 2.0 * eps / omega2


def roll_down(t, theta0: float, eps: float, omega2: float) -> np.ndarray:
    """Paper 1, eq. 7: the roll-down stage, released from rest at theta0 at t = 0.

    theta(t) = c + (theta0 - c) cos(omega t) with c = sign(theta0) eps / omega^2, valid until
    the ball reaches the bottom.

    Parameters
    ----------
    t : array_like
        Times since the release (s).
    theta0 : float
        Release angle (rad).
    eps : float
        Friction parameter (1/s^2).
    omega2 : float
        omega^2 (1/s^2).

    Returns
    -------
    numpy.ndarray
        theta at ``t`` (rad).
    """
    w = math.sqrt(omega2)
    c = math.copysign(eps / omega2, theta0)
    return c + (theta0 - c) * np.cos(w * np.asarray(t, dtype=float))


def climb(t, omega_m: float, eps: float, omega2: float) -> np.ndarray:
    """Paper 1, eq. 11: the climb stage, leaving the bottom at t = 0 with angular velocity omega_m.

    theta(t) = (omega_m / omega) sin(omega t) - sign(omega_m) (eps / omega^2) (1 - cos(omega t)).

    Parameters
    ----------
    t : array_like
        Times since the ball passed the bottom (s).
    omega_m : float
        Angular velocity at the bottom (rad/s, signed).
    eps : float
        Friction parameter (1/s^2).
    omega2 : float
        omega^2 (1/s^2).

    Returns
    -------
    numpy.ndarray
        theta at ``t`` (rad).
    """
    w = math.sqrt(omega2)
    t = np.asarray(t, dtype=float)
    return (omega_m / w) * np.sin(w * t) - math.copysign(eps / omega2, omega_m) * (
        1 - np.cos(w * t))


def solve_small_angle(theta0: float, omega0: float, eps: float, omega2: float, t):
    """Exact solution of theta'' + omega^2 theta + eps sign(theta') = 0 from t[0].

    Half-swing by half-swing, with the sticking rule |theta| <= eps / omega^2 at a turning
    point (the small-angle form of |tan theta| <= mu).

    Parameters
    ----------
    theta0 : float
        theta at t[0] (rad).
    omega0 : float
        theta' at t[0] (rad/s).
    eps : float
        Friction parameter (1/s^2).
    omega2 : float
        omega^2 (1/s^2).
    t : array_like
        Increasing sample times (s).

    Returns
    -------
    theta : numpy.ndarray
        Angle at ``t`` (rad).
    theta_dot : numpy.ndarray
        Angular velocity at ``t`` (rad/s).
    t_stop : float
        Time the ball came to rest for good (``inf`` if not within ``t``).
    """
    t = np.asarray(t, dtype=float)
    w = math.sqrt(omega2)
    d = eps / omega2
    theta = np.empty_like(t)
    theta_dot = np.empty_like(t)
    t_now, th, om = float(t[0]), float(theta0), float(omega0)
    filled = np.zeros(t.size, dtype=bool)
    t_stop = math.inf
    for _ in range(100000):
        if om == 0.0:
            if abs(th) <= d:
                t_stop = t_now
                break
            s = -1.0 if th > 0 else 1.0
        else:
            s = math.copysign(1.0, om)
        c = -s * d  # centre of this half-swing
        amp = math.hypot(th - c, om / w)
        phase = math.atan2(-om / w, th - c)  # theta = c + amp cos(w (t - t_now) + phase)
        # next turning point: w (t - t_now) + phase = k pi with velocity sign s before it
        # velocity = -amp w sin(.) has sign s on the way: the next multiple of pi after phase
        k = math.floor(phase / math.pi) + 1
        t_turn = t_now + (k * math.pi - phase) / w
        sel = (t >= t_now) & (t <= t_turn) & ~filled
        arg = w * (t[sel] - t_now) + phase
        theta[sel] = c + amp * np.cos(arg)
        theta_dot[sel] = -amp * w * np.sin(arg)
        filled |= sel
        th = c + amp * math.cos(k * math.pi)
        om = 0.0
        t_now = t_turn
        if t_now > t[-1]:
            break
    rest = ~filled
    theta[rest] = th
    theta_dot[rest] = 0.0
    return theta, theta_dot, t_stop
