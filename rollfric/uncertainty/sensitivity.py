"""The uncertain inputs of a setup and the re-fits that find what each does to mu.

:func:`setup_inputs` lists every numeric setup input with its standard uncertainty (a key
``K`` with ``K_u``, a lens calibration's parameters), :func:`moved` is the setup with one of
them moved, :func:`acts` / :func:`why_not` say whether it can act on mu in a measurement.
:class:`Refitter` re-fits the measurement with a moved setup: a local least-squares
refinement from the nominal solution over the nominal fit's samples, memoised, and made on
threads where CPUs are free (:func:`rollfric.parallel.map_ordered`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import optimize

from rollfric import parallel
from rollfric.fit import eom
from rollfric.fit.air import WALL_FACTOR_U, coefficients_of
from rollfric.setup.model import AS_BUILT_FIELDS, LAB_KEYS, Setup, SetupError

# parameter -> (lower, upper, typical scale) of the local re-fits (as in rollfric.fit.estimate)
_BOUNDS = {"mu": (0.0, 1.0, 1e-3), "theta0": (-math.pi / 2, math.pi / 2, 1e-3),
           "omega0": (-np.inf, np.inf, 1e-2), "offset": (-0.5, 0.5, 1e-3),
           "mu1": (0.0, np.inf, 1e-3)}
_FIT_PARAMS = ("mu", "theta0", "omega0", "offset", "mu1")


def fitted_mask(t, theta, n_samples):
    """The samples the nominal fit used: the first ``n_samples`` finite ones (it ends a
    quarter period before the ball rests for good)."""
    good = np.isfinite(t) & np.isfinite(theta)
    return good & (np.cumsum(good) <= n_samples)


class Refitter:
    """Local least-squares re-fits from the nominal solution, memoised on their inputs.

    ``meas`` is the :class:`rollfric.uncertainty.measured.Measurement` the nominal least-squares
    fit ``result`` was made of; ``fit_length``: L is a free parameter of every re-fit."""

    def __init__(self, meas, result, *, fit_length: bool):
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
            fitted_mask(t, th, result.n_samples)
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
        done = parallel.map_ordered(lambda job: self._solve(*job), todo.values(),
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

def setup_inputs(setup: Setup):
    """(source name, setup field, component or None, value in lab units, u in lab units,
    factor lab -> SI) for every numeric setup input; u 0 where exact. The trough and camera as
    built (AS_BUILT_FIELDS) are not among them: :mod:`rollfric.uncertainty.asbuilt` makes their
    rows."""
    out = []
    for name, (section, key, scale) in LAB_KEYS.items():
        if name in AS_BUILT_FIELDS:
            continue
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


def moved(setup: Setup, field: str, component, delta_lab: float, factor: float) -> Setup:
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


def acts(meas, field: str) -> str:
    """'' when ``field`` can change mu in the measurement ``meas``
    (:class:`rollfric.uncertainty.measured.Measurement`), else why not."""
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


def why_not(meas, field: str, fit_length: bool) -> str:
    """'' when ``field`` acts on mu in the budget, else why not (:func:`acts`; with
    ``fit_length`` the inputs that act only through L or g do not)."""
    why = acts(meas, field)
    if fit_length and field in ("cylinder_radius", "ball_diameter", "gravity") and not why:
        if not (meas.from_centres and meas.angle == "arcsin"):
            why = "acts only through L/g, which is fitted (self-calibration)"
    return why

