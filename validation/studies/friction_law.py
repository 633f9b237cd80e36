"""The friction-law test (:mod:`rollfric.uncertainty.law`) calibrated by simulation, at track level.

Each case draws a motion of one of the thesis's three balls in room air: mu(theta') = mu0 + mu1
|theta'| (mu1 = 0: Coulomb), a release angle, a record length, a locator noise (white or AR(1),
0.01-0.1 px) and the air as it is (density, viscosity and the drag law's wall factor drawn
from their stated distributions, :mod:`rollfric.fit.air`). The ball's path is the equation of
motion with that air (:func:`rollfric.fit.eom.solve` at a step five times finer than the
fitter's), sampled at 1000 Hz, projected to pixels about the trough's centre, the noise added;
the measurement sees the nominal room air with its u and runs the real Coulomb fit
(:func:`rollfric.fit.estimate.fit_mu`) and the test (:func:`rollfric.uncertainty.law.friction_law`).

Parts (``--part``, each a few minutes of one core):

- ``level``: Coulomb + drag cases, the wall factor drawn normal with the law's u (the test's
  assumption) and, in a set of its own, rectangular over the law's range 1 .. 2 (its stated
  distribution): the share of cases the test calls "speed" (the level, 0.05 by design).
- ``power``: the rejection rate against mu1 for each ball (4 s from 20 deg, 0.05 px white,
  mu0 0.008) and, for the 10 mm ball at one mu1, against noise, release angle and record length;
  beside each, the mu1 the recording could detect (80 % power by the test's own u(mu1)) and
  the mu1 Cross's law would give (the whole resistance proportional to speed: mu0 / mean
  |theta'|).
- ``thesis``: each ball's thesis recording (its mu and release angle, 4 s, the locator's noise
  of the blind default case) under Coulomb's law, Cross's (mu0 = 0, mu1 = mu / mean |theta'|)
  and a tenth of Cross's: which ball could have told the two apart.
- ``coverage``: speed-law cases (mu1 drawn 1e-5 .. 1e-3 s/rad): mu0 and mu1 within their
  u and U = 2u.

``python -m validation.studies.friction_law --out DIR [--part level|power|coverage|thesis]
[--scale 1.0]`` writes DIR/friction_law_<part>.csv and DIR/friction_law.json (every part found
in DIR summarised; docs/data/friction_law.json is that file).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from rollfric.fit import air, eom
from rollfric.fit.estimate import fit_mu
from rollfric.setup.model import THESIS_BALLS, thesis_setup
from rollfric.uncertainty.law import LEVEL, friction_law
from rollfric.uncertainty.measured import Measurement

FPS = 1000.0
CENTER = (640.0, 380.0)
ROOM_AIR_U = (("air_density", air.ROOM_AIR_DENSITY_U), ("air_viscosity", air.AIR_VISCOSITY_U))
BALLS = tuple(THESIS_BALLS)
MU0_POWER = 0.008
MU1_GRID = (0.0, 3e-6, 1e-5, 3e-5, 1e-4, 3e-4)
NOISE_GRID = (0.01, 0.03, 0.1, 0.3)
ANGLE_GRID = (5.0, 10.0, 20.0, 30.0)
SECONDS_GRID = (1.0, 2.0, 4.0, 8.0)
MU1_SWEEP = 3e-5  # the 10 mm ball's mu1 of the noise, angle and length curves


def lab_setup(ball: str):
    """The lab's setup: the thesis's trough and camera, its ``ball``, room air with its u."""
    return thesis_setup(ball, center_px=CENTER, air_density=air.ROOM_AIR_DENSITY,
                        uncertainty=ROOM_AIR_U)


def true_air(rng, wall: str) -> dict:
    """The air as it is: density, viscosity normal with their u, the wall factor ``wall``
    ("normal": with the law's u; "rectangular": over the law's range 1 .. 2)."""
    w = (rng.normal(air.WALL_FACTOR, air.WALL_FACTOR_U) if wall == "normal"
         else rng.uniform(1.0, 2.0))
    return {"air_density": float(rng.normal(air.ROOM_AIR_DENSITY, air.ROOM_AIR_DENSITY_U)),
            "air_viscosity": float(rng.normal(air.AIR_VISCOSITY, air.AIR_VISCOSITY_U)),
            "air_wall_factor": float(max(w, 0.2))}


def draw_case(seed: int, *, mu1: float | None = 0.0, wall: str = "normal", **fixed) -> dict:
    """One case drawn with ``seed``: ball, mu0, release angle, length, noise, AR(1), the air;
    ``mu1`` None draws it log-uniform over 1e-5 .. 1e-3 s/rad; ``fixed`` overrides draws."""
    rng = np.random.default_rng(seed)
    case = {
        "seed": seed, "ball": str(rng.choice(BALLS)),
        "mu0": float(math.exp(rng.uniform(math.log(0.004), math.log(0.02)))),
        "theta0_deg": float(rng.uniform(6.0, 30.0)),
        "seconds": float(rng.choice([1.0, 2.0, 4.0])),
        "noise_px": float(math.exp(rng.uniform(math.log(0.01), math.log(0.1)))),
        "ar": float(rng.choice([0.0, 0.5, 0.9])),
        "mu1": float(math.exp(rng.uniform(math.log(1e-5), math.log(1e-3)))) if mu1 is None
        else float(mu1),
        "wall": wall, **true_air(rng, wall)}
    case.update(fixed)
    return case


def centres(case: dict, lab):
    """Frames and located centres (px): the motion with the true air, plus AR(1) noise."""
    n = int(round(case["seconds"] * FPS))
    t = np.arange(n) / FPS
    true = lab.replace(air_density=case["air_density"], air_viscosity=case["air_viscosity"],
                       air_wall_factor=case["air_wall_factor"])
    th, om, _ = eom.solve(math.radians(case["theta0_deg"]), 0.0, case["mu0"], t,
                          track_radius=lab.track_radius, mu1=case["mu1"],
                          steps_per_radian=1000.0, air=air.coefficients_of(true))
    L_px = lab.track_radius / lab.pixel_size
    rng = np.random.default_rng(10_000 + case["seed"])
    ar = case["ar"]
    w = rng.normal(0.0, case["noise_px"] * math.sqrt(1 - ar**2), (2, n))
    e = np.empty_like(w)
    e[:, 0] = rng.normal(0.0, case["noise_px"], 2)
    for i in range(1, n):
        e[:, i] = ar * e[:, i - 1] + w[:, i]
    moving = om != 0
    mean_speed = float(np.mean(np.abs(om[moving]))) if moving.any() else math.nan
    return (np.arange(n, dtype=float), CENTER[0] + L_px * np.sin(th) + e[0],
            CENTER[1] + L_px * np.cos(th) + e[1], mean_speed)


def run_case(case: dict) -> dict:
    """The Coulomb fit and the law test of one case: a row of the study."""
    lab = lab_setup(case["ball"])
    frames, x, y, mean_speed = centres(case, lab)
    meas = Measurement(setup=lab, frames=frames, x=x, y=y, center=CENTER)
    start = time.perf_counter()
    row = dict(case)
    try:
        t, th = meas.series(lab)
        fit = fit_mu(t, th, lab, checks=False)
        law = friction_law(meas, fit)
    except Exception as exc:  # a case the fit refuses (a record too short) is counted
        return {**row, "error": f"{type(exc).__name__}: {exc}"}
    row.update(seconds_cpu=time.perf_counter() - start, mu_coulomb=fit.mu,
               selected=law.selected, p_value=law.p_value, z=law.z, mu0_fit=law.mu0,
               mu0_u=law.mu0_u, mu1_fit=law.mu1, mu1_u=law.mu1_u,
               mu1_u_statistical=law.mu1_u_statistical, mu1_u_inputs=law.mu1_u_inputs,
               mu1_detectable=law.mu1_detectable, mean_speed=mean_speed,
               mu1_cross=case["mu0"] / mean_speed if mean_speed > 0 else math.nan,
               rejected=law.selected == "speed" if law.selected else None)
    if law.selected:
        row.update(z0=(law.mu0 - case["mu0"]) / law.mu0_u,
                   z1=(law.mu1 - case["mu1"]) / law.mu1_u)
    return row


# -- the parts -------------------------------------------------------------------------------

def level_cases(scale: float) -> list:
    n = int(round(400 * scale))
    n_rect = int(round(100 * scale))
    return ([draw_case(s) for s in range(n)]
            + [draw_case(100_000 + s, wall="rectangular") for s in range(n_rect)])


def power_cases(scale: float) -> list:
    n = max(int(round(20 * scale)), 2)
    base = {"mu0": MU0_POWER, "theta0_deg": 20.0, "seconds": 4.0, "noise_px": 0.05, "ar": 0.0}
    cases = []
    seed = 200_000
    for ball in BALLS:
        for mu1 in MU1_GRID:
            for _ in range(n):
                cases.append(draw_case(seed, mu1=mu1, **base, ball=ball, curve="mu1"))
                seed += 1
    for key, grid in (("noise_px", NOISE_GRID), ("theta0_deg", ANGLE_GRID),
                      ("seconds", SECONDS_GRID)):
        for v in grid:
            for _ in range(n):
                cases.append(draw_case(seed, mu1=MU1_SWEEP, **dict(base, **{key: v}),
                                       ball="10mm", curve=key))
                seed += 1
    return cases


# the thesis's recordings (its mu, release angle; 4 s at 1000 Hz of the 10 and 12.69 mm balls,
# as validation.studies.thesis_error assumes; the 1.58 mm ball's first paper released it at
# 8.49 deg), the locator's noise of the blind default case (validation.track_level)
THESIS_RECORDINGS = {"1.58mm": (0.0164, 8.49), "10mm": (0.0079, 20.0),
                     "12.69mm": (0.0065, 20.0)}
THESIS_NOISE_PX = 0.017
# the laws of the thesis part: Coulomb, Cross's (all of the resistance proportional to speed,
# mu0 = 0) and a tenth of Cross's on a Coulomb part (mu0 = 0.9 mu)
THESIS_LAWS = {"coulomb": (1.0, 0.0), "cross": (0.0, 1.0), "cross_tenth": (0.9, 0.1)}


def cross_mu1(ball: str, mu: float, theta0_deg: float, seconds: float = 4.0) -> float:
    """The mu1 of Cross's law with the mean resistance of ``mu``: mu / mean |theta'| of the
    Coulomb motion (in room air) while the ball moves."""
    lab = lab_setup(ball)
    t = np.arange(int(seconds * FPS)) / FPS
    _, om, _ = eom.solve(math.radians(theta0_deg), 0.0, mu, t, track_radius=lab.track_radius,
                         air=air.coefficients_of(lab))
    return mu / float(np.mean(np.abs(om[om != 0])))


def thesis_cases(scale: float) -> list:
    n = max(int(round(20 * scale)), 2)
    cases, seed = [], 400_000
    for ball, (mu, theta0) in THESIS_RECORDINGS.items():
        mu1c = cross_mu1(ball, mu, theta0)
        for law, (f0, f1) in THESIS_LAWS.items():
            for _ in range(n):
                cases.append(draw_case(seed, mu1=f1 * mu1c, ball=ball, mu0=f0 * mu,
                                       theta0_deg=theta0, seconds=4.0,
                                       noise_px=THESIS_NOISE_PX, ar=0.0, law=law,
                                       mu_thesis=mu, mu1_cross=mu1c))
                seed += 1
    return cases


def coverage_cases(scale: float) -> list:
    return [draw_case(300_000 + s, mu1=None) for s in range(int(round(200 * scale)))]


RENDERED_BALLS = ("10mm", "1.58mm")  # the rendered study's small frames (0.25 mm/px)


def rendered_cases(scale: float) -> list:
    """Coulomb + room air rendered by synth (sim's reference engine with the fitter's drag
    law, :mod:`validation.studies.rendered_faults`' small frames, 2 s): the level on
    recordings that went through a renderer, a sensor and the locator."""
    from validation.studies.rendered_faults import Case

    n = int(round(40 * scale))
    cases = []
    for s in range(n):
        rng = np.random.default_rng([500_000, s])
        cases.append({"rendered": Case(
            family="law", seed=500_000 + s, ball=RENDERED_BALLS[s % len(RENDERED_BALLS)],
            mu=float(math.exp(rng.uniform(math.log(0.004), math.log(0.012)))),
            theta0=float(rng.uniform(0.15, 0.35)), seconds=2.0,
            air_density=air.ROOM_AIR_DENSITY), "mu0": None, "mu1": 0.0})
    return cases


def run_rendered(case: dict) -> dict:
    """``rollfric.measure`` of a rendered recording and the law test of its fit."""
    from rollfric.measurement import measure
    from rollfric.uncertainty.measured import measurement_from_track
    from validation.faults.recordings import ArraySource
    from validation.studies.rendered_faults import rendered

    c = case["rendered"]
    row = {"seed": c.seed, "ball": c.ball, "mu0": c.mu, "mu1": 0.0, "theta0_deg":
           math.degrees(c.theta0), "seconds": c.seconds}
    start = time.perf_counter()
    with rendered(c) as base:
        try:
            df, info, fit = measure(ArraySource(base.frames), base.setup, base.background)
            law = friction_law(measurement_from_track(df, info), fit)
        except Exception as exc:  # a recording measure refuses is counted
            return {**row, "error": f"{type(exc).__name__}: {exc}"}
    row.update(seconds_cpu=time.perf_counter() - start, mu_coulomb=fit.mu,
               selected=law.selected, p_value=law.p_value, z=law.z, mu1_fit=law.mu1,
               mu1_u=law.mu1_u, rejected=law.selected == "speed" if law.selected else None)
    return row


def summarize_rendered(df: pd.DataFrame) -> dict:
    ok = df[df["selected"].notna()] if "selected" in df else df.iloc[:0]
    return {"cases": int(len(df)), "tested": int(len(ok)),
            "rejected": rate(ok["selected"] == "speed"),
            "by_ball": {b: rate(g["selected"] == "speed") for b, g in ok.groupby("ball")},
            "what": "Coulomb + room air (the fitter's drag law) rendered by synth, 2 s at "
                    "1000 Hz, 0.25 mm/px; rollfric.measure, then the test"}


PARTS = {"level": level_cases, "power": power_cases, "coverage": coverage_cases,
         "thesis": thesis_cases, "rendered": rendered_cases}


# -- the summary -----------------------------------------------------------------------------

def rate(x) -> dict:
    """A share of booleans with its binomial standard error and count."""
    x = np.asarray(x, dtype=bool)
    n = int(x.size)
    p = float(x.mean()) if n else math.nan
    return {"rate": p, "se": math.sqrt(p * (1 - p) / n) if n else math.nan, "n": n,
            "k": int(x.sum())}


def summarize_level(df: pd.DataFrame) -> dict:
    ok = df[df["selected"].notna()] if "selected" in df else df.iloc[:0]
    out = {"level_design": LEVEL, "not_tested": int(len(df) - len(ok))}
    for wall, g in ok.groupby("wall"):
        out[f"wall_{wall}"] = {"rejected": rate(g["selected"] == "speed"),
                               "by_ball": {b: rate(h["selected"] == "speed")
                                           for b, h in g.groupby("ball")},
                               "by_ar": {str(a): rate(h["selected"] == "speed")
                                         for a, h in g.groupby("ar")},
                               "by_seconds": {str(s): rate(h["selected"] == "speed")
                                              for s, h in g.groupby("seconds")},
                               # under the null the p-values are uniform: their KS test
                               "p_uniform_ks": float(stats.kstest(g["p_value"], "uniform")
                                                     .pvalue),
                               "z_mean": float(g["z"].mean()), "z_sd": float(g["z"].std())}
    return out


def summarize_power(df: pd.DataFrame) -> dict:
    ok = df[df["selected"].notna()]
    out = {"mu1_sweep": MU1_SWEEP, "mu0": MU0_POWER, "curves": {}}
    g = ok[ok["curve"] == "mu1"]
    out["curves"]["mu1"] = {
        b: [{"mu1": float(m), **rate(h["selected"] == "speed"),
             "mu1_detectable_median": float(h["mu1_detectable"].median()),
             "mu1_u_median": float(h["mu1_u"].median()),
             "mu1_cross_median": float(h["mu1_cross"].median())}
            for m, h in gb.groupby("mu1")] for b, gb in g.groupby("ball")}
    for key in ("noise_px", "theta0_deg", "seconds"):
        g = ok[ok["curve"] == key]
        out["curves"][key] = [{key: float(v), **rate(h["selected"] == "speed"),
                               "mu1_detectable_median": float(h["mu1_detectable"].median())}
                              for v, h in g.groupby(key)]
    return out


def summarize_coverage(df: pd.DataFrame) -> dict:
    ok = df[df["selected"].notna()]
    return {"n": int(len(ok)), "not_tested": int(len(df) - len(ok)),
            "mu0_within_u": rate(ok["z0"].abs() <= 1), "mu0_within_U": rate(ok["z0"].abs() <= 2),
            "mu1_within_u": rate(ok["z1"].abs() <= 1), "mu1_within_U": rate(ok["z1"].abs() <= 2),
            "selected_speed": rate(ok["selected"] == "speed"),
            "by_ball": {b: {"mu0_within_U": rate(h["z0"].abs() <= 2),
                            "mu1_within_U": rate(h["z1"].abs() <= 2)}
                        for b, h in ok.groupby("ball")}}


def summarize_thesis(df: pd.DataFrame) -> dict:
    ok = df[df["selected"].notna()]
    out = {"noise_px": THESIS_NOISE_PX, "seconds": 4.0, "balls": {}}
    for ball, g in ok.groupby("ball"):
        c = g[g["law"] == "coulomb"]
        out["balls"][ball] = {
            "mu": float(g["mu_thesis"].iloc[0]), "theta0_deg": float(g["theta0_deg"].iloc[0]),
            "mu1_cross": float(g["mu1_cross"].iloc[0]),
            "mu1_detectable": float(c["mu1_detectable"].median()),
            "mu1_u": float(c["mu1_u"].median()),
            "mu1_u_statistical": float(c["mu1_u_statistical"].median()),
            "mu1_u_inputs": float(c["mu1_u_inputs"].median()),
            "rejected": {law: rate(h["selected"] == "speed") for law, h in g.groupby("law")}}
    return out


SUMMARIES = {"level": summarize_level, "power": summarize_power,
             "coverage": summarize_coverage, "thesis": summarize_thesis,
             "rendered": summarize_rendered}


def summarize(out: Path) -> dict:
    """Every part's csv found in ``out``, summarised."""
    s = {"study": "validation.studies.friction_law", "test_level": LEVEL}
    for part, fn in SUMMARIES.items():
        path = out / f"friction_law_{part}.csv"
        if path.exists():
            df = pd.read_csv(path)
            s[part] = fn(df)
            s[part]["cpu_seconds_per_case"] = float(df["seconds_cpu"].median()) \
                if "seconds_cpu" in df else None
            if "error" in df:
                s[part]["errors"] = int(df["error"].notna().sum())
    return s


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.studies.friction_law",
                                description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--part", choices=list(PARTS), action="append",
                   help="the part(s) to run (default: all)")
    p.add_argument("--scale", type=float, default=1.0,
                   help="the number of cases, times the default's (400 + 100 level, 20 a point "
                        "of a power curve, 200 coverage)")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for part in args.part or list(PARTS):
        cases = PARTS[part](args.scale)
        rows = []
        for i, case in enumerate(cases):
            rows.append(run_rendered(case) if "rendered" in case else run_case(case))
            if (i + 1) % 50 == 0 or i + 1 == len(cases):
                pd.DataFrame(rows).to_csv(out / f"friction_law_{part}.csv", index=False)
                print(f"{part}: {i + 1} of {len(cases)} cases", flush=True)
    s = summarize(out)
    (out / "friction_law.json").write_text(json.dumps(s, indent=2) + "\n")
    print(json.dumps(s, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
