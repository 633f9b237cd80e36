"""Estimate mu from an angle series theta(t): :func:`fit_mu`, the one entry to every fit method.

The default method (``"lsq"``) is a least-squares fit of the Lagrange equation of motion
(:mod:`rollfric.fit.eom`) to theta(t), with mu, theta(t0) and theta'(t0) free, optionally also a
constant angle offset and the velocity term mu1 (:mod:`rollfric.fit.lsq`), started from the
data (:mod:`rollfric.fit.start`). The thesis's own procedures are offered beside it for
comparison (:mod:`rollfric.fit.thesis`): ``"paper1_eps"`` (the first paper's analytic eps
iteration for a small ball at small angles) and ``"paper2_grid"`` (the second paper's grid
search around a first estimate). A method is any :class:`FitMethod` registered in
:data:`rollfric.registry.FIT_METHODS`; :func:`fit_mu` refuses angles that are not radians
and runs the quality checks (:mod:`rollfric.uncertainty.quality`) on what it returns.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol, runtime_checkable

import numpy as np

from rollfric.errors import InputError
from rollfric.fit.lsq import MU_MAX, NOISE_FLOOR
from rollfric.fit.result import FitResult
from rollfric.fit.start import initial_guess
from rollfric.registry import FIT_METHODS
from rollfric.setup.model import Setup
from rollfric.uncertainty import quality

METHODS = FIT_METHODS.names()


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
