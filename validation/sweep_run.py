"""Running a sweep: its cases on Dask distributed, each written as it finishes, resumable.

:func:`run_sweep` checks OUT (:func:`check_out`: new, resumed, or afresh with ``overwrite``),
submits the cases not done yet (:func:`run_one` on a worker), writes each one's part and
rebuilds the table (:mod:`validation.sweep_table`), then draws the plots
(:mod:`validation.sweep_plots`), the summary and the report page.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import os
import re
import socket
import sys
import time
import traceback
from pathlib import Path

from rollfric.output.atomic import is_leftover, remove_leftovers, remove_path, write_text
from rollfric.output.folder import check_folder
from validation import e2e
from validation.sweep import SweepError, SweepSpec
from validation.sweep_plots import plot_sweep
from validation.sweep_table import (
    part_row,
    previous_name,
    read_parts,
    rebuild_table,
    write_html,
    write_part,
    write_recordings_index,
    write_summary,
)
from validation.track_level import run_track_case

REBUILD_EVERY_S = 20.0

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


# -- the output folder ------------------------------------------------------------------------

# what a sweep writes into OUT (rollfric.output.folder: --overwrite replaces only these)
OUTPUTS = {"parts": "folder", "plots": "folder", "recordings": "folder", "sweep.toml": "file",
           "results.parquet": "file", "results.csv": "file", "summary.md": "file",
           "report.html": "file"}


def check_out(out: str | Path, spec: SweepSpec, *, overwrite: bool = False) -> str:
    """What running ``spec`` into OUT means, checked before any work: ``"new"`` (absent or
    empty), ``"resume"`` (OUT holds this sweep's results: the cases not done yet are run),
    ``"fresh"`` (``overwrite``: the sweep's own outputs in OUT are removed first, other files
    stay). Refused (SweepError, exit 2): a file; a folder holding another sweep's results or
    anything else, without ``overwrite``."""
    out = Path(out)
    check_folder(out, OUTPUTS, overwrite=True, command="sweep")  # kinds, permissions
    if not out.is_dir() or all(is_leftover(p) for p in out.iterdir()):
        return "new"
    if overwrite:
        return "fresh"
    if (out / "parts").is_dir() or (out / "sweep.toml").is_file():
        prev = previous_name(out)
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
    own_part = re.compile(r"^[0-9a-f]{12}\.(parquet|zarr)$")
    for sub, keep_names in (("parts", ()), ("recordings", ("index.csv",)), ("plots", ())):
        d = out / sub
        if not d.is_dir():
            continue
        for p in d.iterdir():
            if own_part.match(p.name) or p.name in keep_names \
                    or (sub == "plots" and p.suffix == ".png"):
                remove_path(p)
        with contextlib.suppress(OSError):
            d.rmdir()  # only if empty
    for name in ("sweep.toml", "results.parquet", "results.csv", "summary.md", "report.html"):
        remove_path(out / name)


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


def _run_cases(client, todo: list, spec: SweepSpec, out: Path, *, keep_recordings: bool,
               case_fn, progress: bool) -> int:
    """Run the cases ``todo`` on the Dask ``client``, writing each one's part as it finishes
    (and the table every REBUILD_EVERY_S); how many were ok."""
    from distributed import as_completed
    from tqdm import tqdm

    parts_dir = out / "parts"
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
    bar = tqdm(total=len(spec.cases), initial=len(spec.cases) - len(todo), unit="case",
               desc=f"sweep {spec.name}", disable=not progress)
    last = time.perf_counter()
    n_ok = 0
    for fut in as_completed(list(futures)):
        sc = futures[fut]
        try:
            outcome = fut.result()
        except Exception as exc:  # KilledWorker, lost connection, unpicklable result
            outcome = {"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                       "metrics": {}, "worker": "", "wall_s": math.nan}
        write_part(parts_dir, part_row(sc, outcome))
        if outcome["status"] == "ok":
            n_ok += 1
        else:
            bar.write(f"case {sc.case_id} failed: {outcome['error']}", file=sys.stderr)
        bar.update(1)
        fut.release()
        if time.perf_counter() - last > REBUILD_EVERY_S:
            rebuild_table(out, spec)
            last = time.perf_counter()
    bar.close()
    return n_ok


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
    n_ok = 0
    own = None
    if todo:
        if client is None:
            client, own = _start_client(scheduler, n_workers)
            own = (client, own)
        try:
            n_ok = _run_cases(client, todo, spec, out, keep_recordings=keep_recordings,
                              case_fn=case_fn, progress=progress)
        finally:
            if own is not None:
                own[0].close()
                if own[1] is not None:
                    own[1].close()
    df = rebuild_table(out, spec)
    if keep_recordings and not any(c.recording for c in spec.cases):
        write_recordings_index(out, spec, df)
    n_failed_total = int((df["status"] != "ok").sum()) if len(df) else 0
    notes = []
    try:
        plots = plot_sweep(df, spec, out / "plots") if len(df) else []
    except Exception as exc:  # the table and the summary are written whatever the plots do
        plots = []
        notes.append(f"the plots could not be drawn: {type(exc).__name__}: {exc}")
    write_summary(df, spec, out, plots, notes=notes)
    write_html(df, spec, out, plots)
    return SweepSummary(out=out, n_cases=len(spec.cases), n_done_before=n_before,
                        n_run=len(todo), n_ok=n_ok, n_failed=n_failed_total,
                        seconds=time.perf_counter() - t0, plots=plots)
