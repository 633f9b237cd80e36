"""Coverage with the loop open: a truth richer than the fitter's physics, the lab's knowledge only.

The coverage study (:mod:`validation.studies.coverage`) draws the lab's tolerances but keeps
the ball in a level, round trough with Coulomb friction: the truth shares the fitter's
physics. Here each case draws the same motion, locator noise and as-built setup
(:func:`validation.studies.coverage.draw_case`) and, by its **family**, physics the fitter does
not assume or knows only within a stated u (drawn by :mod:`validation.studies.openloop_cases`):

- ``air``: room air (density drawn 1.20 +- 0.03 kg/m^3, the setup's stated u) with a
  **constant** drag coefficient drawn over the fitter's law's stated u: the law's Cd at the
  swing's Reynolds number (the free sphere's Schiller-Naumann Cd, energy-weighted over the
  record's swings, :func:`swing_cd`) times a wall factor drawn uniform over 1 .. 2
  (:data:`rollfric.fit.air.WALL_FACTOR` +- its rectangular half-width); sim's reference engine
  with ``air_drag = "constant"``. The lab states room air (the setup's default).
- ``air_beyond``: the same with the wall factor uniform over :data:`WALL_FACTOR_BEYOND`
  (beyond the law's stated u: what happens when the law is wrong).
- ``tilt``: the trough's axis tilted along its length, N(0, :data:`TILT_DEG_U`) deg (PyBullet:
  a 3D motion the reference refuses), no air.
- ``ovality``: an elliptic bore, D_max - D_min half-normal of scale :data:`OVALITY_MM_U`,
  major axis at any angle (reference engine, ``surface = "tangent"``), no air.
- ``camera``: a camera yawed and pitched uniformly within +-:data:`CAMERA_DEG` deg: the
  located centres compressed about the trough centre by cos(yaw) across x and cos(pitch)
  across y (orthographic, :mod:`rollfric.geometry.pathshape`), no air.
- ``speed``: a speed law mu(v) = mu0 + mu_speed v (sim's ``motion.mu_speed_s_m``), the speed
  term at the swing's top speed a fraction :data:`SPEED_FRACTION` of mu0, no air; the truth
  is mu0.
- ``all``: all of the above at once (PyBullet), the speed law in half of its cases.

The lab's setup (:func:`lab_setup`) is what coverage's lab states (radius, diameter, centre,
fps, pixel size with their ``_u``), room air where the truth has air (else
``air_density_kg_m3 = 0``), and the trough-as-built tolerances ``cylinder.tilt_deg_u``,
``cylinder.ovality_mm_u`` (rows of the budget: :mod:`rollfric.uncertainty.asbuilt`). The
measurement runs rollfric's fit, the path-ellipse reading of a tilted camera
(:func:`rollfric.geometry.pathreading.read_path`, as ``rollfric measure`` does: a "camera"
verdict corrects the angles) and the budget. z = (mu - truth) / u_mu. Each case is also
fitted on its **exact** centres (no noise, the exact as-built setup, the lab's air): that
fit's error, ``bias_phys`` (relative) and ``z_phys`` (in the blind u_mu), is what the drawn
physics alone does to mu, so a miss is told from the budget's own tolerances and noise.
The friction-law test (:func:`rollfric.uncertainty.law.friction_law`) runs on every case: its
verdicts are counted (its false alarms on air and the trough as built too) and, where it
selects the speed law, mu0 is compared with the truth's.

``python -m validation.studies.openloop --cases 420 --out DIR`` writes DIR/openloop.csv (one
row a case), DIR/openloop.json (the fractions, by family, and the misses by source) and
DIR/openloop.png (z histograms per family).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rollfric.errors import InputError
from rollfric.fit.estimate import fit_mu
from rollfric.geometry import ellipse as ell
from rollfric.geometry import pathreading
from rollfric.geometry.theta import angles
from rollfric.output.atomic import replacing
from rollfric.setup.model import setup_from_dict
from rollfric.uncertainty.budget import budget
from rollfric.uncertainty.law import friction_law
from rollfric.uncertainty.measured import Measurement
from validation.studies.coverage import (
    NOMINAL,
    TOLERANCE,
    drawn_setups,
    locator_noise,
    misses,
)
from validation.studies.openloop_cases import (
    CAMERA_DEG,
    FAMILIES,
    OVALITY_MM_U,
    SPEED_FRACTION,
    TILT_DEG_U,
    WALL_FACTOR_BEYOND,
    WALL_FACTOR_STATED,
    draw_openloop,
    family_of,
    swing_cd,  # noqa: F401  (importable from here, as before the cases had their module)
)

logger = logging.getLogger(__name__)

# the source columns the misses are analysed by: (column, what, family it is drawn in)
SOURCES = (("wall_factor_off", "|wall factor - 1.5|", ("air", "air_beyond", "all")),
           ("tilt_abs_deg", "|tilt| (deg)", ("tilt", "all")),
           ("ovality_mm", "ovality (mm)", ("ovality", "all")),
           ("camera_deg", "max(|yaw|, |pitch|) (deg)", ("camera", "all")),
           ("speed_fraction", "speed term / mu0 at the top speed", ("speed", "all")))


def truth_scenario(case: dict):
    """The case's truth as a :class:`sim.Scenario` (the as-built trough and ball, the
    family's physics) at the as-built frame rate."""
    import sim

    air = case["air_density"] > 0
    return sim.Scenario(
        ball_diameter=case["true_diameter_mm"] * 1e-3, ball_mass=case["mass_kg"],
        cylinder_radius=case["true_radius_mm"] * 1e-3, mu=case["mu"],
        theta0=math.radians(case["theta0_deg"]), duration=case["seconds"],
        fps=case["true_fps"], pixel_size=case["true_pixel_size_mm"] * 1e-3,
        engine=case["engine"], mu_speed=case["mu_speed_s_m"],
        air_density=case["air_density"], air_cd=case["air_cd"] if air else 0.47,
        air_drag="constant", ovality=case["ovality_mm"] * 1e-3,
        ovality_angle=math.radians(case["ovality_angle_deg"]),
        tilt=math.radians(case["tilt_deg"]), seed=case["seed"])


def lab_setup(case: dict):
    """The lab's setup file (lab units): coverage's nominal values and tolerances, room air
    (its default u) where the truth has air, else none, and the trough-as-built tolerances."""
    tol = TOLERANCE
    data = {
        "cylinder": {"radius_mm": NOMINAL["radius_mm"], "radius_mm_u": tol["radius_mm"],
                     "center_px": list(NOMINAL["center_px"]),
                     "center_px_u": [tol["center_px"], tol["center_px"]]},
        "ball": {"diameter_mm": case["diameter_mm"], "diameter_mm_u": tol["diameter_mm"],
                 "mass_g": case["mass_kg"] * 1e3},
        "camera": {"fps": NOMINAL["fps"], "fps_u": tol["fps"],
                   "pixel_size_mm": NOMINAL["pixel_size_mm"],
                   "pixel_size_mm_u": tol["pixel_size_mm"]},
        "environment": {} if case["air_density"] > 0 else {"air_density_kg_m3": 0.0},
    }
    data["cylinder"].update(tilt_deg=0.0, tilt_deg_u=TILT_DEG_U, ovality_mm=0.0,
                            ovality_mm_u=OVALITY_MM_U)  # a level, round trough, within these
    return setup_from_dict(data, "openloop lab")


def camera_map(x, y, center, yaw_deg: float, pitch_deg: float):
    """Centres (px) as a camera yawed by ``yaw_deg`` (about the image's vertical) and pitched
    by ``pitch_deg`` (about its horizontal) sees them, orthographic: compressed about the
    trough centre by cos(yaw) across x and cos(pitch) across y."""
    cx, cy = center
    return (cx + (np.asarray(x, dtype=float) - cx) * math.cos(math.radians(yaw_deg)),
            cy + (np.asarray(y, dtype=float) - cy) * math.cos(math.radians(pitch_deg)))


def exact_centres(case: dict, traj, true):
    """The ball's centres (px) in the camera: the trajectory's (x, y) projected with the
    as-built scale about the as-built centre (image y down), then the camera's yaw/pitch."""
    n = int(case["seconds"] * NOMINAL["fps"])
    if len(traj) < n:
        raise RuntimeError(f"the trajectory has {len(traj)} samples, {n} needed")
    pos = traj.position[:n]
    xc, yc = true.center_px
    x = xc + pos[:, 0] / true.pixel_size
    y = yc - pos[:, 1] / true.pixel_size
    x, y = camera_map(x, y, true.center_px, case["yaw_deg"], case["pitch_deg"])
    return np.arange(n, dtype=float), x, y


def law_verdict(meas: Measurement, result) -> dict:
    """The friction-law test's verdict (``rollfric.uncertainty.law.friction_law``) on the measured
    track: ``law_selected`` ("coulomb", "speed", or None with the test's reason),
    ``law_mu0``, ``law_mu0_u``, ``law_p_value``; ``law_error`` when it could not be called
    as expected."""
    try:
        out = friction_law(meas, result)
    except Exception as exc:  # another module's API: recorded, the study goes on
        return {"law_error": f"{type(exc).__name__}: {exc}"}
    return {"law_selected": out.selected or "none", "law_mu0": out.mu0,
            "law_mu0_u": out.mu0_u, "law_p_value": out.p_value}


def _path_reading(meas: Measurement, result, lab):
    """rollfric measure's reading of the path's ellipse on the centres: (result, meas,
    verdict, reason): a "camera" verdict corrects the angles (the fit and the measurement's
    angle map replaced), an "undecided" one beyond ``BIAS_WARN`` is the reason
    ``camera_orientation``."""
    center = lab.center_px
    L_px = lab.track_radius / lab.pixel_size
    t, th = meas.series(lab)
    try:
        reading = pathreading.read_path(
            meas.x, meas.y, center, t, th, lab, result, offset=False,
            refit=lambda tt, tth, s: fit_mu(tt, tth, s), ball_radius_px=lab.ball_radius
            / lab.pixel_size, angle_of=lambda xx, yy: angles(xx, yy, center,
                                                              track_radius_px=L_px),
            center_u=lab.u("center_px"))
    except (InputError, ValueError, np.linalg.LinAlgError) as exc:
        logger.info(f"path not read: {exc}")
        return result, meas, "not fitted", None
    if reading.verdict == "camera":
        amap = tuple(map(tuple, reading.path.round_map(L_px)))
        return reading.result_camera, dataclasses.replace(meas, angle_map=amap), "camera", None
    reason = "camera_orientation" if reading.verdict == "undecided" and \
        reading.spread > ell.BIAS_WARN else None
    return result, meas, reading.verdict, reason


def run_case(case: dict) -> dict:
    """Simulate one case's truth, film it, measure it blind with the lab's setup, and fit its
    exact centres (the physics' own bias)."""
    import sim

    out = dict(case)
    true, _ = drawn_setups(case)
    start = time.perf_counter()
    traj = sim.simulate(truth_scenario(case))
    out["sim_seconds"] = time.perf_counter() - start
    frames, xe, ye = exact_centres(case, traj, true)
    e = locator_noise(case, frames.size)
    lab = lab_setup(case)
    meas = Measurement(setup=lab, frames=frames, x=xe + e[0], y=ye + e[1],
                       center=lab.center_px)
    start = time.perf_counter()
    res = fit_mu(*meas.series(lab), lab)
    res, meas, out["path_verdict"], path_reason = _path_reading(meas, res, lab)
    b = budget(meas, res)
    out["fit_budget_seconds"] = time.perf_counter() - start
    reasons = [r.code for r in res.quality_reasons] + ([path_reason] if path_reason else [])
    mu_true = out["mu_true"] = case["mu"]  # mu0 of a speed law
    out.update(mu=b.mu, u_mu=b.u_mu, U_mu=b.U_mu, z=(b.mu - mu_true) / b.u_mu,
               top_source=b.rows[0].source, quality=";".join(reasons) or "ok",
               rows=";".join(f"{r.source}={r.u_mu / b.mu:.3g}" for r in b.rows))
    # the physics alone: the exact centres, the exact as-built setup, the lab's air
    exact = dataclasses.replace(true, uncertainty=(), air_density=lab.air_density)
    m_x = Measurement(setup=exact, frames=frames, x=xe, y=ye, center=true.center_px)
    mu_phys = fit_mu(*m_x.series(exact), exact, checks=False).mu
    out.update(mu_phys=mu_phys, bias_phys=mu_phys / mu_true - 1.0,
               z_phys=(mu_phys - mu_true) / b.u_mu, z_rest=(b.mu - mu_phys) / b.u_mu)
    out.update(law_verdict(meas, res))  # every case: false alarms on air, the trough too
    return out


def _frac(z, k):
    z = np.asarray(z, dtype=float)
    z = z[np.isfinite(z)]
    return float(np.mean(np.abs(z) <= k)) if z.size else math.nan


def _se(p, n):
    return float(math.sqrt(p * (1.0 - p) / n)) if n else math.nan


def coverage_of(df: pd.DataFrame, prefix: str = "") -> dict:
    """Within u and U (|z| <= 1, 2) with their binomial standard errors, the z's mean and
    rms, the misses' binomial tails (:func:`validation.studies.coverage.misses`) and how many
    of the misses outside U the drawn physics alone explains (|z_phys| > 1)."""
    z = df["z"].to_numpy(float)
    n = int(np.isfinite(z).sum())
    wu, wU = _frac(z, 1.0), _frac(z, 2.0)
    out = {"cases": n, "within_u": wu, "within_u_se": _se(wu, n), "within_U": wU,
           "within_U_se": _se(wU, n),
           "z_mean": float(np.nanmean(z)) if n else math.nan,
           "z_rms": float(np.sqrt(np.nanmean(z**2))) if n else math.nan}
    if "z_phys" in df:
        zp = df["z_phys"].to_numpy(float)
        miss = np.abs(z) > 2.0
        out.update(z_phys_rms=float(np.sqrt(np.nanmean(zp**2))) if n else math.nan,
                   bias_phys_median=float(np.nanmedian(df["bias_phys"])) if n else math.nan,
                   misses_U_physics=int(np.sum(miss & (np.abs(zp) > 1.0))),
                   misses_U_rest=int(np.sum(miss & (np.abs(zp) <= 1.0))))
    if "quality" in df:
        ok = df["quality"] == "ok"
        out.update(suspect=int((~ok).sum()), within_U_ok=_frac(df.loc[ok, "z"], 2.0),
                   within_u_ok=_frac(df.loc[ok, "z"], 1.0))
    out.update({k.replace("x_", "", 1): v for k, v in misses(z, "x").items()})
    return {f"{prefix}{k}": v for k, v in out.items()}


def by_source(df: pd.DataFrame) -> dict:
    """The misses against each drawn source's magnitude, in the families that draw it (in
    ``all``, the cases without the speed law; for the speed law's row, those with it): the
    cases in the lower and upper half of the magnitude, their fractions within U, the median
    physics bias of each half and the rank correlation of z_phys (and |z|) with the
    magnitude."""
    from scipy.stats import spearmanr

    out = {}
    for col, what, fams in SOURCES:
        for fam in fams:
            g = df[(df["family"] == fam) & np.isfinite(df["z"])]
            if fam == "all":  # the speed law would swamp the other sources
                g = g[g["speed_fraction"] > 0] if col == "speed_fraction" else \
                    g[g["speed_fraction"] == 0]
            if len(g) < 4:
                continue
            mag = g[col].to_numpy(float)
            lo = mag <= np.median(mag)
            row = {"what": what, "cases": len(g), "magnitude_median": float(np.median(mag)),
                   "magnitude_max": float(np.max(mag)),
                   "within_U_low": _frac(g["z"][lo], 2.0), "within_U_high": _frac(g["z"][~lo],
                                                                                  2.0),
                   "bias_phys_median_low": float(np.median(g["bias_phys"][lo])),
                   "bias_phys_median_high": float(np.median(g["bias_phys"][~lo]))}
            if np.ptp(mag) > 0:
                row["spearman_z_phys"] = float(spearmanr(mag, g["z_phys"]).statistic)
                row["spearman_abs_z"] = float(spearmanr(mag, np.abs(g["z"])).statistic)
            out[f"{col}[{fam}]"] = row
    return out


def summarize(df: pd.DataFrame) -> dict:
    """The study's summary: the cases within the stated tolerances (every family but
    ``air_beyond``) against the targets, each family alone, all cases, the misses by source
    (:func:`by_source`) and, for the speed law, the friction-law test's verdicts."""
    stated = df[df["family"] != "air_beyond"]
    s = {"targets": {"within_U": [0.92, 0.98], "within_u": [0.63, 0.73]},
         "stated": coverage_of(stated),
         # the same without the speed law (its truth mu0 is not what a Coulomb fit measures)
         "stated_coulomb": coverage_of(stated[stated["speed_fraction"] == 0]),
         "all_cases": coverage_of(df),
         "families": {f: coverage_of(g) for f, g in df.groupby("family", sort=False)},
         # the everything-at-once family with and without its speed law
         "all_split": {name: coverage_of(g) for name, g in (
             ("coulomb", df[(df["family"] == "all") & (df["speed_fraction"] == 0)]),
             ("speed law", df[(df["family"] == "all") & (df["speed_fraction"] > 0)]))
             if len(g)},
         "sources": by_source(df),
         "draws": {"tilt_deg_u": TILT_DEG_U, "ovality_mm_u": OVALITY_MM_U,
                   "camera_deg": CAMERA_DEG, "wall_factor_stated": list(WALL_FACTOR_STATED),
                   "wall_factor_beyond": list(WALL_FACTOR_BEYOND),
                   "speed_fraction": list(SPEED_FRACTION)}}
    speed = df[df["speed_fraction"] > 0]
    if len(speed):
        law = {"cases": len(speed), "law_test": "law_selected" in df,
               "coulomb_bias_median": float(np.median(speed["mu"] / speed["mu_true"] - 1.0))}
        if "law_selected" in df:
            sel = df["law_selected"].fillna("error")
            law["verdicts"] = {f"{fam}, {'speed law' if sp else 'coulomb'}": {
                str(k): int(v) for k, v in g.value_counts().items()}
                for (fam, sp), g in sel.groupby([df["family"], df["speed_fraction"] > 0])}
            sp = speed[sel[speed.index] == "speed"]
            zl = (sp["law_mu0"].astype(float) - sp["mu_true"]) / sp["law_mu0_u"].astype(float)
            law["mu0_within_U_when_speed"] = _frac(zl, 2.0)
            law["mu0_within_u_when_speed"] = _frac(zl, 1.0)
            law["mu0_cases_when_speed"] = len(sp)
        else:
            law["note"] = ("no friction-law verdicts in these cases' table: the Coulomb fit's mu "
                           "against the truth's mu0")
        s["speed_law"] = law
    return s


def plot(df: pd.DataFrame, path: Path) -> None:
    """Histograms of z (blind) and z_phys (the physics alone) per family, and below them z and
    z_phys against each drawn source's magnitude (its own family: dots; ``all``: crosses)."""
    from matplotlib.figure import Figure  # no pyplot: no backend, no global figure state

    fams = [f for f in FAMILIES if (df["family"] == f).any()]
    srcs = [src for src in SOURCES if df["family"].isin(src[2]).any()]
    cols = max(4, len(srcs))
    rows = math.ceil(len(fams) / cols) + (1 if srcs else 0)
    fig = Figure(figsize=(3.9 * cols, 3.3 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    grid = np.linspace(-4, 4, 200)
    bins = np.linspace(-6, 6, 49)
    hist_axes = axes[:math.ceil(len(fams) / cols)].ravel()
    for ax, fam in zip(hist_axes, fams, strict=False):
        g = df[df["family"] == fam]
        z = np.clip(g["z"].to_numpy(float), -6, 6)
        zp = np.clip(g["z_phys"].to_numpy(float), -6, 6)
        ax.hist(z, bins=bins, density=True, color="tab:blue", alpha=0.6, label="z")
        ax.hist(zp, bins=bins, density=True, histtype="step", color="tab:red",
                label="z_phys (physics alone)")
        ax.plot(grid, np.exp(-0.5 * grid**2) / math.sqrt(2 * math.pi), "k-", lw=1,
                label="N(0, 1)")
        ax.set_title(f"{fam}: {len(g)} cases\n|z| <= 1: {100 * _frac(z, 1):.1f} %, "
                     f"|z| <= 2: {100 * _frac(z, 2):.1f} %", fontsize=9)
        ax.set_xlabel("(mu - truth) / u_mu, clipped to +-6", fontsize=8)
        ax.legend(fontsize=7)
    for ax in hist_axes[len(fams):]:
        ax.set_visible(False)
    if srcs:
        for ax, (col, what, src_fams) in zip(axes[-1], srcs, strict=False):
            for fam in src_fams:
                g = df[df["family"] == fam]
                if fam == "all":  # as by_source: the speed law apart from the rest
                    g = g[(g["speed_fraction"] > 0) == (col == "speed_fraction")]
                if not len(g):
                    continue
                marker = "x" if fam == "all" else "o" if fam == src_fams[0] else "^"
                m = g[col].to_numpy(float)
                ax.scatter(m, np.clip(g["z"], -8, 8), s=9, marker=marker, color="tab:blue",
                           label=f"z ({fam})")
                ax.scatter(m, np.clip(g["z_phys"], -8, 8), s=9, marker=marker,
                           color="tab:red", label=f"z_phys ({fam})")
            ax.axhline(2, color="k", lw=0.6, ls="--")
            ax.axhline(-2, color="k", lw=0.6, ls="--")
            ax.set_xlabel(what, fontsize=8)
            ax.set_ylabel("z (clipped to +-8)", fontsize=8)
            ax.legend(fontsize=6)
        for ax in axes[-1][len(srcs):]:
            ax.set_visible(False)
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=90)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.studies.openloop", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", type=int, default=420)
    p.add_argument("--seed", type=int, default=0, help="first case seed")
    p.add_argument("--families", nargs="+", choices=FAMILIES, default=list(FAMILIES),
                   help="the families drawn, in turn (default: all)")
    p.add_argument("--out", help="output folder")
    p.add_argument("--merge", nargs="+", metavar="DIR",
                   help="report the openloop.csv of these folders together in --out")
    args = p.parse_args(argv)
    if not args.out:
        p.error("--out is needed")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.merge:
        df = pd.concat([pd.read_csv(Path(d) / "openloop.csv") for d in args.merge],
                       ignore_index=True)
        return _write(df, out)
    rows = []
    for i in range(args.cases):
        case = draw_openloop(args.seed + i, family_of(args.seed + i, args.families))
        rows.append(run_case(case))
        if (i + 1) % 10 == 0:
            df = pd.DataFrame(rows)
            df.to_csv(out / "openloop.csv", index=False)
            st = coverage_of(df[df["family"] != "air_beyond"])
            print(f"{i + 1} cases: within u {st['within_u']:.3f}, U {st['within_U']:.3f}",
                  flush=True)
    return _write(pd.DataFrame(rows), out)


def _write(df: pd.DataFrame, out: Path) -> int:
    """The study's table, summary and figure into ``out``; the summary printed; exit 0."""
    df.to_csv(out / "openloop.csv", index=False)
    s = summarize(df)
    (out / "openloop.json").write_text(json.dumps(s, indent=2) + "\n")
    plot(df, out / "openloop.png")
    print(json.dumps(s["stated"], indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
