"""The trough's cross-section: a circle, or an out-of-round bore (an ellipse).

An as-built bore is never exactly round. Its out-of-roundness is modelled as an ellipse of
mean radius R (what a caliper averaged over directions reads) and ovality D_max - D_min
(the machinist's "out-of-roundness"), the major axis at ``angle`` from the horizontal (world x,
counter-clockwise, towards +y): semi-axes a = R + ovality / 4, b = R - ovality / 4.

A convex cross-section is parametrised here by phi, the angle of its outward normal from
straight down, n(phi) = (sin phi, -cos phi): phi = 0 is the lowest point of the bore (where a
ball rests), and phi is also the slope angle of the ball centre's path there. For the ellipse
(frame rotated by ``angle``, normal n' = (n'_x, n'_y) in that frame) the support function is
h = sqrt(a^2 n'_x^2 + b^2 n'_y^2), the point with that normal p' = (a^2 n'_x, b^2 n'_y) / h
and the radius of curvature rho = a^2 b^2 / h^3 (a^2 / b at the bottom of a horizontal major
axis). A ball of radius r touching the bore at p(phi) has its centre at c = p - r n: the
ball centre runs on the offset curve, whose radius of curvature is rho - r, with the same
normal. The angle ``theta`` the camera sees is that of the ball centre about the axis (the
ellipse's centre), atan2(c_x, -c_y); it equals phi only for a circle.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


@dataclasses.dataclass(frozen=True)
class Section:
    """A trough cross-section: mean radius, ovality and the major axis's angle (SI units).

    Attributes
    ----------
    radius : float
        Mean radius R = (a + b) / 2, m.
    ovality : float
        D_max - D_min = 2 (a - b), m (0: round).
    angle : float
        Angle of the major axis from world x, counter-clockwise (towards +y), rad.
    """

    radius: float
    ovality: float = 0.0
    angle: float = 0.0

    @property
    def round(self) -> bool:
        """True for a circular bore."""
        return self.ovality == 0.0

    @property
    def semi_axes(self) -> tuple[float, float]:
        """(a, b): the major and minor semi-axes, m."""
        return self.radius + 0.25 * self.ovality, self.radius - 0.25 * self.ovality

    def _local(self, phi):
        """The normal n(phi) and tangent t(phi) in the ellipse's own frame."""
        phi = np.asarray(phi, dtype=float)
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        nx, ny = np.sin(phi), -np.cos(phi)
        tx, ty = np.cos(phi), np.sin(phi)
        return (ca * nx + sa * ny, -sa * nx + ca * ny), (ca * tx + sa * ty, -sa * tx + ca * ty)

    def _support_sq(self, phi):
        a, b = self.semi_axes
        (nx, ny), _ = self._local(phi)
        return a * a * nx * nx + b * b * ny * ny

    def contact(self, phi) -> np.ndarray:
        """Points of the bore whose outward normal is n(phi): (..., 2) (x, y) in m.

        Parameters
        ----------
        phi : float or array_like
            Normal angle(s) from straight down, rad.

        Returns
        -------
        numpy.ndarray
            (x, y) of the bore point(s), shape ``phi.shape + (2,)``.
        """
        a, b = self.semi_axes
        (nx, ny), _ = self._local(phi)
        h = np.sqrt(a * a * nx * nx + b * b * ny * ny)
        px, py = a * a * nx / h, b * b * ny / h
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        return np.stack([ca * px - sa * py, sa * px + ca * py], axis=-1)

    def curvature_radius(self, phi):
        """Radius of curvature rho(phi) of the bore where its normal is n(phi), m."""
        a, b = self.semi_axes
        return a * a * b * b / self._support_sq(phi) ** 1.5

    def curvature_radius_slope(self, phi):
        """d rho / d phi, m/rad."""
        a, b = self.semi_axes
        (nx, ny), (tx, ty) = self._local(phi)
        dh2 = 2.0 * (a * a * nx * tx + b * b * ny * ty)  # d(h^2)/dphi, dn/dphi = t
        return -1.5 * a * a * b * b * self._support_sq(phi) ** -2.5 * dh2

    def centre(self, phi, ball_radius: float) -> np.ndarray:
        """Ball centre(s) (..., 2) for a ball of radius ``ball_radius`` touching at n(phi)."""
        phi = np.asarray(phi, dtype=float)
        n = np.stack([np.sin(phi), -np.cos(phi)], axis=-1)
        return self.contact(phi) - ball_radius * n

    def theta(self, phi, ball_radius: float):
        """The camera's angle of the ball centre about the axis, atan2(x, -y), rad."""
        c = self.centre(phi, ball_radius)
        return np.arctan2(c[..., 0], -c[..., 1])

    def dtheta_dphi(self, phi: float, ball_radius: float) -> float:
        """d theta / d phi at phi (the centre moves along t(phi) at speed rho - r)."""
        x, y = self.centre(phi, ball_radius)
        rc = float(self.curvature_radius(phi)) - ball_radius
        vx, vy = rc * math.cos(phi), rc * math.sin(phi)
        return float((x * vy - y * vx) / (x * x + y * y))

    def phi_of_theta(self, theta: float, ball_radius: float) -> float:
        """The normal angle phi at which the ball centre is seen at angle ``theta``."""
        from scipy.optimize import brentq

        if self.round:
            return float(theta)
        f = lambda p: float(self.theta(p, ball_radius)) - theta  # noqa: E731
        lo, hi = theta - 0.5, theta + 0.5
        return float(brentq(f, lo, hi, xtol=1e-15, rtol=1e-15, maxiter=200))

    def phi_of_point(self, x: float, y: float, phi_guess: float) -> float:
        """Normal angle phi of the bore point nearest to (x, y) (a ball centre inside).

        The foot of the perpendicular: (c - p(phi)) . t(phi) = 0, by Newton's method from
        ``phi_guess`` (d/dphi = -rho - (c - p) . n). A round bore gives atan2(x, -y).
        """
        if self.round:
            return math.atan2(x, -y)
        a, b = self.semi_axes
        a2, b2 = a * a, b * b
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        phi = float(phi_guess)
        for _ in range(20):  # scalar arithmetic: this runs before every engine step
            s, c = math.sin(phi), math.cos(phi)
            nx, ny = ca * s - sa * c, -sa * s - ca * c  # n(phi) in the ellipse's frame
            h2 = a2 * nx * nx + b2 * ny * ny
            h = math.sqrt(h2)
            lx, ly = a2 * nx / h, b2 * ny / h
            px, py = ca * lx - sa * ly, sa * lx + ca * ly
            dx, dy = x - px, y - py
            f = dx * c + dy * s
            fp = -a2 * b2 / (h2 * h) - (dx * s - dy * c)
            step = f / fp
            phi -= step
            if abs(step) < 1e-15:
                break
        return phi

    def bottom_curvature_radius(self) -> float:
        """rho at the lowest point of the bore (phi = 0), m: a^2 / b for a horizontal major
        axis, b^2 / a for a vertical one."""
        return float(self.curvature_radius(0.0))

    def outline(self, phi) -> np.ndarray:
        """Bore points at polar angle ``phi`` about the axis (from the bottom, positive to the
        right, like theta): (..., 2) (x, y) in m, for drawing the bore."""
        a, b = self.semi_axes
        phi = np.asarray(phi, dtype=float)
        ux, uy = np.sin(phi), -np.cos(phi)
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        lx, ly = ca * ux + sa * uy, -sa * ux + ca * uy
        rad = a * b / np.sqrt((b * lx) ** 2 + (a * ly) ** 2)
        return np.stack([rad * ux, rad * uy], axis=-1)
