"""The friction-law test's outcome: :class:`LawTest`, its fit.json object and its line.

:func:`rollfric.uncertainty.law.friction_law` makes it; the test's level (:data:`LEVEL`), the
power its detectable mu1 is stated at (:data:`POWER`, :func:`detectable`) and the statistic's
name (:data:`STATISTIC`) are the outcome's too (:mod:`rollfric.uncertainty.law` re-exports
them).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats

LEVEL = 0.05
POWER = 0.8  # of mu1_detectable
STATISTIC = "one-sided Wald z = mu1 / u(mu1), u: HAC covariance and the setup's inputs (air)"


@dataclasses.dataclass(frozen=True)
class LawTest:
    """The outcome of :func:`rollfric.uncertainty.law.friction_law` (SI: mu1 in s/rad).

    Attributes
    ----------
    selected : str or None
        "coulomb" or "speed"; None when the track is too short to tell them apart.
    p_value, z : float
        The one-sided p-value of mu1 = 0 and the statistic.
    mu0, mu0_u, mu1, mu1_u : float
        The speed law's coefficients and their standard uncertainties (statistical and the
        setup's inputs).
    mu1_u_statistical, mu1_u_inputs : float
        The two parts of u(mu1).
    mu1_detectable : float
        The smallest mu1 the recording detects at ``level`` with probability ``power``.
    why : str
        Why the test was not made ('' when it was).
    """

    selected: str | None
    p_value: float = math.nan
    z: float = math.nan
    mu0: float = math.nan
    mu0_u: float = math.nan
    mu1: float = math.nan
    mu1_u: float = math.nan
    mu1_u_statistical: float = math.nan
    mu1_u_inputs: float = math.nan
    mu1_detectable: float = math.nan
    level: float = LEVEL
    power: float = POWER
    rms_residual: float = math.nan
    n_samples: int = 0
    seconds: float = 0.0
    why: str = ""
    inputs: tuple = ()  # (source, u(mu1) of it)
    curve: np.ndarray | None = dataclasses.field(default=None, repr=False)

    def to_json(self) -> dict:
        """fit.json's ``friction_law`` object.

        Returns
        -------
        dict
            ``selected``, ``p_value``, ``mu0``, ``mu0_u``, ``mu1`` (s/rad), ``mu1_u``,
            ``mu1_detectable`` with ``detectable_power``, ``level``, ``statistic`` and the
            details; ``why`` instead of the figures when the test was not made.
        """
        def num(v):
            return float(v) if math.isfinite(v) else None

        if self.selected is None:
            return {"selected": None, "why": self.why, "level": self.level,
                    "statistic": STATISTIC}
        return {"selected": self.selected, "p_value": num(self.p_value), "z": num(self.z),
                "mu0": num(self.mu0), "mu0_u": num(self.mu0_u), "mu1": num(self.mu1),
                "mu1_u": num(self.mu1_u), "mu1_u_statistical": num(self.mu1_u_statistical),
                "mu1_u_inputs": num(self.mu1_u_inputs),
                "mu1_detectable": num(self.mu1_detectable), "detectable_power": self.power,
                "level": self.level, "statistic": STATISTIC, "units": {"mu1": "s/rad"},
                "rms_residual_rad": num(self.rms_residual), "n_samples": self.n_samples,
                "inputs": [{"source": s, "u_mu1": num(u)} for s, u in self.inputs],
                "seconds": self.seconds}

    def line(self) -> str:
        """The test in one line, as the commands print it."""
        if self.selected is None:
            return f"friction law: not tested ({self.why})"
        return (f"friction law: {self.selected} (p = {self.p_value:.2g}; speed law mu0 = "
                f"{self.mu0:.6f} +- {self.mu0_u:.2g}, mu1 = {self.mu1:.3g} +- {self.mu1_u:.2g}"
                f" s/rad; detectable mu1 >= {self.mu1_detectable:.2g} s/rad at "
                f"{100 * self.power:.0f} % power)")


def detectable(u_mu1: float, level: float = LEVEL, power: float = POWER) -> float:
    """The smallest mu1 a one-sided test at ``level`` detects with probability ``power``.

    Parameters
    ----------
    u_mu1 : float
        The standard uncertainty of the fitted mu1 (s/rad).
    level : float
        The test's level.
    power : float
        The probability of detection (0.5: the mu1 at the threshold itself).

    Returns
    -------
    float
        (z_(1-level) + z_power) u_mu1, s/rad.
    """
    return float((stats.norm.isf(level) + stats.norm.ppf(power)) * u_mu1)
