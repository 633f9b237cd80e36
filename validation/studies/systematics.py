"""The error budget of the ``systematics`` study: what each lab error source does to mu.

``rollfric sweep systematics --out OUT`` runs each source alone over its range (blind mode);
``python -m validation.studies.systematics OUT --json docs/data/systematics.json`` turns its results
into the study's JSON (one row a case: the source, its magnitude, whether rollfric's correction
was on, how the case was run, mu bias, the thesis's relative error, theta rms), and
:func:`budget_table` / :func:`render_markdown` turn that JSON into the docs' error-budget table
(the docs hook ``docs/hooks/systematics_page.py``): for each source and correction, the
magnitude that biases mu by 0.1 % and by 1 %, interpolated linearly between the swept
magnitudes (from no error, no bias, where magnitude 0 means no error).

A case's source and magnitude: :func:`validation.studies.error_sources.classify`.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

from rollfric.output.atomic import write_text
from validation.studies.error_sources import SOURCES, cell_number, classify
from validation.sweep import load_sweep

LEVELS = (0.001, 0.01)  # |mu bias| of the table's columns: 0.1 % and 1 %
STUDY_METRICS = ("mu_bias_rel", "fit_relative_error", "theta_rms_rad", "mu_stderr", "mu_true",
                 "trough_center_err_x_px", "trough_center_err_y_px", "offset_fitted")


def study_rows(df, swept: list[str]) -> list[dict]:
    """The study's rows from a sweep table (one a finished case).

    Parameters
    ----------
    df : pandas.DataFrame
        results.parquet of the sweep.
    swept : list of str
        Its swept keys.

    Returns
    -------
    list of dict
        source, magnitude, unit, corrected, stages and :data:`STUDY_METRICS`.
    """
    out = []
    for _, r in df.iterrows():
        if r.get("status") != "ok":
            continue
        row = {k: (None if isinstance(v, float) and math.isnan(v) else v)
               for k, v in r.to_dict().items()}
        name, mag, unit, corr = classify(row, swept)
        item = {"case_id": row["case_id"], "source": name, "magnitude": mag, "unit": unit,
                "corrected": corr, "stages": row.get("stages") or "full"}
        for m in STUDY_METRICS:
            v = row.get(m)
            item[m] = bool(v) if isinstance(v, bool) else cell_number(v)
        out.append(item)
    return out


def crossing(points: list[tuple[float, float]], level: float, origin: bool):
    """Where |bias| first reaches ``level`` along the swept magnitudes.

    Parameters
    ----------
    points : list of (magnitude, bias)
        One source's cases (one sign of the magnitude, or both: |magnitude| is used).
    level : float
        |bias| to reach.
    origin : bool
        Start from (0, 0) (magnitude 0 is no error).

    Returns
    -------
    tuple
        (kind, value): ("at", m) interpolated linearly; ("above", m_max): not reached up to the
        largest |magnitude| swept; ("below", m_min): already beyond at the smallest one (no
        origin). A source whose bias falls as its magnitude grows (a working distance):
        ("decreasing", m): beyond the level below m; ("nowhere", m_min): not reached down to
        the smallest magnitude; ("everywhere", m_max): beyond it even at the largest.
    """
    pts = sorted((abs(m), abs(b)) for m, b in points if m is not None and b is not None)
    if not pts:
        return ("none", None)
    if origin:
        pts = [(0.0, 0.0), *pts]
    increasing = pts[-1][1] >= pts[0][1]
    seq = pts if increasing else pts[::-1]
    if seq[0][1] >= level:
        return ("below" if increasing else "everywhere", seq[0][0])
    for (m0, b0), (m1, b1) in zip(seq, seq[1:], strict=False):
        if b0 < level <= b1:
            m = m0 + (level - b0) * (m1 - m0) / (b1 - b0)
            return ("at" if increasing else "decreasing", m)
    return ("above" if increasing else "nowhere", seq[-1][0])


def budget_table(rows: list[dict]) -> list[dict]:
    """The error-budget table: one entry per source and correction state.

    Parameters
    ----------
    rows : list of dict
        :func:`study_rows`'s rows (or the study JSON's ``rows``).

    Returns
    -------
    list of dict
        source, unit, corrected, typical, n, range (min, max |magnitude|), the crossings of
        :data:`LEVELS` (:func:`crossing`), the largest |mu bias| and relative error, the stages.
    """
    by = {s.name: s for s in SOURCES}
    groups: dict = {}
    for r in rows:
        if r["source"] == "none" or r["magnitude"] is None:
            continue
        groups.setdefault((r["source"], r["corrected"]), []).append(r)
    order = {s.name: i for i, s in enumerate(SOURCES)}
    out = []
    for (name, corr), rs in sorted(groups.items(),
                                   key=lambda kv: (order.get(kv[0][0], len(order)), kv[0][0],
                                                   str(kv[0][1]))):
        src = by.get(name)
        origin = src.origin if src else True
        pts = [(r["magnitude"], r["mu_bias_rel"]) for r in rs]
        mags = [abs(r["magnitude"]) for r in rs]
        out.append({
            "source": name, "unit": rs[0]["unit"], "corrected": corr,
            "typical": src.typical if src else "",
            "n": len(rs), "range": [min(mags), max(mags)],
            "levels": {f"{lv:g}": crossing(pts, lv, origin) for lv in LEVELS},
            "max_abs_mu_bias_rel": max(abs(r["mu_bias_rel"]) for r in rs
                                       if r["mu_bias_rel"] is not None),
            "max_fit_relative_error": max((r["fit_relative_error"] for r in rs
                                           if r["fit_relative_error"] is not None),
                                          default=None),
            "stages": sorted({r["stages"] for r in rs}),
        })
    return out


def fmt_mag(v: float) -> str:
    """A magnitude to 2 significant figures."""
    if v == 0:
        return "0"
    return f"{v:.2g}" if 1e-3 <= abs(v) < 1e5 else f"{v:.1e}"


def fmt_crossing(c, unit: str) -> str:
    """A table cell for a :func:`crossing`."""
    kind, v = c
    u = f" {unit}" if unit and unit != "1" else ""
    if kind == "at" or kind == "decreasing":
        return ("" if kind == "at" else "below ") + fmt_mag(v) + u
    if kind == "above":
        return f"not reached (> {fmt_mag(v)}{u})"
    if kind == "below":
        return f"< {fmt_mag(v)}{u}"
    if kind == "nowhere":
        return f"not reached (down to {fmt_mag(v)}{u})"
    if kind == "everywhere":
        return f"beyond it up to {fmt_mag(v)}{u}"
    return ""


def render_markdown(data: dict) -> str:
    """The docs' error-budget table (Markdown) from the study JSON.

    Parameters
    ----------
    data : dict
        The study JSON: ``meta`` and ``rows`` (:func:`study_rows`).

    Returns
    -------
    str
    """
    meta = data.get("meta", {})
    rows = data.get("rows", [])
    table = budget_table(rows)
    base = [r for r in rows if r["source"] == "none"]
    lines = [f"**Run:** {meta.get('date', 'unknown date')}, {meta.get('n_cases', len(rows))} "
             f"cases ({meta.get('note', '')}).", ""]
    if base:
        lines += ["Without an error: " + "; ".join(
            f"mu bias {100 * r['mu_bias_rel']:+.4f} %, relative error "
            f"{100 * r['fit_relative_error']:.3f} % ({r['stages']})" for r in base) + ".", ""]
    lines += ["| source | rollfric's correction | mu bias 0.1 % at | mu bias 1 % at | "
              "swept | largest mu bias | largest relative error (eq. 14) | a lab's range |",
              "|---|---|---|---|---|---|---|---|"]
    for t in table:
        corr = {None: "none", True: "on", False: "off"}[t["corrected"]]
        lo, hi = t["range"]
        st = "+".join(t["stages"])
        rel = t["max_fit_relative_error"]
        lines.append(
            f"| {t['source']} | {corr} | {fmt_crossing(t['levels']['0.001'], t['unit'])} | "
            f"{fmt_crossing(t['levels']['0.01'], t['unit'])} | {fmt_mag(lo)} .. {fmt_mag(hi)}"
            f"{' ' + t['unit'] if t['unit'] and t['unit'] != '1' else ''} ({t['n']}, {st}) | "
            f"{100 * t['max_abs_mu_bias_rel']:.3g} % | "
            f"{'' if rel is None else f'{100 * rel:.3g} %'} | {t['typical']} |")
    for f in meta.get("failed", []):
        what = ", ".join(f"{k} = {v}" for k, v in f["params"].items())
        lines += ["", f"Refused by rollfric ({f['stages']}): {what}: {f['error']}"]
    if meta.get("not_run"):
        lines += ["", f"Not run: {meta['not_run']} case(s) of the sweep file."]
    return "\n".join(lines) + "\n"


def study_json(out: str | Path, note: str = "") -> dict:
    """The study JSON of a finished ``systematics`` sweep folder.

    Parameters
    ----------
    out : str or pathlib.Path
        The sweep's --out folder (results.parquet, sweep.toml).
    note : str
        How it was run (machine, load), for the page.

    Returns
    -------
    dict
        ``meta`` (date, n_cases, note, swept) and ``rows``.
    """
    import pandas as pd

    out = Path(out)
    df = pd.read_parquet(out / "results.parquet")
    spec = load_sweep(out / "sweep.toml")
    rows = study_rows(df, list(spec.swept))
    failed = []
    for c in spec.cases:
        r = df[df["case_id"] == c.case_id]
        if len(r) and r["status"].iloc[0] != "ok":
            failed.append({"params": {k: v for k, v in c.params.items()
                                      if k != "render.camera.lens_matrix"},
                           "stages": c.stages, "error": str(r["error"].iloc[0])})
    return {"meta": {"date": time.strftime("%Y-%m-%d", time.gmtime()), "n_cases": len(rows),
                     "note": note, "swept": list(spec.swept), "failed": failed,
                     "not_run": len(spec.cases) - len(df)},
            "rows": rows}


def main(argv=None) -> int:
    """``python -m validation.studies.systematics OUT --json PATH [--note TEXT]``."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m validation.studies.systematics",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="the systematics sweep's --out folder")
    ap.add_argument("--json", required=True, help="where to write the study JSON")
    ap.add_argument("--note", default="", help="how it was run (machine, load)")
    args = ap.parse_args(argv)
    if not (Path(args.out) / "results.parquet").is_file():
        print(f"error: {args.out}: no results.parquet (run rollfric sweep systematics "
              f"--out {args.out} first)")
        return 2
    data = study_json(args.out, args.note)
    write_text(Path(args.json), json.dumps(data, indent=1) + "\n")
    print(render_markdown(data))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
