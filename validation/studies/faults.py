"""The verdicts' hit and false-alarm rates: ``python -m validation.studies.faults``.

For each of the lab's faults (:mod:`validation.faults.recordings`), over a few sizes and seeds,
:func:`rollfric.measure` on the faulty drawn recording: mu's error against the truth in units
of the budget's U(mu) (:func:`rollfric.uncertainty.budget.budget`), the verdict ("ok", "suspect" or
"refused": an InputError / SetupError, the command's exit 2) and whether the fault was named
(:func:`named`: the reason, warning or finding that says what it is). For clean recordings of
several families (noise, contrast, ball size, a median background) the same, and how often each
reason (and each finding that names a fault: a held start, a rest, a camera's motion or turn)
came up: its false alarms. The tables go to a JSON file (docs/data/fault_study.json).

The setups state no ``_u`` keys but the camera's, square on exactly (``yaw_deg_u =
pitch_deg_u = 0``, :func:`square_on`), as the drawn camera is: U(mu) is the statistical part
and the air's (the strictest yardstick a fault's error can be held to). A turned camera's lab
does not know its turn and states nothing of its camera: the path's bound on the turn is then
a row of the budget (``as built: camera turn``).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import time
from pathlib import Path

import numpy as np

from rollfric.errors import InputError
from rollfric.measurement import measure
from rollfric.setup.model import SetupError
from rollfric.uncertainty.budget import budget
from rollfric.uncertainty.measured import measurement_from_track
from rollfric.uncertainty.report import with_budget_reason
from validation.faults.recordings import Family, Recording, clean, faulty

# fault -> the sizes studied (units in validation.faults.recordings)
SIZES = {
    "held": (20, 60, 200),  # frames at 200 Hz: 0.1, 0.3, 1 s
    "rest": (0.5, 0.75),  # the rest's start, share of the recording
    "bump": (1.0, 3.0),  # px
    "drift": (1.0, 2.0),  # px over the recording
    "yaw": (4.0, 8.0),  # deg
    "pitch": (8.0,),
    "flicker": (0.05, 0.10),  # gain amplitude
    "timestamps_ms": (3.0,),
    "timestamps_us": (3.0,),
    "fps": (1.10, 2.0),  # the setup's fps / the true
    "radius": (1.02, 1.10),  # the setup's radius / the true
    "gravity": (98.1, 9.6),  # the setup's g (m/s^2)
    "glitches": (0.015,),
}

# faults on another family than the default: label -> (fault, sizes, family)
VARIANTS = {
    # the resting or held ball sits in the per-pixel median background (issue 33's rest)
    "rest, median background": ("rest", (0.5,), Family(median_background=True)),
    "held, median background": ("held", (60,), Family(median_background=True)),
}

# clean families: name -> Family
FAMILIES = {
    "noise 1 DN": Family(),
    "noise 4 DN": Family(noise=4.0),
    "low contrast": Family(ball_level=0.55, spot=0.3),
    "ball 3 mm": Family(ball_mm=3.0),
    "ball 12 mm": Family(ball_mm=12.0),
    "median background": Family(median_background=True),
    "mu 0.003, 0.5 rad": Family(mu=0.003, theta0=0.5),
}

# faults that need not be named: harmless when mu stays within U (nothing to tell the user)
HARMLESS = ("flicker", "glitches", "timestamps_ms", "timestamps_us")


def _period_says(res, *texts) -> bool:
    return any(r.code == "period" and any(t in r.message for t in texts)
               for r in res.quality_reasons)


def findings(df, info, res) -> list[str]:
    """What the measurement found that names a fault, as short codes: ``still:held``,
    ``still:rest``, ``camera_motion:bump`` / ``drift``, ``path:camera`` (a turned camera
    corrected), ``timestamps:ms`` / ``us``.

    Parameters
    ----------
    df : pandas.DataFrame
        The track.
    info : rollfric.track.track_info.TrackInfo
        How it was measured.
    res : rollfric.fit.estimate.FitResult
        The fit.

    Returns
    -------
    list of str
    """
    out = []
    still = df["still"].to_numpy() if "still" in df.columns else np.array([])
    for name in ("held", "rest"):
        if (still == name).any():
            out.append(f"still:{name}")
    cm = info.camera_motion or {}
    if cm.get("kind") in ("bump", "drift"):
        out.append(f"camera_motion:{cm['kind']}")
    pe = info.path_ellipse or {}
    if pe.get("verdict") == "camera":
        out.append("path:camera")
    for unit in ("ms", "us"):
        if any(f"they are in {unit}, not seconds" in w for w in info.warnings):
            out.append(f"timestamps:{unit}")
    return out


def named(rec: Recording, df, info, res) -> bool | None:
    """Whether the measurement named ``rec``'s fault for what it is; None for a fault that
    need not be named (:data:`HARMLESS`).

    Parameters
    ----------
    rec : Recording
        The faulty recording (its ``fault`` and ``truth``).
    df, info, res
        :func:`rollfric.measure`'s track, TrackInfo and FitResult.

    Returns
    -------
    bool or None
    """
    f = rec.fault
    if f in HARMLESS and not f.startswith("timestamps"):
        return None
    found = findings(df, info, res)
    codes = {r.code for r in res.quality_reasons}
    if f == "held":
        return "still:held" in found
    if f == "rest":
        return "still:rest" in found
    if f in ("bump", "drift"):
        return f"camera_motion:{f}" in found
    if f in ("yaw", "pitch"):
        return "path:camera" in found or "camera_orientation" in codes
    if f.startswith("timestamps"):
        return f"timestamps:{rec.truth['unit']}" in found
    if f == "fps":
        return _period_says(res, "frame rate is wrong", "frame rate or clock is off")
    if f == "radius":
        return "track_radius" in codes or _period_says(
            res, "cylinder.radius_mm or ball.diameter_mm is off")
    if f == "gravity":
        return _period_says(res, "environment.gravity_m_s2")
    raise ValueError(f"no naming rule for {f!r}")


TURNED = ("yaw", "pitch")  # faults whose lab does not know its camera's orientation


def square_on(setup):
    """``setup`` stating its camera square on the trough, exactly (yaw and pitch 0 +- 0)."""
    known = dict(setup.uncertainty)
    known.setdefault("camera_yaw", 0.0)
    known.setdefault("camera_pitch", 0.0)
    return setup.replace(uncertainty=tuple(known.items()))


def run_one(rec: Recording) -> dict:
    """Measure ``rec`` and judge it: a row of the study.

    Parameters
    ----------
    rec : Recording

    Returns
    -------
    dict
        ``fault``, ``magnitude``, ``verdict`` ("ok", "suspect", "refused"), ``mu``, ``U_mu``,
        ``err_rel`` (mu / truth - 1), ``err_U`` ((mu - truth) / U), ``reasons`` (codes),
        ``findings``, ``named``, ``message`` (why refused), ``seconds``.
    """
    row = {"fault": rec.fault, "magnitude": rec.magnitude}
    setup = rec.setup if rec.fault in TURNED else square_on(rec.setup)
    t0 = time.perf_counter()
    try:
        df, info, res = measure(rec.source, setup, rec.background)
        b = budget(measurement_from_track(df, info), res)
        res = with_budget_reason(res, b)
    except (InputError, SetupError) as exc:
        row.update(verdict="refused", message=str(exc), mu=None, U_mu=None, err_rel=None,
                   err_U=None, reasons=[], findings=[],
                   named=None if rec.fault == "clean" else False,
                   seconds=round(time.perf_counter() - t0, 2))
        return row
    mu, U = float(b.mu), float(b.U_mu)
    row.update(verdict=res.quality, mu=mu, U_mu=U, err_rel=mu / rec.mu - 1,
               err_U=(mu - rec.mu) / U if U > 0 else math.inf,
               reasons=sorted({r.code for r in res.quality_reasons}),
               findings=findings(df, info, res),
               named=None if rec.fault == "clean" else named(rec, df, info, res),
               seconds=round(time.perf_counter() - t0, 2))
    return row


def fault_summary(rows) -> dict:
    """Per fault and size: cases, verdicts, named, reasons and findings (:func:`findings`)
    by code, |err| > U, ok with |err| > U (``ok_off``),
    quietly wrong (ok, |err| > U, not named), and the hit rate (named among the cases whose mu
    is off by more than U)."""
    out = {}
    for r in rows:
        key = f"{r['fault']} {r['magnitude']:g}"
        s = out.setdefault(key, {"fault": r["fault"], "magnitude": r["magnitude"], "n": 0,
                                 "ok": 0, "suspect": 0, "refused": 0, "named": 0,
                                 "off_by_U": 0, "named_where_off": 0, "ok_off": 0,
                                 "quietly_wrong": 0,
                                 "err_U": [], "err_rel": [], "reasons": {}, "findings": {}})
        s["n"] += 1
        s[r["verdict"]] += 1
        off = r["err_U"] is not None and abs(r["err_U"]) > 1.0
        s["named"] += bool(r["named"])
        s["off_by_U"] += off
        s["named_where_off"] += off and bool(r["named"])
        s["ok_off"] += off and r["verdict"] == "ok"
        s["quietly_wrong"] += off and r["verdict"] == "ok" and not r["named"]
        if r["err_U"] is not None:
            s["err_U"].append(round(r["err_U"], 2))
            s["err_rel"].append(round(r["err_rel"], 5))
        for c in r["reasons"]:
            s["reasons"][c] = s["reasons"].get(c, 0) + 1
        for c in r["findings"]:
            s["findings"][c] = s["findings"].get(c, 0) + 1
    for s in out.values():
        s["hit_rate"] = s["named_where_off"] / s["off_by_U"] if s["off_by_U"] else None
    return out


def clean_summary(rows) -> dict:
    """Per family: cases, verdicts, |err| > U, and each reason's and finding's count (the
    false alarms), with the totals over all families under "all"."""
    out = {}
    for r in rows:
        for key in (r["family"],):
            s = out.setdefault(key, {"n": 0, "ok": 0, "suspect": 0, "refused": 0,
                                     "off_by_U": 0, "false_alarms": {}})
            s["n"] += 1
            s[r["verdict"]] += 1
            s["off_by_U"] += r["err_U"] is not None and abs(r["err_U"]) > 1.0
            for c in r["reasons"] + r["findings"]:
                s["false_alarms"][c] = s["false_alarms"].get(c, 0) + 1
    total = {"n": 0, "ok": 0, "suspect": 0, "refused": 0, "off_by_U": 0, "false_alarms": {}}
    for s in out.values():
        for k in ("n", "ok", "suspect", "refused", "off_by_U"):
            total[k] += s[k]
        for c, v in s["false_alarms"].items():
            total["false_alarms"][c] = total["false_alarms"].get(c, 0) + v
    out["all"] = total
    return out


def run_study(*, seeds: int = 3, clean_seeds: int = 15, faults=None, families=None,
              sizes=None, log=print) -> dict:
    """The study: every fault of ``faults`` (default all of :data:`SIZES`, then
    :data:`VARIANTS`) at its sizes over
    ``seeds`` seeds, every family of ``families`` (default all of :data:`FAMILIES`) over
    ``clean_seeds`` seeds; the rows and their summaries.

    Parameters
    ----------
    seeds, clean_seeds : int
        Seeds per faulty size and per clean family.
    faults, families : sequence of str, optional
        The faults (of :data:`SIZES` and :data:`VARIANTS`) and clean families to run.
    sizes : dict, optional
        fault -> its sizes, in place of :data:`SIZES`'.
    log : callable
        Called with a line per case.

    Returns
    -------
    dict
        ``faults`` and ``clean`` (summaries), ``fault_rows``, ``clean_rows``, ``setup``
        (what was measured).
    """
    fault_rows, clean_rows = [], []
    sizes = {**SIZES, **(sizes or {})}
    for label in (faults or list(SIZES) + list(VARIANTS)):
        fault, mags, fam = VARIANTS[label] if label in VARIANTS else \
            (label, sizes[label], Family())
        for mag in mags:
            for seed in range(seeds):
                row = run_one(faulty(fault, mag, seed=seed, family=fam))
                row.update(fault=label, seed=seed)
                fault_rows.append(row)
                log(_line(row))
    for fam in (families or FAMILIES):
        for seed in range(clean_seeds):
            rec = clean(FAMILIES[fam], seed=1000 + seed)
            row = run_one(rec)
            row.update(family=fam, seed=1000 + seed)
            clean_rows.append(row)
            log(f"[{fam}] " + _line(row))
    return {
        "what": ("rollfric.measure on drawn recordings (synth.drawn.frames: 480 x 280 px, "
                 "200 px trough, 400 frames at 200 Hz, mu 0.01 from 0.3 rad unless the family "
                 "says otherwise; the lab's center_px in the setup, no _u keys but the "
                 "camera's, square on exactly, except where it is turned: U(mu) is the "
                 "statistical part and the air's, and the path's bound on a turned camera's "
                 "turn), faults from validation.faults.recordings"),
        "seeds": seeds, "clean_seeds": clean_seeds,
        "faults": fault_summary(fault_rows), "clean": clean_summary(clean_rows),
        "fault_rows": fault_rows, "clean_rows": clean_rows,
    }


def _line(r) -> str:
    err = "refused" if r["err_U"] is None else \
        f"err {100 * r['err_rel']:+.3f} % = {r['err_U']:+.2f} U"
    return (f"{r['fault']:>14} {r['magnitude']:<7g} {r['verdict']:<8} {err:<28} "
            f"named {r['named']!s:<5} {','.join(r['reasons'] + r['findings'])}")


def main(argv=None) -> int:
    """The command line: run the study, print the tables, write the JSON."""
    p = argparse.ArgumentParser(prog="python -m validation.studies.faults",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=3, help="seeds per fault size (default 3)")
    p.add_argument("--clean-seeds", type=int, default=15,
                   help="seeds per clean family (default 15)")
    p.add_argument("--faults", nargs="*", choices=sorted(SIZES) + sorted(VARIANTS),
                   help="faults to run (all)")
    p.add_argument("--families", nargs="*", choices=sorted(FAMILIES),
                   help="clean families to run (all)")
    p.add_argument("--out", type=Path, default=None,
                   help="write the JSON here (e.g. docs/data/fault_study.json)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    a = p.parse_args(argv)
    if a.seeds < 0 or a.clean_seeds < 0:
        p.error("--seeds and --clean-seeds must be >= 0")
    if a.out is not None and a.out.exists() and not a.overwrite:
        print(f"{a.out} exists: give --overwrite to replace it", file=sys.stderr)
        return 2
    logging.getLogger("rollfric").setLevel(logging.ERROR)  # the tables say what was found
    study = run_study(seeds=a.seeds, clean_seeds=a.clean_seeds, faults=a.faults,
                      families=a.families)
    print(format_tables(study))
    if a.out is not None:
        a.out.parent.mkdir(parents=True, exist_ok=True)
        tmp = a.out.with_name(a.out.name + ".tmp")
        tmp.write_text(json.dumps(study, indent=1) + "\n")
        tmp.replace(a.out)
    return 0


def format_tables(study) -> str:
    """The two tables as Markdown: the faults, and the clean families' false alarms."""
    lines = ["| fault | size | n | ok / suspect / refused | named | abs(err) > U | hit rate "
             "| ok, abs(err) > U | quietly wrong | err / U (median, max abs) | reasons "
             "| findings |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in study["faults"].values():
        e = np.abs(s["err_U"]) if s["err_U"] else None
        hit = "-" if s["hit_rate"] is None else f"{100 * s['hit_rate']:.0f} %"
        lines.append(
            f"| {s['fault']} | {s['magnitude']:g} | {s['n']} | {s['ok']} / {s['suspect']} / "
            f"{s['refused']} | {s['named']} | {s['off_by_U']} | {hit} | {s['ok_off']} | "
            f"{s['quietly_wrong']} | "
            + ("-" if e is None else f"{np.median(s['err_U']):+.2f}, {e.max():.2f}")
            + " | " + ", ".join(f"{k} {v}" for k, v in sorted(s["reasons"].items()))
            + " | " + ", ".join(f"{k} {v}" for k, v in sorted(s["findings"].items())) + " |")
    lines += ["", "| clean family | n | ok / suspect / refused | abs(err) > U | false alarms |",
              "|---|---|---|---|---|"]
    for fam, s in study["clean"].items():
        fa = ", ".join(f"{k} {v}" for k, v in sorted(s["false_alarms"].items())) or "none"
        lines.append(f"| {fam} | {s['n']} | {s['ok']} / {s['suspect']} / {s['refused']} | "
                     f"{s['off_by_U']} | {fa} |")
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
