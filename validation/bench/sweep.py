"""``rollfric bench``'s sweeps section: cases/hour of one sweep on a local 2-worker Dask cluster
and on a ``dask scheduler`` with workers started apart (as on a lab's machines), beside the same
cases run one after another.

The external cluster is started here the way docs/guide/sweep.md tells a user to (``dask
scheduler``, ``dask worker --nworkers 2 --nthreads 1`` with ``PYOPENGL_PLATFORM=egl``), on this
machine, and stopped when the sweep is done.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from validation.bench.table import Row
from validation.sweep import sweep_from_dict
from validation.sweep_run import run_sweep

WORKERS = 2


def _spec(quick: bool):
    """The benchmark's sweep: the default case cut short, one case per render seed."""
    n, seconds = (4, 0.2) if quick else (8, 0.8)
    return sweep_from_dict({"sweep": {"name": "bench", "seeds": n},
                            "base": {"scenario": {"motion": {"seconds": seconds}}}},
                           source="bench sweep"), n, seconds


def _external_cluster(tmp: Path):
    """Start ``dask scheduler`` and ``dask worker`` processes (this machine, loopback):
    (address, [processes])."""
    exe = Path(sys.executable).with_name("dask")
    if not exe.exists():
        raise RuntimeError("the dask command is not installed beside this Python")
    cmd = [str(exe)]
    sched_file = tmp / "scheduler.json"
    env = dict(os.environ, PYOPENGL_PLATFORM="egl")
    root = str(Path(__file__).resolve().parents[1])  # this checkout's packages first
    env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])
    log = open(tmp / "cluster.log", "w")  # noqa: SIM115 - closed with the processes
    procs = [subprocess.Popen([*cmd, "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(sched_file)],
                              env=env, stdout=log, stderr=subprocess.STDOUT)]
    t0 = time.perf_counter()
    while not sched_file.exists():
        if time.perf_counter() - t0 > 120 or procs[0].poll() is not None:
            _stop(procs, log)
            raise RuntimeError("dask scheduler did not start (see its log)")
        time.sleep(0.2)
    procs.append(subprocess.Popen([*cmd, "worker", "--scheduler-file", str(sched_file),
                                   "--nworkers", str(WORKERS), "--nthreads", "1",
                                   "--no-dashboard"], env=env, stdout=log,
                                  stderr=subprocess.STDOUT))
    import json

    from distributed import Client

    address = json.loads(sched_file.read_text())["address"]
    with Client(address) as client:
        client.wait_for_workers(WORKERS, timeout=180)
    return address, procs, log


def _stop(procs, log) -> None:
    for p in reversed(procs):
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    log.close()


def bench_sweeps(quick: bool) -> list[Row]:
    """Cases/hour of the same sweep on a local 2-worker cluster and on an external scheduler
    with 2 workers started apart, beside the cases' own time one after another."""
    import pandas as pd

    spec, n, seconds = _spec(quick)
    label = f"{n} cases of {seconds:g} s ({int(seconds * 1000) + 1} frames)"
    tmp = Path(tempfile.mkdtemp(prefix="rollfric-bench-sweep-"))
    rows = []
    try:
        t0 = time.perf_counter()
        s_local = run_sweep(spec, tmp / "local", n_workers=WORKERS, progress=False)
        t_local = time.perf_counter() - t0
        df = pd.read_parquet(tmp / "local" / "results.parquet")
        serial = float(df["wall_s"].sum())  # each case's own time, as if run one after another
        ok = s_local.n_failed == 0
        rows.append(Row("sweeps", f"local cluster, {WORKERS} workers: {label}",
                        3600 * n / t_local, "cases/hour", "the cases one after another",
                        3600 * n / serial, serial / t_local, "speed-up",
                        f"{t_local:.0f} s with the cluster's start; "
                        f"{'all ok' if ok else f'{s_local.n_failed} failed'}"))
        try:
            address, procs, log = _external_cluster(tmp)
        except (RuntimeError, OSError, TimeoutError) as exc:
            rows.append(Row("sweeps", f"external dask scheduler: {label}", math.nan,
                            "cases/hour", note=f"not measured: {exc}"))
            return rows
        try:
            t0 = time.perf_counter()
            s_ext = run_sweep(spec, tmp / "external", scheduler=address, progress=False)
            t_ext = time.perf_counter() - t0
        finally:
            _stop(procs, log)
        rows.append(Row("sweeps", f"external `dask scheduler`, {WORKERS} workers started "
                        f"apart: {label}", 3600 * n / t_ext, "cases/hour",
                        "the cases one after another", 3600 * n / serial, serial / t_ext,
                        "speed-up", f"{t_ext:.0f} s, workers already running; "
                        f"{'all ok' if s_ext.n_failed == 0 else f'{s_ext.n_failed} failed'}"))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return rows
