"""A sweep's output folder: one part per finished case, the combined table, the summary and
the report page; and a finished sweep read back (its name, the cases its kept recordings make).

``OUT/parts/<case_id>.parquet`` is one case's row (the parameters, status, error, the metrics);
``OUT/results.parquet`` and ``OUT/results.csv`` are rebuilt from the parts; ``OUT/summary.md``
and ``OUT/report.html`` show them with the plots (:mod:`validation.sweep_plots`).
"""

from __future__ import annotations

import json
import math
import time
import tomllib
from pathlib import Path

import pandas as pd

from rollfric.output.atomic import replacing, write_text
from validation import html_report
from validation.case import _case_seeded_lab
from validation.case_dict import apply_overrides, case_id
from validation.sweep import DEFAULT_METRICS, SweepCase, SweepError, SweepSpec
from validation.sweep_plots import metric_axis

# -- parts and the combined table -----------------------------------------------------------

def _scalar(v):
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v)
    return v


def part_row(sc: SweepCase, outcome: dict) -> dict:
    row = {"case_id": sc.case_id, "status": outcome["status"], "error": outcome["error"],
           "worker": outcome.get("worker", ""), "wall_s": float(outcome.get("wall_s", math.nan)),
           "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    for k, v in sc.params.items():
        row[k] = _scalar(v)
    row["stages"] = sc.stages
    if sc.recording is not None:
        row["recording"] = sc.recording
    for k, v in outcome.get("metrics", {}).items():
        if k in ("case_id",):
            continue
        row[k] = _scalar(v)
    row["case_json"] = json.dumps(sc.case, sort_keys=True)
    return row


def write_part(parts_dir: Path, row: dict) -> Path:
    """One case's row as parts/<case_id>.parquet, atomically (temp file + rename)."""
    parts_dir.mkdir(parents=True, exist_ok=True)
    path = parts_dir / f"{row['case_id']}.parquet"
    with replacing(path) as tmp:
        pd.DataFrame([row]).to_parquet(tmp, index=False)
    return path


def read_parts(out: str | Path, ids: set | None = None):
    """Finished cases' rows (pandas DataFrame, one row per part; only ``ids`` if given),
    sorted by case_id."""
    parts = sorted(p for p in (Path(out) / "parts").glob("*.parquet")
                   if ids is None or p.stem in ids)
    if not parts:
        return pd.DataFrame(columns=["case_id", "status", "error"])
    frames = [pd.read_parquet(p) for p in parts]
    frames = [f for f in frames if not f.empty]
    df = pd.concat(frames, ignore_index=True, sort=False)
    return df.sort_values("case_id", kind="stable").reset_index(drop=True)


def rebuild_table(out: str | Path, spec: SweepSpec | None = None):
    """results.parquet and results.csv from the parts (atomic); returns the DataFrame."""
    out = Path(out)
    df = read_parts(out, None if spec is None else {c.case_id for c in spec.cases})
    if spec is not None and len(df):
        # this sweep's cases only, in the file's order (parts of other case ids -- an edited
        # sweep file or changed defaults -- stay in parts/ but are not this table's rows)
        order = {c.case_id: i for i, c in enumerate(spec.cases)}
        df = df[df["case_id"].isin(order)]
        df = df.assign(_o=df["case_id"].map(order)).sort_values("_o", kind="stable") \
            .drop(columns="_o").reset_index(drop=True)
    for name, write in (("results.parquet", lambda p: df.to_parquet(p, index=False)),
                        ("results.csv", lambda p: df.to_csv(p, index=False))):
        with replacing(out / name) as tmp:
            write(tmp)
    return df


def write_recordings_index(out: Path, spec: SweepSpec, df) -> None:
    rec_dir = out / "recordings"
    rows = []
    for sc in spec.cases:
        p = rec_dir / f"{sc.case_id}.zarr"
        if p.exists():
            status = df.loc[df["case_id"] == sc.case_id, "status"]
            rows.append({"case_id": sc.case_id, "recording": str(p.relative_to(out)),
                         "status": status.iloc[0] if len(status) else "",
                         **{k: _scalar(v) for k, v in sc.params.items()},
                         "case_json": json.dumps(sc.case, sort_keys=True)})
    if rows:
        with replacing(rec_dir / "index.csv") as tmp:
            pd.DataFrame(rows).to_csv(tmp, index=False)


def previous_name(out: Path) -> str | None:
    """The name of the sweep whose results OUT holds (sweep.toml, else a part), if known."""
    try:
        data = tomllib.loads((out / "sweep.toml").read_text(encoding="utf-8"))
        name = data.get("sweep", {}).get("name")
        if isinstance(name, str):
            return name
    except (OSError, ValueError):
        pass
    for p in sorted((out / "parts").glob("*.parquet"))[:1]:
        try:
            row = pd.read_parquet(p).iloc[0]
            return json.loads(row["case_json"]).get("name")
        except Exception:  # an unreadable part says nothing about the name
            return None
    return None


# -- re-measuring a finished sweep's kept recordings ------------------------------------------

def recorded_sweep(src: str | Path, overrides: dict | None = None) -> SweepSpec:
    """The cases of a sweep run with ``--keep-recordings`` into ``src``, to be measured again
    from their recordings with the current code (no render): every case whose part is "ok"
    and whose recording ``src/recordings/<case_id>.zarr`` exists (a sweep still running gives
    the cases finished so far).

    Parameters
    ----------
    src : str or Path
        The recorded sweep's output folder.
    overrides : dict, optional
        Dotted ``measure.*`` keys set in every case: how it is measured now (e.g.
        ``{"measure.oracle": True}``: the setup from the recording). Any other key would
        change what was rendered and is refused. The case's lab draws (``lab.seed =
        "case"``) are resolved from the recorded case first, so that they stay the
        recording's. The cases' ids are then their own; ``recording`` names the one measured.

    Returns
    -------
    SweepSpec
        The recorded sweep's name, description and metrics; one case per recording, each with
        its ``recording`` path, in the recorded sweep's order.

    Raises
    ------
    SweepError
        ``src`` holds no sweep with kept recordings, or an override that is not ``measure.*``.
    """
    src = Path(src)
    overrides = dict(overrides or {})
    bad = sorted(k for k in overrides if not k.startswith("measure."))
    if bad:
        raise SweepError(f"--set {', '.join(bad)}: re-measuring recordings takes only "
                         "measure.* keys (the others would change what was rendered)")
    text, head = "", {}
    if (src / "sweep.toml").is_file():  # a sweep run from a dict (the API) writes none
        try:
            text = (src / "sweep.toml").read_text(encoding="utf-8")
            head = tomllib.loads(text).get("sweep", {})
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise SweepError(f"--from-recordings {src}: unreadable sweep.toml ({exc})") \
                from None
    parts = read_parts(src)
    rec_dir = src / "recordings"
    if not len(parts) or not rec_dir.is_dir():
        raise SweepError(f"--from-recordings {src}: no finished cases with kept recordings "
                         "(run the sweep with --keep-recordings)")
    name = head.get("name") or previous_name(src) or src.name
    metrics = tuple(head.get("metrics", DEFAULT_METRICS))
    swept: list = []
    cases, seen = [], set()
    for _, row in parts.iterrows():
        rec = rec_dir / f"{row['case_id']}.zarr"
        if row["status"] != "ok" or not rec.is_dir():
            continue
        recorded = json.loads(row["case_json"])
        if "stages" in row and isinstance(row["stages"], str) and row["stages"] != "full":
            continue  # not rendered
        d = dict(recorded)
        if isinstance(d.get("lab"), dict):
            d["lab"] = _case_seeded_lab(d)  # the recording's as-built draws, whatever follows
        d = apply_overrides(d, overrides) if overrides else recorded
        cid = case_id(d)
        if cid in seen:
            continue
        seen.add(cid)
        params = {}
        for k in row.index:
            if "." in k and k not in ("case_json",) and not _isnan(row[k]):
                params[k] = row[k]
                if k not in swept:
                    swept.append(k)
        params.update(overrides)
        cases.append(SweepCase(case_id=cid, params=params, case=d, stages="full",
                               recording=str(rec.resolve())))
    if not cases:
        raise SweepError(f"--from-recordings {src}: no finished cases with kept recordings")
    swept += [k for k in overrides if k not in swept]
    note = f"\n# re-measured from the recordings of {src.resolve()}" + "".join(
        f"\n# with --set {k}={v!r}" for k, v in overrides.items()) + "\n"
    return SweepSpec(name=name, description=head.get("description", ""), stages="full",
                     metrics=metrics, swept=tuple(swept), cases=tuple(cases),
                     source=str(src / "sweep.toml"), text=text + note)


def _isnan(v) -> bool:
    return isinstance(v, float) and math.isnan(v)


# -- the summary and the report page ----------------------------------------------------------

def write_summary(df, spec: SweepSpec, out: Path, plots: list, notes=()) -> Path:
    """OUT/summary.md: what was swept, one line per case (parameters, status, the plotted
    metrics), the plots, and ``notes`` (e.g. why a plot is missing)."""
    def fmt(v):
        if isinstance(v, float):
            return "" if math.isnan(v) else f"{v:.4g}"
        return str(v)

    cols = [k for k in spec.swept if k in df.columns]
    mets = [m for m in spec.metrics if m in df.columns]
    axes = {m: metric_axis(m) for m in mets}  # in the unit the CLI prints: %, px, deg
    lines = [f"# sweep {spec.name}", "", spec.description, "",
             f"{len(spec.cases)} case(s) from {spec.source or 'a sweep dict'}, stages "
             f"{spec.stages}; {int((df['status'] == 'ok').sum()) if len(df) else 0} ok, "
             f"{int((df['status'] != 'ok').sum()) if len(df) else 0} failed, "
             f"{len(spec.cases) - len(df)} not run. Table: results.parquet, results.csv.", "",
             "| case_id | " + " | ".join(cols + ["status"] + [axes[m][1] for m in mets]) + " |",
             "|" + "---|" * (len(cols) + len(mets) + 2)]

    def scaled(v, m):
        return v * axes[m][0] if isinstance(v, float) else v

    for _, r in df.iterrows():
        lines.append("| " + " | ".join([str(r["case_id"])] + [fmt(r[c]) for c in cols]
                                       + [str(r["status"])]
                                       + [fmt(scaled(r[m], m)) for m in mets]) + " |")
    failed = df[df["status"] != "ok"] if len(df) else df
    if len(failed):
        lines += ["", "## failed", ""]
        lines += [f"- {r['case_id']}: {r['error']}" for _, r in failed.iterrows()]
    if plots:
        lines += ["", "## plots", ""]
        lines += [f"![{p.stem}](plots/{p.name})" for p in plots]
    if notes:
        lines += ["", "## notes", ""]
        lines += [f"- {n}" for n in notes]
    return write_text(out / "summary.md", "\n".join(lines) + "\n")


def sweep_verdict(df) -> tuple[str, bool]:
    """The sweep's answer in words, and whether it is the hoped-for one: how many cases ran,
    and of those with an uncertainty budget how many hold the truth within U(mu)."""
    n = len(df)
    ok = df[df["status"] == "ok"] if n else df
    failed = n - len(ok)
    words = f"{len(ok)} of {n} case(s) ran" + (f", {failed} failed" if failed else "")
    good = failed == 0
    if len(ok) and "within_U" in ok.columns and ok["within_U"].notna().any():
        w = ok["within_U"].dropna().astype(bool)
        words += (f"; the truth is within U(mu) (k = 2) in {int(w.sum())} of {len(w)} "
                  f"({100 * w.mean():.0f} %; about 95 % expected)")
        good = good and bool(w.mean() >= 0.9 or len(w) < 10 and w.all())
    return words + ".", good


def write_html(df, spec: SweepSpec, out: Path, plots: list) -> Path:
    """OUT/report.html: the verdict, the summary table and the plots on one page."""
    words, good = sweep_verdict(df)
    table = (out / "summary.md").read_text() if (out / "summary.md").is_file() else ""
    figures = [(p, f"Each metric against {p.stem.replace('_', '.')}: one point a case"
                   + ("; error bars and the grey band are U(mu), k = 2" if "U_mu" in df.columns
                      else "")) for p in plots]
    page = html_report.render(f"rollfric sweep: {spec.name}", words, good, table, figures)
    return write_text(out / "report.html", page)
