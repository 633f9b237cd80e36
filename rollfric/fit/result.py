"""What a fit of mu gives: the model it fits to theta(t) and the result it returns.

:func:`model_theta` is the angle the equation of motion (:mod:`rollfric.fit.eom`) gives from a
start, plus the trough bottom's offset: every fit method fits it. :class:`FitResult` is the
outcome of one fit, whatever the method; :func:`relative_error` is the thesis's residual
measure (eq. 14) each method reports.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rollfric.fit import air, eom
from rollfric.setup.model import Setup


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
    quality_reasons: tuple = ()  # rollfric.uncertainty.reasons.Reason: why the fit is suspect

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


def relative_error(model, data) -> float:
    """The thesis's eq. 14: sum |model - data| / sum |data|; NaN when every angle is 0."""
    den = float(np.sum(np.abs(data)))
    # angles all 0 (a ball that never moved): no relative error (NaN, null in fit.json)
    return float(np.sum(np.abs(model - data))) / den if den > 0 else math.nan

