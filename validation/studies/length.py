"""When does fitting L = R - r (self-calibration) beat the nominal trough radius?

For record lengths and damping (mu) on a grid, each with a few seeds: tracks from the reference
ODE on an as-built trough drawn from the lab's tolerance (radius +- 0.5 mm about 85.3 mm,
10 mm ball), AR(0) locator noise, the real fit and budget once with the nominal L (its radius
uncertainty in the budget) and once with L fitted. Reported per grid point: the rms error of
mu and the median u_mu of each, the fitted L's median uncertainty against the nominal 0.5 mm,
and the coverage of each (|z| <= 2).

``python -m validation.studies.length --out DIR`` writes DIR/length_study.csv and prints the
table.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from validation.studies.coverage import draw_case, run_case

SECONDS = (0.5, 1.0, 2.0, 4.0)
MUS = (0.005, 0.0079, 0.02, 0.05)


def study(seeds: int = 5, *, noise_px: float = 0.05, theta0_deg: float = 15.0) -> pd.DataFrame:
    """One row per (seconds, mu, seed) with the nominal-L and fitted-L results."""
    rows = []
    for seconds in SECONDS:
        for mu in MUS:
            for s in range(seeds):
                case = draw_case(1000 + s)
                case.update(seconds=seconds, mu=mu, theta0_deg=theta0_deg, noise_px=noise_px,
                            ar=0.0, ball="10mm", diameter_mm=10.0, mass_kg=4.07612e-3)
                case["true_diameter_mm"] = 10.0
                nominal = run_case(case, oracle=False)
                fitted = run_case(case, fit_length=True, oracle=False)
                rows.append({"seconds": seconds, "mu_true": mu, "seed": s,
                             "err_nominal": nominal["mu"] / mu - 1,
                             "u_nominal": nominal["u_mu"] / mu, "z_nominal": nominal["z"],
                             "err_fitted": fitted["mu"] / mu - 1,
                             "u_fitted": fitted["u_mu"] / mu, "z_fitted": fitted["z"],
                             "u_L_fit_mm": fitted["u_L_fit_mm"], "z_L": fitted["z_L"]})
    return pd.DataFrame(rows)


def table(df: pd.DataFrame) -> pd.DataFrame:
    """Per (seconds, mu): rms relative error and median relative u of mu, nominal vs fitted L,
    the median u of the fitted L (mm), and the fractions with |z| <= 2."""
    g = df.groupby(["seconds", "mu_true"])
    return pd.DataFrame({
        "rms_err_nominal_%": 100 * g["err_nominal"].apply(lambda v: np.sqrt(np.mean(v**2))),
        "u_nominal_%": 100 * g["u_nominal"].median(),
        "rms_err_fitted_%": 100 * g["err_fitted"].apply(lambda v: np.sqrt(np.mean(v**2))),
        "u_fitted_%": 100 * g["u_fitted"].median(),
        "u_L_fit_mm": g["u_L_fit_mm"].median(),
        "cover_nominal": g["z_nominal"].apply(lambda v: np.mean(np.abs(v) <= 2)),
        "cover_fitted": g["z_fitted"].apply(lambda v: np.mean(np.abs(v) <= 2)),
        "cover_L": g["z_L"].apply(lambda v: np.mean(np.abs(v) <= 2)),
    })


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.studies.length", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--out", required=True)
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    df = study(args.seeds)
    df.to_csv(out / "length_study.csv", index=False)
    print(table(df).to_string(float_format=lambda v: f"{v:.3g}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
