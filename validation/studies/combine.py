"""Does ``rollfric combine``'s U cover the truth? Repeated releases of one setup, track level.

Each **setup** draws, once, what every release of it shares: the ball and its true mu, the
as-built trough radius, ball diameter, trough centre, frame rate and pixel size from the lab's
tolerances (:data:`validation.studies.coverage.TOLERANCE`, about the nominal setup), the locator's
noise
level and correlation and the record length. Its **releases** (``releases`` of them) each draw
their own release angle (6-30 deg, to either side) and their own noise. As in
:mod:`validation.studies.coverage`, the ball's path is the reference ODE on the as-built trough,
sampled at the as-built frame rate and projected with the as-built scale and centre; the
measurement sees only the nominal setup with its ``_u`` keys, fits and runs the budget
(:func:`rollfric.uncertainty.budget.budget`) of each release, and the releases' fit.json keys are
combined by :func:`rollfric.uncertainty.combine.combine` as ``rollfric combine`` does (suspect
releases
left out). Per setup: z = (mu_combined - mu_true) / u_combined; an honest combination has the
truth within U (k = 2) in about 95 % of the setups and within u in about 68 %. The Birge
ratios are compared with their distribution for consistent releases (chi2 with N - 1 degrees
of freedom: 2.5 % above the 95 % range).

``python -m validation.studies.combine --setups 200 --releases 5 --out DIR`` writes
DIR/combine_study.csv (one row a setup), DIR/combine_study.json (the fractions) and
DIR/combine_study.png (z and the Birge ratios); :func:`run_study` does the same in Python.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rollfric.errors import InputError
from rollfric.fit.estimate import fit_mu
from rollfric.setup.model import THESIS_BALLS, Setup
from rollfric.uncertainty.budget import budget
from rollfric.uncertainty.combine import birge_range, combine, run_from_fit
from rollfric.uncertainty.measured import Measurement
from validation.studies.coverage import drawn_as_built, drawn_centres, drawn_setups, misses

RELEASE_SEEDS = 1000  # release k of setup s draws its noise with seed s * RELEASE_SEEDS + k


def draw_setup(seed: int, releases: int) -> dict:
    """One setup (shared by its releases) and its releases' angles, drawn with ``seed``.

    Parameters
    ----------
    seed : int
        The setup's seed.
    releases : int
        Number of releases.

    Returns
    -------
    dict
        The true mu, ball, as-built setup (``true_*`` keys), noise, record length, and
        ``theta0_deg``: one release angle per release.
    """
    rng = np.random.default_rng(seed)
    ball = str(rng.choice(list(THESIS_BALLS)))
    d_mm, mass = THESIS_BALLS[ball][0] * 1e3, THESIS_BALLS[ball][1]
    return {
        "seed": seed, "ball": ball, "mass_kg": mass, "releases": releases,
        "mu": float(math.exp(rng.uniform(math.log(0.004), math.log(0.02)))),
        "seconds": float(rng.choice([1.0, 2.0])),
        "noise_px": float(math.exp(rng.uniform(math.log(0.01), math.log(0.1)))),
        "ar": float(rng.choice([0.0, 0.5, 0.9])),
        "diameter_mm": d_mm,
        **drawn_as_built(rng, d_mm),
        "theta0_deg": [float(rng.choice([-1.0, 1.0]) * rng.uniform(6.0, 30.0))
                       for _ in range(releases)],
    }


def _setups(case: dict) -> tuple[Setup, Setup]:
    """(as built, the lab's nominal setup with its _u) of a drawn setup; with ``exact`` in
    the case the lab knows the as-built setup exactly (only the independent part is left)."""
    true, lab = drawn_setups(case)
    if case.get("exact"):
        lab = true
    return true, lab


def release_fit(case: dict, k: int, order: int = 1) -> dict:
    """The fit.json keys ``rollfric combine`` reads of release ``k`` of a drawn setup.

    Parameters
    ----------
    case : dict
        From :func:`draw_setup`.
    k : int
        The release.
    order : int
        The budget's order (2: with its ``second order`` row, as ``--second-order``).

    Returns
    -------
    dict
        mu, method, n_samples, u_mu, uncertainty_budget, quality, quality_reasons, setup.
    """
    true, lab = _setups(case)
    release = {**case, "theta0_deg": case["theta0_deg"][k],
               "seed": case["seed"] * RELEASE_SEEDS + k}
    frames, x, y = drawn_centres(release, true)
    meas = Measurement(setup=lab, frames=frames, x=x, y=y, center=lab.center_px)
    res = fit_mu(*meas.series(lab), lab)
    b = budget(meas, res, order=order)
    return {"mu": b.mu, "method": res.method, "n_samples": res.n_samples, "u_mu": b.u_mu,
            "uncertainty_budget": [r.to_dict() for r in b.rows], "quality": res.quality,
            "quality_reasons": [{"code": r.code} for r in res.quality_reasons],
            "setup": lab.to_toml_dict()}


def rendered_release_fit(case: dict, k: int, order: int = 1) -> dict:
    """:func:`release_fit` of a release rendered by synth and measured by ``rollfric.measure``
    (:mod:`validation.studies.rendered_faults`' small frames, 2 s, the renderer's exact setup,
    its camera stated square on (``yaw_deg_u = pitch_deg_u = 0``): the budget is the
    statistical part, the combination's independent part alone)."""
    from rollfric.measurement import measure
    from rollfric.uncertainty.measured import measurement_from_track
    from validation.faults.recordings import ArraySource
    from validation.studies.faults import square_on
    from validation.studies.rendered_faults import Case, rendered

    release = Case(family="combine", seed=case["seed"] * RELEASE_SEEDS + k, mu=case["mu"],
                   theta0=math.radians(abs(case["theta0_deg"][k])), ball=case["ball"],
                   seconds=2.0)
    with rendered(release) as base:
        setup = square_on(base.setup)
        df, info, res = measure(ArraySource(base.frames), setup, base.background)
        b = budget(measurement_from_track(df, info), res, order=order)
    return {"mu": b.mu, "method": res.method, "n_samples": res.n_samples, "u_mu": b.u_mu,
            "uncertainty_budget": [r.to_dict() for r in b.rows], "quality": res.quality,
            "quality_reasons": [{"code": r.code} for r in res.quality_reasons],
            "setup": setup.to_toml_dict()}


RENDERED_BALLS = ("1.58mm", "10mm")  # the rendered frames' balls (0.25 mm/px)


def run_setup(case: dict, order: int = 1) -> dict:
    """Measure every release of a drawn setup and combine them; one row of the study.

    Parameters
    ----------
    case : dict
        From :func:`draw_setup`.
    order : int
        The releases' budget order (:func:`release_fit`).

    Returns
    -------
    dict
        The setup's draws, the combined mu, u, U and its parts, z, the Birge ratio and its
        range, the releases left out as suspect (``n_suspect``); ``error`` when fewer than two
        releases were left.
    """
    start = time.perf_counter()
    fit = rendered_release_fit if case.get("rendered") else release_fit
    fits = [fit(case, k, order) for k in range(case["releases"])]
    runs = [run_from_fit(f, f"release {k}") for k, f in enumerate(fits)]
    ok = [r for r in runs if r.quality == "ok"]
    out = {k: v for k, v in case.items() if not isinstance(v, (tuple, list))}
    out.update(n_suspect=len(runs) - len(ok),
               z_runs_max=max(abs(r.mu - case["mu"]) / r.u_mu for r in runs))
    try:
        c = combine(ok)
    except InputError as exc:
        return {**out, "error": str(exc)}
    out.update(mu_combined=c.mu, u=c.mu_u, U=c.U_mu, u_independent=c.u_independent,
               u_independent_unscaled=c.u_independent_unscaled, u_shared=c.u_shared,
               z=(c.mu - case["mu"]) / c.mu_u, birge_ratio=c.birge_ratio,
               birge_ratio_independent=c.birge_ratio_independent,
               birge_low=c.birge_range[0], birge_high=c.birge_range[1], n=c.n,
               flagged=bool(c.quality_reasons), study_seconds=time.perf_counter() - start)
    return out


def summarize(df: pd.DataFrame) -> dict:
    """The study's figures: coverage of U and u, the Birge ratios against their distribution.

    Parameters
    ----------
    df : pandas.DataFrame
        Rows of :func:`run_setup`.

    Returns
    -------
    dict
    """
    from scipy.stats import chi2

    good = df[df["z"].notna()] if "z" in df else df.iloc[:0]
    n = len(good)
    z = good["z"].to_numpy(float)

    def se(p):
        return math.sqrt(p * (1 - p) / n) if n else math.nan

    within_U = float(np.mean(np.abs(z) <= 2.0)) if n else math.nan
    within_u = float(np.mean(np.abs(z) <= 1.0)) if n else math.nan
    rb = good["birge_ratio"].to_numpy(float)
    dof = good["n"].to_numpy(int) - 1
    # each setup's ratio as a probability under chi2(N - 1): uniform for consistent releases
    p = chi2.cdf(rb**2 * dof, dof)
    return {"setups": len(df), "combined": n,
            "too_few_releases": int(len(df) - n),
            "releases_left_out_suspect": int(df["n_suspect"].sum()),
            "within_U": within_U, "within_U_se": se(within_U),
            "within_u": within_u, "within_u_se": se(within_u),
            "z_rms": float(np.sqrt(np.mean(z**2))) if n else math.nan,
            **misses(z, "combined"),
            "birge_median": float(np.median(rb)) if n else math.nan,
            "birge_quantiles_5_50_95": [float(v) for v in np.quantile(rb, [0.05, 0.5, 0.95])]
            if n else [],
            "birge_above_range": float(np.mean(rb > good["birge_high"])) if n else math.nan,
            "birge_below_range": float(np.mean(rb < good["birge_low"])) if n else math.nan,
            "birge_above_1": float(np.mean(rb > 1.0)) if n else math.nan,
            "birge_expected_above_range": 0.025,
            "birge_probability_ks_p": float(_ks_uniform(p)) if n > 1 else math.nan,
            "median_shared_fraction": float(np.median(good["u_shared"] / good["u"]))
            if n else math.nan,
            "median_U_rel": float(np.median(good["U"] / good["mu"])) if n else math.nan}


def _ks_uniform(p) -> float:
    from scipy.stats import kstest

    return kstest(p, "uniform").pvalue


def plot(df: pd.DataFrame, path: Path) -> None:
    """z of the combined results and the Birge ratios against their chi2 distribution."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import chi2, norm

    good = df[df["z"].notna()]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    bins = np.linspace(-4, 4, 33)
    ax[0].hist(good["z"], bins=bins, density=True, alpha=0.7, label="setups")
    xs = np.linspace(-4, 4, 200)
    ax[0].plot(xs, norm.pdf(xs), "k-", label="N(0, 1)")
    ax[0].axvline(-2, color="r", ls=":")
    ax[0].axvline(2, color="r", ls=":")
    ax[0].set_xlabel("(mu combined - truth) / u combined")
    ax[0].set_title(f"within U: {np.mean(np.abs(good['z']) <= 2):.3f} of {len(good)}")
    ax[0].legend()
    n = int(good["n"].mode().iloc[0])
    rb = good.loc[good["n"] == n, "birge_ratio"]
    ax[1].hist(rb, bins=30, density=True, alpha=0.7, label=f"setups with N = {n}")
    r = np.linspace(1e-3, max(3.0, float(rb.max())), 300)
    dof = n - 1
    ax[1].plot(r, chi2.pdf(r**2 * dof, dof) * 2 * r * dof, "k-", label="consistent releases")
    lo, hi = birge_range(n)
    ax[1].axvline(hi, color="r", ls=":", label="95 % range")
    ax[1].axvline(lo, color="r", ls=":")
    ax[1].set_xlabel("Birge ratio")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_study(setups: int, releases: int, out: Path | None = None, seed: int = 0,
              progress: bool = False, order: int = 1,
              exact: bool = False, rendered: bool = False) -> tuple[pd.DataFrame, dict]:
    """Run the study: ``setups`` drawn setups of ``releases`` releases each.

    Parameters
    ----------
    setups : int
        Number of setups.
    releases : int
        Releases per setup (>= 2).
    out : pathlib.Path, optional
        A folder for combine_study.csv, .json and .png.
    seed : int
        The first setup's seed (setup i: seed + i).
    progress : bool
        Print the summary every 10 setups.
    order : int
        The releases' budget order: 1, or 2 with the ``second order`` row.
    exact : bool
        The lab knows its as-built setup exactly: no shared part; checks the weighting, the
        independent parts and the Birge ratio alone.
    rendered : bool
        Each release rendered by synth and measured by ``rollfric.measure``
        (:func:`rendered_release_fit`: the renderer's exact setup, so the independent part
        alone, as ``exact``); the 1.58 and 10 mm balls.

    Returns
    -------
    table : pandas.DataFrame
        One row a setup.
    summary : dict
        :func:`summarize`.
    """
    rows = []
    for i in range(setups):
        case = {**draw_setup(seed + i, releases), "exact": exact or rendered,
                "rendered": rendered}
        if rendered:
            case["ball"] = RENDERED_BALLS[i % len(RENDERED_BALLS)]
        rows.append(run_setup(case, order))
        if progress and (i + 1) % 10 == 0:
            print(f"{i + 1} setups: {json.dumps(summarize(pd.DataFrame(rows)))}", flush=True)
            if out is not None:  # the table so far, kept if the run is stopped
                out.mkdir(parents=True, exist_ok=True)
                pd.DataFrame(rows).to_csv(out / "combine_study.csv", index=False)
    df = pd.DataFrame(rows)
    s = summarize(df)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        df.to_csv(out / "combine_study.csv", index=False)
        (out / "combine_study.json").write_text(json.dumps(s, indent=2) + "\n")
        if s["combined"]:
            plot(df, out / "combine_study.png")
    return df, s


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.studies.combine", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--setups", type=int, default=200)
    p.add_argument("--releases", type=int, default=5)
    p.add_argument("--seed", type=int, default=0, help="first setup's seed")
    p.add_argument("--second-order", action="store_true",
                   help="the releases' budgets with their second-order row (--second-order)")
    p.add_argument("--exact-setup", action="store_true",
                   help="the lab knows the as-built setup exactly (no shared part)")
    p.add_argument("--rendered", action="store_true",
                   help="each release rendered by synth and measured by rollfric.measure "
                        "(the renderer's exact setup: the independent part alone)")
    p.add_argument("--out", required=True, help="output folder")
    args = p.parse_args(argv)
    if args.releases < 2:
        p.error("--releases must be at least 2")
    _, s = run_study(args.setups, args.releases, Path(args.out), args.seed, progress=True,
                     order=2 if args.second_order else 1, exact=args.exact_setup,
                     rendered=args.rendered)
    print(json.dumps(s, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
