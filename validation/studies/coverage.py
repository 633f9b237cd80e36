"""Is the uncertainty budget honest? Coverage of the truth by u_mu and U_mu, without rendering.

Each case draws a motion (mu, theta0, ball, record length), a locator noise (white or AR(1)
correlated, 0.01-0.1 px) and the as-built setup from the lab's tolerances around its nominal
values (trough radius, ball diameter, trough centre, frame rate, pixel size; the setup's
``K_u``). The ball's path is the reference ODE on the as-built trough, sampled at the as-built
frame rate, projected to pixels with the as-built scale and centre; the measurement sees only
the nominal setup (with its ``_u`` keys) and runs the real fit and budget
(:func:`rollfric.uncertainty.budget.budget`) on those centres. z = (mu - mu_true) / u_mu; an honest
budget has |z| <= 1 in about 68 % and |z| <= 2 (truth within U_mu, k = 2) in about 95 % of
the cases. The oracle mode (the exact as-built setup given, only the statistical part) is
checked the same way, with the corrected and the ordinary standard error.

``python -m validation.studies.coverage --cases 200 --out DIR`` writes DIR/coverage.csv (one row a
case), DIR/coverage.json (the fractions) and DIR/coverage.png (z histograms).

The rendered study is the shipped sweep ``coverage`` (validation/sweeps/coverage.toml: blind
cases with ``lab.draw`` and ``measure.budget``); ``python -m validation.studies.coverage
--from-sweep
OUT`` reads its OUT/results.parquet and writes OUT/coverage.json and OUT/coverage.png the same
way (its oracle columns come from an oracle run of the sweep, ``measure.oracle = true``, if
given with ``--oracle-sweep``). ``--from-sweep OUT1 OUT2 --out DIR`` reports several studies
together (the independent second study ``coverage_b`` beside the first), split by study. Every
summary gives the miss counts outside u and U with their binomial tail probabilities.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rollfric.fit import eom
from rollfric.fit.estimate import fit_mu
from rollfric.geometry.trough import ContourError, find_cylinder_center
from rollfric.output.atomic import replacing
from rollfric.setup.model import THESIS_BALLS, Setup
from rollfric.uncertainty.budget import budget
from rollfric.uncertainty.measured import Measurement
from synth.drawn.frames import disk_coverage

# the lab's nominal setup and its standard uncertainties (lab units), issue 14's lab
NOMINAL = {"radius_mm": 85.3, "center_px": (640.0, 380.0), "fps": 1000.0,
           "pixel_size_mm": 0.1343}
TOLERANCE = {"radius_mm": 0.5, "diameter_mm": 0.005, "center_px": 2.0, "fps": 0.05,
             "pixel_size_mm": 0.0003}


def drawn_as_built(rng, d_mm: float) -> dict:
    """The trough, ball and camera as built: the nominal values (NOMINAL, the ball's
    ``d_mm``) each off by a draw of its TOLERANCE, in this order (the studies' seeds stand)."""
    tol = TOLERANCE
    return {
        "true_radius_mm": NOMINAL["radius_mm"] + rng.normal(0.0, tol["radius_mm"]),
        "true_diameter_mm": d_mm + rng.normal(0.0, tol["diameter_mm"]),
        "true_center_px": tuple(float(c + rng.normal(0.0, tol["center_px"]))
                                for c in NOMINAL["center_px"]),
        "true_fps": NOMINAL["fps"] + rng.normal(0.0, tol["fps"]),
        "true_pixel_size_mm": NOMINAL["pixel_size_mm"] + rng.normal(0.0, tol["pixel_size_mm"]),
    }


def draw_case(seed: int) -> dict:
    """One case's motion, noise and as-built setup, drawn with ``seed``."""
    rng = np.random.default_rng(seed)
    ball = str(rng.choice(list(THESIS_BALLS)))
    d_mm, mass = THESIS_BALLS[ball][0] * 1e3, THESIS_BALLS[ball][1]
    return {
        "seed": seed, "ball": ball, "mass_kg": mass,
        "mu": float(math.exp(rng.uniform(math.log(0.004), math.log(0.02)))),
        "theta0_deg": float(rng.uniform(6.0, 30.0)),
        "seconds": float(rng.choice([1.0, 2.0, 4.0])),
        "noise_px": float(math.exp(rng.uniform(math.log(0.01), math.log(0.1)))),
        "ar": float(rng.choice([0.0, 0.5, 0.9])),
        "diameter_mm": d_mm,
        **drawn_as_built(rng, d_mm),
        # the background the contour mode finds the centre in (drawn after the rest, so the
        # cases above are those of the lab mode)
        "contour_gradient": (float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-0.5, 0.5))),
        "contour_blur_px": float(rng.uniform(0.0, 2.0)),
        "contour_noise_dn": float(rng.uniform(1.0, 6.0)),
    }


def drawn_centres(case: dict, true: Setup):
    """Frames and located centres (px) of the case: the reference ODE on the as-built trough,
    sampled at the as-built rate, plus AR(1) locator noise of rms ``noise_px``."""
    n = int(case["seconds"] * NOMINAL["fps"])
    frames = np.arange(n, dtype=float)
    th, _, _ = eom.solve_reference(math.radians(case["theta0_deg"]), 0.0, case["mu"],
                                   frames / true.fps, track_radius=true.track_radius)
    L_px = true.track_radius / true.pixel_size
    e = locator_noise(case, n)
    xc, yc = true.center_px
    return frames, xc + L_px * np.sin(th) + e[0], yc + L_px * np.cos(th) + e[1]


def locator_noise(case: dict, n: int) -> np.ndarray:
    """(2, n) AR(1) locator noise (px, x and y) of rms ``noise_px`` and lag-1 correlation
    ``ar``, drawn with the case's seed."""
    rng = np.random.default_rng(10_000 + case["seed"])
    w = rng.normal(0.0, case["noise_px"] * math.sqrt(1 - case["ar"] ** 2), (2, n))
    e = np.empty_like(w)
    e[:, 0] = rng.normal(0.0, case["noise_px"], 2)
    for i in range(1, n):
        e[:, i] = case["ar"] * e[:, i - 1] + w[:, i]
    return e


FRAME = (1280, 1024)  # the thesis camera's frame (px): the contour background's size


def contour_background(case: dict, true: Setup) -> np.ndarray:
    """The lab's background image of the case (8 bit): the backdrop inside the as-built
    trough's contour circle (its centre and radius in px), the trough's face in a 70 px ring
    around it, drawn with exact area coverage in linear light; a lighting gradient, a blur
    and a sensor noise drawn with the case's seed (``contour_*`` keys of the case)."""
    w, h = FRAME
    xc, yc = true.center_px
    radius = true.cylinder_radius / true.pixel_size
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    gx, gy = case["contour_gradient"]
    rel = (xx - w / 2) / 1000.0 * gx + (yy - h / 2) / 1000.0 * gy
    c1 = disk_coverage(h, w, xc, yc, radius)
    c2 = disk_coverage(h, w, xc, yc, radius + 70.0)
    img = c1 * 0.7 * (1 + rel) + (c2 - c1) * 0.25 * (1 - rel) + (1 - c2) * 0.5
    if case["contour_blur_px"] > 0:
        import cv2

        img = cv2.GaussianBlur(img, (0, 0), case["contour_blur_px"])
    rng = np.random.default_rng(20_000 + case["seed"])
    img = 255.0 * img + rng.normal(0.0, case["contour_noise_dn"], img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def drawn_setups(case: dict) -> tuple[Setup, Setup]:
    """(as built, the lab's nominal setup with its _u: :data:`TOLERANCE`) of a drawn case."""
    true = Setup(cylinder_radius=case["true_radius_mm"] * 1e-3,
                 ball_diameter=case["true_diameter_mm"] * 1e-3, ball_mass=case["mass_kg"],
                 fps=case["true_fps"], pixel_size=case["true_pixel_size_mm"] * 1e-3,
                 center_px=case["true_center_px"])
    tol = TOLERANCE
    lab = Setup(cylinder_radius=NOMINAL["radius_mm"] * 1e-3,
                ball_diameter=case["diameter_mm"] * 1e-3, ball_mass=case["mass_kg"],
                fps=NOMINAL["fps"], pixel_size=NOMINAL["pixel_size_mm"] * 1e-3,
                center_px=NOMINAL["center_px"],
                uncertainty=(("cylinder_radius", tol["radius_mm"] * 1e-3),
                             ("ball_diameter", tol["diameter_mm"] * 1e-3),
                             ("center_px", (tol["center_px"], tol["center_px"])),
                             ("fps", tol["fps"]), ("pixel_size", tol["pixel_size_mm"] * 1e-3)))
    return true, lab


def run_case(case: dict, *, fit_length: bool = False, oracle: bool = True,
             contour: bool = False) -> dict:
    """Measure one case blind (nominal setup with its _u) and, with ``oracle``, with the
    exact as-built setup. ``contour``: the lab gives no centre; rollfric finds it, with its
    uncertainty, from the case's background (:func:`contour_background`)."""
    true, lab = drawn_setups(case)
    frames, x, y = drawn_centres(case, true)
    out = {k: v for k, v in case.items() if not isinstance(v, tuple)}
    center, center_u = lab.center_px, None
    if contour:
        try:
            found = find_cylinder_center(contour_background(case, true),
                                         radius_px=lab.cylinder_radius / lab.pixel_size)
        except ContourError as exc:  # a lab would have to measure the centre: no case
            return {**out, "contour_error": str(exc)}
        center, center_u = found.center, found.center_u
        lab = lab.replace(center_px=None, uncertainty=tuple(
            (k, v) for k, v in lab.uncertainty if k != "center_px"))
        out.update({f"contour_err_{a}_px": found.center[i] - case["true_center_px"][i]
                    for i, a in enumerate("xy")})
        out.update({f"contour_u_{a}_px": found.center_u[i] for i, a in enumerate("xy")})
        out["contour_gradient_y"] = case["contour_gradient"][1]
    start = time.perf_counter()
    meas = Measurement(setup=lab, frames=frames, x=x, y=y, center=center, center_u=center_u)
    res = fit_mu(*meas.series(lab), lab)
    t_fit = time.perf_counter() - start
    b = budget(meas, res, fit_length=fit_length)
    mu_true = case["mu"]
    out.update(mu=b.mu, u_mu=b.u_mu, U_mu=b.U_mu, z=(b.mu - mu_true) / b.u_mu,
               u_stat=next(r.u_mu for r in b.rows if r.source == "statistical"),
               top_source=b.rows[0].source,
               fit_seconds=t_fit, budget_seconds=b.seconds, n_refits=b.n_refits)
    if fit_length:
        ln = b.length
        L_true = (case["true_radius_mm"] - 0.5 * case["true_diameter_mm"])
        out.update(L_fit_mm=ln["L_fit_mm"], u_L_fit_mm=ln["u_L_fit_mm"],
                   z_L=(ln["L_fit_mm"] - L_true) / ln["u_L_fit_mm"])
    if contour:
        # the exact as-built setup but the centre: the contour's own row against the truth
        exact = dataclasses.replace(true, center_px=None, uncertainty=())
        m_c = Measurement(setup=exact, frames=frames, x=x, y=y, center=center,
                          center_u=center_u)
        bc = budget(m_c, fit_mu(*m_c.series(exact), exact))
        out.update(z_contour=(bc.mu - mu_true) / bc.u_mu, u_contour_only=bc.u_mu)
    if not oracle:
        return out
    m_o = Measurement(setup=dataclasses.replace(true, uncertainty=()), frames=frames, x=x, y=y,
                      center=true.center_px)
    ro = fit_mu(*m_o.series(m_o.setup), m_o.setup)
    bo = budget(m_o, ro)
    out.update(mu_oracle=bo.mu, u_oracle=bo.u_mu, z_oracle=(bo.mu - mu_true) / bo.u_mu,
               z_oracle_ordinary=(ro.mu - mu_true) / ro.mu_stderr,
               inflation_oracle=bo.statistical["inflation"])
    return out


# the groups the summary splits by; offset_fitted: whether the record held the turning points
# to fit the angle offset (``--offset auto``), which selects on the as-built radius (a shorter
# period holds more turning points in the same record), so its groups' draws are not the
# stated distribution
GROUP_KEYS = ("render.noise", "render.lighting", "scenario.ball", "scenario.motion.mu",
              "offset_fitted", "study")
# the fraction of a normal z outside k = 1 and k = 2: what an honest budget's misses have
MISS_PROBABILITY = {1.0: math.erfc(1.0 / math.sqrt(2.0)), 2.0: math.erfc(2.0 / math.sqrt(2.0))}


def misses(z, prefix: str) -> dict:
    """The cases outside ``u`` (|z| > 1) and outside ``U`` (|z| > 2), with the binomial tail
    probabilities of that many misses for an honest budget (each case missing with the normal
    distribution's 31.7 % and 4.55 %): ``P(X >= misses)`` and ``P(X <= misses)``, X binomial
    over the finite z's. A tail of 5e-5 says that set of draws is improbable for an honest
    budget, or that the budget is not honest.

    Parameters
    ----------
    z : array_like
        (mu - truth) / u_mu of each case; NaN: left out.
    prefix : str
        The keys' prefix ("blind", "oracle").

    Returns
    -------
    dict
        ``{prefix}_misses_u``, ``{prefix}_misses_U``, their ``_expected`` counts and
        ``_p_at_least`` / ``_p_at_most`` tails.
    """
    from scipy.stats import binom

    z = np.asarray(z, dtype=float)
    z = z[np.isfinite(z)]
    out = {}
    for k, name in ((1.0, "u"), (2.0, "U")):
        m, p = int(np.sum(np.abs(z) > k)), MISS_PROBABILITY[k]
        out.update({f"{prefix}_misses_{name}": m,
                    f"{prefix}_misses_{name}_expected": float(p * z.size),
                    f"{prefix}_misses_{name}_p_at_least": float(binom.sf(m - 1, z.size, p)),
                    f"{prefix}_misses_{name}_p_at_most": float(binom.cdf(m, z.size, p))})
    return out


def summarize(df: pd.DataFrame) -> dict:
    """Coverage fractions of the blind budget and of the oracle's statistical error; of a
    sweep's first-order budget (``z_first_order``), of the draws' linear prediction
    (``z_linear``) and by group (:data:`GROUP_KEYS`) when the table has them."""
    def frac(z, k):
        z = np.asarray(z, dtype=float)
        z = z[np.isfinite(z)]
        return float(np.mean(np.abs(z) <= k)) if z.size else float("nan")

    if "contour_error" in df:  # cases whose contour was not found (reported, left out)
        failed = int(df["contour_error"].notna().sum())
        df = df[df["contour_error"].isna()]
    else:
        failed = 0
    def se(p, n):  # the binomial standard error of a fraction
        return float(math.sqrt(p * (1.0 - p) / n)) if n else float("nan")

    n = int(np.isfinite(df["z"].to_numpy(float)).sum())
    s = {"cases": len(df), "contour_not_found": failed,
         "blind_within_U": frac(df["z"], 2.0), "blind_within_u": frac(df["z"], 1.0),
         "blind_z_rms": float(np.sqrt(np.mean(df["z"] ** 2))),
         "blind_within_U_se": se(frac(df["z"], 2.0), n),
         "blind_within_u_se": se(frac(df["z"], 1.0), n),
         **misses(df["z"], "blind"),
         "median_U_rel": float(np.median(df["U_mu"] / df["mu"])),
         "median_budget_seconds": float(np.median(df["budget_seconds"])),
         "median_fit_seconds": float(np.median(df["fit_seconds"]))}
    if np.isfinite(df["z_oracle"].to_numpy(float)).any():  # an oracle run was given
        s.update(oracle_cases=int(np.isfinite(df["z_oracle"].to_numpy(float)).sum()),
                 oracle_within_2u_stat=frac(df["z_oracle"], 2.0),
                 oracle_within_u_stat=frac(df["z_oracle"], 1.0),
                 oracle_z_rms_stat=float(np.sqrt(np.nanmean(df["z_oracle"].to_numpy(float)
                                                            ** 2))),
                 **misses(df["z_oracle"], "oracle"),
                 oracle_ordinary_within_2se=frac(df["z_oracle_ordinary"], 2.0),
                 oracle_ordinary_within_se=frac(df["z_oracle_ordinary"], 1.0))
    if "z_oracle_budget" in df and np.isfinite(df["z_oracle_budget"].to_numpy(float)).any():
        zb = df["z_oracle_budget"]  # statistical + method rows (the sweep's oracle budget)
        nb = int(np.isfinite(zb.to_numpy(float)).sum())
        s.update(oracle_within_2u_budget=frac(zb, 2.0), oracle_within_u_budget=frac(zb, 1.0),
                 oracle_within_2u_budget_se=se(frac(zb, 2.0), nb),
                 oracle_within_u_budget_se=se(frac(zb, 1.0), nb),
                 oracle_z_rms_budget=float(np.sqrt(np.nanmean(zb.to_numpy(float) ** 2))),
                 **misses(zb, "oracle_budget"))
    if "z_setup" in df and "z_linear" in df:
        zs, zl = df["z_setup"].to_numpy(float), df["z_linear"].to_numpy(float)
        ok = np.isfinite(zs) & np.isfinite(zl)
        if ok.sum() > 2:
            d = zs[ok] - zl[ok]
            s.update(setup_part_rms=float(np.sqrt(np.mean(zs[ok] ** 2))),
                     setup_part_mean=float(np.mean(zs[ok])),
                     setup_vs_linear_corr=float(np.corrcoef(zs[ok], zl[ok])[0, 1]),
                     setup_minus_linear_mean=float(np.mean(d)),
                     setup_minus_linear_sd=float(np.std(d, ddof=1)),
                     rest_part_rms=float(np.sqrt(np.nanmean(df["z_rest"].to_numpy(float)
                                                            ** 2))))
    for ar, g in df.groupby("ar") if df["ar"].nunique() > 1 else ():
        s[f"oracle_within_2u_stat_ar{ar:g}"] = frac(g["z_oracle"], 2.0)
        s[f"oracle_ordinary_within_2se_ar{ar:g}"] = frac(g["z_oracle_ordinary"], 2.0)
    for col in ("z_first_order", "z_linear"):
        if col in df:
            s[f"{col}_within_2u"] = frac(df[col], 2.0)
            s[f"{col}_within_u"] = frac(df[col], 1.0)
            s[f"{col}_rms"] = float(np.sqrt(np.nanmean(df[col].to_numpy(float) ** 2)))
    for key in GROUP_KEYS:
        if key in df and df[key].nunique() > 1:
            for value, g in df.groupby(key):
                s[f"within_U[{key}={value}]"] = frac(g["z"], 2.0)
                s[f"within_u[{key}={value}]"] = frac(g["z"], 1.0)
                s[f"cases[{key}={value}]"] = len(g)
    if "z_contour" in df:
        s["contour_only_within_2u"] = frac(df["z_contour"], 2.0)
        s["contour_only_within_u"] = frac(df["z_contour"], 1.0)
        s["contour_only_z_rms"] = float(np.sqrt(np.mean(df["z_contour"] ** 2)))
    if "z_L" in df:
        s["L_within_2u"] = frac(df["z_L"], 2.0)
        s["L_within_u"] = frac(df["z_L"], 1.0)
    return s


def from_sweep(results: pd.DataFrame, oracle: pd.DataFrame | None = None,
               study: str | None = None) -> pd.DataFrame:
    """The coverage table (z, z_oracle, z_oracle_ordinary, mu, U_mu, ...) of a ``coverage``
    sweep's results (its ok cases). ``oracle``: the same sweep run with ``measure.oracle =
    true``, matched case by case on the swept parameters (its z_stat: the statistical part
    alone; its mu_stderr: the ordinary standard error); without it the oracle columns are NaN
    (a blind run's statistical part alone says nothing: its error is mostly the setup's).
    ``study``: its name in a ``study`` column (several studies reported together are split
    by it)."""
    ok = results[results["status"] == "ok"].reset_index(drop=True)
    df = pd.DataFrame({"case_id": ok["case_id"], "z": ok["z_budget"], "mu": ok["mu_recovered"],
                       "U_mu": ok["U_mu"], "ar": 0.0, "budget_seconds": ok["t_budget_s"],
                       "fit_seconds": ok["t_measure_s"] if "t_measure_s" in ok else np.nan})
    # the first-order budget's z and the draws' linear prediction, when the sweep has them
    for col, name in (("z_first_order", "z_first_order"), ("z_linear", "z_linear")):
        if col in ok:
            df[name] = ok[col].to_numpy(float)
    for key in GROUP_KEYS:  # the groups the summary splits by
        if key in ok:
            df[key] = ok[key].astype(str).to_numpy()
    if study is not None:
        df["study"] = study
    if oracle is None:
        df["z_oracle"] = df["z_oracle_ordinary"] = df["z_oracle_budget"] = np.nan
        return df
    # the swept parameters (dotted case keys) name a case in both runs
    keys = [c for c in ok.columns if "." in c and c in oracle.columns]
    o = oracle[oracle["status"] == "ok"]
    o = o.assign(**{k: o[k].astype(str) for k in keys})
    src = ok[keys].astype(str).merge(o, on=keys, how="left")
    df["z_oracle"] = src["z_stat"].to_numpy(float)
    # the oracle's whole budget: the statistical and the method (angle map) rows
    df["z_oracle_budget"] = src["z_budget"].to_numpy(float)
    df["z_oracle_ordinary"] = ((src["mu_recovered"] - src["mu_true"])
                               / src["mu_stderr"]).to_numpy(float)
    # the blind error split on the same recording: the setup's part (blind - oracle mu) and
    # the rest (oracle - truth), both in the blind u_mu; z_setup against z_linear (the
    # budget's first-order prediction of the setup's part) checks its sensitivities
    u = ok["u_mu"].to_numpy(float) if "u_mu" in ok else df["U_mu"].to_numpy(float) / 2.0
    mu_o = src["mu_recovered"].to_numpy(float)
    df["z_setup"] = (ok["mu_recovered"].to_numpy(float) - mu_o) / u
    df["z_rest"] = (mu_o - src["mu_true"].to_numpy(float)) / u
    return df


def plot(df: pd.DataFrame, path: Path) -> None:
    """Histograms of z (blind, full budget) and of the oracle's z (statistical part, and with
    the method row)."""
    from matplotlib.figure import Figure  # no pyplot: no backend, no global figure state

    cols = [("z", "blind: (mu - truth) / u_mu"),
            ("z_oracle", "oracle: / statistical u (corrected)"),
            ("z_oracle_budget", "oracle: / (statistical + method) u"),
            ("z_oracle_ordinary", "oracle: / ordinary standard error")]
    if "z_contour" in df:
        cols.insert(1, ("z_contour", "exact setup, contour centre:\n/ (statistical + centre) u"))
    if "z_first_order" in df:
        cols.insert(1, ("z_first_order", "blind: / first-order u_mu"))
    if "z_linear" in df:
        cols.insert(2, ("z_linear", "the drawn setup errors through\n"
                                    "the budget's linear model / u_mu"))
    cols = [c for c in cols if np.isfinite(df[c[0]].to_numpy(float)).any()]
    fig = Figure(figsize=(4.4 * len(cols), 3.8))
    axes = fig.subplots(1, len(cols), squeeze=False)[0]
    grid = np.linspace(-4, 4, 200)
    for ax, (col, title) in zip(axes, cols, strict=True):
        z = df[col].to_numpy(float)
        z = np.clip(z[np.isfinite(z)], -6, 6)
        ax.hist(z, bins=np.linspace(-6, 6, 49), density=True, color="tab:blue", alpha=0.7)
        ax.plot(grid, np.exp(-0.5 * grid**2) / math.sqrt(2 * math.pi), "k-", lw=1,
                label="N(0, 1)")
        inside = np.mean(np.abs(z) <= 2) * 100 if z.size else float("nan")
        ax.set_title(f"{title}\n|z| <= 2: {inside:.1f} %", fontsize=9)
        ax.set_xlabel("z (clipped to +-6)")
        ax.legend(fontsize=8)
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.studies.coverage", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", type=int, default=200)
    p.add_argument("--seed", type=int, default=0, help="first case seed")
    p.add_argument("--fit-length", action="store_true", help="blind fits also fit L")
    p.add_argument("--contour", action="store_true",
                   help="blind without center_px: the centre and its uncertainty from a drawn "
                        "background's contour (rollfric.geometry.trough)")
    p.add_argument("--out", help="output folder (track-level cases)")
    p.add_argument("--merge", nargs="+", metavar="DIR",
                   help="report the coverage.csv of these folders (runs of other --seed "
                        "ranges) together in --out")
    p.add_argument("--from-sweep", metavar="OUT", nargs="+",
                   help="report a coverage sweep's results; several: the studies together "
                        "(written to --out, split by study)")
    p.add_argument("--oracle-sweep", metavar="OUT", nargs="+",
                   help="the same sweep(s) run in oracle mode, one per --from-sweep, in order")
    args = p.parse_args(argv)
    if args.from_sweep:
        if args.oracle_sweep and len(args.oracle_sweep) != len(args.from_sweep):
            p.error("--oracle-sweep needs one folder per --from-sweep folder")
        if len(args.from_sweep) > 1 and not args.out:
            p.error("several --from-sweep folders are reported together into --out")
        frames = []
        for i, src in enumerate(args.from_sweep):
            oracle = (pd.read_parquet(Path(args.oracle_sweep[i]) / "results.parquet")
                      if args.oracle_sweep else None)
            frames.append(from_sweep(pd.read_parquet(Path(src) / "results.parquet"), oracle,
                                     study=Path(src).name))
        df = pd.concat(frames, ignore_index=True)
        out = Path(args.out) if args.out else Path(args.from_sweep[0])
        out.mkdir(parents=True, exist_ok=True)
        s = summarize(df)
        (out / "coverage.json").write_text(json.dumps(s, indent=2) + "\n")
        plot(df, out / "coverage.png")
        print(json.dumps(s, indent=2))
        return 0
    if not args.out:
        p.error("--out or --from-sweep is needed")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.merge:
        df = pd.concat([pd.read_csv(Path(d) / "coverage.csv") for d in args.merge],
                       ignore_index=True)
        return _write_study(df, out)
    rows = []
    for i in range(args.cases):
        rows.append(run_case(draw_case(args.seed + i), fit_length=args.fit_length,
                             contour=args.contour))
        if (i + 1) % 10 == 0:
            df = pd.DataFrame(rows)
            df.to_csv(out / "coverage.csv", index=False)
            print(f"{i + 1} cases: {json.dumps(summarize(df))}", flush=True)
    return _write_study(pd.DataFrame(rows), out)


def _write_study(df, out: Path) -> int:
    """Write a study's table, summary and figure into ``out``, print the summary; exit 0."""
    df.to_csv(out / "coverage.csv", index=False)
    s = summarize(df)
    (out / "coverage.json").write_text(json.dumps(s, indent=2) + "\n")
    plot(df, out / "coverage.png")
    print(json.dumps(s, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
