"""Room air on the rolling ball: drag on its centre, buoyancy and added mass.

The ball (radius r, diameter d, mass m, volume V = pi d^3 / 6) moves through air of density
rho and viscosity eta at the speed v = L |theta'| of its centre. Along the track the air adds

- a **drag** D = (1/2) rho Cd pi r^2 v^2 against the motion. Cd depends on the Reynolds
  number Re = rho v d / eta: an unbounded sphere follows the correlation of Schiller and
  Naumann (1933), Cd = 24/Re (1 + 0.15 Re^0.687), which Clift, Grace and Weber, *Bubbles,
  Drops, and Particles* (Academic Press 1978, ch. 5) list; it lies within -4.6 % .. +5.3 %
  of their standard drag curve (Table 5.2) over Re 0.1 .. 800. A ball rolling on a wall has
  more drag than a free one (the gap flow and the wall-side wake: DNS by Zeng et al., Phys.
  Fluids 21, 033302, 2009, and Lee & Balachandar, J. Fluid Mech., 2010; measured on freely
  rolling spheres by Nanayakkara et al., J. Fluid Mech., 2024, rising as the roughness gap
  closes). rollfric multiplies the free-sphere law by a wall factor
  ``WALL_FACTOR`` = 1.5 with a standard uncertainty ``WALL_FACTOR_U`` = 0.29 (a rectangular
  distribution over 1 .. 2: an honest statement that the factor for a given ball, trough and
  roughness is not known better than that). A lab that measured its Cd gives ``air_cd``.
- **buoyancy** rho V g against gravity: the weight and the gravity part of the normal force
  both scale by (1 - beta), beta = rho / rho_ball, so mu (M = mu r N) is unchanged to first
  order; the swing's frequency drops by beta / 2.
- **added mass** C_a rho V, accelerated with the ball along and across the track: the inertia
  7/5 m becomes 7/5 m + C_a rho V, the centripetal part of N grows by the same C_a rho V.
  C_a = 0.5 for an unbounded sphere, 0.5 (1 + 3/16 (r/h)^3) with h = r for a sphere touching
  a wall (the first image term of Milne-Thomson's series): ``ADDED_MASS_COEFFICIENT`` = 0.594.

With all three the equation of motion of :mod:`rollfric.fit.eom` reads::

    (7/5 + C_a beta) L theta'' = -[(1 - beta) g sin(theta)
        + s (mu ((1 - beta) g cos(theta) + (1 + C_a beta) L theta'^2) + k Cd v^2)]

with s = sign(theta') and k = rho pi r^2 / (2 m). For steel (beta = 1.5e-4) buoyancy and added
mass change the frequency by about 1e-4 and leave mu alone to first order, but a fit without
them takes the period misfit partly into mu (0.01-0.1 %, measured): they are modelled. The
drag is the term that matters: for the thesis's 10 mm ball at 20 deg it is a few per cent of
the rolling resistance.

Not modelled: the drag torque on the spinning ball, its Magnus force, the history (Basset)
force, the trough's curvature in the wall correction.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

ROOM_AIR_DENSITY = 1.20  # kg/m^3, room air (20 C, 1013 hPa: 1.204)
# a room's air density over 15 .. 30 C, 950 .. 1050 hPa and any humidity: 1.10 .. 1.26 kg/m^3
ROOM_AIR_DENSITY_U = 0.03  # kg/m^3
AIR_VISCOSITY = 1.81e-5  # Pa s, air at 20 C
AIR_VISCOSITY_U = 0.03e-5  # Pa s: 15 .. 30 C is 1.78 .. 1.86e-5
WALL_FACTOR = 1.5
WALL_FACTOR_U = 0.5 / math.sqrt(3.0)  # rectangular over 1 .. 2
ADDED_MASS_COEFFICIENT = 0.5 * (1.0 + 3.0 / 16.0)
RE_MAX = 800.0  # the free-sphere correlation's range


def cd_sphere(re):
    """Drag coefficient of an unbounded sphere, Schiller and Naumann (1933), Re < 800.

    Parameters
    ----------
    re : float or array_like
        Reynolds number rho v d / eta, > 0.

    Returns
    -------
    float or numpy.ndarray
        Cd = 24/Re (1 + 0.15 Re^0.687).
    """
    return 24.0 / re * (1.0 + 0.15 * re ** 0.687)


@dataclasses.dataclass(frozen=True)
class Air:
    """The air around the ball, in SI units.

    Attributes
    ----------
    density : float
        rho, kg/m^3; 0: no air (a vacuum, or a synthetic recording without it).
    viscosity : float
        eta, Pa s.
    cd : float or None
        A drag coefficient given by the user; None: the wall-corrected law
        (``wall_factor`` x :func:`cd_sphere`).
    wall_factor : float
        The factor of the wall on the free sphere's drag.
    """

    density: float = 0.0
    viscosity: float = AIR_VISCOSITY
    cd: float | None = None
    wall_factor: float = WALL_FACTOR

    def coefficients(self, ball_radius: float, ball_mass: float) -> np.ndarray:
        """The numbers the compiled equation of motion takes (:func:`rollfric.fit.eom.solve`; its
        drag is :func:`rollfric.fit.eom.drag_accel`).

        Parameters
        ----------
        ball_radius : float
            r, m.
        ball_mass : float
            m, kg.

        Returns
        -------
        numpy.ndarray
            [beta, C_a beta, k, rho d / eta, Cd or 0, wall factor]: beta = rho / rho_ball,
            k = rho pi r^2 / (2 m) (1/m).
        """
        if self.density <= 0.0:
            return np.zeros(6)
        volume = 4.0 / 3.0 * math.pi * ball_radius**3
        beta = self.density * volume / ball_mass
        kd = self.density * math.pi * ball_radius**2 / (2.0 * ball_mass)
        return np.array([beta, ADDED_MASS_COEFFICIENT * beta, kd,
                         self.density * 2.0 * ball_radius / self.viscosity,
                         0.0 if self.cd is None else float(self.cd), self.wall_factor])

    def reynolds(self, speed, ball_diameter: float):
        """Re = rho v d / eta at the centre's ``speed`` (m/s).

        Parameters
        ----------
        speed : float or array_like
            m/s.
        ball_diameter : float
            d, m.

        Returns
        -------
        numpy.ndarray or float
        """
        return self.density * np.abs(speed) * ball_diameter / self.viscosity

    def drag_coefficient(self, re):
        """Cd at Reynolds number ``re`` (the user's Cd, or the wall factor x the law).

        Parameters
        ----------
        re : float or array_like
            Re > 0.

        Returns
        -------
        numpy.ndarray or float
        """
        if self.cd is not None:
            return np.full_like(np.asarray(re, dtype=float), float(self.cd))
        re = np.asarray(re, dtype=float)
        return self.wall_factor * 24.0 / re * (1.0 + 0.15 * re ** 0.687)

    def summary(self, speed_max: float, ball_diameter: float) -> dict:
        """The drag used, for fit.json: density, viscosity, law, Re and Cd over the swing.

        Parameters
        ----------
        speed_max : float
            The centre's largest speed in the fitted record, m/s.
        ball_diameter : float
            d, m.

        Returns
        -------
        dict
            ``density_kg_m3``, ``viscosity_pa_s``, ``law`` ("none", "given" or
            "schiller-naumann x wall"), ``wall_factor``, ``reynolds_max``, ``cd_at_reynolds_max``
            (None without air) and ``beyond_law`` (Re above the law's range).
        """
        if self.density <= 0.0:
            return {"density_kg_m3": 0.0, "law": "none"}
        re_max = float(self.reynolds(speed_max, ball_diameter))
        law = "given" if self.cd is not None else "schiller-naumann x wall"
        cd = float(self.drag_coefficient(re_max)) if re_max > 0 else None
        return {"density_kg_m3": self.density, "viscosity_pa_s": self.viscosity, "law": law,
                "cd": self.cd, "wall_factor": None if self.cd is not None else self.wall_factor,
                "reynolds_max": re_max, "cd_at_reynolds_max": cd,
                "beyond_law": self.cd is None and re_max > RE_MAX}


def air_of(setup) -> Air:
    """The :class:`Air` of a :class:`rollfric.setup.model.Setup`.

    Parameters
    ----------
    setup : rollfric.setup.model.Setup

    Returns
    -------
    Air
    """
    return Air(density=setup.air_density, viscosity=setup.air_viscosity, cd=setup.air_cd,
               wall_factor=setup.air_wall_factor)


def coefficients_of(setup) -> np.ndarray:
    """:meth:`Air.coefficients` of a setup's air and ball (zeros without air).

    Parameters
    ----------
    setup : rollfric.setup.model.Setup

    Returns
    -------
    numpy.ndarray
    """
    return air_of(setup).coefficients(setup.ball_radius, setup.ball_mass)
