"""Losses the fitter does not assume: speed-dependent rolling friction and air drag on the ball.

rollfric fits a constant coefficient (M = mu r N). A real ball also loses energy to

- **speed-dependent rolling resistance** (hysteresis in the contact grows with the rolling
  speed): ``mu(v) = mu + mu_speed v`` with v = L |theta'| the speed of the ball's centre (m/s)
  and ``mu_speed`` in s/m (scenario key ``motion.mu_speed_s_m``). rollfric's own "velocity"
  fit model writes the same law per angular speed: its mu1 (s/rad) = mu_speed L.
- **air drag** on the ball's centre, quadratic in its speed, against the motion:
  D = (1/2) rho Cd pi r^2 v^2 (scenario keys ``environment.air_density_kg_m3``, 0 = off, room
  air 1.2; ``environment.air_cd``, default 0.47, a smooth sphere at Re 1e3 .. 2e5). The ball
  of the thesis moves at up to about 0.3 m/s, so its Reynolds number Re = rho v d / eta
  (eta = 1.81e-5 Pa s, air at 20 C) stays below about 200 for the 10 mm ball (30 for the
  1.58 mm one): there a free sphere's Cd is 0.8-4 (Schiller-Naumann, 24/Re (1 + 0.15
  Re^0.687)), and the trough's wall next to the ball raises it further; ``air_cd`` is a single
  number, so a study sweeps it over that range. Not modelled with a constant Cd: buoyancy and
  the air's added mass (both about rho_air / rho_steel = 1.5e-4 of the weight and the
  inertia), the drag torque on the spinning ball and its Magnus force.
- **the fitter's air** (scenario key ``environment.air_drag = "law"``): Cd at every instant's
  Reynolds number by :mod:`rollfric.fit.air`'s wall-corrected law, with buoyancy and added mass,
  written out here (:func:`_law_accel`) as the truth of a recording whose lab states only the
  air's density. MuJoCo and PyBullet apply that drag but neither buoyancy nor added mass (a
  fit with them is then 0.01-0.1 % off, as :mod:`rollfric.fit.air` measures).

With both, the equation of motion of :mod:`rollfric.fit.eom` becomes::

    theta'' = -(5 / (7 L)) [g sin(theta) + s ((mu + mu_speed L |theta'|) (g cos(theta)
              + L theta'^2) + k L^2 theta'^2)],   s = sign(theta'), k = rho Cd pi r^2 / (2 m)

and :func:`solve` integrates it with the loop of :func:`rollfric.fit.eom.solve_reference`,
:func:`rollfric.fit.eom.solve_segments` (DOP853 to 1e-10, an event at every turning point, the ball
sticks for good where |tan(theta)| <= mu: at rest neither the speed term nor the drag acts).
The right-hand side is written here, apart from rollfric, because the truth of a study of what
the fitter does not assume must not share the fitter's model; the loop it shares is the
reference integrator's, not the fitter's compiled one (:func:`rollfric.fit.eom.solve`).

Small-angle checks (tests): with mu = 0 and drag only, each half-swing loses
(4/3) c A^2 of its amplitude A, c = 5 k L / 7 (quadratic damping of a harmonic oscillator);
with mu = 0 and ``mu_speed`` only, the speed term is a viscous damping and the amplitude
decays as exp(-gamma t), gamma = 5 mu_speed g / 14.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rollfric.fit.air import ADDED_MASS_COEFFICIENT, Air
from rollfric.fit.eom import drag_accel, solve_segments

AIR_VISCOSITY = 1.81e-5  # Pa s, air at 20 C (for the Reynolds number only)
ROOM_AIR_DENSITY = 1.204  # kg/m^3, dry air at 20 C and 1013 hPa
SPHERE_CD = 0.47  # a smooth sphere's drag coefficient at Re 1e3 .. 2e5


@dataclasses.dataclass(frozen=True)
class Losses:
    """The extra losses of a scenario (SI units); all zero: the fitter's own model.

    Attributes
    ----------
    mu_speed : float
        Speed coefficient of the rolling resistance, mu(v) = mu + mu_speed v (s/m).
    air_density : float
        Density of the air around the ball (kg/m^3); 0: no drag.
    air_cd : float
        Drag coefficient of the ball (1).
    law : bool
        Use the fitter's air (:mod:`rollfric.fit.air`: Cd from the instant's Reynolds number with
        the wall factor, buoyancy, added mass) instead of the constant ``air_cd``.
    """

    mu_speed: float = 0.0
    air_density: float = 0.0
    air_cd: float = SPHERE_CD
    law: bool = False  # True: rollfric.fit.air's drag law, buoyancy and added mass (air_cd unused)

    @property
    def active(self) -> bool:
        """Whether any loss beyond the constant mu is on."""
        return self.mu_speed != 0.0 or (self.air_density != 0.0
                                        and (self.air_cd != 0.0 or self.law))

    def air(self) -> Air:
        """The drag as :class:`rollfric.fit.air.Air` (density 0 without air)."""
        return Air(density=self.air_density, cd=None if self.law else self.air_cd)

    def drag_per_mass(self, ball_radius: float, ball_mass: float) -> float:
        """k = rho Cd pi r^2 / (2 m) (1/m): the drag's deceleration is k v^2.

        Parameters
        ----------
        ball_radius : float
            r, m.
        ball_mass : float
            m, kg.

        Returns
        -------
        float
            k, 1/m.
        """
        return self.air_density * self.air_cd * math.pi * ball_radius**2 / (2.0 * ball_mass)


def losses_of(scenario) -> Losses:
    """The :class:`Losses` of a :class:`sim.Scenario`.

    Parameters
    ----------
    scenario : sim.Scenario
        The scenario (its ``mu_speed``, ``air_density``, ``air_cd``).

    Returns
    -------
    Losses
    """
    return Losses(mu_speed=scenario.mu_speed, air_density=scenario.air_density,
                  air_cd=scenario.air_cd, law=getattr(scenario, "air_drag", "") == "law")


def reynolds(speed, ball_diameter: float, air_density: float = ROOM_AIR_DENSITY,
             viscosity: float = AIR_VISCOSITY):
    """Reynolds number rho v d / eta of the ball moving at ``speed`` through air.

    Parameters
    ----------
    speed : float or array_like
        Speed of the ball's centre, m/s.
    ball_diameter : float
        d, m.
    air_density : float
        rho, kg/m^3 (room air by default, also when the scenario has the drag off).
    viscosity : float
        eta, Pa s.

    Returns
    -------
    numpy.ndarray or float
        Re (1).
    """
    return air_density * np.abs(speed) * ball_diameter / viscosity


def theta_ddot(theta, theta_dot, mu, losses: Losses, *, track_radius, ball_radius, ball_mass,
               gravity):
    """Right-hand side of the equation of motion with the losses (vectorised; sign(0) = 0).

    Parameters
    ----------
    theta, theta_dot : float or array_like
        Angle (rad) and angular velocity (rad/s).
    mu : float
        The constant part of the rolling-resistance coefficient.
    losses : Losses
        The extra losses.
    track_radius, ball_radius : float
        L = R - r and r, m.
    ball_mass : float
        m, kg.
    gravity : float
        g, m/s^2.

    Returns
    -------
    numpy.ndarray
        theta'', rad/s^2.
    """
    th = np.asarray(theta, dtype=float)
    om = np.asarray(theta_dot, dtype=float)
    L = track_radius
    if losses.law:
        accel = _law_accel(mu, losses, L, ball_radius, ball_mass, gravity)
        out = np.vectorize(lambda a, w: accel(a, w, math.copysign(1.0, w)) if w != 0.0
                           else accel(a, 0.0, 0.0))(th, om)
        return np.asarray(out, dtype=float)
    k = losses.drag_per_mass(ball_radius, ball_mass)
    mu_v = mu + losses.mu_speed * L * np.abs(om)
    resist = mu_v * (gravity * np.cos(th) + L * om**2) + k * L**2 * om**2
    return -(5.0 / (7.0 * L)) * (gravity * np.sin(th) + np.sign(om) * resist)


def _law_accel(mu, losses: Losses, L, ball_radius, ball_mass, gravity):
    """theta''(theta, theta', s) with rollfric.fit.air's drag law, buoyancy and added mass,
    written out (not the fitter's compiled kernel): (7/5 m + C_a rho V) L theta'' =
    -[(m - rho V) g sin + s (mu((m - rho V) g cos + (m + C_a rho V) L theta'^2) + D)]."""
    a = losses.air().coefficients(ball_radius, ball_mass)
    beta = a[0]
    ca = ADDED_MASS_COEFFICIENT * beta
    m1 = losses.mu_speed * L

    def accel(th, w, s):
        drag = drag_accel(L * abs(w), a[2], a[3], a[4], a[5])
        gb = (1.0 - beta) * gravity
        resist = (mu + m1 * abs(w)) * (gb * math.cos(th) + (1.0 + ca) * L * w * w) + drag
        return -(gb * math.sin(th) + s * resist) / ((1.4 + ca) * L)

    return accel


def solve(theta0: float, omega0: float, mu: float, t, losses: Losses, *, track_radius: float,
          ball_radius: float, ball_mass: float, gravity: float, rtol: float = 1e-10,
          atol: float = 1e-13):
    """Integrate the equation of motion with the losses (DOP853, turning-point events).

    Parameters
    ----------
    theta0, omega0 : float
        The state at ``t[0]``: rad, rad/s.
    mu : float
        The constant part of the rolling-resistance coefficient; also the sticking threshold.
    t : array_like
        Strictly increasing sample times, s.
    losses : Losses
        The extra losses.
    track_radius, ball_radius : float
        L = R - r and r, m.
    ball_mass : float
        m, kg.
    gravity : float
        g, m/s^2.
    rtol, atol : float
        Tolerances of :func:`scipy.integrate.solve_ivp`.

    Returns
    -------
    theta, theta_dot : numpy.ndarray
        At ``t``: rad, rad/s.
    t_stop : float
        When the ball came to rest for good, s (inf if it did not within ``t``).

    Raises
    ------
    ValueError
        ``t`` not strictly increasing, a non-positive length, mass or gravity, a negative mu
        or loss.
    RuntimeError
        The integrator failed.
    """
    if min(track_radius, ball_radius, ball_mass, gravity) <= 0:
        raise ValueError("track_radius, ball_radius, ball_mass and gravity must be positive")
    if min(mu, losses.mu_speed, losses.air_density, losses.air_cd) < 0:
        raise ValueError(f"mu and the losses must not be negative, got mu={mu}, {losses}")
    L = track_radius
    kq = losses.drag_per_mass(ball_radius, ball_mass) * L * L
    m1 = losses.mu_speed * L
    a = 5.0 / (7.0 * L)

    def accel(th, w, s):
        resist = (mu + m1 * abs(w)) * (gravity * math.cos(th) + L * w * w) + kq * w * w
        return -a * (gravity * math.sin(th) + s * resist)

    if losses.law:
        accel = _law_accel(mu, losses, L, ball_radius, ball_mass, gravity)

    return solve_segments(theta0, omega0, t, accel, mu_static=mu, rtol=rtol, atol=atol)


def applied_force(velocity, losses: Losses, ball_radius: float, ball_mass: float) -> np.ndarray:
    """The drag force on the ball's centre (N, world frame), for engines that apply it each
    step: -m k |v| v.

    Parameters
    ----------
    velocity : array_like
        The centre's velocity (3,), m/s.
    losses : Losses
        The losses (its drag).
    ball_radius, ball_mass : float
        r (m) and m (kg).

    Returns
    -------
    numpy.ndarray
        (3,) force, N.
    """
    v = np.asarray(velocity, dtype=float)
    speed = float(np.linalg.norm(v))
    if losses.law:  # rollfric.fit.air's Cd at this speed's Reynolds number
        a = losses.air().coefficients(ball_radius, ball_mass)
        if speed == 0.0:
            return np.zeros(3)
        return -ball_mass * drag_accel(speed, a[2], a[3], a[4], a[5]) * v / speed
    return -ball_mass * losses.drag_per_mass(ball_radius, ball_mass) * speed * v


def mu_at(speed: float, mu: float, losses: Losses) -> float:
    """The rolling-resistance coefficient at the centre's ``speed`` (m/s): mu + mu_speed v.

    Parameters
    ----------
    speed : float
        m/s.
    mu : float
        The constant part.
    losses : Losses
        The losses (its ``mu_speed``).

    Returns
    -------
    float
    """
    return mu + losses.mu_speed * abs(speed)
