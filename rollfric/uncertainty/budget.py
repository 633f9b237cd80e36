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

- ``"method (angle map)"``: the measurement's own smooth angle error (a locator's error that
  varies smoothly with the angle, e.g. a lamp's shadow or highlight), which the noise fit
  absorbs into its angle map: the 2nd and 3rd order of that map through the nominal fit's
  weights, less its noise part, 0 unless above twice it; the part of the map the uncertain
  angle inputs (centre, lens) could make is theirs and projected out (:func:`_method_row`).

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
import logging
import math
import time

import numpy as np
from scipy import optimize

from rollfric import parallel as cpus
from rollfric.errors import InputError
from rollfric.fit import eom
from rollfric.fit.air import WALL_FACTOR_U, coefficients_of
from rollfric.fit.hac import autocorrelation, hac_covariance  # noqa: F401 (re-exported)
from rollfric.geometry.theta import centre_angles
from rollfric.setup.model import LAB_KEYS, Setup, SetupError

COVERAGE_FACTOR = 2.0
# parameter -> (lower, upper, typical scale) of the local re-fits (as in rollfric.fit.estimate)
_BOUNDS = {"mu": (0.0, 1.0, 1e-3), "theta0": (-math.pi / 2, math.pi / 2, 1e-3),
           "omega0": (-np.inf, np.inf, 1e-2), "offset": (-0.5, 0.5, 1e-3),
           "mu1": (0.0, np.inf, 1e-3)}
_FIT_PARAMS = ("mu", "theta0", "omega0", "offset", "mu1")


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


# -- the statistical part: rollfric.fit.hac (re-exported here) ---------------------------------

# -- re-evaluating the measurement ----------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Measurement:
    """What a re-evaluation needs: the located centres (``x``, ``y`` px at ``frames``) about
    ``center`` with ``angle`` ("atan2" or "arcsin"), or the given angles ``theta`` at times
    ``t`` (a track CSV: no centres; its t_s taken as frame / camera.fps). Centres with ``t``:
    the recording's own timestamps (the frame rate then does not act). NaN entries are frames
    without a ball. ``center_u``: the standard uncertainty (px, x and y) of a ``center`` found
    from the background's contour (the setup then has no center_px); it makes the centre a
    source of the budget as a setup's ``center_px_u`` does. ``distorted``: ``x``, ``y`` are
    positions in the recorded image, undistorted with the setup's lens calibration before the
    angles (so a moved calibration moves them); ``center`` is in the undistorted image.

    Parameters
    ----------
    setup : Setup
        The nominal setup.
    frames, x, y : numpy.ndarray, optional
        Frame numbers and located centres (px).
    center : tuple of float, optional
        The cylinder axis the angles are taken about (px).
    angle : {"atan2", "arcsin"}, optional
        The angle formula (:func:`rollfric.geometry.theta.angles`).
    t, theta : numpy.ndarray, optional
        Times (s) and given angles (rad).
    center_u : tuple of float, optional
        Standard uncertainty of a contour-found ``center`` (px).
    distorted : bool, optional
        ``x``, ``y`` are in the recorded (distorted) image.

    Examples
    --------
    Two located centres, re-evaluated with the trough's centre 1 px to the right:

    >>> import numpy as np, rollfric
    >>> setup = rollfric.thesis_setup("10mm")
    >>> meas = rollfric.Measurement(setup=setup, frames=np.array([0.0, 1.0]),
    ...                             x=np.array([100.0, 110.0]), y=np.array([700.0, 700.0]),
    ...                             center=(100.0, 100.0))
    >>> t, theta = meas.series(setup)
    >>> t, theta.round(5)
    (array([0.   , 0.001]), array([0.     , 0.01667]))
    >>> meas.series(setup.replace(center_px=(101.0, 100.0)))[1].round(5)
    array([-0.00167,  0.015  ])
    """

    setup: Setup
    frames: np.ndarray | None = None
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    center: tuple[float, float] | None = None
    angle: str = "atan2"
    t: np.ndarray | None = None
    theta: np.ndarray | None = None
    center_u: tuple[float, float] | None = None
    distorted: bool = False
    # a tilted camera's compression undone about the centre before the angles
    # (rollfric.geometry.pathshape; TrackInfo.angle_map); None: none
    angle_map: tuple | None = None

    @property
    def from_centres(self) -> bool:
        """True when the measurement holds located centres, False for given angles."""
        return self.x is not None

    def series(self, setup: Setup):
        """(t, theta) of the measurement with ``setup`` in place of the nominal one.

        Parameters
        ----------
        setup : Setup
            The setup to evaluate with (centre, pixel size, radius, frame rate).

        Returns
        -------
        t : numpy.ndarray
            Times, s.
        theta : numpy.ndarray
            Angles, rad (NaN where no ball).
        """
        if self.from_centres:
            center = setup.center_px if setup.center_px is not None else self.center
            # as the measurement did (rollfric.track.tracker): undistorted, mapped, the angles
            th, _, _ = centre_angles(self.x, self.y, center, setup, method=self.angle,
                                     distorted=self.distorted, angle_map=self.angle_map)
            if self.t is not None:
                return np.asarray(self.t, dtype=float), th
            return np.asarray(self.frames, dtype=float) / setup.fps, th
        return np.asarray(self.t, dtype=float) * (self.setup.fps / setup.fps), \
            np.asarray(self.theta, dtype=float)


def measurement_from_track(track, info) -> Measurement:
    """A :class:`Measurement` from ``rollfric.measurement.measure``'s track DataFrame.

    Parameters
    ----------
    track : pandas.DataFrame
        Columns ``frame``, ``found``, ``x_px``, ``y_px`` (in the recorded image), ``t_s``.
    info : rollfric.track.track_info.TrackInfo
        How it was measured: ``setup`` (the nominal setup), ``center_px``, ``angle`` and
        ``times`` (the recording's timestamps unless it is "frame / camera.fps").

    Returns
    -------
    Measurement
        Centres (NaN where the ball was not found), with the track's times when they are the
        recording's own timestamps, and the contour-found centre's uncertainty
        (``info.center_u_px``) when the setup gave no centre.

    Examples
    --------
    The shipped sample recording, measured, then its uncertainty budget:

    >>> import tempfile, rollfric
    >>> from pathlib import Path
    >>> from rollfric.sample import write_sample
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = write_sample(Path(tmp.name) / "sample")
    >>> track, info, result = rollfric.measure(folder / "frames.tif", folder / "setup.toml")
    >>> meas = rollfric.measurement_from_track(track, info)
    >>> meas.from_centres, meas.center, len(meas.x)
    (True, (191.0, -532.0), 400)
    >>> b = rollfric.budget(meas, result)
    >>> b.rows[0].source, abs(b.mu - 0.0079) < b.U_mu
    ('cylinder.center_px[x]', True)
    >>> tmp.cleanup()
    """
    center = tuple(info.center_px)
    center_u = getattr(info, "center_u_px", None)
    found = track["found"].to_numpy() == 1
    # located in the recorded image; with a lens calibration they are undistorted for the
    # angles (as the measurement did), so that a moved calibration can act
    x = np.where(found, track["x_px"].to_numpy(float), np.nan)
    y = np.where(found, track["y_px"].to_numpy(float), np.nan)
    stamped = info.times != "frame / camera.fps"
    # frame / fps times count the camera's periods: the frame number plus the periods of the
    # dropped frames found before it (rollfric.track.dropped_frames), which t_s holds
    frames = track["frame"].to_numpy(float) if stamped else \
        np.rint(track["t_s"].to_numpy(float) * info.setup.fps)
    return Measurement(setup=info.setup, frames=frames, x=x, y=y,
                       center=center, angle=info.angle,
                       t=track["t_s"].to_numpy(float) if stamped else None,
                       center_u=None if center_u is None or info.setup.center_px is not None
                       else tuple(float(v) for v in center_u),
                       distorted=bool(info.undistorted),
                       angle_map=getattr(info, "angle_map", None))


def _fitted_mask(t, theta, n_samples):
    """The samples the nominal fit used: the first ``n_samples`` finite ones (it ends a
    quarter period before the ball rests for good)."""
    good = np.isfinite(t) & np.isfinite(theta)
    return good & (np.cumsum(good) <= n_samples)


class _Refitter:
    """Local least-squares re-fits from the nominal solution, memoised on their inputs."""

    def __init__(self, meas: Measurement, result, *, fit_length: bool):
        self.meas = meas
        self.result = result
        self.names = [n for n in result.stderr if n in _FIT_PARAMS] or ["mu", "theta0",
                                                                         "omega0"]
        self.start = {"mu": result.mu, "theta0": result.theta0, "omega0": result.omega0,
                      "offset": result.offset, "mu1": result.mu1}
        self.fit_length = fit_length
        t, th = meas.series(meas.setup)
        used = getattr(result, "used", None)
        # the samples the nominal fit used (it may leave outliers out, not only the rest)
        self.mask = used if used is not None and used.shape == t.shape else \
            _fitted_mask(t, th, result.n_samples)
        self.count = 0
        self._cache: dict = {}

    def fit(self, setup: Setup, *, jacobian: bool = False, augmented: bool = False):
        """(parameter dict, Jacobian or None, residuals) of the fit with ``setup``.

        ``augmented``: also free L and a cubic map of the model's angle onto the measured one,
        off + (1 + g1) theta + g2 theta^2 + g3 theta^3 (what a wrong centre, radius, frame
        rate, pixel scale or a lens does to the angles, to third order): a fit whose residuals
        are the noise, not the misfit a setup error leaves."""
        key, t, th = self._key(setup, jacobian, augmented)
        if key not in self._cache:
            self._cache[key] = self._solve(t, th, setup, jacobian, augmented)
            self.count += 1
        return self._cache[key]

    def prefetch(self, jobs) -> None:
        """Make the fits ``jobs`` = [(setup, jacobian, augmented), ...] that are not made yet
        on the CPUs that are free (:func:`rollfric.parallel.map_ordered`): :meth:`fit` then finds
        them made. Each is the fit :meth:`fit` would make, so the results, and ``count``, are
        those of calling :meth:`fit` with them one after another."""
        todo = {}
        for setup, jacobian, augmented in jobs:
            key, t, th = self._key(setup, jacobian, augmented)
            if key not in self._cache and key not in todo:
                todo[key] = (t, th, setup, jacobian, augmented)
        done = cpus.map_ordered(lambda job: self._solve(*job), todo.values(),
                                name="rollfric-budget")
        for key, out in zip(todo, done, strict=True):
            self._cache[key] = out
            self.count += 1

    def _key(self, setup: Setup, jacobian: bool, augmented: bool):
        t, th = self.meas.series(setup)
        t, th = t[self.mask], th[self.mask]
        return (t.tobytes(), th.tobytes(), setup.track_radius, setup.gravity,
                coefficients_of(setup).tobytes(), jacobian, augmented), t, th

    def _solve(self, t, th, setup: Setup, jacobian: bool, augmented: bool):
        L0, g = setup.track_radius, setup.gravity
        air = coefficients_of(setup)
        names = list(self.names) + (["length"] if self.fit_length else [])
        start = dict(self.start, length=L0)
        if augmented:
            # variable projection: the map's four coefficients are linear, solved for in
            # every evaluation; the motion (theta0 in the model's own angle) and L are free
            names = [n for n in names if n != "offset"] + \
                ([] if self.fit_length else ["length"])
            start["theta0"] = self.start["theta0"] - self.start["offset"]
        bounds = dict(_BOUNDS, length=(0.5 * L0, 2.0 * L0, 1e-4))
        lower = np.array([bounds[n][0] for n in names])
        upper = np.array([bounds[n][1] for n in names])
        scale = np.array([bounds[n][2] for n in names])
        x0 = np.clip([start[n] for n in names], lower, upper)

        def residual(x):
            p = dict(zip(names, x, strict=True))
            off = p.get("offset", 0.0)
            m, _, _ = eom.solve(p["theta0"] - off, p["omega0"], p["mu"], t,
                                track_radius=p.get("length", L0), gravity=g,
                                mu1=p.get("mu1", 0.0), air=air)
            if augmented:
                basis = np.stack([np.ones_like(m), m, m * m, m * m * m], axis=1)
                coef, *_ = np.linalg.lstsq(basis, th, rcond=None)
                return basis @ coef - th
            return m + off - th

        sol = optimize.least_squares(residual, x0, bounds=(lower, upper), x_scale=scale,
                                     xtol=1e-10, ftol=1e-10, gtol=1e-10,
                                     max_nfev=200)
        return (dict(zip(names, (float(v) for v in sol.x), strict=True)),
                sol.jac if jacobian else None, sol.fun)

    def mu(self, setup: Setup) -> float:
        return self.fit(setup)[0]["mu"]


# the budget row of the drag law's wall factor (rollfric.fit.air), when no air_cd is given
AIR_LAW = "environment.air_cd (drag law: wall factor)"


# -- the inputs -----------------------------------------------------------------------------

def _inputs(setup: Setup):
    """(source name, setup field, component or None, value in lab units, u in lab units,
    factor lab -> SI) for every numeric setup input; u 0 where exact."""
    out = []
    for name, (section, key, scale) in LAB_KEYS.items():
        value = getattr(setup, name)
        u = setup.u(name)
        if name == "center_px":
            if value is None:
                continue
            for i, axis in enumerate("xy"):
                out.append((f"{section}.{key}[{axis}]", name, i, float(value[i]),
                            0.0 if u is None else float(u[i]), 1.0))
            continue
        if name in ("air_viscosity", "air_cd") and setup.air_density == 0.0:
            continue  # no air: nothing for them to act on
        if name == "air_cd" and value is None:
            if setup.air_density > 0:  # the drag law's own uncertainty: its wall factor
                out.append((AIR_LAW, "air_wall_factor", None, setup.air_wall_factor,
                            WALL_FACTOR_U, 1.0))
            continue
        out.append((f"{section}.{key}", name, None, float(value) * scale,
                    0.0 if u is None else float(u) * scale, 1.0 / scale))
    cal = setup.calibration
    if cal is not None:
        params = cal.parameters()
        if any(u > 0 for _, _, u in params):
            for name, value, u in params:
                out.append((f"camera.{name}", "calibration", name, float(value), float(u),
                            1.0))
        else:
            out.append(("camera.matrix, camera.distortion", "calibration", None, 0.0, 0.0,
                        1.0))
    return out


def _moved(setup: Setup, field: str, component, delta_lab: float, factor: float) -> Setup:
    if field == "calibration":
        return setup.replace(calibration=setup.calibration.moved(component, delta_lab))
    if field == "center_px":
        c = list(setup.center_px)
        c[component] += delta_lab
        return dataclasses.replace(setup, center_px=tuple(c))
    try:
        return dataclasses.replace(setup, **{field: getattr(setup, field) + delta_lab * factor})
    except SetupError as exc:  # a _u as large as its value: name the key, not the field
        section, key, scale = LAB_KEYS[field]
        raise SetupError(
            f"{section}.{key}_u = {setup.u(field) * scale:g}: the uncertainty budget re-fits "
            f"with {section}.{key} = {getattr(setup, field) * scale:g} moved by "
            f"{delta_lab:+g}, which is no setup ({exc}): is its standard uncertainty that "
            "large?") from None


def _acts(meas: Measurement, field: str) -> str:
    """'' when ``field`` can change mu in this measurement, else why not."""
    if field in ("air_viscosity", "air_cd", "air_wall_factor") \
            and meas.setup.air_density == 0.0:
        return "no air (environment.air_density_kg_m3 = 0)"
    if field == "ball_mass":
        return "enters no step of the measurement (mu is defined by M = mu r N)"
    if field in ("center_px", "pixel_size", "calibration") and not meas.from_centres:
        return "cannot act on a track of given angles"
    if field == "calibration" and not meas.distorted:
        return "the centres were given undistorted"
    if field == "fps" and meas.from_centres and meas.t is not None:
        return "times are the recording's own timestamps"
    if field == "pixel_size" and meas.angle == "atan2":
        return "atan2 angles do not depend on the pixel scale"
    return ""


def _why_not(meas: Measurement, field: str, fit_length: bool) -> str:
    """'' when ``field`` acts on mu in the budget, else why not (:func:`_acts`; with
    ``fit_length`` the inputs that act only through L or g do not)."""
    why = _acts(meas, field)
    if fit_length and field in ("cylinder_radius", "ball_diameter", "gravity") and not why:
        if not (meas.from_centres and meas.angle == "arcsin"):
            why = "acts only through L/g, which is fitted (self-calibration)"
    return why


# -- beyond first order: GUM 5.1.2, note ----------------------------------------------------

def second_order(evaluate, n: int) -> tuple[float, list]:
    """The next-order terms of the law of propagation for ``n`` independent normal inputs
    (JCGM 100, 5.1.2, note): sum over i, j of [(1/2) (d2f/dxi dxj)^2 + df/dxi d3f/dxi dxj^2]
    u^2(xi) u^2(xj), the derivatives by finite differences over steps of one and two standard
    uncertainties.

    ``evaluate(k)`` is the measurand with input i moved by ``k[i]`` of its standard
    uncertainties (k a tuple of n integers, 0 the estimate). With df_i = f_i u_i, d2_i =
    f_ii u_i^2 and so on, all in the measurand's unit: a pair (i, j), counted for (i, j) and
    (j, i), is m_ij^2 + df_i t_ijj + df_j t_jii (m_ij = f_ij u_i u_j from the four corners
    +-u_i +-u_j, t_ijj = f_ijj u_i u_j^2 from the same corners); a pure term (i = j) is
    d2_i^2 / 2 + (2/3) df_i d3_i (d3 from the steps of +-2 u): the first-order rows are
    secants over +-u, (f_i + f_iii u_i^2 / 6) u_i, whose square already holds a third of
    f_i f_iii u_i^4. So first-order secant rows plus these terms give the variance to the
    fourth order in u, exactly for a polynomial of degree 3 in each input with interactions
    of degree 2 (x_i x_j, x_i x_j^2). The sum may be negative (a curvature that narrows
    the distribution).

    Parameters
    ----------
    evaluate : callable
        k -> the measurand (float) with the inputs moved by k standard uncertainties.
    n : int
        Number of inputs.

    Returns
    -------
    variance : float
        The sum of the terms (the measurand's unit squared).
    terms : list of tuple
        (i, j, term) for every pure (i == j) and pair (i < j) term.
    """
    def f(*moves):
        k = [0] * n
        for i, step in moves:
            k[i] += step
        return float(evaluate(tuple(k)))

    f0 = f()
    df, d2, terms = [], [], []
    for i in range(n):
        hi, lo = f((i, 1)), f((i, -1))
        hi2, lo2 = f((i, 2)), f((i, -2))
        df.append(0.5 * (hi - lo))
        d2.append(hi + lo - 2.0 * f0)
        d3 = 0.5 * (hi2 - 2.0 * hi + 2.0 * lo - lo2)
        terms.append((i, i, 0.5 * d2[i] ** 2 + (2.0 / 3.0) * df[i] * d3))
    for i in range(n):
        for j in range(i + 1, n):
            c = {(a, b): f((i, a), (j, b)) for a in (1, -1) for b in (1, -1)}
            m = 0.25 * (c[1, 1] - c[1, -1] - c[-1, 1] + c[-1, -1])
            # the curvature along j at x_i +- u_i, and along i at x_j +- u_j
            t_ijj = 0.5 * ((c[1, 1] + c[1, -1] - 2.0 * f((i, 1)))
                           - (c[-1, 1] + c[-1, -1] - 2.0 * f((i, -1))))
            t_jii = 0.5 * ((c[1, 1] + c[-1, 1] - 2.0 * f((j, 1)))
                           - (c[1, -1] + c[-1, -1] - 2.0 * f((j, -1))))
            terms.append((i, j, m * m + df[i] * t_ijj + df[j] * t_jii))
    return float(sum(t for _, _, t in terms)), terms


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
    refit = _Refitter(meas, result, fit_length=fit_length)
    inputs = [(*i, _why_not(meas, i[1], fit_length)) for i in _inputs(setup)]
    # the nominal fits and each acting input's fits at +-u are independent of one another:
    # made at once on the CPUs that are free, then found made below (the same fits; listed in
    # the order they are used, so a fit that fails raises as it would there)
    refit.prefetch([(setup, True, False), (setup, False, True)]
                   + [(_moved(setup, field, comp, sign * u, factor), False, False)
                      for _, field, comp, _, u, factor, why in inputs if u != 0.0 and not why
                      for sign in (1.0, -1.0)]
                   + [(setup, False, False)])
    params, jac, res = refit.fit(setup, jacobian=True)
    names = list(params)
    aug, _, noise = refit.fit(setup, augmented=True)
    # its free parameters: the motion's, L and the map's four coefficients
    ordinary, hac, lag, rho = hac_covariance(jac, noise, dof=noise.size - len(aug) - 4)
    i_mu = names.index("mu")
    u_plain = float(math.sqrt(max(ordinary[i_mu, i_mu], 0.0)))
    u_hac = float(math.sqrt(max(hac[i_mu, i_mu], 0.0)))
    u_stat = max(u_plain, u_hac)
    mu = params["mu"]
    statistical = {"stderr_ordinary": u_plain, "stderr_hac": u_hac, "lag_window": lag,
                   "noise_lag1_autocorrelation": rho,
                   "n_samples": int(res.size), "inflation": u_stat / u_plain
                   if u_plain > 0 else math.nan,
                   "rms_residual_rad": float(np.sqrt(np.mean(res**2))),
                   "rms_noise_rad": float(np.sqrt(np.mean(noise**2))),
                   "noise_fit": "L and a cubic map of the model angle (offset, gain, "
                                "2nd, 3rd order) freed"}
    rows = [Row("statistical", None, u_stat, 1.0, u_stat,
                "least-squares standard error, corrected for correlated residuals (HAC)")]
    exact = []
    length = None
    active = []  # the inputs that act: (source, field, component, u, factor)
    u_l2 = 0.0  # variance of the fitted L (m^2)
    if fit_length:
        i_l = names.index("length")
        u_l2 = max(hac[i_l, i_l], ordinary[i_l, i_l], 0.0)
    for source, field, comp, value, u, factor, why in inputs:
        if u == 0.0:
            exact.append(source)
            continue
        if why:
            rows.append(Row(source, value, u, 0.0, 0.0, why))
            continue
        hi = refit.fit(_moved(setup, field, comp, u, factor))[0]
        lo = refit.fit(_moved(setup, field, comp, -u, factor))[0]
        c = (hi["mu"] - lo["mu"]) / (2 * u)
        active.append((source, field, comp, u, factor))
        rows.append(Row(source, value, u, c, abs(c) * u,
                        CONTOUR_NOTE if contour and field == "center_px" else ""))
        if fit_length:
            u_l2 += (0.5 * (hi["length"] - lo["length"])) ** 2
    if fit_length:
        uR, ud = setup.u("cylinder_radius"), setup.u("ball_diameter")
        u_nom = (math.hypot(uR or 0.0, 0.5 * (ud or 0.0))
                 if uR is not None or ud is not None else None)
        length = {"L_fit_mm": params["length"] * 1e3, "u_L_fit_mm": math.sqrt(u_l2) * 1e3,
                  "u_L_fit_statistical_mm": math.sqrt(max(hac[i_l, i_l], ordinary[i_l, i_l],
                                                          0.0)) * 1e3,
                  "L_nominal_mm": setup.track_radius * 1e3,
                  "u_L_nominal_mm": None if u_nom is None else u_nom * 1e3,
                  "mu_nominal_L": result.mu, "mu_fitted_L": mu}
    # the inputs that act on the angles (centre, lens, arcsin's pixel size): their angle
    # changes over +-u, whose smooth maps their rows hold
    angle_inputs = []
    if meas.from_centres:
        _, th0 = meas.series(setup)
        for _, field, comp, u, factor in active:
            _, th_hi = meas.series(_moved(setup, field, comp, u, factor))
            _, th_lo = meas.series(_moved(setup, field, comp, -u, factor))
            dth = (th_hi - th_lo)[refit.mask]
            if np.any(np.isfinite(dth) & (dth != 0.0)):
                angle_inputs.append(np.nan_to_num(dth))
    method, statistical["method"] = _method_row(refit, setup, aug, angle_inputs,
                                                statistical["inflation"])
    rows.append(method)
    if order == 2 and active:
        rows.append(_second_order_row(refit, setup, active))
    u_mu = math.sqrt(sum(r.u_mu**2 for r in rows))
    rows.sort(key=lambda r: -r.u_mu)
    mc = None
    if monte_carlo:
        mc = _monte_carlo(refit, setup, mu, u_mu, u_stat, coverage_factor * u_mu, monte_carlo,
                          seed, meas)
    return Budget(mu=mu, u_mu=u_mu, U_mu=coverage_factor * u_mu,
                  coverage_factor=coverage_factor, rows=tuple(rows), statistical=statistical,
                  exact=tuple(exact), length=length, monte_carlo=mc,
                  seconds=time.perf_counter() - start, n_refits=refit.count, order=order)


SECOND_ORDER = "second order"
METHOD = "method (angle map)"
METHOD_SIGNIFICANCE = 2.0  # |d| above this many of its noise parts: a smooth angle error
METHOD_NOTE = ("the pipeline's own smooth angle error (the locator's, e.g. a lamp's highlight "
               "or shadow): what the 2nd and 3rd order of the angle map the noise fit absorbs "
               "do to mu, less its noise part; 0 unless above twice that")


def _method_row(refit: _Refitter, setup: Setup, aug: dict, angle_inputs: list,
                inflation: float) -> tuple[Row, dict]:
    """The budget row of the measurement's own smooth angle error, a Type A evaluation from
    the record (see the module docstring): the 2nd and 3rd order part of the noise fit's
    angle map (c2 m^2 + c3 m^3 over the model angle m), less what the uncertain inputs that
    act on the angles (``angle_inputs``: their angle changes over +-u) could make (their own
    rows hold that), propagated to mu through the nominal fit's least-squares weights: d. Its
    noise part, the standard deviation s of the same linear functional of white noise of the
    noise fit's rms (times the statistical row's HAC inflation), is removed:
    u = sqrt(d^2 - s^2) when |d| > 2 s (a smooth angle error the record shows), else 0 (d is
    the noise the statistical row holds). Returns the row and its details."""
    t, th = refit.meas.series(setup)
    t, th = t[refit.mask], th[refit.mask]
    m, _, _ = eom.solve(aug["theta0"], aug["omega0"], aug["mu"], t,
                        track_radius=aug.get("length", setup.track_radius),
                        gravity=setup.gravity, mu1=aug.get("mu1", 0.0),
                        air=coefficients_of(setup))
    basis = np.stack([np.ones_like(m), m, m * m, m * m * m], axis=1)
    pinv = np.linalg.pinv(basis)
    high = basis[:, 2:]
    _, jac, _ = refit.fit(setup, jacobian=True)
    names = list(refit.fit(setup)[0])
    w = np.linalg.pinv(jac)[names.index("mu")]  # d mu / d theta_t of the nominal fit
    # the part of the map's 2nd/3rd order the uncertain angle inputs could make is theirs
    eff = [(high @ (pinv @ d)[2:]) for d in angle_inputs]
    eff = [e for e in eff if np.any(e != 0.0)]
    w_eff = w
    if eff:
        a = np.stack(eff, axis=1)
        w_eff = w - a @ (np.linalg.pinv(a) @ w)  # (I - P) w, P the projector onto their span
    v = (w_eff @ high) @ pinv[2:]  # d = v . theta
    d = float(v @ th)
    noise = refit.fit(setup, augmented=True)[2]
    s = float(np.sqrt(np.sum(v * v)) * np.sqrt(np.mean(noise**2))
              * (inflation if inflation > 1.0 else 1.0))
    # an estimate within twice its noise part is noise: the statistical row holds it
    u = math.sqrt(d * d - s * s) if abs(d) > METHOD_SIGNIFICANCE * s else 0.0
    coef = pinv @ th
    details = {"map_c2": float(coef[2]), "map_c3": float(coef[3]), "d_mu": d,
               "d_mu_noise": s, "u_mu": u, "angle_inputs_projected_out": len(eff)}
    note = METHOD_NOTE + f"; d = {d:.2g}, noise part {s:.2g}"
    return Row(METHOD, None, u, 1.0, u, note), details


def _second_order_row(refit: _Refitter, setup: Setup, active: list) -> Row:
    """The row of the next-order terms (:func:`second_order`) over the acting inputs, each
    evaluation a re-fit with the inputs moved together; its u_mu the root of their sum when
    positive, 0 when the curvature narrows the distribution (the first-order rows are then
    kept as they are: on the safe side). Its note names the largest terms."""
    def evaluate(k):
        s = setup
        for (_, field, comp, u, factor), ki in zip(active, k, strict=True):
            if ki:
                s = _moved(s, field, comp, ki * u, factor)
        return refit.mu(s)

    var, terms = second_order(evaluate, len(active))
    names = [a[0] for a in active]
    top = sorted(terms, key=lambda t: -abs(t[2]))[:3]
    sign = lambda v: "-" if v < 0 else ""  # noqa: E731
    note = "GUM 5.1.2 note: inputs' interactions and curvature; largest: " + ", ".join(
        (f"{names[i]}" if i == j else f"{names[i]} x {names[j]}")
        + f" {sign(t)}{math.sqrt(abs(t)):.2g}" for i, j, t in top if t != 0.0)
    return Row(SECOND_ORDER, None, math.sqrt(max(var, 0.0)), 1.0, math.sqrt(max(var, 0.0)),
               note)


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


def _monte_carlo(refit: _Refitter, setup: Setup, mu, u_mu, u_stat, U, n, seed, meas) -> dict:
    """JCGM 101: propagate normal draws of every uncertain input through re-evaluations."""
    rng = np.random.default_rng(seed)
    active = [(f, c, u, k) for _, f, c, _, u, k in _inputs(setup)
              if u > 0 and not _acts(meas, f)]
    draws = np.empty(n)
    for i in range(n):
        s = setup
        for field, comp, u, factor in active:
            s = _moved(s, field, comp, float(rng.normal(0.0, u)), factor)
        draws[i] = refit.mu(s) + rng.normal(0.0, u_stat)
    lo, hi = np.percentile(draws, [2.5, 97.5])
    sd = float(np.std(draws, ddof=1))
    # JCGM 101 section 8: the GUM interval is validated when both endpoints agree with the
    # Monte-Carlo ones within delta, half a unit of the last of two significant digits of u
    delta = 0.5 * 10.0 ** (math.floor(math.log10(u_mu)) - 1) if u_mu > 0 else 0.0
    d_low, d_high = abs(mu - U - lo), abs(mu + U - hi)
    return {"draws": n, "seed": seed, "mean": float(np.mean(draws)), "u_mu": sd,
            "interval_95": [float(lo), float(hi)], "d_low": d_low, "d_high": d_high,
            "delta": delta, "gum_validated": bool(d_low <= delta and d_high <= delta)}


# -- reporting ------------------------------------------------------------------------------

def format_budget(b: Budget) -> str:
    """The budget as a small text table, largest first.

    Parameters
    ----------
    b : Budget
        The budget.

    Returns
    -------
    str
        The table, lines joined by newlines (no trailing newline).
    """
    rel = (lambda v: f"{100 * v / b.mu:6.3f} %") if b.mu > 0 else (lambda v: "      -")
    lines = [f"uncertainty budget of mu = {b.mu:.6g} (GUM, "
             f"{'first order' if b.order == 1 else 'second order'}):",
             f"  {'source':<26} {'value':>11} {'u':>10} {'sensitivity':>12} {'u(mu)':>10}"
             f" {'rel.':>8}"]
    for r in b.rows:
        value = "" if r.value is None else f"{r.value:.6g}"
        sens = "" if r.sensitivity is None or r.source in ("statistical", SECOND_ORDER,
                                                           METHOD) else \
            f"{r.sensitivity:+.3e}"
        lines.append(f"  {r.source:<26} {value:>11} {r.u:>10.3g} {sens:>12} {r.u_mu:>10.3g}"
                     f" {rel(r.u_mu):>8}" + (f"  ({r.note})" if r.note and (
                         r.u_mu == 0 or r.note == CONTOUR_NOTE or r.source == SECOND_ORDER
                         or r.source == METHOD)
                         else ""))
    lines.append(f"  combined u(mu) = {b.u_mu:.3g} ({rel(b.u_mu).strip()}), expanded U(mu) = "
                 f"{b.U_mu:.3g} ({rel(b.U_mu).strip()}, k = {b.coverage_factor:g})")
    st = b.statistical
    lines.append(f"  statistical: ordinary {st['stderr_ordinary']:.3g}, corrected x"
                 f"{st['inflation']:.2f} for correlated residuals (lag window "
                 f"{st['lag_window']})")
    if b.exact:
        lines.append(f"  taken as exact (no _u in the setup): {', '.join(b.exact)}")
    if b.length is not None:
        ln = b.length
        nom = "" if ln["u_L_nominal_mm"] is None else f" +- {ln['u_L_nominal_mm']:.3g}"
        lines.append(f"  L = R - r fitted: {ln['L_fit_mm']:.4f} +- {ln['u_L_fit_mm']:.2g} mm "
                     f"(nominal {ln['L_nominal_mm']:.4f}{nom} mm); mu with the nominal L "
                     f"{ln['mu_nominal_L']:.6g}")
    if b.monte_carlo is not None:
        m = b.monte_carlo
        lines.append(f"  Monte Carlo ({m['draws']} draws, seed {m['seed']}): u(mu) "
                     f"{m['u_mu']:.3g}, 95 % interval [{m['interval_95'][0]:.6g}, "
                     f"{m['interval_95'][1]:.6g}]; GUM interval "
                     f"{'validated' if m['gum_validated'] else 'not validated'} "
                     f"(endpoint differences {m['d_low']:.2g}, {m['d_high']:.2g}, "
                     f"tolerance {m['delta']:.2g})")
    lines.append(f"  budget: {b.n_refits} re-fits, {b.seconds:.2f} s")
    return "\n".join(lines)


def check_arguments(args) -> None:
    """Refuse budget options no run can use, before the command does any work.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options of :func:`rollfric.cli.fit.add_budget_arguments`.

    Raises
    ------
    rollfric.errors.InputError
        If ``--monte-carlo`` or ``--seed`` is negative.
    """
    if args.monte_carlo < 0:
        raise InputError(f"--monte-carlo must be >= 0, got {args.monte_carlo}")
    if args.seed < 0:
        raise InputError(f"--seed must be >= 0, got {args.seed}")


# a budget whose expanded uncertainty reaches mu (mu within 2 u(mu) of 0, as quality's mu_bound
# judges the statistical error alone) has not measured mu: suspect, naming what dominates
BUDGET_MU_SIGMAS_MIN = 2.0


def budget_reason(b: Budget | None):
    """The quality reason of a budget that does not determine mu, or None.

    Parameters
    ----------
    b : Budget or None
        The budget of a result (None: no budget, no reason).

    Returns
    -------
    rollfric.uncertainty.quality.Reason or None
        ``uncertainty`` when mu < BUDGET_MU_SIGMAS_MIN u(mu) (U(mu) >= mu at k = 2), naming
        the row that dominates u(mu)^2 and, for a setup key, its ``_u`` key.
    """
    from rollfric.uncertainty.quality import Reason

    if b is None or not math.isfinite(b.u_mu) or not b.u_mu > 0:
        return None
    if math.isfinite(b.mu) and abs(b.mu) >= BUDGET_MU_SIGMAS_MIN * b.u_mu:
        return None
    top = max(b.rows, key=lambda r: r.u_mu)
    share = 100.0 * (top.u_mu / b.u_mu) ** 2
    key = top.source.split("[")[0]
    if "." in key and key.split(".")[-1] != "":
        what = (f"{top.source} (u = {top.u:.3g}: check {key}_u in the setup, a standard "
                "uncertainty that large says the key is not known)")
    else:
        what = top.source
    ratio = b.U_mu / abs(b.mu) if b.mu else math.inf
    return Reason("uncertainty", f"the expanded uncertainty U(mu) = {b.U_mu:.3g} is "
                  f"{ratio:.3g} x mu = {b.mu:.3g}: the measurement does not determine mu; "
                  f"{what} makes {share:.0f} % of u(mu)^2")


def with_budget_reason(result, b: Budget | None):
    """``result`` with :func:`budget_reason`'s reason added to its quality reasons, if any.

    Parameters
    ----------
    result : FitResult
        The command's fit.
    b : Budget or None
        Its budget.

    Returns
    -------
    FitResult
    """
    reason = budget_reason(b)
    if reason is None:
        return result
    return dataclasses.replace(result, quality_reasons=tuple(result.quality_reasons) + (reason,))


def run_budget(meas: Measurement, result, args):
    """The budget of a command's result as (fit.json keys, Budget or None), its table printed
    on stdout (the command's output); a fit method without a Jacobian gets no budget (said so,
    as a warning of the ``rollfric.uncertainty.budget`` logger).

    Parameters
    ----------
    meas : Measurement
        The measurement ``result`` was fitted to.
    result : FitResult
        The command's fit.
    args : argparse.Namespace
        The parsed options of :func:`rollfric.cli.fit.add_budget_arguments`.

    Returns
    -------
    keys : dict
        The fit.json keys (``u_mu``, ``U_mu``, ``coverage_factor``, ``uncertainty_budget``,
        ...; with ``--fit-length`` also ``mu`` of the fitted L).
    budget : Budget or None
        The budget, None for a fit method other than "lsq".

    Raises
    ------
    rollfric.errors.InputError
        If ``--monte-carlo`` or ``--seed`` is negative, or as :func:`budget`.
    """
    check_arguments(args)
    if result.method != "lsq":
        logging.getLogger(__name__).warning(
            f"uncertainty budget: only for the lsq fit (this is {result.method}); mu_stderr is "
            "its statistical error alone")
        return {"u_mu": None, "U_mu": None, "coverage_factor": None,
                "uncertainty_budget": []}, None
    b = budget(meas, result, fit_length=args.fit_length, monte_carlo=args.monte_carlo,
               seed=args.seed, order=2 if getattr(args, "second_order", False) else 1)
    print(format_budget(b))
    keys = b.to_json()
    if args.fit_length:
        keys["mu"] = b.mu
    return keys, b
