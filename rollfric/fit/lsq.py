"""The least-squares fit of the equation of motion to theta(t): the fit method ``"lsq"``.

mu, theta(t0) and theta'(t0) are free, optionally also a constant angle offset (the trough's
bottom is never exactly where the camera says it is) and the velocity term mu1 of
mu(theta') = mu0 + mu1 |theta'|. The search starts from the data (:mod:`rollfric.fit.start`):
a coarse fit from every start, the best polished, then (only when some samples lie far off
the model) a robust fit that finds them and a final least-squares fit without them; the
standard errors come from the final Jacobian.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy import optimize

from rollfric import parallel
from rollfric.errors import InputError
from rollfric.fit import air, eom, filtering
from rollfric.fit.filtering import on_grid
from rollfric.fit.result import FitResult, model_theta, relative_error
from rollfric.fit.start import MIN_SAMPLES, clean_series, initial_guess, sample_rate
from rollfric.setup.model import Setup

# The fitter's search: a coarse fit from every start, the best polished, then (only when some
# samples lie far off the model) a robust fit that finds them and a final least-squares fit
# without them. Every stage has an evaluation budget, so no input makes it run for long.
MU_MAX = 1.0
MU_SEEDS = (0.002, 0.02, 0.2)  # beside the turning-point and acceleration estimates
STAGE1_NFEV = 40
POLISH_NFEV = 200
# a sample is an outlier when its residual exceeds this many noise sigmas: at 5 sigma a
# Gaussian residual crosses it once in 1.7 million samples
OUTLIER_SIGMAS = 5.0
# the robust fit's soft-L1 loss is quadratic within ROBUST_F_SCALE noise sigmas, linear beyond
ROBUST_F_SCALE = 3.0
# below this the noise "floor" of a series is the integrator's accuracy (about 1e-9 rad) and
# the rounding of the numbers, not a measured noise
NOISE_FLOOR = 1e-8


def mad_sigma(x: np.ndarray) -> float:
    """The standard deviation of normal ``x`` from its median absolute deviation."""
    return 1.4826 * float(np.median(np.abs(x - np.median(x)))) if x.size else 0.0


def _stderr(jac: np.ndarray, res: np.ndarray) -> np.ndarray:
    """Standard errors from the Jacobian and the residual variance (Gauss-Newton)."""
    dof = max(res.size - jac.shape[1], 1)
    s2 = float(res @ res) / dof
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
    except np.linalg.LinAlgError:
        return np.full(jac.shape[1], np.nan)
    return np.sqrt(np.clip(np.diag(cov), 0, None))


class _Problem:
    """The least-squares problem of one record: the model's angle at the fitted samples
    ``tg`` less the data ``yg``, over the free parameters within their bounds."""

    def __init__(self, tg, yg, setup: Setup, *, offset: bool, model: str):
        self.tg, self.yg, self.setup = tg, yg, setup
        # name, lower, upper, typical scale
        params = [("mu", 0.0, MU_MAX, 1e-3),
                  ("theta0", -math.pi / 2, math.pi / 2, 1e-3),
                  ("omega0", -np.inf, np.inf, 1e-2)]
        if offset:
            params.append(("offset", -0.5, 0.5, 1e-3))
        if model == "velocity":
            params.append(("mu1", 0.0, np.inf, 1e-3))
        self.names = [p[0] for p in params]
        self.lower = np.array([p[1] for p in params])
        self.upper = np.array([p[2] for p in params])
        self.scale = np.array([p[3] for p in params])

    def unpack(self, x):
        """(mu, theta0, omega0, offset, mu1) of the parameter vector ``x``."""
        p = dict(zip(self.names, x, strict=True))
        return (p["mu"], p["theta0"], p["omega0"], p.get("offset", 0.0), p.get("mu1", 0.0))

    def residual_on(self, mask):
        """The residual function over the samples ``mask`` of the fitted ones."""
        def residual(x):
            mu, th0, om0, off, mu1 = self.unpack(x)
            return (model_theta(self.tg, mu, th0, om0, self.setup, offset=off, mu1=mu1)
                    - self.yg)[mask]
        return residual

    # diff_step None: SciPy's forward-difference step is then sqrt(eps) * max(1, |x|). A
    # relative diff_step is multiplied by |x| alone (SciPy >= 1.5), which near mu = 0 (or a
    # ball released from rest, omega0 = 0) is a step of 1e-19: that Jacobian column is zero,
    # mu cannot leave 0 once it gets there (a 0.3 s record fitted to mu 7e-13 for 0.0164)
    # and the standard errors come out NaN.
    def solve(self, x0, mask, nfev, tol, **kw):
        """SciPy's bounded least squares from ``x0`` over ``mask``, ``nfev`` evaluations at
        most, tolerances ``tol``; ``kw``: its loss options."""
        return optimize.least_squares(self.residual_on(mask), x0,
                                      bounds=(self.lower, self.upper), x_scale=self.scale,
                                      diff_step=None, xtol=tol, ftol=tol, gtol=tol,
                                      max_nfev=nfev, **kw)


def _starts(g0: dict) -> list:
    """The coarse fits' starts (label, mu): the turning points' decay, the start's
    acceleration, the seeds ``MU_SEEDS``; one of those within 10 % of an earlier one is left
    out."""
    starts = []
    for label, mu_s in (("turning points", g0["mu"]), ("acceleration", g0.get("mu_acc", 0.0)),
                        *(("seed", m) for m in MU_SEEDS)):
        mu_s = float(np.clip(mu_s, 0.0, MU_MAX))
        if any(abs(mu_s - m) <= 0.1 * max(m, 1e-4) for _, m in starts):
            continue
        starts.append((label, mu_s))
    return starts


def _multistart(problem: _Problem, starts: list, g0: dict):
    """(label of the start, solution): a coarse fit from every start, then every coarse fit
    that came near the best polished, the best polished one kept."""
    everything = np.ones(problem.tg.size, dtype=bool)
    names = problem.names

    def coarse_fit(start):
        label, mu_s = start
        x0 = {"mu": mu_s, "theta0": g0["theta0"], "omega0": g0["omega0"],
              "offset": g0["offset"], "mu1": 0.0}
        x0 = np.clip(np.array([x0[n] for n in names], dtype=float), problem.lower,
                     problem.upper)
        return label, problem.solve(x0, everything, STAGE1_NFEV, 1e-10)

    # the starts are independent: on the CPUs that are free, the same fits (rollfric.parallel)
    coarse = parallel.map_ordered(coarse_fit, starts, name="rollfric-fit")
    # polish every coarse fit that came near the best (a coarse fit that ranks first may
    # still stall in a flat valley): keep the best polished one
    coarse.sort(key=lambda c: c[1].cost)
    least = coarse[0][1].cost
    best = None
    polished = []
    for label, c in coarse:
        if c.cost > 10.0 * least + 1e-30:
            break
        if any(np.all(np.abs(c.x - p) <= 1e-3 * problem.scale) for p in polished):
            continue  # the same minimum as one polished already
        polished.append(c.x)
        sol = problem.solve(c.x, everything, POLISH_NFEV, 1e-12)
        if best is None or sol.cost < best[1].cost:
            best = (label, sol)
    return best


def _without_outliers(problem: _Problem, sol, noise_eff: float):
    """(solution, samples kept, outliers, robust fit made): when samples lie more than
    ``OUTLIER_SIGMAS`` noise sigmas off ``sol``, a soft-L1 fit finds them and a least-squares
    fit without them is the solution (unless fewer than ``MIN_SAMPLES`` would be left)."""
    everything = np.ones(problem.tg.size, dtype=bool)
    res = sol.fun
    if not np.any(np.abs(res - np.median(res))
                  > OUTLIER_SIGMAS * max(noise_eff, mad_sigma(res))):
        return sol, everything, 0, False
    rob = problem.solve(sol.x, everything, POLISH_NFEV, 1e-10, loss="soft_l1",
                        f_scale=ROBUST_F_SCALE * noise_eff)
    res_r = rob.fun
    keep = np.abs(res_r - np.median(res_r)) <= OUTLIER_SIGMAS * max(noise_eff,
                                                                    mad_sigma(res_r))
    if keep.sum() < MIN_SAMPLES:
        return sol, everything, 0, True
    return problem.solve(rob.x, keep, POLISH_NFEV, 1e-12), keep, int(problem.tg.size
                                                                      - keep.sum()), True


def fit_lsq(t, theta, setup: Setup, *, offset: bool = False, model: str = "coulomb",
            guess: dict | None = None, robust: bool = True) -> FitResult:
    """Least-squares fit of the equation of motion (see module docstring).

    ``offset``: also fit a constant angle offset of the trough bottom.
    ``model``: "coulomb" (constant mu) or "velocity" (mu0 + mu1 |theta'|).
    ``robust``: when samples lie more than ``OUTLIER_SIGMAS`` noise sigmas off the fitted
    model, find them with a soft-L1 fit (``f_scale`` ``ROBUST_F_SCALE`` noise sigmas, the
    noise measured from the data by :func:`rollfric.fit.filtering.noise_sigma`) and fit again
    without them (``extra['n_outliers']``).

    The search is multi-start: mu from the turning points' decay, from the start's
    acceleration and the seeds ``MU_SEEDS``, each fitted coarsely, the best polished. One start
    is not enough where mu and other parameters are nearly interchangeable (a record without
    turning points with a free offset: the friction shifts the swing's centre as an offset
    does) and the least-squares path from mu = 0 stalls against the bound.

    Parameters
    ----------
    t : array_like
        Times, s, strictly increasing where finite.
    theta : array_like
        Angles, rad (NaN for frames without a ball).
    setup : Setup
        The trough and ball (``track_radius``, ``gravity``).
    offset : bool
        Also fit a constant angle offset of the trough bottom.
    model : str
        "coulomb" or "velocity".
    guess : dict or None
        A start as :func:`initial_guess` returns it; None computes it.
    robust : bool
        Find and leave out outliers as described above.

    Returns
    -------
    FitResult
        The fit, method "lsq"; samples after the final rest (less a quarter period) and
        outliers are not used (``used``).

    Raises
    ------
    rollfric.errors.InputError
        If ``model`` is unknown, or fewer than ``MIN_SAMPLES`` samples of motion are usable;
        also as :func:`initial_guess`.
    """
    if model not in ("coulomb", "velocity"):
        raise InputError(f"unknown friction model {model!r} (coulomb, velocity)")
    start = time.perf_counter()
    t, theta, good = clean_series(t, theta)
    g0 = guess or initial_guess(t, theta, setup)
    # Once the ball has stopped for good, where it rests jumps between the two sides of the
    # bottom as mu crosses the value at which it would have made one more half-swing: the
    # cost is discontinuous in mu there. The fit therefore ends a quarter period before the
    # rest seen in the data; the resting samples are not used (their count is reported).
    fitted = good & (t < g0["t_rest"] - 0.25 * g0["period"])
    if fitted.sum() < MIN_SAMPLES:
        raise InputError(f"the ball comes to rest after {int(fitted.sum())} usable samples; "
                         f"at least {MIN_SAMPLES} samples of motion are needed to fit mu")
    tg, yg = t[fitted], theta[fitted]
    problem = _Problem(tg, yg, setup, offset=offset, model=model)
    starts = _starts(g0)
    best_start, sol = _multistart(problem, starts, g0)
    # the noise of the data, measured from the data (on the frame grid, gaps as NaN)
    noise = filtering.noise_sigma(on_grid(tg, yg, sample_rate(tg)))
    noise_eff = max(noise, NOISE_FLOOR) if math.isfinite(noise) else NOISE_FLOOR
    if robust:
        sol, keep, n_outliers, robust_used = _without_outliers(problem, sol, noise_eff)
    else:
        keep, n_outliers, robust_used = np.ones(tg.size, dtype=bool), 0, False
    mu, th0, om0, off, mu1 = problem.unpack(sol.x)
    res = sol.fun
    err = _stderr(sol.jac, res)
    stderr = dict(zip(problem.names, (float(e) for e in err), strict=True))
    curve = np.full_like(t, np.nan)
    curve[good] = model_theta(t[good], mu, th0, om0, setup, offset=off, mu1=mu1)
    used = np.zeros(t.size, dtype=bool)
    used[np.nonzero(fitted)[0][keep]] = True
    # the drag used: Re and Cd at the fitted motion's largest speed
    _, om_fit, _ = eom.solve(th0 - off, om0, mu, tg, track_radius=setup.track_radius,
                             gravity=setup.gravity, mu1=mu1, air=air.coefficients_of(setup))
    v_max = setup.track_radius * float(np.max(np.abs(om_fit))) if om_fit.size else 0.0
    return FitResult(
        method="lsq",
        mu=float(mu),
        mu_stderr=stderr["mu"],
        theta0=float(th0),
        omega0=float(om0),
        t0=float(tg[0]),
        rms_residual=float(np.sqrt(np.mean(res**2))),
        relative_error=relative_error(res + yg[keep], yg[keep]),
        n_samples=int(keep.sum()),
        t=t,
        curve=curve,
        offset=float(off),
        mu1=float(mu1),
        stderr=stderr,
        extra={"model": model, "nfev": int(sol.nfev), "converged": bool(sol.status > 0),
               "n_rest_excluded": int(good.sum() - fitted.sum()),
               "n_outliers": n_outliers, "robust": robust_used,
               "noise_rad": noise if math.isfinite(noise) else None,
               "mu_initial": float(g0["mu"]), "start": best_start, "n_starts": len(starts),
               "air": air.air_of(setup).summary(v_max, setup.ball_diameter)},
        seconds=time.perf_counter() - start,
        used=used,
    )
