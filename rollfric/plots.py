"""Figures of the measurement: angle vs model (the thesis's Figure 12)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rollfric.atomic import replacing  # noqa: E402


def plot_fit(t, theta, result, path, *, title: str | None = None) -> Path:
    """Measured theta(t) (dots) against the fitted model (line), and the residual below."""
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    fig, (ax, axr) = plt.subplots(2, 1, figsize=(9, 6), sharex=True,
                                  gridspec_kw={"height_ratios": [3, 1]})
    ax.plot(t, np.degrees(theta), ".", ms=2, color="tab:red", label="measured")
    ax.plot(result.t, np.degrees(result.curve), "-", lw=1.2, color="tab:blue",
            label=f"model ({result.method}), mu = {result.mu:.5f}")
    ax.set_ylabel("theta (deg)")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    ax.set_title(title or f"Angle vs equation of motion: relative error "
                          f"{100 * result.relative_error:.2f} %")
    resid = np.degrees(np.interp(t, result.t, result.curve, left=np.nan, right=np.nan) - theta)
    axr.plot(t, resid, ".", ms=1.5, color="0.3")
    axr.set_ylabel("model - data (deg)")
    axr.set_xlabel("t (s)")
    axr.grid(alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return path
