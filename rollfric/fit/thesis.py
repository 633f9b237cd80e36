"""The thesis's own estimation procedures, kept faithful so users can compare.

- :func:`fit_paper1_eps` — paper 1 (a 1.58 mm ball released at a small angle): the friction
  parameter eps from one recorded sample of the roll-down stage (its eq. 7) and one of the
  climb stage (its eq. 11, with the speed at the bottom from the low-passed derivative),
  then eps iterated between those two values in steps of 1e-4 1/s^2 to minimise the total
  relative error (its eq. 14) of both stages. Reports our mu (eps / omega^2) and the paper's
  own coefficient (its eq. 13).
- :func:`fit_paper2_grid` — paper 2 (10 mm and 12.69 mm balls, any angle): starting from a
  first estimate, a grid search over mu +- 0.001 (step 0.0001), theta(0) +- 0.0016 rad (step
  0.0001) and theta'(0) +- 0.2 rad/s (step 0.01), one Runge-Kutta solution of the equation of
  motion per grid point, keeping the least sum of squared differences.

Neither procedure yields an uncertainty; ``mu_stderr`` is NaN for both.
"""

from __future__ import annotations

import math
import time

import numpy as np
from tqdm.auto import tqdm

from rollfric.errors import InputError
from rollfric.fit import analytic, eom, filtering
from rollfric.fit.air import coefficients_of
from rollfric.fit.result import FitResult, model_theta, relative_error
from rollfric.fit.start import clean_series, initial_guess, turning_points
from rollfric.setup.model import Setup

# Paper 2's grid: (half-width, step) for mu, theta(0) [rad], theta'(0) [rad/s]
PAPER2_GRID = {"mu": (0.001, 0.0001), "theta0": (0.0016, 0.0001), "omega0": (0.2, 0.01)}
PAPER1_EPS_STEP = 1e-4  # 1/s^2


def _stages(t, theta, fps):
    """Indices (release, zero crossing, next turning point) of the first full half-swing."""
    smooth = filtering.lowpass(theta, fps)
    vel = np.gradient(smooth, 1.0 / fps)
    tp = list(turning_points(smooth, fps))
    if tp and np.sign(smooth[0]) != np.sign(smooth[tp[0]]) and (
            abs(smooth[0]) > 0.5 * abs(smooth[tp[0]])):
        tp.insert(0, 0)  # the record starts at (or just after) the release
    if len(tp) < 2:
        raise InputError("paper1_eps needs a release and the next turning point in the record")
    a, b = tp[0], tp[1]
    seg = smooth[a:b + 1]
    cross = np.nonzero(np.sign(seg[:-1]) != np.sign(seg[1:]))[0]
    if cross.size == 0:
        raise InputError("paper1_eps: the ball does not pass the bottom (theta = 0) between "
                         "its first two turning points")
    i = a + int(cross[0])
    # sub-sample zero crossing by linear interpolation
    frac = smooth[i] / (smooth[i] - smooth[i + 1])
    return a, i, frac, b, smooth, vel


def fit_paper1_eps(t, theta, setup: Setup, *, eps_step: float = PAPER1_EPS_STEP) -> FitResult:
    """Paper 1's analytic eps iteration (see the module docstring).

    Parameters
    ----------
    t, theta : array_like
        A gap-free record (s, rad) starting at or just after the release.
    setup : Setup
    eps_step : float, optional
        Step of the eps iteration (1/s^2; the paper's 1e-4).

    Returns
    -------
    FitResult
        Method ``"paper1_eps"``: our mu (eps / omega^2), ``mu_stderr`` NaN, and in ``extra``
        ``eps_s2`` and ``mu_paper1`` (the paper's eq. 13).

    Raises
    ------
    InputError
        A record with gaps, or one where the ball does not pass the bottom between its first
        two turning points.
    """
    start = time.perf_counter()
    t, theta, good = clean_series(t, theta)
    if not good.all():
        raise InputError("paper1_eps needs a gap-free record (frames without a ball found)")
    fps = 1.0 / np.median(np.diff(t))
    w2 = analytic.omega_squared(setup.track_radius, setup.gravity)
    w = math.sqrt(w2)
    a, i, frac, b, smooth, vel = _stages(t, theta, fps)
    ta, theta_a = t[a], theta[a]
    tz = t[i] + frac * (t[i + 1] - t[i])
    omega_m = vel[i] + frac * (vel[i + 1] - vel[i])
    s1 = slice(a, i + 1)  # roll-down samples
    s2 = slice(i + 1, b + 1)  # climb samples
    t1, d1 = t[s1] - ta, theta[s1]
    t2, d2 = t[s2] - tz, theta[s2]
    # the two first values of eps, each from the sample in the middle of its stage
    k1 = (len(t1) - 1) // 2
    c1 = math.cos(w * t1[k1])
    eps1 = w2 * (d1[k1] - theta_a * c1) / (math.copysign(1.0, theta_a) * (1 - c1))
    k2 = (len(t2) - 1) // 2
    c2 = math.cos(w * t2[k2])
    eps2 = math.copysign(1.0, omega_m) * w2 * ((omega_m / w) * math.sin(w * t2[k2]) - d2[k2]) / (
        1 - c2)
    lo, hi = sorted((eps1, eps2))
    lo = max(lo, 0.0)
    hi = max(hi, lo)
    grid = np.arange(lo, hi + 0.5 * eps_step, eps_step)
    denom = np.sum(np.abs(d1)) + np.sum(np.abs(d2))
    errors = np.empty(grid.size)
    for j0 in range(0, grid.size, 512):
        e = grid[j0:j0 + 512, None]
        m1 = np.copysign(e / w2, theta_a) + (theta_a - np.copysign(e / w2, theta_a)) * np.cos(
            w * t1)
        m2 = (omega_m / w) * np.sin(w * t2) - np.copysign(e / w2, omega_m) * (1 - np.cos(w * t2))
        errors[j0:j0 + 512] = (np.abs(m1 - d1).sum(1) + np.abs(m2 - d2).sum(1)) / denom
    eps = float(grid[int(np.argmin(errors))])
    mu = analytic.mu_from_eps(eps, setup.track_radius, setup.gravity)
    model1 = analytic.roll_down(t1, theta_a, eps, w2)
    model2 = analytic.climb(t2, omega_m, eps, w2)
    curve = np.full_like(t, np.nan)
    curve[s1], curve[s2] = model1, model2
    used = np.concatenate([model1 - d1, model2 - d2])
    return FitResult(
        method="paper1_eps",
        mu=float(mu),
        mu_stderr=float("nan"),
        theta0=float(theta_a),
        omega0=0.0,
        t0=float(ta),
        rms_residual=float(np.sqrt(np.mean(used**2))),
        relative_error=float(errors.min()),
        n_samples=int(used.size),
        t=t,
        curve=curve,
        extra={
            "eps_s2": eps,
            "eps_rolldown_s2": float(eps1),
            "eps_climb_s2": float(eps2),
            "omega_m_rad_s": float(omega_m),
            "mu_paper1": analytic.paper1_mu_from_eps(eps, theta_a, setup.track_radius,
                                                     setup.gravity),
            "t_bottom_s": float(tz),
            "t_turn_s": float(t[b]),
        },
        seconds=time.perf_counter() - start,
    )


def fit_paper2_grid(t, theta, setup: Setup, *, first: dict | None = None, grid: dict | None = None,
                    offset: bool = False, progress: bool = False) -> FitResult:
    """Paper 2's grid search around a first estimate (see the module docstring).

    Parameters
    ----------
    t, theta : array_like
        The record (s, rad); NaN samples are left out.
    setup : Setup
    first : dict, optional
        The first estimate {"mu", "theta0", "omega0"}; by default the self-start of
        :func:`rollfric.fit.start.initial_guess` (mu from the amplitude decay, theta(0) and
        theta'(0)
        measured from the record), which is what the thesis had before its grid search.
    grid : dict, optional
        Overrides of the half-widths and steps of :data:`PAPER2_GRID`.
    offset : bool, optional
        Must be False: the thesis's procedure fits no angle offset.
    progress : bool, optional
        Show a progress bar.

    Returns
    -------
    FitResult
        Method ``"paper2_grid"``, the grid point of least squared differences; ``mu_stderr``
        NaN.

    Raises
    ------
    InputError
        ``offset`` True.
    """
    if offset:
        raise InputError("paper2_grid fits no angle offset (the thesis's procedure has none)")
    start = time.perf_counter()
    t, theta, good = clean_series(t, theta)
    tg, yg = t[good], theta[good]
    first = first or initial_guess(t, theta, setup)
    spec = dict(PAPER2_GRID, **(grid or {}))

    def axis(name):
        half, step = spec[name]
        n = int(round(half / step))
        return first[name] + step * np.arange(-n, n + 1)

    mus = axis("mu")
    mus = mus[mus >= 0]
    th0s, om0s = axis("theta0"), axis("omega0")
    best = (math.inf, None)
    total = mus.size * th0s.size * om0s.size
    with tqdm(total=total, disable=not progress, desc="paper2 grid", unit="solve") as bar:
        for mu in mus:
            for th0 in th0s:
                for om0 in om0s:
                    th, _, _ = eom.solve(th0, om0, mu, tg, track_radius=setup.track_radius,
                                         gravity=setup.gravity,
                                         air=coefficients_of(setup))
                    cost = float(np.sum((th - yg) ** 2))
                    if cost < best[0]:
                        best = (cost, (mu, th0, om0))
                bar.update(om0s.size)
    mu, th0, om0 = best[1]
    curve = np.full_like(t, np.nan)
    curve[good] = model_theta(tg, mu, th0, om0, setup)
    res = curve[good] - yg
    return FitResult(
        method="paper2_grid",
        mu=float(mu),
        mu_stderr=float("nan"),
        theta0=float(th0),
        omega0=float(om0),
        t0=float(tg[0]),
        rms_residual=float(np.sqrt(np.mean(res**2))),
        relative_error=relative_error(curve[good], yg),
        n_samples=int(good.sum()),
        t=t,
        curve=curve,
        extra={"grid_points": int(total), "mu_first": float(first["mu"]),
               "grid_step_mu": spec["mu"][1]},
        seconds=time.perf_counter() - start,
    )


# --------------------------------------------------------------------------------------------
# as rollfric.fit.estimate.fit_mu calls them (rollfric.fit.estimate.FitMethod)


def paper1_eps_method(t, theta, setup: Setup, *, offset: bool = False, model: str = "coulomb",
                      **options) -> FitResult:
    """The :class:`rollfric.fit.estimate.FitMethod` ``"paper1_eps"``.

    :func:`fit_paper1_eps` with ``options``; it has neither an angle offset nor a friction model
    (both ignored).

    Parameters
    ----------
    t, theta : array_like
    setup : Setup
    offset : bool, optional
        Ignored.
    model : str, optional
        Ignored.
    **options
        Passed to :func:`fit_paper1_eps`.

    Returns
    -------
    FitResult
    """
    return fit_paper1_eps(t, theta, setup, **options)


def paper2_grid_method(t, theta, setup: Setup, *, offset: bool = False, model: str = "coulomb",
                       **options) -> FitResult:
    """The :class:`rollfric.fit.estimate.FitMethod` ``"paper2_grid"``.

    :func:`fit_paper2_grid` with ``offset`` and ``options``; it fits constant mu (``model``
    ignored).

    Parameters
    ----------
    t, theta : array_like
    setup : Setup
    offset : bool, optional
        Refused when True (the thesis has none).
    model : str, optional
        Ignored.
    **options
        Passed to :func:`fit_paper2_grid`.

    Returns
    -------
    FitResult
    """
    return fit_paper2_grid(t, theta, setup, offset=offset, **options)
