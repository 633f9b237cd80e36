"""The friction-law page's figure: the test's power curves (docs/img/pages/friction_law.png).

Reads docs/data/friction_law.json, the summary ``python -m validation.studies.friction_law``
writes; draws the rejection rate against mu1 for the thesis's three balls (with the mu1 each
detects at 80 % power and the mu1 Cross's law would give) and, for the 10 mm ball, against the
noise, the release angle and the record length.

Usage (from the repository root)::

    PYTHONPATH=$PWD python docs/scripts/friction_law_figure.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "docs" / "data" / "friction_law.json"
OUT = ROOT / "docs" / "img" / "pages" / "friction_law.png"
DPI = 110
COLORS = {"1.58mm": "#c0392b", "10mm": "#2e6da4", "12.69mm": "#3c8d40"}


def _errorbars(ax, x, rows, **kw):
    ax.errorbar(x, [r["rate"] for r in rows], yerr=[r["se"] for r in rows], capsize=2,
                marker="o", ms=4, **kw)


def figure(data: dict, out: Path) -> None:
    """Draw the four panels of ``data`` (the study's summary) into ``out``."""
    power = data["power"]
    level = data["test_level"]
    fig, axes = plt.subplots(1, 4, figsize=(13.0, 3.4), gridspec_kw={"width_ratios":
                                                                      [1.6, 1, 1, 1]})
    ax = axes[0]
    for ball, rows in power["curves"]["mu1"].items():
        rows = [r for r in rows if r["mu1"] > 0]
        c = COLORS.get(ball, "k")
        _errorbars(ax, [r["mu1"] for r in rows], rows, color=c, label=f"{ball} ball")
        det = rows[0]["mu1_detectable_median"]
        ax.axvline(det, color=c, ls=":", lw=1)
        cross = rows[0]["mu1_cross_median"]
        ax.plot([cross], [1.04], marker="v", color=c, ms=7, clip_on=False)
    ax.axhline(level, color="0.4", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_ylim(0, 1.08)
    ax.set_xlabel("mu1 (s/rad), mu = 0.008 + mu1 |theta'|")
    ax.set_ylabel("rejects Coulomb (share of cases)")
    ax.set_title("(a) power: 4 s from 20 deg, 0.05 px\n"
                 "dotted: detectable at 80 %; triangles: Cross's law", fontsize=9)
    ax.legend(fontsize=8, loc="center left")
    for ax, key, label, log in ((axes[1], "noise_px", "locator noise (px)", True),
                                (axes[2], "theta0_deg", "release angle (deg)", False),
                                (axes[3], "seconds", "record length (s)", True)):
        rows = power["curves"][key]
        _errorbars(ax, [r[key] for r in rows], rows, color=COLORS["10mm"])
        ax.axhline(level, color="0.4", lw=0.8, ls="--")
        if log:
            ax.set_xscale("log")
        xs = [r[key] for r in rows]
        ax.set_xticks(xs, [f"{v:g}" for v in xs])
        ax.minorticks_off()
        ax.set_ylim(0, 1.08)
        ax.set_xlabel(label)
        ax.set_title(f"({'bcd'[list(power['curves']).index(key) - 1]}) 10 mm ball, mu1 = "
                     f"{power['mu1_sweep']:.0e} s/rad", fontsize=9)
    normal = data.get("level", {}).get("wall_normal", {}).get("rejected")
    if normal:
        fig.suptitle(f"The friction-law test (level {level:g}): on Coulomb + drag cases it "
                     f"rejects {100 * normal['rate']:.1f} +- {100 * normal['se']:.1f} % "
                     f"of {normal['n']}", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def main() -> int:
    figure(json.loads(DATA.read_text()), OUT)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
