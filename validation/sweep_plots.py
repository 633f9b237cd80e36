"""A sweep's plots: every metric against each swept key, in the unit a user reads.

:func:`metric_axis` names a metric and scales it (relative errors in %, radians in degrees);
:func:`plot_sweep` draws ``OUT/plots/<key>.png`` from the combined table
(:mod:`validation.sweep_table`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rollfric.output.atomic import replacing
from validation.sweep import SweepSpec

# what a metric is called on a plot, by name (the rest: its name without the unit suffix)
METRIC_NAMES = {
    "mu_bias_rel": "bias in mu",
    "mu_pipeline_bias_rel": "bias in mu from the camera, locator and fit",
    "mu_engine_bias_rel": "bias in mu of the engine",
    "center_rms_px": "centre error, rms",
    "center_max_px": "centre error, largest",
    "theta_rms_rad": "angle error, rms",
    "theta_max_rad": "angle error, largest",
    "found_fraction": "frames located",
}


def metric_axis(name: str) -> tuple[float, str]:
    """(scale, label) that shows metric ``name`` in the unit a user reads: a relative error
    or a fraction in percent, radians in degrees, pixels as pixels."""
    label = METRIC_NAMES.get(name, name.replace("_", " "))
    if name.endswith("_rel") or name.endswith("fraction"):
        return 100.0, f"{label} (%)"
    if name.endswith("_rad"):
        return 180.0 / math.pi, f"{label.removesuffix(' rad')} (deg)"
    if name.endswith("_px"):
        return 1.0, f"{label.removesuffix(' px')} (px)"
    if name.endswith("_s"):
        return 1.0, f"{label.removesuffix(' s')} (s)"
    return 1.0, label


def _distinct_metrics(ok, metrics: list[str]) -> tuple[list[str], dict]:
    """The metrics with a panel of their own, and {dropped: kept} for those whose column
    equals an earlier one's in every case (on an exact engine the pipeline's bias is the
    whole bias: one panel, not two identical ones)."""
    kept, same = [], {}
    for m in metrics:
        v = ok[m].to_numpy(float)
        twin = next((k for k in kept if np.allclose(ok[k].to_numpy(float), v, rtol=0,
                                                     atol=1e-15, equal_nan=True)), None)
        if twin is None:
            kept.append(m)
        else:
            same[m] = twin
    return kept, same


def _panel(ax, sub, x: str, met: str, groups: list, others: list, pos: dict,
           numeric: bool, with_U: bool, twins: list) -> None:
    """One metric against x on ``ax``: a point a case (``with_U``: with its U(mu) and the
    median U as a grey band), the mean over repeats joined when x is a number, a colour for
    each group of the ``others`` keys; ``twins``: metrics equal to this one."""
    xs_all = list(pos)
    span = (max(pos.values()) - min(pos.values())) or 1.0
    scale, ylabel = metric_axis(met)
    for j, (gkey, g) in enumerate(groups):
        gkey = gkey if isinstance(gkey, tuple) else (gkey,)
        label = ", ".join(f"{k} = {v}" for k, v in zip(others, gkey, strict=True))
        # repeats side by side, not on top of each other
        shift = (j - (len(groups) - 1) / 2) * 0.015 * span
        px = np.array([pos[v] for v in g[x]]) + shift
        y = scale * g[met].to_numpy(float)
        yerr = (scale * g["U_mu"].to_numpy(float) / g["mu_true"].to_numpy(float)
                if with_U else None)
        line = ax.errorbar(px, y, yerr=yerr, fmt="o", ms=4, capsize=2, lw=0.8,
                           label=label or None)
        if numeric:
            mean = g.groupby(x)[met].mean().reindex([v for v in xs_all
                                                      if v in set(g[x])])
            ax.plot([pos[v] + shift for v in mean.index], scale * mean.to_numpy(float),
                    "-", lw=1, color=line[0].get_color())
    if with_U:
        band = float(np.nanmedian(scale * sub["U_mu"] / sub["mu_true"]))
        ax.axhspan(-band, band, color="0.85", zorder=0,
                   label=f"median U(mu), k = 2: +-{band:.2g} %")
        ax.axhline(0, color="k", lw=0.7)
    elif np.nanmin(sub[met].to_numpy(float)) >= 0:
        ax.set_ylim(bottom=0)  # a small spread is not drawn as a cliff
    ax.set_ylabel(ylabel, fontsize=9)
    ax.grid(alpha=0.3)
    title = METRIC_NAMES.get(met, met) + (
        f" (the same as {', '.join(twins)} here)" if twins else "")
    ax.set_title(title, fontsize=9)
    handles, _ = ax.get_legend_handles_labels()
    if handles and len(groups) <= 12:
        ax.legend(fontsize=7, loc="best")


def plot_sweep(df, spec: SweepSpec, plot_dir: Path) -> list[Path]:
    """For every swept key x: one panel per metric against x, in the metric's unit.

    Every case is a point; a relative bias in mu carries its case's expanded uncertainty
    U(mu) (k = 2) as an error bar, with the median U as a grey band about zero (the target:
    a bias inside it is within what the measurement claims). The mean over repeats is
    joined by a line when x is a number; categories (a lighting preset, a renderer) are
    points only. The other swept keys are colours.
    """
    from matplotlib.figure import Figure  # no pyplot: no backend, no global figure state

    ok = df[df["status"] == "ok"]
    if ok.empty:
        return []
    plot_dir.mkdir(parents=True, exist_ok=True)
    written = []
    keys = [k for k in spec.swept if k in ok.columns and k != "render.seed"]
    metrics, same = _distinct_metrics(ok, [m for m in spec.metrics if m in ok.columns])
    has_U = {"U_mu", "mu_true"} <= set(ok.columns)

    def determines(a, b):  # every value of a comes with one value of b (where both are set)
        both = ok[ok[a].notna() & ok[b].notna()]
        return not both.empty and bool((both.groupby(a)[b].nunique() <= 1).all())

    plotted: list = []
    for x in keys:
        if any(determines(x, k) and determines(k, x) for k in plotted):
            continue  # co-varies one to one with a key already plotted (a list sweep)
        plotted.append(x)
        # the cases that set x (in a list sweep a case may leave a key at the base's value)
        sub = ok[ok[x].notna()]
        # colours only for keys that vary among them, independently of x
        others = [k for k in keys if k != x and not determines(x, k)
                  and sub[k].nunique(dropna=False) > 1]
        if not metrics or sub.empty:
            continue
        fig = Figure(figsize=(8, 2.6 * len(metrics) + 0.8))
        axes = fig.subplots(len(metrics), 1, squeeze=False, sharex=True)
        xs_all = list(dict.fromkeys(sub[x].tolist()))
        numeric = all(isinstance(v, (int, float, np.number)) and not isinstance(v, bool)
                      for v in xs_all)
        pos = ({v: float(v) for v in xs_all} if numeric
               else {v: float(i) for i, v in enumerate(xs_all)})
        groups = list(sub.groupby(others, dropna=False)) if others else [((), sub)]
        for ax, met in zip(axes[:, 0], metrics, strict=True):
            _panel(ax, sub, x, met, groups, others, pos, numeric,
                   with_U=has_U and met.startswith("mu_") and met.endswith("bias_rel"),
                   twins=[d for d, k in same.items() if k == met])
        axes[-1, 0].set_xlabel(x)
        if not numeric:
            axes[-1, 0].set_xticks(list(pos.values()), [str(v) for v in pos], rotation=20)
        fig.suptitle(f"sweep {spec.name}: against {x}", fontsize=10)
        fig.tight_layout()
        path = plot_dir / f"{x.replace('.', '_')}.png"
        with replacing(path) as tmp:
            fig.savefig(tmp, dpi=100)
        written.append(path)
    return written
