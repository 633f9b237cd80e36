"""The bench's end-to-end section: the default ``rollfric validate`` case, run in a new process
as a user runs it, against as many stock pyrender full frames, and the command's wall time.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from validation.bench import locate, render
from validation.bench.table import Row
from validation.case_dict import default_case_dict


def _child_env() -> dict:
    """The environment of a new Python process that finds the packages where this process
    found them (an uninstalled checkout included)."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}


def _case_in_new_process(case: dict) -> tuple[dict, dict]:
    """:func:`validation.e2e.run_case`'s metrics and the measure stage's parts (wall seconds)
    from a new Python process, as ``rollfric validate`` runs a case: its render processes' fork
    server starts with it (in the bench's own process it would already be running from the
    rendering section, ~1 s of a 4001-frame case's render stage)."""
    code = ("import json, sys\n"
            "from validation.e2e import run_case\n"
            "res = run_case(json.load(sys.stdin))\n"
            "parts = dict(getattr(res.track_info, 'seconds', None) or {})\n"
            "print(json.dumps({'metrics': res.metrics, 'parts': parts}, default=float))\n")
    out = subprocess.run([sys.executable, "-c", code], input=json.dumps(case), text=True,
                         capture_output=True, env=_child_env())
    if out.returncode != 0:
        raise RuntimeError(f"the default validate case failed in a new process:\n{out.stderr}")
    res = json.loads(out.stdout.strip().splitlines()[-1])
    return res["metrics"], res["parts"]


def validate_command(seconds: float, out: str | Path) -> tuple[float, dict]:
    """Run the real ``rollfric validate --set scenario.motion.seconds=SECONDS --out OUT
    --no-progress`` in a new process, as a user does; its wall time as the user waits (the
    interpreter's start, the imports, the case, the report's files and plots, the exit) and the
    metrics it wrote (OUT/metrics.json: ``t_total_s`` is the total it printed).

    Parameters
    ----------
    seconds : float
        The default case's duration (s).
    out : str or pathlib.Path
        The report folder (must not hold anything).

    Returns
    -------
    wall : float
        Seconds from the start of the process to its end.
    metrics : dict
        The case's metrics.

    Raises
    ------
    RuntimeError
        The command failed.
    """
    # the console script when it sits beside this Python (a virtual environment), else its
    # equivalent: rollfric.cli.main's main in a new interpreter
    script = Path(sys.executable).with_name("rollfric")
    cmd = [str(script)] if script.is_file() else [
        sys.executable, "-c", "import sys; from rollfric.cli.main import main; sys.exit(main())"]
    cmd += ["validate", "--set", f"scenario.motion.seconds={seconds:g}", "--out", str(out),
            "--no-progress"]
    # its output into files, not pipes: the wait ends with the command's process, as a
    # terminal's prompt comes back (a pipe's end would also wait for the render's fork server,
    # which holds the output too and ends ~0.2 s after it)
    with tempfile.TemporaryFile() as log:
        t0 = time.perf_counter()
        res = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT,
                             env=_child_env())
        wall = time.perf_counter() - t0
        if res.returncode != 0:
            log.seek(0)
            raise RuntimeError(f"rollfric validate failed (exit {res.returncode}):\n"
                               f"{log.read().decode(errors='replace')}")
    return wall, json.loads((Path(out) / "metrics.json").read_text(encoding="utf-8"))


E2E_RUNS = 3  # runs of the validate case; the one with the median ratio is reported


def bench_e2e(quick: bool) -> list[Row]:
    """Seconds per stage of the default ``rollfric validate`` case run for 4 s (0.3 s with
    --quick), and its total against as many stock pyrender full frames: the case is run
    :data:`E2E_RUNS` times (once with --quick), each between stock frames measured just
    before and just after it, and the run with the median ratio is reported (its stages, its
    measure rate), with every run's ratio in the note."""
    case = default_case_dict()
    case["scenario"]["motion"]["seconds"] = 4.0
    note = "the default validate case, 4 s (4001 frames), in a new process"
    if quick:
        case["scenario"]["motion"]["seconds"] = 0.3
        note = "the default validate case cut to 0.3 s (--quick), in a new process"
    # the baseline beside each run: stock frames just before and just after it (the machine's
    # speed drifts within minutes, by more than 10 %); the stock frames after a run are the
    # next one's before
    runs = []
    before = render.stock_frame_times(repeats=3)
    for _ in range(1 if quick else E2E_RUNS):
        m_k, parts_k = _case_in_new_process(case)
        after = render.stock_frame_times(repeats=3)
        ratio = m_k["n_frames"] * float(np.median(before + after)) / m_k["t_total_s"]
        runs.append((ratio, m_k, parts_k, before, after))
        before = after
    ratios = [r[0] for r in runs]
    _, m, parts, before, after = sorted(runs, key=lambda r: r[0])[len(runs) // 2]
    totals = [r[1]["t_total_s"] for r in runs]
    runs_note = "" if len(runs) == 1 else (
        f"; the median of {len(runs)} runs of the case, in order "
        + " / ".join(f"{r:.1f}x" for r in ratios)
        + " (totals " + " / ".join(f"{t:.1f}" for t in totals) + " s)")
    rows = [Row("end-to-end", f"stage {k[2:-2]}", v, "s", note=note)
            for k, v in sorted(m.items()) if k.startswith("t_") and k.endswith("_s")
            and k != "t_total_s"]
    rows += _measure_rows(m, parts, quick)
    stock_frame = float(np.median(before + after))
    stock = m["n_frames"] * stock_frame
    rows.append(Row("end-to-end", "total", m["t_total_s"], "s",
                    f"{m['n_frames']} stock pyrender full frames alone", stock,
                    stock / m["t_total_s"], "speed-up",
                    f"{m['n_frames']} frames; mu bias {100 * m['mu_bias_rel']:+.3f} %, "
                    f"centre rms {m['center_rms_px']:.3f} px; the stock frame "
                    f"{1e3 * stock_frame:.0f} ms, the median of 3 just before the case "
                    f"({1e3 * np.median(before):.0f} ms) and 3 just after it "
                    f"({1e3 * np.median(after):.0f} ms){runs_note}; target >= 100x"))
    # the whole command as a user waits for it, beside the total it prints
    seconds = case["scenario"]["motion"]["seconds"]
    with tempfile.TemporaryDirectory(prefix="rollfric-bench-") as tmp:
        wall, mc = validate_command(seconds, Path(tmp) / "report")
    rows.append(Row("end-to-end", "rollfric validate command, wall time as a user waits", wall,
                    "s", "the total it printed", mc["t_total_s"], mc["t_total_s"] / wall,
                    "of the wall time",
                    f"`rollfric validate --set scenario.motion.seconds={seconds:g} "
                    "--no-progress` in a new process: the total (simulate to metrics) and "
                    "before it Python's start, the imports and the case, after it the report "
                    "(metrics.json, fit.json, frames.csv, plots, overlays) and the exit; "
                    f"{mc['n_frames']} frames, against the stock frames: "
                    f"{stock / wall:.1f}x"))
    return rows


def _measure_rows(m: dict, parts: dict, quick: bool) -> list[Row]:
    """The case's measure stage: its frames/s against the 1000 frames/s target, where its wall
    time goes (``parts``), and beside the locator alone."""
    if not m.get("t_measure_s", 0) > 0:
        return []
    fps = m["n_frames"] / m["t_measure_s"]
    rows = []
    rows.append(Row("end-to-end", "measure a synth recording end to end, open to fit, "
                    "reading included (frames/s)", fps,
                    "frames/s", "target 1000 frames/s", 1000.0, fps / 1000.0, "speed-up",
                    "wall time of the case's measure stage: the store opened, background, "
                    "trough centre, each tracked region read with the sensor model, the "
                    "locator (the recording's halves, on 2 threads when a core is free), fits, "
                    "checks and budget "
                    "(the process's imports not counted)"))
    # where the measure stage's wall time goes (rollfric.measurement.measure's own stages)
    if parts:
        parts["the store opened, the setup read (before measure())"] = max(
            0.0, m["t_measure_s"] - sum(parts.values()))
        rows += [Row("end-to-end", f"measure stage: {k}", v, "s", note=(
            f"wall time, {100 * v / m['t_measure_s']:.0f} % of the measure stage; fits on "
            "2 threads and the recording's halves on 2 threads when a core is free"))
            for k, v in parts.items()]
    alone = locate.throughput("10mm", 150 if quick else 600)
    rows.append(Row("end-to-end", "measure end to end beside the locator alone (frames/s)",
                    fps, "frames/s", "the streaming loop alone (recognition section)",
                    alone, fps / alone, "x the locator alone",
                    "the locator alone: in-memory frames, no reads, fit or checks, CPU time "
                    "of one core; end to end: wall time"))
    return rows
