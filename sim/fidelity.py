"""Engine fidelity: fit mu back from each engine's ground-truth theta(t) with the project's own
fitter (rollfric.fit.estimate.fit_mu) and compare with the configured mu.

    python -m sim.fidelity --out DIR      # writes DIR/sim_fidelity.csv and .md

Grid: the thesis's three balls x mu in {0.0065, 0.0079, 0.0164} x theta0 in {10, 20, 35} deg,
4 s at 1000 Hz, released at rest. Accurate (tangent) surfaces and the reference run the whole
grid; the naive faceted surfaces (mesh, heightfield) run the mu = 0.0079 subset by default
(``naive="all"`` for the whole grid).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

import sim
from rollfric.fit.estimate import fit_mu
from rollfric.output.atomic import write_text
from sim.engines import ENGINES

BALLS = ("1.58mm", "10mm", "12.69mm")
MUS = (0.0065, 0.0079, 0.0164)
THETA0_DEG = (10.0, 20.0, 35.0)
ACCURATE = (("reference", "tangent"), ("mujoco", "tangent"), ("pybullet", "tangent"))
NAIVE = (("mujoco", "mesh"), ("mujoco", "heightfield"), ("pybullet", "mesh"),
         ("pybullet", "heightfield"))
NAIVE_SUBSET_MUS = (0.0079,)


def _cases(balls, mus, theta0s):
    for ball in balls:
        for mu in mus:
            for th in theta0s:
                yield ball, mu, th


def fidelity_table(engines=tuple(ENGINES), *, balls=BALLS, mus=MUS,
                   theta0_deg=THETA0_DEG, naive: str = "subset", duration: float = 4.0,
                   fps: float = 1000.0, engine_options: dict | None = None,
                   progress: bool = False):
    """Configured vs recovered mu per engine, surface and case (a pandas DataFrame).

    ``naive``: "subset" (naive surfaces on the mu = 0.0079 cases only), "all" or "none".
    ``engine_options``: {engine: {option: value}} overrides.
    Columns: engine, surface, ball, ball_diameter_mm, mu, theta0_deg, mu_fit, mu_stderr,
    rel_error (mu_fit / mu - 1), max_angle_error_deg (vs the reference trajectory),
    rms_residual_deg (fit), sim_wall_s, realtime_factor (simulated s per wall s).
    """
    import pandas as pd
    from tqdm import tqdm

    if naive not in ("subset", "all", "none"):
        raise sim.ScenarioError(f"naive must be subset, all or none, got {naive!r}")
    unknown = set(engines) - set(sim.ENGINES)
    if unknown:
        raise sim.ScenarioError(f"unknown engine(s) {sorted(unknown)}")
    engine_options = engine_options or {}
    jobs = []
    for engine, surface in ACCURATE:
        if engine in engines:
            jobs += [(engine, surface, c) for c in _cases(balls, mus, theta0_deg)]
    if naive != "none":
        naive_mus = mus if naive == "all" else tuple(m for m in mus if m in NAIVE_SUBSET_MUS)
        for engine, surface in NAIVE:
            if engine in engines:
                jobs += [(engine, surface, c) for c in _cases(balls, naive_mus, theta0_deg)]
    references: dict = {}
    rows = []
    for engine, surface, (ball, mu, th) in tqdm(jobs, disable=not progress, desc="fidelity",
                                                unit="run"):
        base = sim.Scenario.thesis(ball, mu=mu, theta0=math.radians(th), duration=duration,
                                   fps=fps)
        key = (ball, mu, th)
        if key not in references:
            references[key] = sim.simulate(base)
        ref = references[key]
        sc = base.replace(engine=engine, surface=surface,
                          engine_options=dict(engine_options.get(engine, {})))
        traj = ref if engine == "reference" else sim.simulate(sc)
        fit = fit_mu(traj.t, traj.theta, sc.setup())
        wall = float(traj.meta["wall_time_s"])
        rows.append({
            "engine": engine, "surface": surface, "ball": ball,
            "ball_diameter_mm": sc.ball_diameter * 1e3, "mu": mu, "theta0_deg": th,
            "mu_fit": fit.mu, "mu_stderr": fit.mu_stderr, "rel_error": fit.mu / mu - 1.0,
            "max_angle_error_deg": math.degrees(float(np.max(np.abs(traj.theta - ref.theta)))),
            "rms_residual_deg": math.degrees(fit.rms_residual),
            "sim_wall_s": wall, "realtime_factor": duration / wall if wall > 0 else math.inf,
        })
    return pd.DataFrame(rows)


def summarize(table):
    """One row per engine and surface: cases, rel. error range, speed."""
    g = table.groupby(["engine", "surface"], sort=False)
    out = g.agg(cases=("rel_error", "size"),
                rel_error_min=("rel_error", "min"), rel_error_max=("rel_error", "max"),
                abs_rel_error_max=("rel_error", lambda s: float(np.max(np.abs(s)))),
                max_angle_error_deg=("max_angle_error_deg", "max"),
                sim_wall_s_median=("sim_wall_s", "median"),
                sim_wall_s_max=("sim_wall_s", "max"))
    return out.reset_index()


def to_markdown(table, duration: float = 4.0) -> str:
    def pct(v):
        return f"{100 * v:+.4f} %"

    lines = ["| engine | surface | cases | mu_fit/mu - 1 (min .. max) | max abs | "
             "max angle err (deg) | wall for "
             f"{duration:g} s (median / max) |", "|---|---|---|---|---|---|---|"]
    for _, r in summarize(table).iterrows():
        lines.append(f"| {r.engine} | {r.surface} | {r.cases} | {pct(r.rel_error_min)} .. "
                     f"{pct(r.rel_error_max)} | {100 * r.abs_rel_error_max:.4f} % | "
                     f"{r.max_angle_error_deg:.3f} | {r.sim_wall_s_median:.2f} s / "
                     f"{r.sim_wall_s_max:.2f} s |")
    lines += ["", "Per case:", "",
              "| engine | surface | ball | mu | theta0 (deg) | mu_fit | mu_fit/mu - 1 | "
              "max angle err (deg) | wall (s) |", "|---|---|---|---|---|---|---|---|---|"]
    for _, r in table.iterrows():
        lines.append(f"| {r.engine} | {r.surface} | {r.ball} | {r.mu:g} | {r.theta0_deg:g} | "
                     f"{r.mu_fit:.6f} | {pct(r.rel_error)} | {r.max_angle_error_deg:.4f} | "
                     f"{r.sim_wall_s:.2f} |")
    return "\n".join(lines) + "\n"


def write_report(table, out_dir, duration: float = 4.0) -> tuple[Path, Path]:
    out_dir = Path(out_dir)
    return (write_text(out_dir / "sim_fidelity.csv",
                       table.to_csv(index=False, float_format="%.10g")),
            write_text(out_dir / "sim_fidelity.md", to_markdown(table, duration)))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m sim.fidelity",
        description="Fit mu back from each engine's ground-truth theta(t) "
                    "(rollfric.fit.estimate) and "
                    "compare with the configured mu: three thesis balls x mu {0.0065, 0.0079, "
                    "0.0164} x theta0 {10, 20, 35} deg. Writes sim_fidelity.csv and .md.")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--engines", nargs="+", default=list(ENGINES), choices=list(ENGINES))
    parser.add_argument("--naive", choices=["subset", "all", "none"], default="subset",
                        help="naive surfaces (mesh, heightfield): mu = 0.0079 cases (subset), "
                             "the whole grid (all) or none")
    parser.add_argument("--seconds", type=float, default=4.0)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    table = fidelity_table(tuple(args.engines), naive=args.naive, duration=args.seconds,
                           progress=True)
    csv_path, md_path = write_report(table, args.out, args.seconds)
    print(to_markdown(table, args.seconds).split("\n\nPer case")[0])
    print(f"wrote {csv_path} and {md_path} in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
