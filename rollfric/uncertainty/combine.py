"""Repeated releases of one setup combined: a weighted mean of their mu with the budget split.

Each run's budget (fit.json's ``uncertainty_budget``) splits into two parts:

- the **independent** part: the statistical rows (the least-squares error of the locator's
  noise, ``"statistical"``; a row whose ``part`` is ``"independent"``), whose errors are
  independent between releases and average down;
- the **shared** part: every other row (the setup's inputs: trough radius, ball diameter, frame
  rate, pixel size, the trough's centre, the lens, gravity; the method and second-order rows),
  whose error is the same on every release of one setup (fully correlated) and does not.

With u_i the independent part of run i, the weights are w_i = u_i^-2 / sum_j u_j^-2, the
combined mu = sum_i w_i mu_i and its independent part u_ind = (sum_i u_i^-2)^-1/2. A shared
row s, whose common input error moves run i's mu by its signed u_mu,i,s (the row's ``u_mu``
with the sign of its ``sensitivity``), moves the mean by sum_i w_i u_mu,i,s: that is the row's
part of the combined u (it equals the runs' common value when they agree, so it does not
average down). A row whose recorded input value differs between the runs (a trough centre
found from each recording's own contour) is not certainly common: it is never taken below its
value for independent errors, sqrt(sum_i (w_i u_mu,i,s)^2).

The scatter is checked against the runs' own budgets with the Birge ratio
R_B = sqrt(chi2 / (N - 1)) of the runs about the weighted mean. chi2 uses the residuals'
covariance from the runs' budgets: a shared row that moves every run alike drops out of the
residuals, and chi2 is then sum_i (mu_i - mu)^2 / u_i^2 exactly (the runs' independent u);
a shared row that moves the runs differently (a trough centre's error on releases to either
side) is scatter the budgets expect and enters chi2's covariance (``birge_ratio_independent``
keeps the ratio with the independent parts alone). The ``second order`` row of a budget made
with ``--second-order`` (the inputs' interactions, e.g. radius x centre, which act on releases
to either side with opposite signs) enters the mean's u in full and chi2 as independent
between runs: first-order budgets lack it, and releases whose statistical u is far below their
setup part then scatter more than their budgets say. Its 95 % range at N follows from the chi2
distribution with N - 1 degrees of freedom. As the Particle Data Group does, the independent
part is scaled by R_B when R_B > 1; a ratio above its range also makes the result suspect (a
reason ``birge_ratio``: the releases scatter more than their budgets allow). The combined
standard uncertainty is sqrt((S u_ind)^2 + u_shared^2), S = max(1, R_B), and U = k u with
k = 2.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path

from rollfric.errors import InputError
from rollfric.uncertainty.law import combined_law
from rollfric.uncertainty.runs import Run, check_one_setup, read_fit, run_from_fit, same_value

log = logging.getLogger(__name__)

COVERAGE_FACTOR = 2.0
BIRGE_LEVEL = 0.95  # the probability of the Birge ratio's expected range
# shared rows whose effect differs in sign and size between releases even for one common
# input error (the inputs' interactions: radius x centre): full in the mean's u, independent
# in the Birge ratio's chi2
UNLIKE_SOURCES = ("second order",)


@dataclasses.dataclass(frozen=True)
class Combined:
    """The combined mu of N releases, its uncertainty split into parts, the Birge ratio."""

    mu: float
    mu_u: float
    U_mu: float
    coverage_factor: float
    u_independent: float  # of the mean, scaled by ``scale``
    u_independent_unscaled: float
    u_shared: float
    shared_rows: tuple  # ({"source", "u_mu", "correlation"}, ...), largest first
    runs: tuple  # ({"path", "mu", "u_independent", "u_mu", "weight", "quality"}, ...)
    birge_ratio: float
    birge_range: tuple
    chi2: float
    scale: float
    birge_ratio_independent: float  # with the runs' independent parts alone
    left_out: tuple  # ({"path", "reason"}, ...)
    quality_reasons: tuple  # ({"code", "message"}, ...)
    friction_law: dict = dataclasses.field(default_factory=dict)  # the releases' law test

    @property
    def n(self) -> int:
        """The number of runs combined."""
        return len(self.runs)

    @property
    def quality(self) -> str:
        """``ok``, or ``suspect`` when there is a reason."""
        return "suspect" if self.quality_reasons else "ok"

    def to_json(self) -> dict:
        """The combined.json keys (see docs/formats/combined-json.md).

        Returns
        -------
        dict
        """
        return {"mu": self.mu, "mu_u": self.mu_u, "U_mu": self.U_mu,
                "coverage_factor": self.coverage_factor, "n": self.n,
                "u_independent": self.u_independent,
                "u_independent_unscaled": self.u_independent_unscaled,
                "u_shared": self.u_shared, "shared_budget": [dict(r) for r in self.shared_rows],
                "birge_ratio": self.birge_ratio,
                "birge_range": list(self.birge_range), "birge_level": BIRGE_LEVEL,
                "birge_ratio_independent": self.birge_ratio_independent,
                "chi2": self.chi2, "scale": self.scale,
                "runs": [dict(r) for r in self.runs],
                "left_out": [dict(r) for r in self.left_out],
                "friction_law": dict(self.friction_law),
                "quality": self.quality,
                "quality_reasons": [dict(r) for r in self.quality_reasons]}



# -- combining -------------------------------------------------------------------------------

def birge_range(n: int, level: float = BIRGE_LEVEL) -> tuple[float, float]:
    """The central ``level`` interval of the Birge ratio of ``n`` consistent measurements.

    Parameters
    ----------
    n : int
        Number of measurements (>= 2).
    level : float
        Probability of the interval.

    Returns
    -------
    (low, high) : tuple of float
        sqrt(q / (n - 1)) for the chi2 quantiles q at (1 - level) / 2 and (1 + level) / 2
        with n - 1 degrees of freedom.
    """
    from scipy.stats import chi2

    dof = n - 1
    lo, hi = chi2.ppf([(1 - level) / 2, (1 + level) / 2], dof)
    return math.sqrt(lo / dof), math.sqrt(hi / dof)


def combine(runs: list[Run], *, coverage_factor: float = COVERAGE_FACTOR,
            left_out: tuple = (), level: float = BIRGE_LEVEL) -> Combined:
    """Combine repeated releases of one setup (see the module's docstring for the formulas).

    Parameters
    ----------
    runs : list of Run
        At least two releases of one setup.
    coverage_factor : float
        k of U = k u.
    left_out : tuple of dict
        ``{"path", "reason"}`` of runs left out, recorded in the result.
    level : float
        Probability of the Birge ratio's expected range.

    Returns
    -------
    Combined

    Raises
    ------
    rollfric.errors.InputError
        If there are fewer than two runs.
    """
    n = len(runs)
    if n < 2:
        raise InputError(f"combine needs at least two runs, got {n}"
                         + (f" ({len(left_out)} suspect run(s) left out: --include-suspect "
                            "keeps them)" if left_out else ""))
    import numpy as np

    inv = [1.0 / r.u_independent ** 2 for r in runs]
    total = sum(inv)
    w = [v / total for v in inv]
    mu = sum(wi * r.mu for wi, r in zip(w, runs, strict=True))
    u_ind = 1.0 / math.sqrt(total)
    # the runs' covariance: the independent parts on the diagonal, each shared row's signed
    # u_mu as a common error (an input found anew in each run: independent)
    cov = np.diag([r.u_independent ** 2 for r in runs])
    rows = []
    for source in dict.fromkeys(s for r in runs for s in r.shared):
        c = np.array([r.shared[source][0] if source in r.shared else 0.0 for r in runs])
        values = [r.shared[source][1] for r in runs if source in r.shared]
        agree = all(v is not None and same_value(v, values[0]) for v in values) or \
            all(v is None for v in values)
        common = abs(float(np.dot(w, c)))
        u = common
        if agree and source in UNLIKE_SOURCES:  # a common error, its effect unlike per run
            cov += np.diag(c * c)
        elif agree:
            cov += np.outer(c, c)
        else:  # not certainly a common error: never below its value for independent errors
            u = max(common, float(np.sqrt(np.sum((np.asarray(w) * c) ** 2))))
            cov += np.diag(c * c)
        rows.append({"source": source, "u_mu": u,
                     "correlation": "full" if agree else "full, or none where larger"})
    rows.sort(key=lambda r: -r["u_mu"])
    chi2, chi2_independent = _chi2(np.array([r.mu for r in runs]), mu, np.asarray(w), cov,
                                   np.array(inv))
    rb = math.sqrt(chi2 / (n - 1))
    lo, hi = birge_range(n, level)
    scale = max(1.0, rb)
    u_shared = math.sqrt(sum(r["u_mu"] ** 2 for r in rows))
    u = math.hypot(scale * u_ind, u_shared)
    reasons = []
    if rb > hi:
        reasons.append({"code": "birge_ratio", "message": (
            f"the releases scatter more than their budgets allow: Birge ratio {rb:.3g} above "
            f"its {100 * level:g} % range [{lo:.3g}, {hi:.3g}] for N = {n}; the independent "
            f"part is scaled by {rb:.3g}. Look for a release that differs (a setup moved, a "
            "suspect track) or an error the budget lacks"
            + ("" if any(UNLIKE_SOURCES[0] in r.shared for r in runs) else
               "; the runs' budgets are first order: made with --second-order they hold the "
               "setup inputs' interactions, which act differently on each release"))})
    law = combined_law([r.law for r in runs])
    if law.get("selected") == "speed":
        reasons.append({"code": "friction_law", "message": (
            f"the {law['n']} releases together reject Coulomb friction (p = "
            f"{law['p_value']:.2g}): mu1 = {law['mu1']:.3g} +- {law['mu1_u']:.2g} s/rad, a "
            "resistance that grows with speed; mu is the Coulomb coefficient of each release "
            "(measure them with --model speed for mu0)")})
    suspect = [r.path for r in runs if _suspect(r)]
    if suspect:
        reasons.append({"code": "suspect_runs", "message": (
            f"{len(suspect)} run(s) whose own quality is suspect are included "
            f"(--include-suspect): {', '.join(suspect)}")})
    run_rows = tuple({"path": r.path, "mu": r.mu, "u_independent": r.u_independent,
                      "u_mu": r.u_mu, "weight": wi, "quality": r.quality}
                     for r, wi in zip(runs, w, strict=True))
    return Combined(mu=mu, mu_u=u, U_mu=coverage_factor * u, coverage_factor=coverage_factor,
                    u_independent=scale * u_ind, u_independent_unscaled=u_ind,
                    u_shared=u_shared, shared_rows=tuple(rows), runs=run_rows,
                    birge_ratio=rb, birge_range=(lo, hi), chi2=chi2, scale=scale,
                    birge_ratio_independent=math.sqrt(chi2_independent / (n - 1)),
                    left_out=tuple(left_out), quality_reasons=tuple(reasons),
                    friction_law=law)


def _suspect(run: Run) -> bool:
    """A run whose own quality is not ok, for a reason other than its friction law (a run
    suspect for its law alone is kept: the releases test the law together)."""
    return run.quality != "ok" and set(run.quality_codes) != {"friction_law"}


def _chi2(mus, mean: float, w, cov, inv) -> tuple[float, float]:
    """chi2 of the runs about their weighted mean: with the residuals' covariance from the
    runs' (``cov``), and with the independent parts alone (sum of r_i^2 / u_i^2).

    The residuals r = (I - 1 w^T) mu have covariance P cov P^T (rank N - 1: the weighted sum
    of the residuals is 0), so the first N - 1 of them, with their block of it, carry the
    chi2. A shared row that acts alike on every run drops out of P cov P^T, and the chi2 is
    then the independent one exactly; one that acts differently (a centre error on releases
    to either side) is scatter the budgets expect.
    """
    import numpy as np

    r = mus - mean
    n = r.size
    p = np.eye(n) - np.outer(np.ones(n), w)
    c = (p @ cov @ p.T)[: n - 1, : n - 1]
    try:
        chi2 = float(r[: n - 1] @ np.linalg.solve(c, r[: n - 1]))
    except np.linalg.LinAlgError:
        chi2 = float(r[: n - 1] @ np.linalg.pinv(c) @ r[: n - 1])
    return chi2, float(np.sum(r * r * inv))


def combine_files(paths, *, include_suspect: bool = False,
                  coverage_factor: float = COVERAGE_FACTOR) -> tuple[Combined, list[str]]:
    """Read fit.json files of repeated releases of one setup and combine them.

    Parameters
    ----------
    paths : sequence of str or os.PathLike
        The fit.json files, each named once.
    include_suspect : bool
        Keep runs whose quality is not ``ok`` (the result is then suspect); by default they
        are left out with a warning.
    coverage_factor : float
        k of U = k u.

    Returns
    -------
    combined : Combined
    warnings : list of str
        What the user should know (runs left out, setups compared only through the budget).

    Raises
    ------
    rollfric.errors.InputError
        A file that is not a rollfric fit.json with a budget, a file named twice, runs of
        different setups, fewer than two runs (after leaving out the suspect ones).
    """
    seen: dict = {}
    for p in paths:
        key = Path(p).resolve()
        if key in seen:
            raise InputError(f"{p}: named twice (as {seen[key]}): each release counts once")
        seen[key] = str(p)
    runs = [run_from_fit(read_fit(p), p) for p in paths]
    if len(runs) >= 2:
        warnings = check_one_setup(runs)
    else:
        warnings = []
    models = {r.model for r in runs}
    if len(models) > 1:
        raise InputError("the runs were fitted with different friction models ("
                         + "; ".join(f"{r.path}: {r.model}" for r in runs)
                         + "): fit them all with one --model")
    left_out = []
    if not include_suspect:
        for r in runs:
            if _suspect(r):
                why = ", ".join(r.quality_codes) or r.quality
                left_out.append({"path": r.path, "reason": f"quality {r.quality} ({why})"})
                warnings.append(f"{r.path}: left out, its quality is {r.quality} ({why}); "
                                "--include-suspect keeps it")
        runs = [r for r in runs if not _suspect(r)]
    for w in warnings:
        log.warning(w)
    return combine(runs, coverage_factor=coverage_factor, left_out=tuple(left_out)), warnings


def format_summary(c: Combined, out=None) -> str:
    """The combined result as a few lines of text (the command's printed summary).

    Parameters
    ----------
    c : Combined
    out : str or os.PathLike, optional
        Where it was written (named on the first line).

    Returns
    -------
    str
        Lines joined by newlines (no trailing newline).
    """
    rel = (lambda v: f"{100 * v / c.mu:.3g} %") if c.mu > 0 else (lambda v: "-")
    lines = [f"combined {c.n} releases: mu = {c.mu:.6f} +- {c.mu_u:.2g} (u, {rel(c.mu_u)}), "
             f"U = {c.U_mu:.2g} (k = {c.coverage_factor:g})"
             + (f" -> {out}" if out is not None else ""),
             f"  independent part {c.u_independent:.3g}"
             + (f" (scaled by the Birge ratio from {c.u_independent_unscaled:.3g})"
                if c.scale > 1 else "")
             + f", shared part {c.u_shared:.3g} (setup: does not average down)",
             f"  Birge ratio {c.birge_ratio:.3g} (95 % range at N = {c.n}: "
             f"[{c.birge_range[0]:.3g}, {c.birge_range[1]:.3g}]"
             + ("; below it: the runs agree better than their budgets expect"
                if c.birge_ratio < c.birge_range[0] else "")
             + f"); with the independent parts alone {c.birge_ratio_independent:.3g}"]
    law = c.friction_law
    if law.get("selected"):
        lines.append(f"  friction law, the releases together: {law['selected']} (p = "
                     f"{law['p_value']:.2g}; mu1 = {law['mu1']:.3g} +- {law['mu1_u']:.2g} s/rad, "
                     f"of which the setup's inputs {law['mu1_u_inputs']:.2g}, shared; "
                     f"detectable mu1 >= {law['mu1_detectable']:.2g} s/rad)")
    elif law:
        lines.append(f"  friction law: not tested together ({law.get('why', '')})")
    for r in c.runs:
        lines.append(f"  {r['path']}: mu = {r['mu']:.6f} +- {r['u_independent']:.2g} "
                     f"(independent), weight {r['weight']:.3f}")
    for r in c.left_out:
        lines.append(f"  {r['path']}: left out ({r['reason']})")
    return "\n".join(lines)
