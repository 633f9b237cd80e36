"""The trough's contour fitted as an ellipse, and the mu bias an elliptic contour implies.

A round trough filmed square-on has a circular contour. Two things make it an ellipse:

- the camera: its optical axis yawed or pitched against the trough axis compresses the image
  across the tilt axis by cos(angle) (orthographic); the ball's path is compressed alike, so
  the measured angle is theta_m = atan2 of the compressed point, and near the bottom
  theta_m = f theta with f = d theta_m / d theta at the bottom (1 / cos(pitch) for a pitch,
  cos(yaw) for a yaw). The Coulomb offset of each half-swing, mu in radians, is scaled alike:
  mu is biased by f - 1 (:func:`camera_bias`).
- the trough: an out-of-round bore (an ellipse). The ball centre runs on the
  offset curve; near the bottom its angle about the centre is theta = f_B phi with
  f_B = (rho_b - r) / D, rho_b the bore's radius of curvature at its lowest point, D the
  distance from the centre to the ball centre there; the period is set by rho_b - r, not by the
  nominal R - r. Both are corrected by re-fitting with R_eff = rho_b and dividing by f_B
  (:func:`trough_bias`, in :func:`rollfric.measurement.measure`); the lab's nominal radius is
  taken as
  the bore's mean radius (what the contour's circle and a caliper give).

From the image alone the two cannot be told apart (both make the contour and the ball's path
the same ellipse to within r / R); the period can, when R is known well: an out-of-round trough
changes the period, a tilted camera does not (``--fit-length`` fits L = R - r).

An ellipse is only reported as one (warned about) when its axes differ by more than
SIGNIFICANT standard errors of that difference (the least-squares fit's covariance widened for
the points' errors correlated along the contour): a short arc of a round contour fits
ellipses of any small eccentricity.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
from scipy.optimize import least_squares

BIAS_WARN = 0.001  # implied |mu bias| that is warned about
BIAS_SUSPECT = 0.01  # ... that makes the measurement suspect
SIGNIFICANT = 3.0  # axes' difference / its standard error above which the ellipse is real


@dataclasses.dataclass(frozen=True)
class ContourEllipse:
    """An ellipse fitted to the trough's contour points (image pixels, y down).

    Attributes
    ----------
    center : tuple of float
        (xc, yc), px.
    semi_axes : tuple of float
        (a, b), a >= b, px.
    angle_deg : float
        The major axis's angle from the image x axis towards +y (clockwise on screen), in
        (-90, 90] deg.
    rms_px : float
        Rms distance of the points from the ellipse, px.
    n_points : int
        Points fitted.
    axes_diff_u_px : float
        Standard error of a - b from the fit's covariance, px (inf: not estimable).
    """

    center: tuple[float, float]
    semi_axes: tuple[float, float]
    angle_deg: float
    rms_px: float
    n_points: int
    axes_diff_u_px: float = math.inf

    @property
    def significant(self) -> bool:
        """Whether a - b exceeds SIGNIFICANT standard errors (a real ellipse)."""
        a, b = self.semi_axes
        return a - b > SIGNIFICANT * self.axes_diff_u_px

    @property
    def eccentricity(self) -> float:
        """sqrt(1 - b^2 / a^2)."""
        a, b = self.semi_axes
        return math.sqrt(max(0.0, 1.0 - (b / a) ** 2))

    @property
    def mean_radius(self) -> float:
        """(a + b) / 2, px."""
        return 0.5 * (self.semi_axes[0] + self.semi_axes[1])

    def _bottom(self):
        """Normal angle in the ellipse frame of the point whose outward normal is image +y."""
        t = math.radians(self.angle_deg)
        # image down (0, 1) in the ellipse's frame (rotated by the angle)
        return math.sin(t), math.cos(t)

    def bottom_curvature_radius(self) -> float:
        """Radius of curvature at the contour's lowest point (normal straight down), px."""
        a, b = self.semi_axes
        nx, ny = self._bottom()
        h2 = a * a * nx * nx + b * b * ny * ny
        return a * a * b * b / h2 ** 1.5

    def bottom_distance(self, inset: float = 0.0) -> float:
        """Distance from the centre to the lowest point moved ``inset`` px along the inward
        normal (the ball centre's path there for inset = r), px."""
        a, b = self.semi_axes
        nx, ny = self._bottom()
        h = math.sqrt(a * a * nx * nx + b * b * ny * ny)
        px, py = a * a * nx / h - inset * nx, b * b * ny / h - inset * ny
        return math.hypot(px, py)

    def tilt_bound_deg(self) -> float:
        """The largest camera tilt the contour allows within one standard uncertainty:
        acos(1 - (a - b + u(a - b)) / a), deg (90 where u(a - b) is not finite).

        Examples
        --------
        >>> from rollfric.geometry.ellipse import ContourEllipse
        >>> e = ContourEllipse(center=(0.0, 0.0), semi_axes=(500.0, 499.5), angle_deg=90.0,
        ...                    rms_px=0.1, n_points=300, axes_diff_u_px=0.5)
        >>> round(e.tilt_bound_deg(), 2)  # acos(1 - 1 / 500)
        3.62
        """
        a, b = self.semi_axes
        ratio = 1.0 - (a - b + self.axes_diff_u_px) / a
        return math.degrees(math.acos(ratio)) if 0.0 <= ratio <= 1.0 else 90.0

    def to_dict(self) -> dict:
        """The fit.json form (px, deg)."""
        return {"center_px": list(self.center), "semi_axes_px": list(self.semi_axes),
                "angle_deg": self.angle_deg, "eccentricity": self.eccentricity,
                "axis_ratio": self.semi_axes[1] / self.semi_axes[0], "rms_px": self.rms_px,
                "n_points": self.n_points,
                "axes_diff_u_px": self.axes_diff_u_px if math.isfinite(self.axes_diff_u_px)
                else None, "significant": self.significant,
                "tilt_deg_bound": self.tilt_bound_deg()}


def fit_ellipse(points: np.ndarray) -> ContourEllipse:
    """The ellipse through contour ``points`` (N, 2) px: OpenCV's direct least-squares fit
    (``cv2.fitEllipseDirect``), polished by least squares on the points' distances.

    Parameters
    ----------
    points : numpy.ndarray
        (N, 2) contour points, N >= 6.

    Returns
    -------
    ContourEllipse
        The ellipse (the distance used is (sqrt(u^2/a^2 + v^2/b^2) - 1) sqrt(a b), exact to
        first order in the eccentricity for a near-circle).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 6:
        raise ValueError("fit_ellipse needs (N, 2) points, N >= 6")
    off = pts.mean(axis=0)
    q = pts - off
    (cx, cy), (w, h), ang = cv2.fitEllipseDirect(q.astype(np.float32))
    x0 = [cx, cy, 0.5 * w, 0.5 * h, math.radians(ang)]

    def resid(p):
        xc, yc, ax, bx, t = p
        c, s = math.cos(t), math.sin(t)
        dx, dy = q[:, 0] - xc, q[:, 1] - yc
        u, v = c * dx + s * dy, -s * dx + c * dy
        return (np.sqrt((u / ax) ** 2 + (v / bx) ** 2) - 1.0) * math.sqrt(ax * bx)

    sol = least_squares(resid, x0, xtol=1e-14, ftol=1e-14, gtol=1e-14)
    xc, yc, ax, bx, t = sol.x
    # the points run along the contour (one side, then the other) and their errors are
    # correlated over neighbouring rows (the pixel grid): the ordinary covariance s^2 (J'J)^-1
    # widened by the AR(1) long-run factor (1 + rho) / (1 - rho), rho the residuals' lag-1
    # autocorrelation
    res = sol.fun - sol.fun.mean()
    rr = float(res @ res)
    rho = float(np.clip(res[1:] @ res[:-1] / rr, 0.0, 0.97)) if rr > 0 else 0.0
    g = np.array([0.0, 0.0, 1.0, -1.0, 0.0])
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * float(sol.fun @ sol.fun) / max(len(q) - 5, 1)
        var = float(g @ cov @ g) * (1.0 + rho) / (1.0 - rho)
        u_diff = math.sqrt(var) if math.isfinite(var) and var >= 0 else math.inf
    except np.linalg.LinAlgError:
        u_diff = math.inf
    ax, bx = abs(ax), abs(bx)
    if bx > ax:
        ax, bx, t = bx, ax, t + math.pi / 2
    deg = math.degrees(t) % 180.0
    if deg > 90.0:
        deg -= 180.0
    return ContourEllipse(center=(float(xc + off[0]), float(yc + off[1])),
                          semi_axes=(float(ax), float(bx)), angle_deg=float(deg),
                          rms_px=float(np.sqrt(np.mean(sol.fun ** 2))), n_points=len(pts),
                          axes_diff_u_px=u_diff)


def _slope(angle_of, amplitude: float) -> float:
    """Mean slope of angle_of(x) at x = +-amplitude (central differences)."""
    h = 1e-6
    return 0.5 * sum((angle_of(x + h) - angle_of(x - h)) / (2 * h)
                     for x in (amplitude, -amplitude))


def camera_bias(ellipse: ContourEllipse, amplitude: float = 0.0) -> float:
    """The mu bias if the camera made the contour elliptic (yaw/pitch of a round trough).

    The image is taken as a round one compressed by b / a across the major axis. Each
    half-swing loses 2 mu of amplitude (rad); measured on theta_m, that loss is scaled by the
    slope f = d theta_m / d theta at the turning points, so mu is biased by f - 1 (f at the
    bottom: 1 / cos(pitch) for a pitch; at a turning point theta_0, 1 + (f_0 - 1) cos(2 theta_0)).

    Parameters
    ----------
    ellipse : ContourEllipse
        The contour's ellipse.
    amplitude : float, optional
        The swing's typical turning-point angle (rad); 0: the slope at the bottom.

    Returns
    -------
    float
        f - 1 (fraction; +: mu measured too high).
    """
    a, b = ellipse.semi_axes
    t = math.radians(ellipse.angle_deg)
    m = np.array([-math.sin(t), math.cos(t)])  # minor-axis direction
    A = np.eye(2) - (1.0 - b / a) * np.outer(m, m)

    def seen(th):
        x, y = A @ np.array([math.sin(th), math.cos(th)])  # image y down
        return math.atan2(x, y)

    return float(_slope(seen, amplitude) - 1.0)


def trough_scale(ellipse: ContourEllipse, ball_radius_px: float,
                 amplitude: float = 0.0) -> tuple[float, float]:
    """What an out-of-round bore does: (R_eff / R, f_B).

    R_eff / R: the bottom's radius of curvature over the mean radius (the period's radius);
    f_B = d theta / d phi, the slope of the ball centre's angle about the centre against the
    contact normal's angle phi, at the turning points phi = +-amplitude ((rho_b - r) / D at the
    bottom, see the module docstring).

    Parameters
    ----------
    ellipse : ContourEllipse
        The contour's ellipse (the bore).
    ball_radius_px : float
        The ball's radius, px.
    amplitude : float, optional
        The swing's typical turning-point angle (rad); 0: the bottom.

    Returns
    -------
    tuple of float
        (R_eff / R, f_B).
    """
    a, b = ellipse.semi_axes
    t = math.radians(ellipse.angle_deg)
    c, s = math.cos(t), math.sin(t)

    def seen(phi):
        nx, ny = math.sin(phi), math.cos(phi)  # outward normal, image y down
        u, v = c * nx + s * ny, -s * nx + c * ny  # in the ellipse's frame
        h = math.sqrt(a * a * u * u + b * b * v * v)
        pu, pv = a * a * u / h, b * b * v / h
        x, y = c * pu - s * pv - ball_radius_px * nx, s * pu + c * pv - ball_radius_px * ny
        return math.atan2(x, y)

    return ellipse.bottom_curvature_radius() / ellipse.mean_radius, _slope(seen, amplitude)


def trough_bias(mu: float, mu_refit: float, f_b: float) -> float:
    """The mu bias if the trough is out of round: mu / (mu_refit / f_B) - 1, with mu_refit
    the fit re-done with R_eff (:func:`trough_scale`)."""
    if mu_refit <= 0:
        return math.nan
    return float(mu * f_b / mu_refit - 1.0)


def warning_text(ellipse: ContourEllipse, cam: float, trough: float) -> str:
    """The warning an elliptic contour gives (both readings, and what tells them apart)."""
    a, b = ellipse.semi_axes
    return (f"the trough's contour is an ellipse (axes {2 * a:.2f} x {2 * b:.2f} px, ratio "
            f"{b / a:.5f}, major axis at {ellipse.angle_deg:.1f} deg): if the camera is yawed "
            f"or pitched against the trough that biases mu by {100 * cam:+.2f} %, if the trough "
            f"is out of round by {100 * trough:+.2f} %; the image cannot tell which (an "
            "out-of-round trough changes the period, a tilted camera does not: compare L "
            "from --fit-length with R - r)")
