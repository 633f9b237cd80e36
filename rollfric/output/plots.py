"""Figures of the measurement: angle vs model (the thesis's Figure 12)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from rollfric.output.atomic import replacing


def plot_fit(t, theta, result, path, *, title: str | None = None) -> Path:
    """Measured theta(t) (dots) against the fitted model (line), and the residual below.

    Parameters
    ----------
    t, theta : array_like
        The measured series (s, rad).
    result : FitResult
        The fit (its ``t``, ``curve``, ``mu``, ``method``, ``relative_error``).
    path : str or pathlib.Path
        The PNG to write (atomically).
    title : str, optional
        Default: mu and the residual rms.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    fig = Figure(figsize=(9, 6))  # no pyplot: no backend, no global figure state
    ax, axr = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    # the model under the data, so that every measured point stays visible
    ax.plot(result.t, np.degrees(result.curve), "-", lw=2.5, color="tab:blue", alpha=0.45,
            zorder=1, label=f"equation of motion ({result.method}), mu = {result.mu:.6f}")
    ax.plot(t, np.degrees(theta), ".", ms=1.5, color="black", zorder=2, label="measured")
    ax.set_ylabel("theta (deg)")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    resid = np.degrees(theta - np.interp(t, result.t, result.curve, left=np.nan, right=np.nan))
    rms = float(np.sqrt(np.nanmean(resid ** 2))) if np.isfinite(resid).any() else float("nan")
    ax.set_title(title or f"theta(t) and the fitted equation of motion: mu = {result.mu:.6f}, "
                          f"residual rms {rms:.2g} deg")
    axr.plot(t, resid, ".", ms=1.5, color="0.3")
    axr.axhline(0, color="tab:blue", lw=1)
    axr.set_ylabel("data - model (deg)")
    axr.set_xlabel("t (s)")
    axr.grid(alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=120)
    return path


def plot_budget(budget, path) -> Path:
    """The uncertainty budget as horizontal bars.

    Each source's u(mu), largest on top, with the combined and the expanded uncertainty
    (relative to mu, %).

    Parameters
    ----------
    budget : rollfric.uncertainty.budget.Budget
    path : str or pathlib.Path
        The PNG to write (atomically).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    rows = [r for r in budget.rows if r.u_mu > 0]
    scale = 100.0 / budget.mu if budget.mu > 0 else 1.0
    unit = "% of mu" if budget.mu > 0 else "mu"
    # bottom to top: expanded U, combined u, then the sources smallest to largest
    names = [f"expanded U (k = {budget.coverage_factor:g})", "combined u"] + \
        [r.source for r in rows][::-1]
    values = [budget.U_mu * scale, budget.u_mu * scale] + [r.u_mu * scale for r in rows][::-1]
    fig = Figure(figsize=(7, 0.45 * len(names) + 1.2))  # no pyplot, as plot_fit
    ax = fig.subplots()
    ax.barh(range(len(names)), values, color=["tab:red", "tab:orange"] + ["tab:blue"] * len(rows))
    ax.set_yticks(range(len(names)), names)
    for i, v in enumerate(values):
        ax.text(v, i, f" {v:.3g}", va="center", fontsize=8)
    ax.set_xlabel(f"standard uncertainty of mu ({unit})")
    # over the whole figure: the axes are narrow beside long source names
    fig.suptitle(f"Uncertainty budget: mu = {budget.mu:.6g}, U = {budget.U_mu:.2g} (k = "
                 f"{budget.coverage_factor:g})", fontsize=11)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=120)
    return path
