"""The budget as a command reports it: the text table, the quality reason of a budget that
does not determine mu, and the budget of a command's fit with its options checked.
"""

from __future__ import annotations

import dataclasses
import logging
import math

from rollfric.errors import InputError
from rollfric.uncertainty.anglemap import METHOD
from rollfric.uncertainty.asbuilt import SOURCES as AS_BUILT
from rollfric.uncertainty.asbuilt import TILT
from rollfric.uncertainty.budget import CONTOUR_NOTE, Budget, budget
from rollfric.uncertainty.measured import Measurement
from rollfric.uncertainty.propagation import SECOND_ORDER
from rollfric.uncertainty.reasons import Reason


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
                         or r.source == METHOD or r.source in AS_BUILT)
                         else ""))
    lines.append(f"  combined u(mu) = {b.u_mu:.3g} ({rel(b.u_mu).strip()}), expanded U(mu) = "
                 f"{b.U_mu:.3g} ({rel(b.U_mu).strip()}, k = {b.coverage_factor:g})")
    st = b.statistical
    lines.append(f"  statistical: ordinary {st['stderr_ordinary']:.3g}, corrected x"
                 f"{st['inflation']:.2f} for correlated residuals (lag window "
                 f"{st['lag_window']})")
    if b.exact:
        lines.append(f"  taken as exact (no _u in the setup): {', '.join(b.exact)}")
    if TILT in b.exact:
        lines.append("  the trough is taken as level along its axis (state cylinder.tilt_deg "
                     "and tilt_deg_u: a tilt of 0.055 deg biases mu by about -0.1 % over 2 s)")
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
    rollfric.uncertainty.reasons.Reason or None
        ``uncertainty`` when mu < BUDGET_MU_SIGMAS_MIN u(mu) (U(mu) >= mu at k = 2), naming
        the row that dominates u(mu)^2 and, for a setup key, its ``_u`` key.
    """
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
    as a warning of the ``rollfric.uncertainty.report`` logger).

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
