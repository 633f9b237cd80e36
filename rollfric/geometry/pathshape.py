"""The ball's path as an ellipse about the trough axis, from the located centres themselves.

A round trough filmed square-on puts the ball centre's path on a circle of radius L = R - r
about the axis. Two things make its image an ellipse (:mod:`rollfric.geometry.ellipse`): the
camera yawed or pitched against the trough axis (the image compressed across the tilt axis)
and an out-of-round bore (the path really an ellipse). This module fits the conic through the
centres (:func:`fit_path`) with a covariance that holds the centres' noise, the trough axis's
uncertainty and the locator's smooth error, and says whether the ellipse stands out from them
(:attr:`PathEllipse.significant`) and which camera tilt it cannot exclude
(:meth:`PathEllipse.tilt_bound_deg`). What an ellipse means for mu, the camera's reading or
the bore's as the period decides, is :mod:`rollfric.geometry.pathreading`'s.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import optimize, stats

# the path's anisotropy (2 degrees of freedom) is real above the chi-square of 3 sigma
SIGNIFICANT_CHI2 = float(stats.chi2.ppf(stats.norm.cdf(3.0) * 2 - 1, 2))
MIN_POINTS = 20
# the locator's smooth error across the path (px), as a standard uncertainty: a centre error
# that changes slowly with the angle (the lamp's shading, the highlight's drift over the
# ball) bends a short arc like an ellipse. Rendered 10 mm balls put their centres 0.008-0.011
# px farther from the axis near the bottom than at +-0.2 rad, which read as a camera tilted
# 2.4 deg and "corrected" mu by +0.085 % (17 U); the path's anisotropy must now stand out
# from an error of that size as from its noise
LOCATOR_SMOOTH_PX = 0.01
# q = (Q11, Q12, Q22) to the path's anisotropy ((Q11 - Q22) / 2, Q12): zero for a circle
_ANISOTROPY = np.array([[0.5, 0.0, -0.5], [0.0, 1.0, 0.0]])


@dataclasses.dataclass(frozen=True)
class PathEllipse:
    """The conic p' Q p = 1 (p the centre minus the trough axis, px) through the path.

    Attributes
    ----------
    q : tuple of float
        (Q11, Q12, Q22), 1/px^2.
    cov : numpy.ndarray
        3 x 3 covariance of q (widened for correlated residuals), the axis's share included.
    center_cov : numpy.ndarray or None
        The axis's share of ``cov`` (None: none).
    center : tuple of float
        The axis the path was fitted about (px).
    rms_px : float
        Rms distance of the centres from the conic (px).
    n_points : int
        Centres fitted.
    """

    q: tuple[float, float, float]
    cov: np.ndarray = dataclasses.field(repr=False)
    center: tuple[float, float]
    rms_px: float
    n_points: int
    center_cov: np.ndarray | None = dataclasses.field(default=None, repr=False)

    @property
    def matrix(self) -> np.ndarray:
        """Q as a 2 x 2 matrix."""
        a, b, c = self.q
        return np.array([[a, b], [b, c]])

    @property
    def semi_axes(self) -> tuple[float, float]:
        """(a, b), a >= b, px."""
        lam = np.linalg.eigvalsh(self.matrix)  # ascending: the major axis first
        return float(1.0 / math.sqrt(lam[0])), float(1.0 / math.sqrt(lam[1]))

    @property
    def angle_deg(self) -> float:
        """The major axis's angle from the image x axis towards +y, in (-90, 90] deg."""
        _, vec = np.linalg.eigh(self.matrix)
        deg = math.degrees(math.atan2(vec[1, 0], vec[0, 0])) % 180.0
        return deg - 180.0 if deg > 90.0 else deg

    @property
    def chi2(self) -> float:
        """Chi-square of the anisotropy ((Q11 - Q22) / 2, Q12) against 0 (2 dof)."""
        g = _ANISOTROPY
        d = g @ np.asarray(self.q)
        try:
            return float(d @ np.linalg.solve(g @ self.cov @ g.T, d))
        except np.linalg.LinAlgError:
            return 0.0

    @property
    def significant(self) -> bool:
        """Whether the path is an ellipse beyond its noise (chi2 > SIGNIFICANT_CHI2)."""
        return self.chi2 > SIGNIFICANT_CHI2

    def bottom_curvature_radius(self, offset: float = 0.0, q=None) -> float:
        """The path's radius of curvature where its normal points down (turned by ``offset``
        rad, the camera's roll), px: det(Q^-1) / (n' Q^-1 n)^1.5."""
        a, b, c = self.q if q is None else q
        inv = np.linalg.inv(np.array([[a, b], [b, c]]))
        n = np.array([math.sin(offset), math.cos(offset)])
        return float(np.linalg.det(inv) / (n @ inv @ n) ** 1.5)

    def bottom_curvature_u(self, offset: float = 0.0) -> float:
        """Standard uncertainty of :meth:`bottom_curvature_radius` (px), from ``cov``."""
        q = np.asarray(self.q)
        grad = np.empty(3)
        for i in range(3):
            h = 1e-6 * abs(q[i]) + 1e-12
            qp, qm = q.copy(), q.copy()
            qp[i] += h
            qm[i] -= h
            grad[i] = (self.bottom_curvature_radius(offset, qp)
                       - self.bottom_curvature_radius(offset, qm)) / (2 * h)
        return float(math.sqrt(max(grad @ self.cov @ grad, 0.0)))

    def round_map(self, radius_px: float) -> np.ndarray:
        """The symmetric 2 x 2 map that takes the path onto a circle of ``radius_px`` about
        the axis (radius_px Q^(1/2)): a camera's compression undone, its roll left alone."""
        lam, vec = np.linalg.eigh(self.matrix)
        return radius_px * (vec * np.sqrt(lam)) @ vec.T

    def tilt_deg(self) -> float:
        """The camera's tilt that would make this ellipse: acos(b / a), deg."""
        a, b = self.semi_axes
        return math.degrees(math.acos(min(1.0, b / a)))

    def tilt_bound_deg(self) -> float:
        """The largest camera tilt the path allows within one standard uncertainty, deg.

        The path's anisotropy s = |((Q11 - Q22) / 2, Q12)| / ((Q11 + Q22) / 2) (a tilt t
        makes s = (1 - cos^2 t) / (1 + cos^2 t)) taken at its estimate plus the standard
        uncertainty along the worst direction (the covariance's largest eigenvalue): a yaw or
        pitch that the path cannot exclude. The axis's share of the covariance is left out: a
        tilt hidden by an axis off its place (a yaw's narrowing undone by an axis nearer the
        path) moves mu by half as much as that axis's own error, which the axis's budget rows
        hold. 90 where the covariance is not finite.

        Examples
        --------
        >>> import numpy as np
        >>> from rollfric.geometry.pathshape import PathEllipse
        >>> c = np.cos(np.radians(3.0))  # a 3 deg yaw squeezes x, known exactly
        >>> e = PathEllipse(q=(1 / c**2, 0.0, 1.0), cov=np.zeros((3, 3)), center=(0.0, 0.0),
        ...                 rms_px=0.0, n_points=100)
        >>> round(e.tilt_bound_deg(), 6)
        3.0
        """
        g = _ANISOTROPY
        q = np.asarray(self.q, dtype=float)
        d = g @ q
        mean = 0.5 * (q[0] + q[2])
        cov = self.cov if self.center_cov is None else self.cov - self.center_cov
        cd = g @ cov @ g.T
        if not (np.all(np.isfinite(cd)) and mean > 0):
            return 90.0
        s = (float(np.hypot(*d)) + math.sqrt(max(float(np.linalg.eigvalsh(cd)[-1]), 0.0))) \
            / mean
        if s >= 1.0:
            return 90.0
        return math.degrees(math.acos(math.sqrt((1.0 - s) / (1.0 + s))))

    def to_dict(self) -> dict:
        """The fit.json form (px, deg)."""
        a, b = self.semi_axes
        return {"center_px": list(self.center), "semi_axes_px": [a, b],
                "angle_deg": self.angle_deg, "axis_ratio": b / a, "rms_px": self.rms_px,
                "n_points": self.n_points, "chi2": self.chi2, "significant": self.significant,
                "tilt_deg_if_camera": self.tilt_deg(), "tilt_deg_bound": self.tilt_bound_deg()}


def fit_path(x, y, center, center_u=None) -> PathEllipse:
    """The conic through the ball centres (x, y) px about the trough axis ``center``.

    Parameters
    ----------
    x, y : array_like
        Located centres (px), finite.
    center : tuple of float
        The trough axis (px).
    center_u : tuple of float or None
        The axis's standard uncertainty (px, x and y): a centre off the axis makes a round
        path look elliptic about it (2 px sideways an oblique ellipse), so its share is added
        to the covariance.

    Returns
    -------
    PathEllipse
        The conic (linear least squares on p' Q p = 1, polished on the distances) with its
        covariance widened by the residuals' AR(1) long-run factor, plus the centre's.
    """
    u = np.asarray(x, dtype=float) - center[0]
    v = np.asarray(y, dtype=float) - center[1]
    if u.size < MIN_POINTS:
        raise ValueError(f"fit_path needs at least {MIN_POINTS} centres")
    a = np.column_stack([u * u, 2 * u * v, v * v])
    q0, *_ = np.linalg.lstsq(a, np.ones_like(u), rcond=None)
    scale = float(np.median(np.hypot(u, v)))

    def resid(q):
        s = np.sqrt(np.clip(a @ q, 1e-12, None))
        return (s - 1.0) * scale  # px, to first order

    sol = optimize.least_squares(resid, q0, x_scale=np.abs(q0) + 1e-12, xtol=1e-15,
                                 ftol=1e-15, gtol=1e-15)
    res = sol.fun - sol.fun.mean()
    rr = float(res @ res)
    rho = float(np.clip(res[1:] @ res[:-1] / rr, 0.0, 0.97)) if rr > 0 else 0.0
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * float(sol.fun @ sol.fun) / max(u.size - 3, 1)
        cov = cov * (1.0 + rho) / (1.0 - rho)
    except np.linalg.LinAlgError:
        cov = np.full((3, 3), np.inf)
    center_cov = np.zeros((3, 3))
    if center_u is not None:
        for k, uk in enumerate(np.ravel(center_u)[:2]):
            if uk and np.isfinite(uk):
                d = np.zeros(2)
                d[k] = uk
                moved = fit_path(x, y, (center[0] + d[0], center[1] + d[1]))
                g = np.asarray(moved.q) - np.asarray(sol.x)  # q's change over one u
                center_cov = center_cov + np.outer(g, g)
    cov = cov + center_cov + _smooth_error_cov(u, v, a, q0)
    return PathEllipse(q=tuple(float(v) for v in sol.x), cov=cov,
                       center=(float(center[0]), float(center[1])),
                       rms_px=float(np.sqrt(np.mean(sol.fun ** 2))), n_points=int(u.size),
                       center_cov=center_cov)


def _smooth_error_cov(u, v, a, q0) -> np.ndarray:
    """The covariance of q that a smooth radial error of the locator, LOCATOR_SMOOTH_PX in
    size, can make: the conic's change when the centres move along their radius by a bulge
    (s^2 less its mean) and by a slope (s) across the arc, s the angle scaled to [-1, 1]
    (each as one systematic error: outer product of the change)."""
    phi = np.arctan2(u, v)
    half = 0.5 * float(np.ptp(phi))
    if not half > 0:
        return np.zeros((3, 3))
    s = (phi - 0.5 * (phi.max() + phi.min())) / half
    r = np.hypot(u, v)
    cov = np.zeros((3, 3))
    for f in (s * s - np.mean(s * s), s):
        k = 1.0 + LOCATOR_SMOOTH_PX * f / r  # each centre moved along its radius
        uu, vv = u * k, v * k
        am = np.column_stack([uu * uu, 2 * uu * vv, vv * vv])
        qm, *_ = np.linalg.lstsq(am, np.ones_like(u), rcond=None)
        cov += np.outer(qm - q0, qm - q0)
    return cov


def mapped_centres(x, y, center, matrix):
    """Centres moved by ``matrix`` about ``center`` (the camera reading's centres)."""
    u = np.asarray(x, dtype=float) - center[0]
    v = np.asarray(y, dtype=float) - center[1]
    m = np.asarray(matrix, dtype=float)
    return center[0] + m[0, 0] * u + m[0, 1] * v, center[1] + m[1, 0] * u + m[1, 1] * v
