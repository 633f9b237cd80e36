"""The uncertainty budget of one measurement of mu (GUM, JCGM 100; Monte-Carlo check JCGM 101).

A budget has one row per source:

- ``"statistical"``: the least-squares standard error of mu, corrected for correlated
  residuals with a heteroscedasticity-and-autocorrelation-consistent (HAC, Newey-West)
  sandwich, prewhitened (:func:`hac_covariance`), computed on the residuals of a noise fit
  that also frees L and a cubic angle map (so a setup error's misfit, which its own row
  covers, is not counted as noise). White residuals give the ordinary standard error,
  residuals correlated over tens of samples (a locator's smoothing) widen it. The corrected
  value is never taken below the ordinary one (negative residual correlation estimated at
  short lags is sampling noise, not a gain in precision).
- one row per uncertain setup input (a key ``K`` with ``K_u`` in setup.toml, see
  :mod:`rollfric.setup.model`): its sensitivity coefficient c = d mu / d input by central
  differences over +-u, each side a re-evaluation of the measurement with that input moved:
  the located centres are kept; the angles (centre, pixel size for arcsin angles), the times
  (frame rate) and the fit (trough radius, ball diameter, gravity) are redone. Each re-fit is
  a local least-squares refinement started from the nominal solution, over the same samples
  and parameters as the nominal fit. u(mu) of the row is |c| u. A trough centre found from
  the background's contour is such an input with its own uncertainty
  (:class:`rollfric.geometry.trough.CylinderContour` ``center_u``), and so is each parameter of a
  lens calibration with ``matrix_u`` / ``distortion_u`` (the located centres undistorted
  again with the moved calibration).

- the trough and camera as built (:mod:`rollfric.uncertainty.asbuilt`): the axis's tilt along
  its length, an out-of-round bore and the camera's yaw and pitch, from the tolerances the
  setup states (``cylinder.tilt_deg_u``, ``ovality_mm_u``, ``camera.yaw_deg_u``,
  ``pitch_deg_u``) or from the ellipse the contour or the path shows (both readings when
  the data cannot tell a camera from a bore). None is corrected; without a tolerance the
  trough is taken as level and round and the camera as square on it (listed as exact).
- ``"method (angle map)"``: the measurement's own smooth angle error (a locator's error that
  varies smoothly with the angle, e.g. a lamp's shadow or highlight), which the noise fit
  absorbs into its angle map: the 2nd and 3rd order of that map through the nominal fit's
  weights, less its noise part, 0 unless above twice it; the part of the map the uncertain
  angle inputs (centre, lens) could make is theirs and projected out
  (:func:`rollfric.uncertainty.anglemap.method_row`).

The combined standard uncertainty is the root sum of squares of the rows (first-order law of
propagation, inputs uncorrelated) and the expanded uncertainty U = k u with k = 2. Inputs
without ``_u`` are listed as exact. On a track CSV (``rollfric fit``) the angles are given: the
trough centre and the pixel size cannot act there, the frame rate acts by rescaling t_s.

Self-calibration (``fit_length=True``): L = R - r, the radius of the ball centre's path, is
fitted with mu; the radius, diameter and gravity then act only through L/g, which the data
fix, so their rows vanish and their effect is in the statistical row (the L-fit's HAC error).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from rollfric.errors import InputError
from rollfric.fit.hac import autocorrelation, hac_covariance  # noqa: F401 (re-exported)
from rollfric.setup.model import Setup
from rollfric.uncertainty import propagation
from rollfric.uncertainty.anglemap import METHOD, method_row
from rollfric.uncertainty.asbuilt import as_built_rows
from rollfric.uncertainty.measured import Measurement
from rollfric.uncertainty.motion import motion_row
from rollfric.uncertainty.propagation import SECOND_ORDER
from rollfric.uncertainty.sensitivity import Refitter, moved, setup_inputs, why_not

COVERAGE_FACTOR = 2.0


@dataclasses.dataclass(frozen=True)
class Row:
    """One source of the budget, in the setup file's units (value, u) and per that unit
    (sensitivity, d mu / d input); ``u_mu`` = |sensitivity| u."""

    source: str
    value: float | None
    u: float
    sensitivity: float | None
    u_mu: float
    note: str = ""

    def to_dict(self) -> dict:
        """The row as a JSON object (``note`` only when it is not empty).

        Returns
        -------
        dict
            ``source``, ``value``, ``u``, ``sensitivity``, ``u_mu`` and perhaps ``note``.
        """
        out = {"source": self.source, "value": self.value, "u": self.u,
               "sensitivity": self.sensitivity, "u_mu": self.u_mu}
        if self.note:
            out["note"] = self.note
        return out


@dataclasses.dataclass(frozen=True)
class Budget:
    """The uncertainty of one mu: rows largest first, combined and expanded uncertainty.

    Attributes
    ----------
    mu, u_mu, U_mu : float
        mu, its combined standard uncertainty and its expanded uncertainty U = k u.
    coverage_factor : float
        k.
    rows : tuple of Row
        One per source (``source``, ``value``, ``u``, ``sensitivity``, ``u_mu``, ``note``).
    statistical : dict
        The ordinary and corrected standard error, lag window, n.
    exact : tuple of str
        The setup's keys taken as exact (no ``_u``).

    Examples
    --------
    >>> import numpy as np, rollfric
    >>> from rollfric.fit.eom import solve_reference
    >>> setup = rollfric.setup_from_dict({  # the exact motion below is airless
    ...     "cylinder": {"radius_mm": 85.3, "radius_mm_u": 0.05},
    ...     "ball": {"diameter_mm": 10.0, "mass_g": 4.07612},
    ...     "camera": {"fps": 1000, "pixel_size_mm": 0.1343},
    ...     "environment": {"air_density_kg_m3": 0}})
    >>> t = np.arange(2000) / 1000.0
    >>> theta, _, _ = solve_reference(np.radians(20.0), 0.0, 0.0079, t,
    ...                               track_radius=setup.track_radius)
    >>> result = rollfric.fit_mu(t, theta, setup)
    >>> b = rollfric.budget(rollfric.Measurement(setup=setup, t=t, theta=theta), result)
    >>> b.rows[0].source, f"{b.rows[0].u_mu:.1e}"
    ('cylinder.radius_mm', '2.5e-06')
    >>> sorted(b.to_json())  # the keys it adds to fit.json
    ['U_mu', 'coverage_factor', 'u_mu', 'uncertainty', 'uncertainty_budget']
    """

    mu: float
    u_mu: float
    U_mu: float
    coverage_factor: float
    rows: tuple
    statistical: dict  # ordinary and corrected standard error, lag window, n
    exact: tuple  # setup keys taken as exact (no _u)
    length: dict | None = None  # self-calibrated L when asked
    monte_carlo: dict | None = None
    seconds: float = 0.0
    n_refits: int = 0
    order: int = 1  # of the law of propagation: 1, or 2 with the next-order terms

    def to_json(self) -> dict:
        """The fit.json keys: u_mu, U_mu, coverage_factor, uncertainty_budget, and details."""
        out = {"u_mu": self.u_mu, "U_mu": self.U_mu, "coverage_factor": self.coverage_factor,
               "uncertainty_budget": [r.to_dict() for r in self.rows],
               "uncertainty": {"method": "GUM (JCGM 100) " + (
                                   "first order" if self.order == 1 else
                                   "with the second-order terms of 5.1.2") +
                               ", inputs uncorrelated",
                               "mu": self.mu, "statistical": dict(self.statistical),
                               "exact_inputs": list(self.exact), "seconds": self.seconds,
                               "n_refits": self.n_refits}}
        if self.monte_carlo is not None:
            out["uncertainty"]["monte_carlo"] = dict(self.monte_carlo)
        if self.length is not None:
            out["length_fit"] = dict(self.length)
        return out





CONTOUR_NOTE = "found from the background's contour; u: its circle fit and edge definition"


def _contour_centre_as_input(meas: Measurement):
    """(measurement, True) with a contour-found centre and its u moved into the setup as
    ``center_px`` with ``center_px_u`` (then a source like a lab's measured centre), else
    (``meas``, False)."""
    s = meas.setup
    if not meas.from_centres or s.center_px is not None or meas.center_u is None:
        return meas, False
    setup = s.replace(center_px=tuple(meas.center),
                      uncertainty=tuple(s.uncertainty) + (("center_px",
                                                             tuple(meas.center_u)),))
    return dataclasses.replace(meas, setup=setup), True



# -- the budget -----------------------------------------------------------------------------

def budget(meas: Measurement, result, *, fit_length: bool = False, monte_carlo: int = 0,
           seed: int = 0, coverage_factor: float = COVERAGE_FACTOR,
           order: int = 1) -> Budget:
    """The uncertainty budget of ``result`` (a least-squares FitResult of ``meas``).

    ``fit_length``: fit L = R - r as well (self-calibration; mu and the budget then use the
    fitted L). ``monte_carlo``: that many draws of the uncertain inputs (normal, their u) each
    re-evaluated, plus a normal draw of the statistical part (JCGM 101), seeded by ``seed``.

    Parameters
    ----------
    meas : Measurement
        The measurement ``result`` was fitted to.
    result : FitResult
        Its least-squares fit (method "lsq").
    fit_length : bool
        Also fit L = R - r.
    monte_carlo : int
        Number of Monte-Carlo draws; 0 for none.
    seed : int
        Seed of the draws.
    coverage_factor : float
        k of the expanded uncertainty U = k u.
    order : int
        1 (default): the first-order law of propagation; 2: with the next-order terms of
        :func:`second_order` (the inputs' interactions and curvature), a row of their own.

    Returns
    -------
    Budget
        Rows largest first, combined and expanded uncertainty of mu.

    Raises
    ------
    rollfric.errors.InputError
        If ``result`` is not a least-squares ("lsq") fit.

    Examples
    --------
    The exact motion of a 10 mm ball (mu = 0.0079) in a vacuum, in a trough whose radius the
    lab knows to 0.05 mm: that uncertainty is the budget's largest row.

    >>> import numpy as np, rollfric
    >>> from rollfric.fit.eom import solve_reference
    >>> setup = rollfric.setup_from_dict({  # the exact motion below is airless
    ...     "cylinder": {"radius_mm": 85.3, "radius_mm_u": 0.05},
    ...     "ball": {"diameter_mm": 10.0, "mass_g": 4.07612},
    ...     "camera": {"fps": 1000, "pixel_size_mm": 0.1343},
    ...     "environment": {"air_density_kg_m3": 0}})
    >>> t = np.arange(2000) / 1000.0
    >>> theta, _, _ = solve_reference(np.radians(20.0), 0.0, 0.0079, t,
    ...                               track_radius=setup.track_radius)
    >>> result = rollfric.fit_mu(t, theta, setup)
    >>> b = rollfric.budget(rollfric.Measurement(setup=setup, t=t, theta=theta), result)
    >>> print(f"mu = {b.mu:.5f}, u_mu = {b.u_mu:.1e}, U_mu = {b.U_mu:.1e} "
    ...       f"(k = {b.coverage_factor:g})")
    mu = 0.00790, u_mu = 2.5e-06, U_mu = 5.1e-06 (k = 2)
    >>> b.rows[0].source
    'cylinder.radius_mm'
    """
    if result.method != "lsq":
        raise InputError(f"the uncertainty budget needs the lsq fit, not {result.method!r}")
    if order not in (1, 2):
        raise InputError(f"the budget's order must be 1 or 2, got {order!r}")
    start = time.perf_counter()
    meas, contour = _contour_centre_as_input(meas)
    setup = meas.setup
    refit = Refitter(meas, result, fit_length=fit_length)
    inputs = [(*i, why_not(meas, i[1], fit_length)) for i in setup_inputs(setup)]
    # the nominal fits and each acting input's fits at +-u are independent of one another:
    # made at once on the CPUs that are free, then found made below (the same fits; listed in
    # the order they are used, so a fit that fails raises as it would there)
    refit.prefetch([(setup, True, False), (setup, False, True)]
                   + [(moved(setup, field, comp, sign * u, factor), False, False)
                      for _, field, comp, _, u, factor, why in inputs if u != 0.0 and not why
                      for sign in (1.0, -1.0)]
                   + [(setup, False, False)])
    params, aug, ordinary, hac, u_stat, statistical = _statistical(refit, setup)
    mu = params["mu"]
    rows = [Row("statistical", None, u_stat, 1.0, u_stat,
                "least-squares standard error, corrected for correlated residuals (HAC)")]
    input_rows, exact, active, d_length = _input_rows(refit, setup, inputs, contour,
                                                      fit_length)
    rows += input_rows
    length = _length_fit(setup, params, ordinary, hac, d_length, result.mu) if fit_length \
        else None
    u_m, note, statistical["method"] = method_row(
        refit, setup, aug, _angle_inputs(meas, refit, setup, active), statistical["inflation"])
    rows.append(Row(METHOD, None, u_m, 1.0, u_m, note))
    built = as_built_rows(meas, result, refit, setup, params, fit_length=fit_length)
    rows += [Row(*r) for r in built.rows]
    exact += list(built.exact)
    motion, n_motion = motion_row(meas, result, setup, mu, fit_length=fit_length)
    if motion is not None:
        rows.append(Row(*motion))
    if order == 2 and active:
        u_2, note = propagation.second_order_row(refit, setup, active)
        rows.append(Row(SECOND_ORDER, None, u_2, 1.0, u_2, note))
    u_mu = math.sqrt(sum(r.u_mu**2 for r in rows))
    rows.sort(key=lambda r: -r.u_mu)
    mc = None
    if monte_carlo:
        mc = propagation.monte_carlo(refit, setup, mu, u_mu, u_stat, coverage_factor * u_mu,
                                     monte_carlo, seed, meas)
    return Budget(mu=mu, u_mu=u_mu, U_mu=coverage_factor * u_mu,
                  coverage_factor=coverage_factor, rows=tuple(rows), statistical=statistical,
                  exact=tuple(exact), length=length, monte_carlo=mc,
                  seconds=time.perf_counter() - start,
                  n_refits=refit.count + built.n_refits + n_motion, order=order)


def _statistical(refit: Refitter, setup: Setup):
    """The statistical row's part: (nominal parameters, noise fit's parameters, ordinary and
    HAC covariance of the nominal fit, u of mu, the details for fit.json). The covariance is
    the nominal fit's Jacobian with the noise fit's residuals (its free parameters: the
    motion's, L and the map's four coefficients); never below the ordinary error."""
    params, jac, res = refit.fit(setup, jacobian=True)
    names = list(params)
    aug, _, noise = refit.fit(setup, augmented=True)
    ordinary, hac, lag, rho = hac_covariance(jac, noise, dof=noise.size - len(aug) - 4)
    i_mu = names.index("mu")
    u_plain = float(math.sqrt(max(ordinary[i_mu, i_mu], 0.0)))
    u_hac = float(math.sqrt(max(hac[i_mu, i_mu], 0.0)))
    u_stat = max(u_plain, u_hac)
    statistical = {"stderr_ordinary": u_plain, "stderr_hac": u_hac, "lag_window": lag,
                   "noise_lag1_autocorrelation": rho,
                   "n_samples": int(res.size), "inflation": u_stat / u_plain
                   if u_plain > 0 else math.nan,
                   "rms_residual_rad": float(np.sqrt(np.mean(res**2))),
                   "rms_noise_rad": float(np.sqrt(np.mean(noise**2))),
                   "noise_fit": "L and a cubic map of the model angle (offset, gain, "
                                "2nd, 3rd order) freed"}
    return params, aug, ordinary, hac, u_stat, statistical


def _input_rows(refit: Refitter, setup: Setup, inputs: list, contour: bool, fit_length: bool):
    """The rows of the setup's inputs: (rows, keys taken as exact, the inputs that act as
    (source, field, component, u, factor), each acting input's half change of the fitted L
    over +-u when L is fitted). Sensitivity c = d mu / d input by central differences over
    +-u, each side a re-fit with the input moved; an input that cannot act gets a row of 0
    that says why."""
    rows, exact, active, d_length = [], [], [], []
    for source, field, comp, value, u, factor, why in inputs:
        if u == 0.0:
            exact.append(source)
            continue
        if why:
            rows.append(Row(source, value, u, 0.0, 0.0, why))
            continue
        hi = refit.fit(moved(setup, field, comp, u, factor))[0]
        lo = refit.fit(moved(setup, field, comp, -u, factor))[0]
        c = (hi["mu"] - lo["mu"]) / (2 * u)
        active.append((source, field, comp, u, factor))
        rows.append(Row(source, value, u, c, abs(c) * u,
                        CONTOUR_NOTE if contour and field == "center_px" else ""))
        if fit_length:
            d_length.append(0.5 * (hi["length"] - lo["length"]))
    return rows, exact, active, d_length


def _length_fit(setup: Setup, params: dict, ordinary, hac, d_length: list,
                mu_nominal_l: float) -> dict:
    """fit.json's ``length_fit``: the fitted L with its uncertainty (the fit's statistical
    variance plus each input's ``d_length`` squared) beside the nominal L."""
    i_l = list(params).index("length")
    u_l2 = max(hac[i_l, i_l], ordinary[i_l, i_l], 0.0)  # variance of the fitted L (m^2)
    for d in d_length:
        u_l2 += d ** 2
    uR, ud = setup.u("cylinder_radius"), setup.u("ball_diameter")
    u_nom = (math.hypot(uR or 0.0, 0.5 * (ud or 0.0))
             if uR is not None or ud is not None else None)
    return {"L_fit_mm": params["length"] * 1e3, "u_L_fit_mm": math.sqrt(u_l2) * 1e3,
            "u_L_fit_statistical_mm": math.sqrt(max(hac[i_l, i_l], ordinary[i_l, i_l],
                                                    0.0)) * 1e3,
            "L_nominal_mm": setup.track_radius * 1e3,
            "u_L_nominal_mm": None if u_nom is None else u_nom * 1e3,
            "mu_nominal_L": mu_nominal_l, "mu_fitted_L": params["mu"]}


def _angle_inputs(meas: Measurement, refit: Refitter, setup: Setup, active: list) -> list:
    """The angle changes over +-u (at the fitted samples) of the acting inputs that act on
    the angles (centre, lens, arcsin's pixel size), whose smooth maps their rows hold."""
    angle_inputs = []
    if meas.from_centres:
        for _, field, comp, u, factor in active:
            _, th_hi = meas.series(moved(setup, field, comp, u, factor))
            _, th_lo = meas.series(moved(setup, field, comp, -u, factor))
            dth = (th_hi - th_lo)[refit.mask]
            if np.any(np.isfinite(dth) & (dth != 0.0)):
                angle_inputs.append(np.nan_to_num(dth))
    return angle_inputs
