"""Sweeps: many validation cases on Dask distributed, one tidy table row per case.

A sweep file (TOML)::

    [sweep]
    name = "noise"
    description = "mu bias and centre error vs read noise and shot noise"
    mode = "grid"              # grid: every combination of [grid]; list: the [[cases]] tables
    stages = "full"            # full: sim -> synth -> rollfric; sim: simulate + fit only;
                               # track: rollfric on the exact projection (validation.track_level)
    seeds = 2                  # each case repeated with render.seed = 0 .. seeds-1
    metrics = ["mu_bias_rel", "center_rms_px"]   # what the plots show

    [base]                     # a case (validation.case), merged over the built-in default
    scenario.motion = { seconds = 1.0 }
    render = { noise = "realistic" }

    [grid]                     # dotted case keys -> values
    "render.sensor.read_noise" = [0.0, 8.0, 20.0, 40.0]
    "render.sensor.shot_noise" = [false, true]

    [[cases]]                  # (mode = "list") one table per case
    "render.lighting" = "dim"
    stages = "full"            # (optional) this case's stages instead of sweep.stages (with
                               # sweep.stages = "track", a case setting a key the track level
                               # does not represent, validation.track_level.EXACT_KEYS, is full)

Each case's id is a hash of its full case dict (:func:`validation.case.case_id`), so the same
parameters always give the same id. A finished case is written at once to
``OUT/parts/<case_id>.parquet`` (one row: the parameters, status, error, the metrics); the
combined ``OUT/results.parquet`` and ``OUT/results.csv`` are rebuilt from the parts. Running the
same sweep into the same OUT resumes: cases with a part are not run again (failed ones only with
``retry_failed``). A case that raises is recorded as failed with its error; a case whose worker
dies is re-run by Dask on another worker, and recorded as failed (KilledWorker) only when it
kills workers repeatedly.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.resources
import itertools
import json
import logging
import math
import os
import socket
import sys
import time
import tomllib
import traceback
from pathlib import Path

from rollfric.errors import InputError
from rollfric.output.atomic import replacing, write_text
from validation.case import (
    apply_overrides,
    case_from_dict,
    case_id,
    default_case_dict,
    merge_case,
)

STAGES = ("full", "sim", "track")
DEFAULT_METRICS = ("mu_bias_rel", "mu_pipeline_bias_rel", "center_rms_px", "center_max_px")
SWEEP_KEYS = ("name", "description", "mode", "stages", "seeds", "metrics")
REBUILD_EVERY_S = 20.0


class SweepError(InputError):
    """A sweep file that cannot be run (the message names the bad input)."""


@dataclasses.dataclass(frozen=True)
class SweepCase:
    case_id: str
    params: dict  # swept dotted key -> value (includes render.seed when seeds > 1)
    case: dict  # the full case dict
    stages: str = "full"  # what runs: full, sim or track (sweep.stages or the case's own)
    recording: str | None = None  # re-measure this existing recording (recorded_sweep)


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    name: str
    description: str
    stages: str
    metrics: tuple
    swept: tuple  # swept dotted keys, in file order
    cases: tuple  # SweepCase
    source: str = ""
    text: str = ""  # the sweep file's text (copied into OUT)


# -- reading sweep files --------------------------------------------------------------------

def shipped_sweeps() -> list[tuple[str, str, str]]:
    """(name, path, description) of the example sweeps shipped in validation/sweeps/."""
    out = []
    root = importlib.resources.files("validation") / "sweeps"
    for entry in sorted(root.iterdir(), key=lambda e: e.name):
        if entry.name.endswith(".toml"):
            data = tomllib.loads(entry.read_text())
            out.append((entry.name[:-5], str(entry),
                        data.get("sweep", {}).get("description", "")))
    return out


def _find_sweep(path_or_name: str | Path) -> Path:
    p = Path(path_or_name)
    if p.is_file():
        return p
    for name, path, _ in shipped_sweeps():
        if name == str(path_or_name):
            return Path(path)
    raise SweepError(f"sweep file not found: {path_or_name} (nor a shipped study: "
                     f"{', '.join(n for n, _, _ in shipped_sweeps())})")


def load_sweep(path_or_name: str | Path, overrides: dict | None = None) -> SweepSpec:
    """Read a sweep file (or a shipped study by name) and expand its cases.

    Parameters
    ----------
    path_or_name : str or Path
        A sweep TOML file, or the name of a shipped study.
    overrides : dict, optional
        Dotted case keys set in every case's ``[base]`` (``rollfric sweep --set``), e.g.
        ``{"measure.oracle": True}``: the same study measured otherwise. They change the cases'
        ids, and are recorded in the text copied to OUT/sweep.toml.

    Returns
    -------
    SweepSpec
    """
    from rollfric.setup.tomlfile import read_text

    path = _find_sweep(path_or_name)
    text = read_text(path, "sweep", SweepError)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SweepError(f"{path}: not valid TOML: {exc}") from None
    if overrides:
        if not isinstance(data.get("base", {}), dict):
            raise SweepError(f"{path}: [base] must be a table")
        data = {**data, "base": apply_overrides(data.get("base", {}), overrides)}
        text += "".join(f"\n# run with --set {k}={v!r}" for k, v in overrides.items()) + "\n"
    return sweep_from_dict(data, source=str(path), text=text)


def _flatten_keys(table: dict, prefix: str = "") -> dict:
    """{"render": {"sensor": {"read_noise": [..]}}} -> {"render.sensor.read_noise": [..]}."""
    out = {}
    for k, v in table.items():
        key = f"{prefix}.{k}" if prefix else k
        if isinstance(v, dict):
            out.update(_flatten_keys(v, key))
        else:
            out[key] = v
    return out


def _check_count(n: int, source: str) -> None:
    """SweepError when a sweep would hold more than MAX_CASES cases (checked before they are
    made: a typo of seeds = 100000000 must not fill the memory, even for --dry-run)."""
    from rollfric.io.limits import MAX_CASES

    if n > MAX_CASES:
        raise SweepError(f"{source}: {n:,} cases (grid x seeds), more than the limit of "
                         f"{MAX_CASES:,}")


def sweep_from_dict(data: dict, source: str = "sweep", text: str = "") -> SweepSpec:
    unknown = sorted(set(data) - {"sweep", "base", "grid", "cases"})
    if unknown:
        raise SweepError(f"{source}: unknown section(s) {unknown} (sweep, base, grid, cases)")
    for section in ("sweep", "base", "grid"):
        if not isinstance(data.get(section, {}), dict):
            raise SweepError(f"{source}: [{section}] must be a table")
    head = data.get("sweep", {})
    bad = sorted(set(head) - set(SWEEP_KEYS))
    if bad:
        raise SweepError(f"{source}: unknown key(s) sweep.{bad} (known: {', '.join(SWEEP_KEYS)})")
    name = head.get("name", Path(source).stem)
    mode = head.get("mode", "grid")
    stages = head.get("stages", "full")
    seeds = head.get("seeds", 1)
    metrics = head.get("metrics", DEFAULT_METRICS)
    if not isinstance(name, str) or not isinstance(head.get("description", ""), str):
        raise SweepError(f"{source}: sweep.name and sweep.description must be strings")
    if not isinstance(metrics, (list, tuple)) or not all(isinstance(m, str) for m in metrics):
        raise SweepError(f"{source}: sweep.metrics must be a list of metric names")
    metrics = tuple(metrics)
    if not isinstance(mode, str) or mode not in ("grid", "list"):
        raise SweepError(f"{source}: sweep.mode must be 'grid' or 'list', got {mode!r}")
    if not isinstance(stages, str) or stages not in STAGES:
        raise SweepError(f"{source}: sweep.stages must be one of {STAGES}, got {stages!r}")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise SweepError(f"{source}: sweep.seeds must be a positive integer, got {seeds!r}")
    from validation.e2e import METRICS, is_metric

    unknown_m = [m for m in metrics if not is_metric(m)]
    if unknown_m:
        raise SweepError(f"{source}: unknown metric(s) {unknown_m} in sweep.metrics (known: "
                         f"{', '.join(sorted(METRICS))}, t_<stage>_s)")
    base = merge_case(default_case_dict(), data.get("base", {}), f"{source} [base]")
    combos: list[dict] = []
    if mode == "grid":
        grid = _flatten_keys(data.get("grid", {}))
        if "cases" in data:
            raise SweepError(f"{source}: [[cases]] given but sweep.mode is 'grid'")
        for k, v in grid.items():
            if not isinstance(v, list) or not v:
                raise SweepError(f"{source}: grid.{k} must be a non-empty list of values")
        _check_count(math.prod(len(v) for v in grid.values()) * seeds, source)
        keys = list(grid)
        combos = [dict(zip(keys, vals, strict=True))
                  for vals in itertools.product(*(grid[k] for k in keys))]
        swept = keys
    else:
        if "grid" in data:
            raise SweepError(f"{source}: [grid] given but sweep.mode is 'list'")
        cases = data.get("cases", [])
        if not isinstance(cases, list) or not cases \
                or not all(isinstance(c, dict) for c in cases):
            raise SweepError(f"{source}: mode 'list' needs [[cases]] tables")
        _check_count(len(cases) * seeds, source)
        combos = [_flatten_keys(c) for c in cases]
        for c in combos:
            st = c.get("stages", stages)
            if not isinstance(st, str) or st not in STAGES:
                raise SweepError(f"{source}: a case's stages must be one of {STAGES}, "
                                 f"got {st!r}")
        swept = list(dict.fromkeys(k for c in combos for k in c if k != "stages"))
    if seeds > 1:
        if "render.seed" in swept:
            raise SweepError(f"{source}: sweep.seeds and a swept render.seed exclude each other")
        combos = [dict(c, **{"render.seed": s}) for c in combos for s in range(seeds)]
        swept = [*swept, "render.seed"]
    out, seen = [], set()
    for params in combos:
        params = dict(params)
        st = params.pop("stages", None)
        if st is None:
            st = stages
            if st == "track":  # a key the track level does not represent: rendered
                from validation.track_level import exact_at_track_level

                if not exact_at_track_level(params):
                    st = "full"
        d = apply_overrides(base, params)
        d["name"] = name
        try:
            case_from_dict(d, source=f"{source} case {params}")
        except InputError as exc:
            raise SweepError(str(exc)) from None
        # a track-level case measures otherwise than the full one: its own id
        cid = case_id({**d, "stages": st}) if st == "track" else case_id(d)
        if cid in seen:
            continue  # the same case twice (e.g. a list repeating itself)
        seen.add(cid)
        out.append(SweepCase(case_id=cid, params=params, case=d, stages=st))
    return SweepSpec(name=name, description=head.get("description", ""), stages=stages,
                     metrics=metrics, swept=tuple(swept), cases=tuple(out), source=source,
                     text=text)


# -- running one case (on a worker) ---------------------------------------------------------

def run_one(case_dict: dict, stages: str = "full", recording: str | None = None,
            case_fn=None, remeasure: bool = False) -> dict:
    """What a worker runs for one case: {"status", "error", "metrics", "worker", "wall_s"}.

    ``recording``: where the full case keeps its recording; with ``remeasure`` the existing
    recording measured again instead of rendered (:func:`validation.e2e.remeasure_case`).

    An exception in the case is caught and returned as status "failed" with its traceback's
    last line as the error; a dying process is left to Dask (the case is re-run elsewhere).
    """
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from validation import e2e

    t0 = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    try:
        if case_fn is not None:
            metrics = case_fn(case_dict)
        elif remeasure:
            metrics = e2e.remeasure_case(case_dict, recording).metrics
        elif stages == "sim":
            metrics = e2e.sim_only_case(case_dict)
        elif stages == "track":
            from validation.track_level import run_track_case

            metrics = run_track_case(case_dict)
        else:
            metrics = e2e.run_case(case_dict, recording=recording, render_workers=1,
                                   render_threads=1).metrics
        return {"status": "ok", "error": "", "metrics": metrics, "worker": worker,
                "wall_s": time.perf_counter() - t0}
    except Exception as exc:  # recorded, not raised: one bad case must not stop the sweep
        tb = traceback.format_exc(limit=6)
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}", "traceback": tb,
                "metrics": {}, "worker": worker, "wall_s": time.perf_counter() - t0}


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
    from validation.case import _case_seeded_lab

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
    name = head.get("name") or _previous_name(src) or src.name
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


# -- parts and the combined table -----------------------------------------------------------

def _scalar(v):
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v)
    return v


def _row(sc: SweepCase, outcome: dict) -> dict:
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
    import pandas as pd

    parts_dir.mkdir(parents=True, exist_ok=True)
    path = parts_dir / f"{row['case_id']}.parquet"
    with replacing(path) as tmp:
        pd.DataFrame([row]).to_parquet(tmp, index=False)
    return path


def read_parts(out: str | Path, ids: set | None = None):
    """Finished cases' rows (pandas DataFrame, one row per part; only ``ids`` if given),
    sorted by case_id."""
    import pandas as pd

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


def _write_recordings_index(out: Path, spec: SweepSpec, df) -> None:
    import pandas as pd

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


# -- the output folder ------------------------------------------------------------------------

# what a sweep writes into OUT (rollfric.output.folder: --overwrite replaces only these)
OUTPUTS = {"parts": "folder", "plots": "folder", "recordings": "folder", "sweep.toml": "file",
           "results.parquet": "file", "results.csv": "file", "summary.md": "file",
           "report.html": "file"}


def _previous_name(out: Path) -> str | None:
    """The name of the sweep whose results OUT holds (sweep.toml, else a part), if known."""
    try:
        data = tomllib.loads((out / "sweep.toml").read_text(encoding="utf-8"))
        name = data.get("sweep", {}).get("name")
        if isinstance(name, str):
            return name
    except (OSError, ValueError):
        pass
    import pandas as pd

    for p in sorted((out / "parts").glob("*.parquet"))[:1]:
        try:
            row = pd.read_parquet(p).iloc[0]
            return json.loads(row["case_json"]).get("name")
        except Exception:  # an unreadable part says nothing about the name
            return None
    return None


def check_out(out: str | Path, spec: SweepSpec, *, overwrite: bool = False) -> str:
    """What running ``spec`` into OUT means, checked before any work: ``"new"`` (absent or
    empty), ``"resume"`` (OUT holds this sweep's results: the cases not done yet are run),
    ``"fresh"`` (``overwrite``: the sweep's own outputs in OUT are removed first, other files
    stay). Refused (SweepError, exit 2): a file; a folder holding another sweep's results or
    anything else, without ``overwrite``."""
    from rollfric.output.atomic import is_leftover
    from rollfric.output.folder import check_folder

    out = Path(out)
    check_folder(out, OUTPUTS, overwrite=True, command="sweep")  # kinds, permissions
    if not out.is_dir() or all(is_leftover(p) for p in out.iterdir()):
        return "new"
    if overwrite:
        return "fresh"
    if (out / "parts").is_dir() or (out / "sweep.toml").is_file():
        prev = _previous_name(out)
        if prev is not None and prev != spec.name:
            raise SweepError(f"--out {out} holds the results of sweep {prev!r}, not "
                             f"{spec.name!r}: give another folder, or --overwrite to start "
                             "afresh there")
        return "resume"
    raise SweepError(f"--out {out} exists and is not empty (and holds no sweep results); "
                     "--overwrite writes the sweep's own files there and leaves the others alone")


def _remove_own_outputs(out: Path) -> None:
    """Start afresh: remove the sweep's own outputs from OUT (parts, tables, summary, plots,
    recordings, sweep.toml); files that are not the sweep's stay."""
    import re

    from rollfric.output.atomic import remove_path as _remove

    own_part = re.compile(r"^[0-9a-f]{12}\.(parquet|zarr)$")
    for sub, keep_names in (("parts", ()), ("recordings", ("index.csv",)), ("plots", ())):
        d = out / sub
        if not d.is_dir():
            continue
        for p in d.iterdir():
            if own_part.match(p.name) or p.name in keep_names \
                    or (sub == "plots" and p.suffix == ".png"):
                _remove(p)
        with contextlib.suppress(OSError):
            d.rmdir()  # only if empty
    for name in ("sweep.toml", "results.parquet", "results.csv", "summary.md", "report.html"):
        _remove(out / name)


# -- the sweep --------------------------------------------------------------------------------

@dataclasses.dataclass
class SweepSummary:
    out: Path
    n_cases: int
    n_done_before: int
    n_run: int
    n_ok: int
    n_failed: int
    seconds: float
    plots: list

    def text(self) -> str:
        lines = [f"sweep: {self.n_cases} case(s), {self.n_done_before} already done, "
                 f"{self.n_run} run now in {self.seconds:.1f} s; {self.n_ok} ok, "
                 f"{self.n_failed} failed",
                 f"results: {self.out / 'results.parquet'} and results.csv"]
        if self.plots:
            lines.append(f"plots:   {self.out / 'plots'}/ ({len(self.plots)} files)")
        lines.append(f"summary: {self.out / 'summary.md'}")
        lines.append(f"report:  {self.out / 'report.html'} (open it in a browser)")
        return "\n".join(lines)


def _start_client(scheduler: str | None, n_workers: int):
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler), None
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")  # inherited by the worker processes
    cluster = LocalCluster(n_workers=max(1, int(n_workers)), threads_per_worker=1,
                           processes=True, dashboard_address=":0",
                           silence_logs=logging.ERROR)
    return Client(cluster), cluster


def run_sweep(spec: SweepSpec, out: str | Path, *, scheduler: str | None = None,
              n_workers: int = 2, keep_recordings: bool = False, retry_failed: bool = False,
              progress: bool = True, case_fn=None, client=None,
              overwrite: bool = False) -> SweepSummary:
    """Run the sweep's cases not yet in OUT/parts on Dask; rebuild the table; plot.

    ``case_fn(case_dict) -> metrics dict`` replaces the end-to-end case (for cheap sweeps
    and tests); ``client``: an existing ``distributed.Client`` to use (else ``scheduler``,
    else a local cluster of ``n_workers`` processes, one thread each). OUT is checked first
    (:func:`check_out`): a folder of this sweep is resumed; ``overwrite`` starts afresh.
    """
    import pandas as pd
    from distributed import as_completed
    from tqdm import tqdm

    from rollfric.output.atomic import remove_leftovers

    t0 = time.perf_counter()
    out = Path(out)
    if check_out(out, spec, overwrite=overwrite) == "fresh":
        _remove_own_outputs(out)
    out.mkdir(parents=True, exist_ok=True)
    parts_dir = out / "parts"
    parts_dir.mkdir(exist_ok=True)
    for d in (out, parts_dir, out / "plots", out / "recordings"):
        remove_leftovers(d)
    if spec.text:
        write_text(out / "sweep.toml", spec.text)
    done = read_parts(out, {c.case_id for c in spec.cases})
    status = dict(zip(done["case_id"], done["status"], strict=True)) if len(done) else {}
    todo = [c for c in spec.cases
            if c.case_id not in status or (retry_failed and status[c.case_id] != "ok")]
    n_before = len(spec.cases) - len(todo)
    n_ok = n_failed = 0
    own = None
    if todo:
        if client is None:
            client, own = _start_client(scheduler, n_workers)
            own = (client, own)
        try:
            futures = {}
            for sc in todo:
                rec = sc.recording
                if keep_recordings and rec is None:
                    (out / "recordings").mkdir(exist_ok=True)
                    rec = str((out / "recordings" / f"{sc.case_id}.zarr").resolve())
                fut = client.submit(run_one, sc.case, sc.stages, rec, case_fn,
                                    sc.recording is not None,
                                    key=f"case-{spec.name}-{sc.case_id}", pure=False)
                futures[fut] = sc
            bar = tqdm(total=len(spec.cases), initial=n_before, unit="case",
                       desc=f"sweep {spec.name}", disable=not progress)
            last = time.perf_counter()
            for fut in as_completed(list(futures)):
                sc = futures[fut]
                try:
                    outcome = fut.result()
                except Exception as exc:  # KilledWorker, lost connection, unpicklable result
                    outcome = {"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                               "metrics": {}, "worker": "", "wall_s": math.nan}
                write_part(parts_dir, _row(sc, outcome))
                if outcome["status"] == "ok":
                    n_ok += 1
                else:
                    n_failed += 1
                    bar.write(f"case {sc.case_id} failed: {outcome['error']}", file=sys.stderr)
                bar.update(1)
                fut.release()
                if time.perf_counter() - last > REBUILD_EVERY_S:
                    rebuild_table(out, spec)
                    last = time.perf_counter()
            bar.close()
        finally:
            if own is not None:
                own[0].close()
                if own[1] is not None:
                    own[1].close()
    df = rebuild_table(out, spec)
    if keep_recordings and not any(c.recording for c in spec.cases):
        _write_recordings_index(out, spec, df)
    n_failed_total = int((df["status"] != "ok").sum()) if len(df) else 0
    notes = []
    try:
        plots = plot_sweep(df, spec, out / "plots") if len(df) else []
    except Exception as exc:  # the table and the summary are written whatever the plots do
        plots = []
        notes.append(f"the plots could not be drawn: {type(exc).__name__}: {exc}")
    write_summary(df, spec, out, plots, notes=notes)
    write_html(df, spec, out, plots)
    _ = pd
    return SweepSummary(out=out, n_cases=len(spec.cases), n_done_before=n_before,
                        n_run=len(todo), n_ok=n_ok, n_failed=n_failed_total,
                        seconds=time.perf_counter() - t0, plots=plots)


def write_summary(df, spec: SweepSpec, out: Path, plots: list, notes=()) -> Path:
    """OUT/summary.md: what was swept, one line per case (parameters, status, the plotted
    metrics), the plots, and ``notes`` (e.g. why a plot is missing)."""
    import math as _m

    def fmt(v):
        if isinstance(v, float):
            return "" if _m.isnan(v) else f"{v:.4g}"
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
    from validation import html_report

    words, good = sweep_verdict(df)
    table = (out / "summary.md").read_text() if (out / "summary.md").is_file() else ""
    figures = [(p, f"Each metric against {p.stem.replace('_', '.')}: one point a case"
                   + ("; error bars and the grey band are U(mu), k = 2" if "U_mu" in df.columns
                      else "")) for p in plots]
    page = html_report.render(f"rollfric sweep: {spec.name}", words, good, table, figures)
    return write_text(out / "report.html", page)


# -- plots ------------------------------------------------------------------------------------

# what a metric is called on a plot, by name (the rest: its name without the unit suffix)
METRIC_NAMES = {
    "mu_bias_rel": "bias in mu",
    "mu_pipeline_bias_rel": "bias in mu from the camera, locator and fit",
    "mu_engine_bias_rel": "bias in mu of the engine",
    "center_rms_px": "centre error, rms",
    "center_max_px": "centre error, largest",
    "theta_rms_rad": "angle error, rms",
    "theta_max_rad": "angle error, largest",
    "found_fraction": "frames located",
}


def metric_axis(name: str) -> tuple[float, str]:
    """(scale, label) that shows metric ``name`` in the unit a user reads: a relative error
    or a fraction in percent, radians in degrees, pixels as pixels."""
    label = METRIC_NAMES.get(name, name.replace("_", " "))
    if name.endswith("_rel") or name.endswith("fraction"):
        return 100.0, f"{label} (%)"
    if name.endswith("_rad"):
        return 180.0 / math.pi, f"{label.removesuffix(' rad')} (deg)"
    if name.endswith("_px"):
        return 1.0, f"{label.removesuffix(' px')} (px)"
    if name.endswith("_s"):
        return 1.0, f"{label.removesuffix(' s')} (s)"
    return 1.0, label


def _distinct_metrics(ok, metrics: list[str]) -> tuple[list[str], dict]:
    """The metrics with a panel of their own, and {dropped: kept} for those whose column
    equals an earlier one's in every case (on an exact engine the pipeline's bias is the
    whole bias: one panel, not two identical ones)."""
    import numpy as np

    kept, same = [], {}
    for m in metrics:
        v = ok[m].to_numpy(float)
        twin = next((k for k in kept if np.allclose(ok[k].to_numpy(float), v, rtol=0,
                                                     atol=1e-15, equal_nan=True)), None)
        if twin is None:
            kept.append(m)
        else:
            same[m] = twin
    return kept, same


def plot_sweep(df, spec: SweepSpec, plot_dir: Path) -> list[Path]:
    """For every swept key x: one panel per metric against x, in the metric's unit.

    Every case is a point; a relative bias in mu carries its case's expanded uncertainty
    U(mu) (k = 2) as an error bar, with the median U as a grey band about zero (the target:
    a bias inside it is within what the measurement claims). The mean over repeats is
    joined by a line when x is a number; categories (a lighting preset, a renderer) are
    points only. The other swept keys are colours.
    """
    import numpy as np
    from matplotlib.figure import Figure  # no pyplot: no backend, no global figure state

    ok = df[df["status"] == "ok"]
    if ok.empty:
        return []
    plot_dir.mkdir(parents=True, exist_ok=True)
    written = []
    keys = [k for k in spec.swept if k in ok.columns and k != "render.seed"]
    metrics, same = _distinct_metrics(ok, [m for m in spec.metrics if m in ok.columns])
    has_U = {"U_mu", "mu_true"} <= set(ok.columns)

    def determines(a, b):  # every value of a comes with one value of b (where both are set)
        both = ok[ok[a].notna() & ok[b].notna()]
        return not both.empty and bool((both.groupby(a)[b].nunique() <= 1).all())

    plotted: list = []
    for x in keys:
        if any(determines(x, k) and determines(k, x) for k in plotted):
            continue  # co-varies one to one with a key already plotted (a list sweep)
        plotted.append(x)
        # the cases that set x (in a list sweep a case may leave a key at the base's value)
        sub = ok[ok[x].notna()]
        # colours only for keys that vary among them, independently of x
        others = [k for k in keys if k != x and not determines(x, k)
                  and sub[k].nunique(dropna=False) > 1]
        if not metrics or sub.empty:
            continue
        fig = Figure(figsize=(8, 2.6 * len(metrics) + 0.8))
        axes = fig.subplots(len(metrics), 1, squeeze=False, sharex=True)
        xs_all = list(dict.fromkeys(sub[x].tolist()))
        numeric = all(isinstance(v, (int, float, np.number)) and not isinstance(v, bool)
                      for v in xs_all)
        pos = ({v: float(v) for v in xs_all} if numeric
               else {v: float(i) for i, v in enumerate(xs_all)})
        span = (max(pos.values()) - min(pos.values())) or 1.0
        groups = list(sub.groupby(others, dropna=False)) if others else [((), sub)]
        for ax, met in zip(axes[:, 0], metrics, strict=True):
            scale, ylabel = metric_axis(met)
            with_U = has_U and met.startswith("mu_") and met.endswith("bias_rel")
            for j, (gkey, g) in enumerate(groups):
                gkey = gkey if isinstance(gkey, tuple) else (gkey,)
                label = ", ".join(f"{k} = {v}" for k, v in zip(others, gkey, strict=True))
                # repeats side by side, not on top of each other
                shift = (j - (len(groups) - 1) / 2) * 0.015 * span
                px = np.array([pos[v] for v in g[x]]) + shift
                y = scale * g[met].to_numpy(float)
                yerr = (scale * g["U_mu"].to_numpy(float) / g["mu_true"].to_numpy(float)
                        if with_U else None)
                line = ax.errorbar(px, y, yerr=yerr, fmt="o", ms=4, capsize=2, lw=0.8,
                                   label=label or None)
                if numeric:
                    mean = g.groupby(x)[met].mean().reindex([v for v in xs_all
                                                              if v in set(g[x])])
                    ax.plot([pos[v] + shift for v in mean.index], scale * mean.to_numpy(float),
                            "-", lw=1, color=line[0].get_color())
            if with_U:
                band = float(np.nanmedian(scale * sub["U_mu"] / sub["mu_true"]))
                ax.axhspan(-band, band, color="0.85", zorder=0,
                           label=f"median U(mu), k = 2: +-{band:.2g} %")
                ax.axhline(0, color="k", lw=0.7)
            elif np.nanmin(sub[met].to_numpy(float)) >= 0:
                ax.set_ylim(bottom=0)  # a small spread is not drawn as a cliff
            ax.set_ylabel(ylabel, fontsize=9)
            ax.grid(alpha=0.3)
            twins = [d for d, k in same.items() if k == met]
            title = METRIC_NAMES.get(met, met) + (
                f" (the same as {', '.join(twins)} here)" if twins else "")
            ax.set_title(title, fontsize=9)
            handles, _ = ax.get_legend_handles_labels()
            if handles and len(groups) <= 12:
                ax.legend(fontsize=7, loc="best")
        axes[-1, 0].set_xlabel(x)
        if not numeric:
            axes[-1, 0].set_xticks(list(pos.values()), [str(v) for v in pos], rotation=20)
        fig.suptitle(f"sweep {spec.name}: against {x}", fontsize=10)
        fig.tight_layout()
        path = plot_dir / f"{x.replace('.', '_')}.png"
        with replacing(path) as tmp:
            fig.savefig(tmp, dpi=100)
        written.append(path)
    return written
