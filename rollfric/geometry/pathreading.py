"""What the ball's elliptic path means for mu: a turned camera or an out-of-round bore.

A round trough filmed square-on puts the ball centre's path on a circle of radius L = R - r
about the axis. Two things make its image an ellipse (:mod:`rollfric.geometry.ellipse`; the
conic through the centres: :mod:`rollfric.geometry.pathshape`):

- the camera yawed or pitched against the trough axis compresses the image across the tilt
  axis; the motion is that of the round trough (the period is set by L), only the angles are
  seen through the compression. The camera reading maps the path back onto a circle (the
  symmetric square root of the path's conic,
  :meth:`rollfric.geometry.pathshape.PathEllipse.round_map`) and fits mu again.
- an out-of-round bore: the path is really an ellipse (the offset curve of the bore), the
  period is set by the path's radius of curvature at the bottom, rho_b - r. The trough reading
  fits again with that length and scales by the bore's angle slope
  (:func:`rollfric.geometry.ellipse.trough_scale`, :func:`rollfric.geometry.ellipse.trough_bias`).

The image cannot tell them apart, the period can: the swing's length is fitted
(:func:`fit_length`) and compared with L = R - r (the camera's reading) and with the path's
bottom curvature (the trough's). Only a reading the period singles out (within SEPARATE
standard uncertainties of one, beyond them of the other) is acted on: the camera's corrects mu
(the angles become the mapped ones), the trough's leaves mu as it was (its reading is
reported). Otherwise both readings are reported and, when they differ by more than
:data:`rollfric.geometry.ellipse.BIAS_WARN` of mu, the measurement is suspect
(``camera_orientation``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import optimize

from rollfric.fit import eom
from rollfric.geometry import ellipse as ell
from rollfric.geometry.pathshape import PathEllipse, fit_path, mapped_centres

# the period singles a reading out when it agrees with it within SEPARATE standard
# uncertainties and disagrees with the other by more
SEPARATE = 3.0


def fit_length(t, theta, setup, result, offset: bool) -> tuple[float, float]:
    """The swing's length L (m) fitted with the motion, and its standard uncertainty.

    Starts from the fit ``result`` (its ``used`` samples); L free besides mu, the start and,
    with ``offset``, the bottom's angle. The uncertainty is the Gauss-Newton one widened by the
    residuals' AR(1) long-run factor.
    """
    t = np.asarray(t, dtype=float)
    th = np.asarray(theta, dtype=float)
    used = result.used if result.used is not None and result.used.shape == t.shape else \
        np.isfinite(t) & np.isfinite(th)
    t, th = t[used], th[used]
    L0, g = setup.track_radius, setup.gravity
    rt, rc = np.asarray(result.t, dtype=float), np.asarray(result.curve, dtype=float)
    keep = np.isfinite(rt) & np.isfinite(rc)  # the curve is NaN where frames were left out
    rt, rc = rt[keep], rc[keep]
    if rt.size < 2:
        raise ValueError("the fitted curve has fewer than 2 finite samples")
    th0 = float(np.interp(t[0], rt, rc))
    om0 = float(np.interp(t[0], rt, np.gradient(rc, rt)))
    x0 = [max(result.mu, 1e-6), th0 - result.offset, om0, L0] + ([result.offset] if offset
                                                                   else [])

    def resid(p):
        m, _, _ = eom.solve(p[1], p[2], p[0], t, track_radius=p[3], gravity=g, mu1=result.mu1)
        return m + (p[4] if offset else 0.0) - th

    lo = [0.0, -math.pi, -np.inf, 0.5 * L0] + ([-np.inf] if offset else [])
    hi = [1.0, math.pi, np.inf, 2.0 * L0] + ([np.inf] if offset else [])
    sol = optimize.least_squares(resid, np.clip(x0, lo, hi), bounds=(lo, hi),
                                 x_scale=[1e-4, 1e-3, 1e-3, 1e-5 * L0] + ([1e-3] if offset
                                                                          else []),
                                 xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200)
    res = sol.fun
    rr = float((res - res.mean()) @ (res - res.mean()))
    rho = float(np.clip((res[1:] - res.mean()) @ (res[:-1] - res.mean()) / rr, 0.0, 0.97)) \
        if rr > 0 else 0.0
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * float(res @ res) / max(res.size - len(x0), 1)
        u = math.sqrt(max(cov[3, 3], 0.0) * (1.0 + rho) / (1.0 - rho))
    except np.linalg.LinAlgError:
        u = math.inf
    return float(sol.x[3]), u


def swing_amplitude(result) -> float:
    """The swing's typical turning-point angle about the bottom (rad), from the fitted curve."""
    swing = np.asarray(result.curve, dtype=float) - result.offset
    k = np.flatnonzero(np.diff(np.sign(np.diff(swing))) != 0) + 1
    return float(np.median(np.abs(swing[k]))) if len(k) else float(np.nanmax(np.abs(swing)))


@dataclasses.dataclass(frozen=True)
class PathReading:
    """What the path's ellipse means (:func:`read_path`).

    Attributes
    ----------
    path : PathEllipse
        The path's conic.
    verdict : str
        "round" (no significant ellipse), "camera" (the period agrees with L = R - r: the
        camera's tilt, corrected), "trough" (the period agrees with the path's bottom
        curvature: an out-of-round bore, mu left as it was), "undecided".
    mu_camera, mu_trough : float
        mu read as the camera's tilt (the mapped angles) and as an out-of-round bore.
    result_camera : object or None
        The camera reading's fit (:class:`rollfric.fit.estimate.FitResult`).
    theta_camera : numpy.ndarray or None
        The camera reading's angles (NaN where no centre).
    lengths : dict
        L fitted from the period, L = R - r and the path's bottom curvature (m) with their
        standard uncertainties.
    """

    path: PathEllipse
    verdict: str
    mu_as_measured: float
    mu_camera: float = math.nan
    mu_trough: float = math.nan
    result_camera: object = dataclasses.field(default=None, repr=False)
    theta_camera: np.ndarray | None = dataclasses.field(default=None, repr=False)
    lengths: dict = dataclasses.field(default_factory=dict)

    @property
    def spread(self) -> float:
        """|mu_camera - mu_trough| / mu; where one reading could not be made, the other's
        difference from mu as measured (NaN when neither was made)."""
        if not self.mu_as_measured:
            return math.nan
        cam, tr = self.mu_camera, self.mu_trough
        if not math.isfinite(cam) or not math.isfinite(tr):
            made = cam if math.isfinite(cam) else tr
            return abs(made - self.mu_as_measured) / abs(self.mu_as_measured)
        return abs(cam - tr) / abs(self.mu_as_measured)

    def kind(self) -> str:
        """"yawed" (the path squeezed sideways), "pitched" (squeezed vertically) or "turned"."""
        ang = abs(self.path.angle_deg)
        return "pitched" if ang < 30 else "yawed" if ang > 60 else "turned"

    def to_dict(self) -> dict:
        """The fit.json form."""
        out = self.path.to_dict()
        out.update(verdict=self.verdict, mu_as_measured=self.mu_as_measured,
                   mu_if_camera=_finite(self.mu_camera), mu_if_trough=_finite(self.mu_trough),
                   mu_spread=_finite(self.spread), **{k: _finite(v) for k, v in
                                                      self.lengths.items()})
        return out

    def message(self) -> str | None:
        """The warning (None: nothing to say)."""
        if self.verdict == "round":
            return None
        a, b = self.path.semi_axes
        shape = (f"the ball's path is an ellipse about the trough axis (axes {2 * a:.2f} x "
                 f"{2 * b:.2f} px, ratio {b / a:.5f}, major axis at {self.path.angle_deg:.1f} "
                 "deg)")
        lg = self.lengths
        given = (f"R - r is {1e3 * lg['L_nominal_m']:.2f} mm, the path's bottom curvature "
                 f"{1e3 * lg['L_path_m']:.2f} mm")
        period = (f"the swing's period gives L = {1e3 * lg['L_period_m']:.2f} +- "
                  f"{1e3 * lg['L_period_u_m']:.2f} mm, {given}"
                  if math.isfinite(lg["L_period_m"]) else
                  f"the swing's period could not be fitted with L free ({given})")
        cam = _change(self.mu_camera, self.mu_as_measured)
        trough = _change(self.mu_trough, self.mu_as_measured)
        tilt = f"{self.path.tilt_deg():.1f} deg"
        if self.verdict == "camera":
            return (f"{shape}: {period}, so the trough is round and the camera is "
                    f"{self.kind()} by {tilt} against its axis; corrected: the angles are "
                    f"taken on the path mapped back to a circle, mu {cam} (from "
                    f"{self.mu_as_measured:.6g} to {self.mu_camera:.6g}); left: the "
                    "perspective of a tilted lens (the correction is orthographic)")
        if self.verdict == "trough":
            return (f"{shape}: {period}, so the trough is out of round (the camera is square "
                    f"on): mu left as measured; read with the bore's curvature it would be "
                    f"{trough} ({self.mu_trough:.6g}); left: the bore's shape beyond an "
                    "ellipse")
        return (f"{shape}: if the camera is {self.kind()} by {tilt} against the trough axis "
                f"mu is {_reading(self.mu_camera, self.mu_as_measured)}, if the trough is out "
                f"of round {_reading(self.mu_trough, self.mu_as_measured)}; {period}: the "
                "period cannot tell which. "
                "Nothing corrected; square the camera on the trough axis, or state "
                "cylinder.radius_mm_u small enough for the period to decide")


def _finite(v):
    return float(v) if v is not None and math.isfinite(v) else None


def _change(mu, mu0) -> str:
    return f"{100 * (mu / mu0 - 1):+.2f} %" if math.isfinite(mu) and mu0 else "?"


def _reading(mu, mu0) -> str:
    """A reading of mu with its change from ``mu0``, or that its fit failed."""
    return f"{mu:.6g} ({_change(mu, mu0)})" if math.isfinite(mu) else \
        "not known (its fit failed)"


def read_path(x, y, center, t, theta, setup, result, *, offset: bool, refit,
              ball_radius_px: float, angle_of, center_u=None) -> PathReading:
    """The path's ellipse from the located centres and what it means for mu.

    Parameters
    ----------
    x, y : numpy.ndarray
        Centres (px) the angles were taken from, NaN where no ball.
    center : tuple of float
        The trough axis (px).
    t, theta : numpy.ndarray
        Times (s) and the measured angles (rad).
    setup : rollfric.setup.model.Setup
        The setup.
    result : rollfric.fit.estimate.FitResult
        The fit of the measured angles.
    offset : bool
        Whether the bottom's angle was fitted.
    refit : callable
        refit(t, theta, setup) -> FitResult, as the measurement fits.
    ball_radius_px : float
        The ball's radius (px).
    angle_of : callable
        angle_of(x, y) -> theta, the measurement's angle formula about ``center``.
    center_u : tuple of float or None
        The centre's standard uncertainty (px): see :func:`fit_path`.

    Returns
    -------
    PathReading
    """
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(theta)
    if result.used is not None and result.used.shape == ok.shape:
        ok &= result.used
    path = fit_path(x[ok], y[ok], center, center_u)
    mu = result.mu
    if not path.significant:
        return PathReading(path, "round", mu)
    L_px = setup.track_radius / setup.pixel_size
    # the camera's reading: the path mapped back onto a circle, the angles again
    mx, my = mapped_centres(x, y, center, path.round_map(L_px))
    th_cam = angle_of(mx, my)
    try:
        res_cam = refit(t, th_cam, setup)
    except ValueError:  # the mapped angles would not fit: no camera reading
        res_cam = None
    # the trough's: the bore's curvature at the bottom sets the period, its slope the angles
    amp = swing_amplitude(result)
    a, b = path.semi_axes
    bore = ell.ContourEllipse(center=path.center, semi_axes=(a + ball_radius_px,
                                                             b + ball_radius_px),
                              angle_deg=path.angle_deg, rms_px=path.rms_px,
                              n_points=path.n_points)
    r_eff, f_b = ell.trough_scale(bore, ball_radius_px, amp)
    rho_path = path.bottom_curvature_radius(result.offset)
    L_path = rho_path * setup.pixel_size
    try:
        res_tr = refit(t, theta, setup.replace(cylinder_radius=L_path + setup.ball_radius))
        mu_tr = res_tr.mu / f_b
    except ValueError:
        mu_tr = math.nan
    # the period decides (not without the camera reading's fit to start from)
    try:
        L_fit, u_fit = fit_length(t, th_cam, setup, res_cam, offset) if res_cam is not None \
            else (math.nan, math.inf)
    except ValueError:
        L_fit, u_fit = math.nan, math.inf
    uR, ud = setup.u("cylinder_radius"), setup.u("ball_diameter")
    u_nom = math.hypot(uR or 0.0, 0.5 * (ud or 0.0))
    up = setup.u("pixel_size")
    u_path = math.hypot(path.bottom_curvature_u(result.offset) * setup.pixel_size,
                        rho_path * (up or 0.0))
    z_cam = (L_fit - setup.track_radius) / max(math.hypot(u_fit, u_nom), 1e-300)
    z_tr = (L_fit - L_path) / max(math.hypot(u_fit, u_path), 1e-300)
    if abs(z_cam) <= SEPARATE < abs(z_tr):  # NaN without the camera's fit: never
        verdict = "camera"
    elif abs(z_tr) <= SEPARATE < abs(z_cam) and math.isfinite(mu_tr):
        verdict = "trough"
    else:
        verdict = "undecided"
    lengths = {"L_period_m": L_fit, "L_period_u_m": u_fit, "L_nominal_m": setup.track_radius,
               "L_nominal_u_m": u_nom, "L_path_m": L_path, "L_path_u_m": u_path,
               "z_camera": z_cam, "z_trough": z_tr}
    return PathReading(path, verdict, mu, mu_camera=math.nan if res_cam is None else res_cam.mu,
                       mu_trough=mu_tr,
                       result_camera=res_cam, theta_camera=th_cam, lengths=lengths)
