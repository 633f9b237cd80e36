"""Estimate mu from an angle series theta(t).

The default method (``"lsq"``) is a least-squares fit of the Lagrange equation of motion
(:mod:`rollfric.fit.eom`) to theta(t), with mu, theta(t0) and theta'(t0) free, optionally also a
constant angle offset (the trough's bottom is never exactly where the camera says it is) and
the velocity term mu1 of mu(theta') = mu0 + mu1 |theta'|. It starts itself from the data:
turning points of the low-passed series, mu from the amplitude lost per half-swing
(2 mu per half-swing in the small-angle limit), theta'(t0) from the filtered derivative.

The thesis's own procedures are offered beside it for comparison (:mod:`rollfric.fit.thesis`):
``"paper1_eps"`` (the first paper's analytic eps iteration for a small ball at small angles)
and ``"paper2_grid"`` (the second paper's grid search around a first estimate).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Protocol, runtime_checkable

import numpy as np
from scipy import optimize, signal

from rollfric import parallel as cpus
from rollfric.errors import InputError
from rollfric.fit import air, eom, filtering
from rollfric.fit.filtering import on_grid
from rollfric.registry import FIT_METHODS
from rollfric.setup.model import Setup

METHODS = FIT_METHODS.names()
MIN_SAMPLES = 50


@dataclasses.dataclass(frozen=True)
class FitResult:
    """The outcome of one fit. Angles in rad, rates in rad/s, times in s.

    Attributes
    ----------
    method : str
        The fitter (``"lsq"``, ``"paper1_eps"``, ``"paper2_grid"``).
    mu, mu_stderr : float
        The rolling friction coefficient (M = mu r N) and its least-squares standard error.
    theta0, omega0, t0 : float
        The fitted angle (with the offset) and angular velocity at ``t0``.
    rms_residual : float
        Root mean square of data minus model, rad.
    relative_error : float
        The thesis's eq. 14: sum |model - data| / sum |data| (a residual, not mu's error).
    n_samples : int
        Finite samples used.
    t, curve : numpy.ndarray
        The times and the model's angle at them.
    offset, mu1 : float
        The trough bottom's angle in the camera's frame (rad) and the velocity term (s/rad).
    stderr, extra : dict
        Standard errors of every fitted parameter; the fitter's details.
    quality_reasons : tuple
        Why the fit is suspect (:attr:`quality` is then "suspect"); empty when ok.

    Examples
    --------
    >>> import numpy as np
    >>> from rollfric import fit_mu, thesis_setup
    >>> from rollfric.fit.eom import solve_reference
    >>> setup = thesis_setup("10mm")
    >>> t = np.arange(2000) / 1000.0
    >>> theta, _, _ = solve_reference(np.radians(20.0), 0.0, 0.0079, t,
    ...                               track_radius=setup.track_radius)
    >>> fit = fit_mu(t, theta, setup).to_dict()  # the keys fit.json holds
    >>> round(fit["mu"], 6), round(float(np.degrees(fit["theta0_rad"])), 3), fit["quality"]
    (0.0079, 20.0, 'ok')
    """

    method: str
    mu: float
    mu_stderr: float
    theta0: float  # theta at t0 (rad), including the offset
    omega0: float  # theta' at t0 (rad/s)
    t0: float
    rms_residual: float  # rad
    relative_error: float  # thesis eq. 14: sum |model - data| / sum |data|
    n_samples: int  # samples used (finite)
    t: np.ndarray = dataclasses.field(repr=False)
    curve: np.ndarray = dataclasses.field(repr=False)  # model theta at t
    offset: float = 0.0  # angle of the trough bottom in the camera's frame (rad)
    mu1: float = 0.0  # s/rad, velocity term (model "velocity")
    stderr: dict = dataclasses.field(default_factory=dict)
    extra: dict = dataclasses.field(default_factory=dict)
    seconds: float = 0.0
    # samples that entered the fit (finite, moving, not outliers); None: every finite one
    used: np.ndarray | None = dataclasses.field(default=None, repr=False)
    quality_reasons: tuple = ()  # rollfric.uncertainty.quality.Reason: why the fit is suspect

    @property
    def quality(self) -> str:
        """"ok", or "suspect" when any quality check failed (see ``quality_reasons``)."""
        return "suspect" if self.quality_reasons else "ok"

    def to_dict(self) -> dict:
        """The JSON form written to fit.json (no arrays)."""
        out = {
            "method": self.method,
            "mu": self.mu,
            "mu_stderr": self.mu_stderr,
            "theta0_rad": self.theta0,
            "omega0_rad_s": self.omega0,
            "t0_s": self.t0,
            "offset_rad": self.offset,
            "mu1_s_rad": self.mu1,
            "rms_residual_rad": self.rms_residual,
            "relative_error": self.relative_error,
            "n_samples": self.n_samples,
            "stderr": dict(self.stderr),
            "fit_seconds": self.seconds,
            "quality": self.quality,
            "quality_reasons": [r.to_dict() for r in self.quality_reasons],
        }
        out.update(self.extra)
        return out


def model_theta(t, mu, theta0, omega0, setup: Setup, *, offset=0.0, mu1=0.0):
    """theta(t) of the equation of motion started at t[0] (fast integrator), plus offset.

    Parameters
    ----------
    t : array_like
        Strictly increasing times, s.
    mu : float
        Rolling-resistance coefficient (mu0 of the velocity model).
    theta0 : float
        Angle at ``t[0]`` in the data's frame (offset included), rad.
    omega0 : float
        Angular velocity at ``t[0]``, rad/s.
    setup : Setup
        The trough and ball (``track_radius``, ``gravity``) and the air around it
        (:mod:`rollfric.fit.air`: drag, buoyancy, added mass).
    offset : float
        Angle of the trough bottom in the data's frame, rad.
    mu1 : float
        Velocity coefficient of mu(theta') = mu + mu1 |theta'|, s/rad.

    Returns
    -------
    numpy.ndarray
        Model angle at ``t``, rad.
    """
    th, _, _ = eom.solve(theta0 - offset, omega0, mu, t, track_radius=setup.track_radius,
                         gravity=setup.gravity, mu1=mu1, air=air.coefficients_of(setup))
    return th + offset


def _clean(t, theta):
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    if t.ndim != 1 or t.shape != theta.shape:
        raise InputError(f"t and theta must be 1-D arrays of one length, got shapes "
                         f"{t.shape} and {theta.shape}")
    good = np.isfinite(t) & np.isfinite(theta)
    if good.sum() < MIN_SAMPLES:
        raise InputError(f"only {int(good.sum())} usable samples of theta(t); at least "
                         f"{MIN_SAMPLES} are needed to fit mu")
    tg = t[good]
    if np.any(np.diff(tg) <= 0):
        raise InputError("times t_s must be strictly increasing")
    return t, theta, good


def _sample_rate(t: np.ndarray) -> float:
    dt = np.median(np.diff(t))
    return 1.0 / dt


def turning_points(theta_smooth: np.ndarray, fps: float) -> np.ndarray:
    """Indices of the turning points (extrema) of a low-passed angle series.

    Extrema are peaks of |theta - centre| separated by at least a quarter of the dominant
    period, so locator noise near a turning point gives one extremum, not several.

    Parameters
    ----------
    theta_smooth : numpy.ndarray
        Low-passed, uniformly sampled angle, rad.
    fps : float
        Sampling rate, Hz.

    Returns
    -------
    numpy.ndarray
        Sample indices of alternating maxima and minima, increasing.
    """
    f0 = filtering.dominant_frequency(theta_smooth, fps)
    distance = max(1, int(0.25 * fps / max(f0, 1e-3)))
    centre = np.median(theta_smooth)
    peaks_hi, _ = signal.find_peaks(theta_smooth - centre, distance=distance)
    peaks_lo, _ = signal.find_peaks(centre - theta_smooth, distance=distance)
    idx = np.sort(np.concatenate([peaks_hi, peaks_lo]))
    # keep alternating extrema only (a max followed by a min ...)
    keep = []
    for i in idx:
        if keep and (theta_smooth[i] > centre) == (theta_smooth[keep[-1]] > centre):
            if abs(theta_smooth[i] - centre) > abs(theta_smooth[keep[-1]] - centre):
                keep[-1] = i
            continue
        keep.append(i)
    return np.asarray(keep, dtype=int)


def mu_from_acceleration(t, theta, setup: Setup, *, offset: float = 0.0,
                         span: float | None = None) -> float:
    """mu from the start's acceleration, which the equation of motion splits into gravity and
    friction: a cubic over the first ``span`` seconds (default 0.15 of the small-angle
    period, at least 10 samples) gives theta, theta' and theta'' at t[0]; clipped to [0, 0.5].
    ``offset``: the angle of the trough bottom in the data's frame. NaN samples are skipped.

    Parameters
    ----------
    t : array_like
        Times, s.
    theta : array_like
        Angles, rad.
    setup : Setup
        The trough and ball (``track_radius``, ``gravity``).
    offset : float
        Angle of the trough bottom in the data's frame, rad.
    span : float or None
        Length of the start used for the cubic, s; None: 0.15 of the small-angle period.

    Returns
    -------
    float
        mu in [0, 0.5]; 0 when fewer than 4 samples are finite or the estimate is undefined.
    """
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    good = np.isfinite(t) & np.isfinite(theta)
    tt, yy = t[good], theta[good] - offset
    if tt.size < 4:
        return 0.0
    if span is None:
        span = 0.15 * 2 * math.pi / math.sqrt(eom.omega_squared(setup.track_radius,
                                                                 setup.gravity))
    n_acc = max(min(tt.size, 10), int(np.searchsorted(tt, tt[0] + span)))
    c = np.polynomial.polynomial.polyfit(tt[:n_acc] - tt[0], yy[:n_acc], 3)
    th0, om0, acc = c[0], c[1], 2 * c[2]
    s = math.copysign(1.0, om0) if abs(om0) > 1e-3 else -math.copysign(1.0, th0)
    k = 5.0 / (7.0 * setup.track_radius)
    normal = setup.gravity * math.cos(th0) + setup.track_radius * om0**2
    if not (normal > 0 and math.isfinite(acc)):
        return 0.0
    return float(np.clip((-acc / k - setup.gravity * math.sin(th0)) / (s * normal), 0, 0.5))


def initial_guess(t, theta, setup: Setup) -> dict:
    """Self-start: mu from the amplitude decay per half-swing, theta0/omega0 from the data.

    Amplitudes are half the swing between consecutive turning points (so a constant angle
    offset cancels); in the small-angle limit each half-swing loses 2 mu. ``mu_acc`` is mu
    from the start's acceleration (:func:`mu_from_acceleration`), the only estimate a record
    without turning points has (it is then also ``mu``).

    Parameters
    ----------
    t : array_like
        Times, s, strictly increasing where finite.
    theta : array_like
        Angles, rad (NaN for frames without a ball).
    setup : Setup
        The trough and ball (``track_radius``, ``gravity``).

    Returns
    -------
    dict
        ``mu``, ``mu_acc``, ``theta0`` (rad), ``omega0`` (rad/s), ``offset`` (rad),
        ``turning_points_s`` (s), ``turning_points_theta`` (rad), ``fps`` (Hz), ``t_rest``
        (s, the start of the final rest, inf if none), ``period`` (small-angle period, s).

    Raises
    ------
    rollfric.errors.InputError
        If ``t`` and ``theta`` are not 1-D arrays of one length, fewer than ``MIN_SAMPLES``
        samples are finite, or the finite times are not strictly increasing.
    """
    t, theta, good = _clean(t, theta)
    fps = _sample_rate(t[good])
    # uniform resampling over gaps for the filter
    tt = t[good]
    grid = np.arange(tt[0], tt[-1] + 0.5 / fps, 1.0 / fps)
    x = np.interp(grid, tt, theta[good])
    smooth = filtering.lowpass(x, fps)
    tp = turning_points(smooth, fps)
    mu0 = 0.0
    # without two turning points the record shows no centre of the swing: the camera's zero
    # is the best guess of the trough bottom
    offset = 0.0
    if tp.size >= 3:
        swings = np.abs(np.diff(smooth[tp]))  # peak-to-peak of consecutive half-swings
        # each half-swing loses 2 mu of amplitude; the peak-to-peak of consecutive swings
        # (a_k + a_{k+1}) drops by 4 mu from one to the next
        drops = -np.diff(swings)
        drops = drops[swings[1:] > 0.02 * swings[0]]
        if drops.size:
            mu0 = max(float(np.median(drops)) / 4.0, 0.0)
        offset = float(np.mean(0.5 * (smooth[tp[:-1]] + smooth[tp[1:]])))
    elif tp.size == 2:
        offset = float(0.5 * (smooth[tp[0]] + smooth[tp[1]]))
        a0, a1 = abs(smooth[tp[0]] - offset), abs(smooth[tp[1]] - offset)
        mu0 = max((a0 - a1) / 2.0, 0.0)
    # the ball at rest for good at the end of the record?
    period = 2 * math.pi / math.sqrt(eom.omega_squared(setup.track_radius, setup.gravity))
    noise = 1.4826 * float(np.median(np.abs(x - smooth - np.median(x - smooth))))
    tail = max(20, x.size // 50)
    final = float(np.median(smooth[-tail:]))
    moving = np.nonzero(np.abs(smooth - final) > max(5 * noise, 1e-7))[0]
    t_rest = math.inf
    if moving.size and grid[-1] - grid[moving[-1]] >= 0.25 * period:
        t_rest = float(grid[moving[-1]])
    # theta and theta' at t0 from a local quadratic on the raw samples (the zero-phase filter
    # is least reliable at the ends of the series)
    n_head = min(int(good.sum()), max(10, int(0.03 * fps)))
    coef = np.polynomial.polynomial.polyfit(tt[:n_head] - tt[0], theta[good][:n_head], 2)
    mu_acc = mu_from_acceleration(tt, theta[good], setup, offset=offset,
                                  span=max(0.15 * period, (n_head - 1) / fps))
    if tp.size < 2:
        mu0 = mu_acc  # too short for a decay
    return {
        "mu": mu0,
        "mu_acc": mu_acc,
        "theta0": float(coef[0]),
        "omega0": float(coef[1]),
        "offset": offset,
        "turning_points_s": grid[tp],
        "turning_points_theta": smooth[tp],
        "fps": fps,
        "t_rest": t_rest,
        "period": period,
    }


def _relative_error(model, data):
    den = float(np.sum(np.abs(data)))
    # angles all 0 (a ball that never moved): no relative error (NaN, null in fit.json)
    return float(np.sum(np.abs(model - data))) / den if den > 0 else math.nan


def _stderr(jac: np.ndarray, res: np.ndarray) -> np.ndarray:
    """Standard errors from the Jacobian and the residual variance (Gauss-Newton)."""
    dof = max(res.size - jac.shape[1], 1)
    s2 = float(res @ res) / dof
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
    except np.linalg.LinAlgError:
        return np.full(jac.shape[1], np.nan)
    return np.sqrt(np.clip(np.diag(cov), 0, None))


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


def _mad_sigma(x: np.ndarray) -> float:
    return 1.4826 * float(np.median(np.abs(x - np.median(x)))) if x.size else 0.0


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
    t, theta, good = _clean(t, theta)
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
    # name, lower, upper, typical scale
    params = [("mu", 0.0, MU_MAX, 1e-3),
              ("theta0", -math.pi / 2, math.pi / 2, 1e-3),
              ("omega0", -np.inf, np.inf, 1e-2)]
    if offset:
        params.append(("offset", -0.5, 0.5, 1e-3))
    if model == "velocity":
        params.append(("mu1", 0.0, np.inf, 1e-3))
    names = [p[0] for p in params]
    lower = np.array([p[1] for p in params])
    upper = np.array([p[2] for p in params])
    scale = np.array([p[3] for p in params])

    def unpack(x):
        p = dict(zip(names, x, strict=True))
        return (p["mu"], p["theta0"], p["omega0"], p.get("offset", 0.0), p.get("mu1", 0.0))

    def residual_on(mask):
        def residual(x):
            mu, th0, om0, off, mu1 = unpack(x)
            return (model_theta(tg, mu, th0, om0, setup, offset=off, mu1=mu1) - yg)[mask]
        return residual

    # diff_step None: SciPy's forward-difference step is then sqrt(eps) * max(1, |x|). A
    # relative diff_step is multiplied by |x| alone (SciPy >= 1.5), which near mu = 0 (or a
    # ball released from rest, omega0 = 0) is a step of 1e-19: that Jacobian column is zero,
    # mu cannot leave 0 once it gets there (a 0.3 s record fitted to mu 7e-13 for 0.0164)
    # and the standard errors come out NaN.
    def solve(x0, mask, nfev, tol, **kw):
        return optimize.least_squares(residual_on(mask), x0, bounds=(lower, upper),
                                      x_scale=scale, diff_step=None, xtol=tol, ftol=tol,
                                      gtol=tol, max_nfev=nfev, **kw)

    everything = np.ones(tg.size, dtype=bool)
    starts = []
    for label, mu_s in (("turning points", g0["mu"]), ("acceleration", g0.get("mu_acc", 0.0)),
                        *(("seed", m) for m in MU_SEEDS)):
        mu_s = float(np.clip(mu_s, 0.0, MU_MAX))
        if any(abs(mu_s - m) <= 0.1 * max(m, 1e-4) for _, m in starts):
            continue
        starts.append((label, mu_s))
    def coarse_fit(start):
        label, mu_s = start
        x0 = {"mu": mu_s, "theta0": g0["theta0"], "omega0": g0["omega0"],
              "offset": g0["offset"], "mu1": 0.0}
        x0 = np.clip(np.array([x0[n] for n in names], dtype=float), lower, upper)
        return label, solve(x0, everything, STAGE1_NFEV, 1e-10)

    # the starts are independent: on the CPUs that are free, the same fits (rollfric.parallel)
    coarse = cpus.map_ordered(coarse_fit, starts, name="rollfric-fit")
    # polish every coarse fit that came near the best (a coarse fit that ranks first may
    # still stall in a flat valley): keep the best polished one
    coarse.sort(key=lambda c: c[1].cost)
    least = coarse[0][1].cost
    best = None
    polished = []
    for label, c in coarse:
        if c.cost > 10.0 * least + 1e-30:
            break
        if any(np.all(np.abs(c.x - p) <= 1e-3 * scale) for p in polished):
            continue  # the same minimum as one polished already
        polished.append(c.x)
        sol = solve(c.x, everything, POLISH_NFEV, 1e-12)
        if best is None or sol.cost < best[1].cost:
            best = (label, sol)
    best_start, sol = best
    # the noise of the data, measured from the data (on the frame grid, gaps as NaN)
    fps = _sample_rate(tg)
    noise = filtering.noise_sigma(on_grid(tg, yg, fps))
    noise_eff = max(noise, NOISE_FLOOR) if math.isfinite(noise) else NOISE_FLOOR
    keep = everything
    n_outliers = 0
    robust_used = False
    res = sol.fun
    if robust and np.any(np.abs(res - np.median(res))
                         > OUTLIER_SIGMAS * max(noise_eff, _mad_sigma(res))):
        robust_used = True
        rob = solve(sol.x, everything, POLISH_NFEV, 1e-10, loss="soft_l1",
                    f_scale=ROBUST_F_SCALE * noise_eff)
        res_r = rob.fun
        keep = np.abs(res_r - np.median(res_r)) <= OUTLIER_SIGMAS * max(noise_eff,
                                                                        _mad_sigma(res_r))
        if keep.sum() >= MIN_SAMPLES:
            n_outliers = int(tg.size - keep.sum())
            sol = solve(rob.x, keep, POLISH_NFEV, 1e-12)
        else:
            keep = everything
    mu, th0, om0, off, mu1 = unpack(sol.x)
    res = sol.fun
    err = _stderr(sol.jac, res)
    stderr = dict(zip(names, (float(e) for e in err), strict=True))
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
        relative_error=_relative_error(res + yg[keep], yg[keep]),
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


def check_angles(theta) -> None:
    """Refuse angles that no ball in a trough has: degrees given as radians, or not angles.

    When most samples (the 90th percentile of |theta|) lie beyond +-pi/2 rad the series
    cannot be radians of a ball below the trough's axis: up to 90 in magnitude it is taken
    for degrees. A few stray samples beyond +-pi/2 are left to the fit's quality checks.

    Parameters
    ----------
    theta : array_like
        Angles that should be in rad; NaN samples are ignored.

    Raises
    ------
    rollfric.errors.InputError
        If the 90th percentile of |theta| exceeds pi/2 (the message says whether the values
        look like degrees).
    """
    theta = np.asarray(theta, dtype=float)
    a = np.abs(theta[np.isfinite(theta)])
    if a.size == 0 or float(np.quantile(a, 0.9)) <= math.pi / 2:
        return
    top = float(a.max())
    frac = float(np.mean(a > math.pi / 2))
    if top <= 90.0:
        raise InputError(
            f"theta_rad reaches {top:.4g} and {100 * frac:.0f} % of the samples lie beyond "
            f"+-pi/2: these look like angles in degrees ({top:.4g} deg = "
            f"{math.radians(top):.4g} rad); give theta in radians (deg * pi / 180)")
    raise InputError(
        f"theta_rad reaches {top:.4g} and {100 * frac:.0f} % of the samples lie beyond +-pi/2 "
        "(+-90 deg): not angles of a ball in a trough, in radians or in degrees")


@runtime_checkable
class FitMethod(Protocol):
    """A way to fit mu to theta(t), as :func:`fit_mu` calls it.

    Registered by name in :data:`rollfric.registry.FIT_METHODS` (the CLI's ``--method`` and
    ``--fit-method``).

    Parameters
    ----------
    t, theta : array_like
        Times (s) and angles (rad); NaN angles are frames without a ball.
    setup : Setup
        The lab's setup (trough and ball).
    offset : bool
        Also fit a constant angle offset of the trough bottom (a method that cannot ignores it).
    model : str
        The friction model, "coulomb" or "velocity" (a method that has one model ignores it).
    **options
        The method's own options.

    Returns
    -------
    FitResult
    """

    def __call__(self, t, theta, setup: Setup, *, offset: bool = False,
                 model: str = "coulomb", **options) -> FitResult: ...


def fit_mu(t, theta, setup: Setup, *, method: str = "lsq", offset: bool = False,
           model: str = "coulomb", checks: bool = True, **kwargs) -> FitResult:
    """Fit mu (M = mu r N) to theta(t).

    NaN samples (frames without a ball) are left out.

    Parameters
    ----------
    t, theta : array_like
        Times (s) and angles (rad, > 0 right of the trough bottom).
    setup : Setup
        The geometry (L = R - r) and gravity.
    method : str, optional
        One of :data:`METHODS` (registered in :data:`rollfric.registry.FIT_METHODS`): ``"lsq"``
        (least squares, default), ``"paper1_eps"``, ``"paper2_grid"``.
    offset : bool, optional
        Also fit a constant angle offset of the trough bottom.
    model : {"coulomb", "velocity"}, optional
        Constant mu, or mu0 + mu1 |theta'| (``lsq`` only).
    checks : bool, optional
        Run the quality checks of :mod:`rollfric.uncertainty.quality` on the result
        (``quality_reasons``;
        empty: ok).
    **kwargs
        Options of the method.

    Returns
    -------
    FitResult
        mu, its standard error, the fitted initial state, residuals and the quality reasons.

    Raises
    ------
    InputError
        Too few samples, or angles that are not radians (:func:`check_angles`).

    Examples
    --------
    The exact motion of the thesis's 10 mm ball (mu = 0.0079, released at rest at 20 deg),
    2 s at 1000 Hz, fitted:

    >>> import numpy as np
    >>> from rollfric import fit_mu, thesis_setup
    >>> from rollfric.fit.eom import solve_reference
    >>> setup = thesis_setup("10mm")
    >>> t = np.arange(2000) / 1000.0
    >>> theta, _, _ = solve_reference(np.radians(20.0), 0.0, 0.0079, t,
    ...                               track_radius=setup.track_radius)
    >>> result = fit_mu(t, theta, setup)
    >>> round(result.mu, 6), result.quality, result.n_samples
    (0.0079, 'ok', 2000)
    """
    from rollfric.uncertainty import quality

    check_angles(theta)
    guess = None
    if checks:
        try:
            guess = initial_guess(t, theta, setup)
        except InputError:  # the fit may succeed; a record too short to filter has no swings
            guess = None
        if method == "lsq" and guess is not None and "guess" not in kwargs:
            # the self-start the least-squares fit makes of the same t, theta: made once
            kwargs = dict(kwargs, guess=guess)
    result = FIT_METHODS.load(method)(t, theta, setup, offset=offset, model=model, **kwargs)
    if checks:
        reasons = quality.check_fit(t, theta, result, setup, offset=offset,
                                    model=model if method == "lsq" else "coulomb", guess=guess,
                                    mu_max=MU_MAX, noise_floor=NOISE_FLOOR)
        result = dataclasses.replace(result, quality_reasons=tuple(reasons))
    return result


def json_safe(value):
    """A value made fit for JSON.

    Parameters
    ----------
    value
        A dict, list, tuple or scalar (nested).

    Returns
    -------
    object
        The same with NumPy scalars made plain and non-finite floats made None (JSON null).
    """
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def save_fit(result: FitResult, path, **extra) -> None:
    """Write ``result.to_dict()`` plus ``extra`` keys as JSON (NaN becomes null), atomically.

    Parameters
    ----------
    result : FitResult
    path : str or pathlib.Path
    **extra
        More keys for the file.
    """
    import json

    from rollfric.output.atomic import write_text

    write_text(path, json.dumps(json_safe({**result.to_dict(), **extra}), indent=2) + "\n")
