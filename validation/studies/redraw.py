"""Coverage of the budget on rendered tracks with fresh lab errors: many draws per recording.

A blind coverage study draws each case's as-built setup once (:mod:`validation.lab`), so its
miss count mixes two things: whether the budget states the right spread for the errors a lab
can make, and how extreme the few hundred draws it made happen to be. On the rendered studies
the second dominates: their blind error is the setup's part to within a tenth of u_mu (the
statistical part is ~1 % of u_mu). This module separates the two on recordings that exist.

For every recording the ball is located once, with the case's own lab setup
(:func:`validation.e2e.measure_recording`, as the study measured it). Then for each of K draws
the lab's values are drawn afresh around the recording's as-built ones: nominal = as-built +
u z for every key with a stated ``_u`` and the lab's trough centre = the true centre + u z, z
standard normal, seeded by the case and the draw (draw 0 is the study's own lab). So nominal -
as-built has the distribution the study draws (N(0, u)). The angles, times, offset decision, fit
and budget are redone from the located centres with that setup, as
:func:`rollfric.measurement.measure` does after locating (:func:`refit`), and z = (mu - mu_true) /
u_mu is recorded. What is not redone: the locating itself (the ball's radius in px and the
per-frame plausibility checks use the lab's setup; its draws move them by ~0.2 % and a few px
of the centre, which the study's own draws also do).

``python -m validation.studies.redraw --from-recordings SRC [SRC ...] --draws K --out DIR`` (SRC: a
sweep run with ``--keep-recordings``; ``--track-level``: its cases at the track level, same
draws, for contrast) writes DIR/redraw.csv (one row per recording and draw),
DIR/redraw.json (coverage of draw 0, of the fresh draws, of all; by study) and DIR/summary.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from rollfric.fit.estimate import fit_mu
from rollfric.fit.offset import resolve_offset
from rollfric.setup.model import setup_from_dict
from rollfric.uncertainty.budget import budget
from rollfric.uncertainty.measured import measurement_from_track
from validation.case import Case, case_from_dict
from validation.e2e import measure_recording
from validation.lab import standard_normal
from validation.studies.coverage import misses
from validation.sweep_table import recorded_sweep
from validation.track_level import measure_track

_TAG = 0x726564726177  # "redraw": the draws' own stream, apart from the study's


def redrawn_lab(case: Case, draw: int):
    """The case's lab with its values drawn afresh around the as-built ones (draw 0: itself).

    Parameters
    ----------
    case : Case
        A blind case with a ``[lab]`` (``lab.draw`` or not).
    draw : int
        0: the case's own lab; k >= 1: nominal = as-built + u z for every key with a stated
        ``_u``, and the lab's centre error u z when it states ``center_px_u``, z standard normal
        from (the lab's seed, k), one stream per key.

    Returns
    -------
    validation.lab.Lab
    """
    lab = case.lab
    if draw == 0:
        return lab
    rng_seed = [int(lab.seed), _TAG, int(draw)]

    def z(key: str) -> float:
        return standard_normal(int(np.random.SeedSequence(rng_seed).generate_state(1)[0]),
                               key)

    nominal = dict(lab.nominal)
    for dotted, u in lab.tolerance.items():
        nominal[dotted] = lab.asbuilt[dotted] + u * z(dotted)
    center = lab.center_error_px
    if lab.center_u is not None and center is not None:
        center = tuple(lab.center_u[i] * z(f"cylinder.center_px.{axis}")
                       for i, axis in enumerate("xy"))
    return dataclasses.replace(lab, nominal=nominal, center_error_px=center)


def redrawn_setup(case: Case, draw: int):
    """The lab's rollfric setup of :func:`redrawn_lab` (nominal values with their ``_u``).

    Parameters
    ----------
    case : Case
        The case.
    draw : int
        As :func:`redrawn_lab`.

    Returns
    -------
    rollfric.setup.model.Setup
    """
    cam = case.scene.camera
    d = redrawn_lab(case, draw).setup_dict(cam.center_px, cam)
    return setup_from_dict(d, source="the redrawn lab's setup")


def refit(track, info, setup, offset: str = "auto"):
    """Angles, times, offset decision, fit and budget of located centres with ``setup``.

    What :func:`rollfric.measurement.measure` does after locating, with the angles about
    ``setup.center_px`` and the times frame / ``setup.fps``
    (:meth:`rollfric.uncertainty.measured.Measurement.series`, the budget's own re-evaluation).

    Parameters
    ----------
    track : pandas.DataFrame
        ``rollfric.measurement.measure``'s track (``frame``, ``found``, ``x_px``, ``y_px``,
        ``t_s``).
    info : rollfric.track.track_info.TrackInfo
        How it was measured (times frame / camera.fps, atan2 or arcsin angles).
    setup : rollfric.setup.model.Setup
        The setup to measure with; it must give ``center_px``.
    offset : str or bool
        As ``rollfric measure --offset``.

    Returns
    -------
    fit : rollfric.fit.estimate.FitResult
    budget : rollfric.uncertainty.budget.Budget
    """
    if setup.center_px is None:
        raise ValueError("refit needs a setup with center_px")
    meas = measurement_from_track(track, info)
    meas = dataclasses.replace(meas, setup=setup, center=tuple(setup.center_px),
                               center_u=None)
    t, th = meas.series(setup)
    use, _ = resolve_offset(offset, t, th, setup, "lsq")
    fit = fit_mu(t, th, setup, method="lsq", offset=use)
    return fit, budget(meas, fit)


def redraw_case(case: Case | dict, recording: str | Path | None, draws: int) -> list[dict]:
    """Locate a recording once and measure it with draws 0 .. ``draws`` of the lab.

    Parameters
    ----------
    case : Case or dict
        The blind case the recording was rendered from.
    recording : str or Path or None
        Its recording (synth's Zarr); None: the case at the track level instead (the exact
        projection plus the locator's noise, :func:`validation.track_level.measure_track`),
        with the same draws.
    draws : int
        Number of fresh draws (besides draw 0, the study's own lab).

    Returns
    -------
    list of dict
        One row per draw: ``draw``, ``mu``, ``mu_true``, ``u_mu``, ``U_mu``, ``z``,
        ``within_u``, ``within_U``, ``top_source``, the errors (nominal - as-built, in units of
        their u) of the centre and the radius, ``mu_study`` (draw 0 as the study measured it:
        :func:`rollfric.measurement.measure`'s own fit, or the track level's).
    """
    if isinstance(case, dict):
        case = case_from_dict(case)
    if case.lab is None or case.oracle:
        raise ValueError("redraw needs a blind case with a [lab]")
    if recording is None:
        tc = measure_track(case)
        track, fit0 = tc.track, tc.fit
        # what rollfric.measurement.measure tells the budget (as validation.track_level does)
        info = SimpleNamespace(center_px=tc.center_px, undistorted=tc.undistorted,
                               setup=tc.setup, angle="atan2", times="frame / camera.fps")
    else:
        track, info, fit0, _, _ = measure_recording(Path(recording), case)
    mu_true = float(case.scenario.mu)
    rows = []
    for k in range(draws + 1):
        lab = redrawn_lab(case, k)
        fit, b = refit(track, info, redrawn_setup(case, k), case.offset)
        err = lab.errors()
        u_r = lab.tolerance.get("cylinder.radius_mm")
        ce = lab.center_error_px or (math.nan, math.nan)
        cu = lab.center_u or (math.nan, math.nan)
        rows.append({
            "case_id": case.case_id, "recording": "" if recording is None else str(recording),
            "stages": "track" if recording is None else "full", "draw": k,
            "mu_true": mu_true, "mu": b.mu, "mu_study": float(fit0.mu),
            "u_mu": b.u_mu, "U_mu": b.U_mu, "z": (b.mu - mu_true) / b.u_mu,
            "within_u": float(abs(b.mu - mu_true) <= b.u_mu),
            "within_U": float(abs(b.mu - mu_true) <= b.U_mu),
            "top_source": b.rows[0].source, "offset_fitted": bool(fit.offset != 0.0),
            "n_samples": int(fit.n_samples),
            "e_center_x": ce[0] / cu[0], "e_center_y": ce[1] / cu[1],
            "e_radius": err["cylinder.radius_mm"] / u_r if u_r else math.nan,
        })
    return rows


def _recorded_cases(src: Path) -> list[tuple[dict, str]]:
    spec = recorded_sweep(src)
    return [(sc.case, sc.recording) for sc in spec.cases]


def _one(args) -> list[dict]:
    case, rec, draws, study = args
    logging.disable(logging.WARNING)
    t0 = time.perf_counter()
    try:
        rows = redraw_case(case, rec, draws)
    except Exception as exc:  # one bad recording must not stop the study; it is reported
        return [{"recording": rec, "study": study, "error": f"{type(exc).__name__}: {exc}"}]
    for r in rows:
        r["study"] = study
        r["seconds"] = time.perf_counter() - t0
    return rows


def summarize(df: pd.DataFrame) -> dict:
    """Coverage of draw 0 (the study's own draws), of the fresh draws and of all, as
    :func:`validation.studies.coverage.misses` reports it.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`redraw_case`'s rows (columns ``draw``, ``z``).

    Returns
    -------
    dict
        ``{"draw 0": ..., "fresh": ..., "all": ...}``, each with n, the fractions within
        u and U, the miss counts and their binomial tails, mean and sd of z.
    """
    out = {}
    for name, sel in (("draw 0", df["draw"] == 0), ("fresh", df["draw"] > 0),
                      ("all", df["draw"] >= 0)):
        z = df.loc[sel, "z"].to_numpy(float)
        z = z[np.isfinite(z)]
        n = z.size
        if n == 0:
            continue
        s = {"n": int(n), "within_U": float(np.mean(np.abs(z) <= 2.0)),
             "within_u": float(np.mean(np.abs(z) <= 1.0)),
             "z_mean": float(np.mean(z)), "z_mean_se": float(np.std(z, ddof=1) / math.sqrt(n))
             if n > 1 else math.nan,
             "z_sd": float(np.std(z, ddof=1)) if n > 1 else math.nan}
        m = misses(z, "blind")
        m = misses(z, "blind")
        for k in ("u", "U"):
            s.update({f"outside_{k}{tail}": m[f"blind_misses_{k}{tail}"]
                      for tail in ("", "_expected", "_p_at_least")})
        out[name] = s
    return out


def _table(summary: dict) -> str:
    lines = ["| draws | n | within U (95 +- 3) | misses (exp., P>=) | within u (68 +- 5) | "
             "outside u (exp., P>=) | z mean | z sd |", "|---|---|---|---|---|---|---|---|"]
    for name, s in summary.items():
        lines.append(f"| {name} | {s['n']} | {100 * s['within_U']:.1f} % | "
                     f"{s['outside_U']} ({s['outside_U_expected']:.1f}, "
                     f"{s['outside_U_p_at_least']:.2g}) | {100 * s['within_u']:.1f} % | "
                     f"{s['outside_u']} ({s['outside_u_expected']:.1f}, "
                     f"{s['outside_u_p_at_least']:.2g}) | {s['z_mean']:+.3f} +- "
                     f"{s['z_mean_se']:.3f} | {s['z_sd']:.3f} |")
    return "\n".join(lines)


def report(df: pd.DataFrame, title: str, out: Path) -> str:
    """Write ``out``/redraw.json and ``out``/summary.md of :func:`redraw_case`'s rows (all
    studies, then each) and return the summary's text.

    Parameters
    ----------
    df : pandas.DataFrame
        The rows (columns ``study``, ``draw``, ``z``; ``error`` for failed recordings).
    title : str
        The summary's heading.
    out : Path
        An existing folder.

    Returns
    -------
    str
        summary.md's text.
    """
    ok = df[df["z"].notna()] if "z" in df else df.iloc[:0]
    summary = {"all studies": summarize(ok)}
    for study, g in ok.groupby("study"):
        summary[str(study)] = summarize(g)
    failed = int(df["error"].notna().sum()) if "error" in df else 0
    n_rec = int((ok["draw"] == 0).sum())
    draws = int(ok["draw"].max()) if len(ok) else 0
    (out / "redraw.json").write_text(json.dumps({**summary, "failed": failed,
                                                 "recordings": n_rec, "draws": draws},
                                                indent=2))
    text = [f"# {title}", "", f"{n_rec} recordings, {draws} fresh draws each; failed "
            f"recordings: {failed}", ""]
    for name, s in summary.items():
        text += [f"## {name}", "", _table(s), ""]
    (out / "summary.md").write_text("\n".join(text))
    return "\n".join(text)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.studies.redraw", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--from-recordings", nargs="+", metavar="SRC",
                   help="sweeps run with --keep-recordings (blind cases with a [lab])")
    p.add_argument("--report", nargs="+", metavar="DIR",
                   help="instead: report earlier runs' DIR/redraw.csv together")
    p.add_argument("--draws", type=int, default=4, help="fresh lab draws per recording")
    p.add_argument("--out", required=True, help="output folder (must not exist)")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--limit", type=int, default=0, help="only the first N recordings of each")
    p.add_argument("--every", type=int, default=1, metavar="N",
                   help="every N-th recording of each (a subset spread over the whole grid)")
    p.add_argument("--start", type=int, default=0, metavar="I",
                   help="with --every: start at the I-th recording (0-based)")
    p.add_argument("--track-level", action="store_true",
                   help="the recordings' cases at the track level (no recording read: the "
                        "exact projection plus the locator's noise), with the same draws")
    a = p.parse_args(argv)
    out = Path(a.out)
    if out.exists():
        print(f"--out {out} exists: give a new folder", file=sys.stderr)
        return 2
    if (a.from_recordings is None) == (a.report is None):
        print("give --from-recordings SRC ... or --report DIR ...", file=sys.stderr)
        return 2
    if a.report is not None:
        missing = [d for d in a.report if not (Path(d) / "redraw.csv").is_file()]
        if missing:
            print(f"--report: no redraw.csv in {', '.join(missing)}", file=sys.stderr)
            return 2
        df = pd.concat([pd.read_csv(Path(d) / "redraw.csv") for d in a.report],
                       ignore_index=True)
        out.mkdir(parents=True)
        print(report(df, f"fresh lab draws: {', '.join(a.report)}", out))
        return 0
    if a.draws < 0 or a.workers < 1 or a.every < 1 or a.start < 0:
        print("--draws and --start must be >= 0, --workers and --every >= 1", file=sys.stderr)
        return 2
    jobs = []
    for src in a.from_recordings:
        try:
            cases = _recorded_cases(Path(src))
        except Exception as exc:  # noqa: BLE001 (a bad folder is bad input)
            print(f"--from-recordings {src}: {exc}", file=sys.stderr)
            return 2
        cases = cases[a.start::a.every]
        if a.limit:
            cases = cases[:a.limit]
        jobs += [(c, None if a.track_level else r, a.draws, Path(src).name)
                 for c, r in cases]
    out.mkdir(parents=True)
    rows = []
    with ProcessPoolExecutor(a.workers) as ex:
        for i, rs in enumerate(ex.map(_one, jobs)):
            rows += rs
            print(f"{i + 1}/{len(jobs)} {rs[0].get('case_id', rs[0].get('error'))}",
                  flush=True)
            if (i + 1) % 10 == 0:  # what is finished so far, for a run stopped early
                pd.DataFrame(rows).to_csv(out / "redraw.partial.csv", index=False)
    df = pd.DataFrame(rows)
    df.to_csv(out / "redraw.csv", index=False)
    (out / "redraw.partial.csv").unlink(missing_ok=True)
    title = f"fresh lab draws on {', '.join(a.from_recordings)}" + (
        " (at the track level)" if a.track_level else "")
    print(report(df, title, out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
