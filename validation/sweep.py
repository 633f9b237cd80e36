"""Sweep files: many validation cases, read into their cases (:func:`load_sweep`).

They run on Dask distributed, one tidy table row per case (:mod:`validation.sweep_run`; the
table: :mod:`validation.sweep_table`, the plots: :mod:`validation.sweep_plots`).

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

Each case's id is a hash of its full case dict (:func:`validation.case_dict.case_id`), so the same
parameters always give the same id. A finished case is written at once to
``OUT/parts/<case_id>.parquet`` (one row: the parameters, status, error, the metrics); the
combined ``OUT/results.parquet`` and ``OUT/results.csv`` are rebuilt from the parts. Running the
same sweep into the same OUT resumes: cases with a part are not run again (failed ones only with
``retry_failed``). A case that raises is recorded as failed with its error; a case whose worker
dies is re-run by Dask on another worker, and recorded as failed (KilledWorker) only when it
kills workers repeatedly.
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import itertools
import math
import tomllib
from pathlib import Path

from rollfric.errors import InputError
from rollfric.io.limits import MAX_CASES
from rollfric.setup.schema import Key, Schema, read_section
from rollfric.setup.tomlfile import read_text
from validation.case import case_from_dict
from validation.case_dict import apply_overrides, case_id, default_case_dict, merge_case
from validation.metrics import METRICS, is_metric

STAGES = ("full", "sim", "track")
DEFAULT_METRICS = ("mu_bias_rel", "mu_pipeline_bias_rel", "center_rms_px", "center_max_px")
SWEEP_KEYS = ("name", "description", "mode", "stages", "seeds", "metrics")


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
    if n > MAX_CASES:
        raise SweepError(f"{source}: {n:,} cases (grid x seeds), more than the limit of "
                         f"{MAX_CASES:,}")


# The [sweep] table's checked values (rollfric.setup.schema); name, description and metrics
# are checked by _sweep_head
SWEEP_SCHEMA = Schema(sections={"sweep": (
    Key("mode", "str", choices=("grid", "list"), hint="must be 'grid' or 'list'",
        default="grid"),
    Key("stages", "str", choices=STAGES, hint=f"must be one of {STAGES}", default="full"),
    Key("seeds", "int", sign=">0", hint="must be a positive integer", default=1),
)}, error=SweepError)


def _sweep_head(data: dict, source: str) -> dict:
    """The file's sections and its [sweep] table checked: name, description, mode, stages,
    seeds and metrics (defaults filled in)."""
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
    metrics = head.get("metrics", DEFAULT_METRICS)
    if not isinstance(name, str) or not isinstance(head.get("description", ""), str):
        raise SweepError(f"{source}: sweep.name and sweep.description must be strings")
    if not isinstance(metrics, (list, tuple)) or not all(isinstance(m, str) for m in metrics):
        raise SweepError(f"{source}: sweep.metrics must be a list of metric names")
    values = read_section(SWEEP_SCHEMA, "sweep", head, source)

    unknown_m = [m for m in metrics if not is_metric(m)]
    if unknown_m:
        raise SweepError(f"{source}: unknown metric(s) {unknown_m} in sweep.metrics (known: "
                         f"{', '.join(sorted(METRICS))}, t_<stage>_s)")
    return dict(values, name=name, description=head.get("description", ""),
                metrics=tuple(metrics))


def _sweep_combos(data: dict, head: dict, source: str) -> tuple[list[dict], list[str]]:
    """The swept keys' combinations ("dotted.key" -> value; a list's case may set its stages)
    of a grid or a list, each repeated for sweep.seeds render seeds; and the swept keys."""
    seeds, stages = head["seeds"], head["stages"]
    if head["mode"] == "grid":
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
    return combos, swept


def sweep_from_dict(data: dict, source: str = "sweep", text: str = "") -> SweepSpec:
    """The sweep a parsed sweep file describes (each case checked); SweepError naming the
    fault."""
    head = _sweep_head(data, source)
    name, stages = head["name"], head["stages"]
    combos, swept = _sweep_combos(data, head, source)
    base = merge_case(default_case_dict(), data.get("base", {}), f"{source} [base]")
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
    return SweepSpec(name=name, description=head["description"], stages=stages,
                     metrics=head["metrics"], swept=tuple(swept), cases=tuple(out), source=source,
                     text=text)


