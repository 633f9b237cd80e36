"""One case end to end: scenario -> sim -> synth -> rollfric -> metrics, with stage timings.

    >>> from validation import case, case_dict, e2e
    >>> result = e2e.run_case(case.case_from_dict(case_dict.default_case_dict()))
    >>> result.metrics["mu_bias_rel"], result.timings["render"]

The metrics separate the engine's bias from the pipeline's: ``mu_engine`` is what the same
fitter (same method, same options) recovers from the engine's ground-truth theta(t), so
``mu_engine_bias_rel`` is the physics engine's error and ``mu_pipeline_bias_rel`` (recovered
against mu_engine) is the camera + locator + fit error on top of it. ``mu_bias_rel`` is the
total, against the configured mu.

Blind mode (the default, ``measure.oracle = false``): rollfric gets the lab's setup file
(:mod:`validation.lab`: nominal values, no center_px unless the lab measured it), the recording
and its background; ``mode``, the lab's errors (``lab_err_<key>``: nominal - as built) and the
trough centre rollfric used against the true one (``trough_center_err_x_px``, ...) are in the
metrics. Oracle mode hands it the renderer's own setup (exact geometry and center_px).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import dataclasses
import json
import math
import secrets
import shutil
import tempfile
import time
from pathlib import Path

import sim
import synth
import synth.pipeline
from rollfric.fit.estimate import fit_mu
from rollfric.fit.offset import resolve_offset
from rollfric.io import readers as io
from rollfric.measurement import measure
from rollfric.output.atomic import remove_leftovers, temp_path
from rollfric.output.folder import check_folder, staged_folder
from rollfric.setup.model import setup_from_dict
from rollfric.track.setup_checks import setup_from_recording
from synth.store import read_truth, scratch_dir
from synth.video import export_video
from validation.case import Case, case_from_dict
from validation.metrics import (
    budget_metrics,
    compute_metrics,
    finite,
    mode_metrics,
    timing_metrics,
    true_center,
)
from validation.report import OUTPUTS, write_report

STAGES = ("simulate", "fit_truth", "render", "measure", "metrics")

@dataclasses.dataclass(frozen=True, eq=False)
class CaseResult:
    """Everything one end-to-end run produced (arrays kept for the report)."""

    case: Case
    metrics: dict  # flat: name -> float/int/bool/str
    timings: dict  # stage -> seconds (also in metrics as t_<stage>_s)
    trajectory: object  # sim.Trajectory
    truth: object  # pandas.DataFrame, one row per frame (synth's truth)
    track: object  # pandas.DataFrame: frame, t_s, x_px, y_px, theta_rad, found, ...
    track_info: object  # rollfric.track.track_info.TrackInfo: how the track was measured
    fit: object  # rollfric.fit.estimate.FitResult from the measured track
    fit_truth: object  # the same fitter on the engine's theta(t)
    setup: object  # rollfric.setup.model.Setup used by the measurement
    setup_dict: dict  # the setup file rollfric was given (lab-file form)
    recording: Path | None  # the recording, when kept


@contextlib.contextmanager
def _timer(timings: dict, stage: str):
    t0 = time.perf_counter()
    try:
        yield
    finally:
        timings[stage] = timings.get(stage, 0.0) + time.perf_counter() - t0


def run_case(case: Case | dict, *, recording: str | Path | None = None,
             keep_recording: bool = False, report_dir: str | Path | None = None,
             render_workers: int | None = None, render_threads: int | None = None,
             progress: bool = False, overwrite: bool = False) -> CaseResult:
    """Run one case end to end and return its metrics, per-stage timings and arrays.

    ``recording``: where to write the rendered recording (kept); otherwise it goes to a
    temporary directory, removed at the end unless ``keep_recording`` (then it is kept as
    ``report_dir/recording.zarr``). ``report_dir``: also write the report there
    (:mod:`validation.report`): an existing non-empty folder is refused unless ``overwrite``,
    which replaces the report's own files only (:mod:`rollfric.output.folder`); the report is
    written
    to a hidden folder first and moved in when complete. ``render_workers``/
    ``render_threads``: rendering processes (synth's default: up to 2) and llvmpipe threads
    each; a sweep worker uses 1/1. With render processes the fit of the engine's angles
    (stage "fit_truth") runs on a thread during the render, whose work is theirs (metric
    ``fit_truth_beside_render``); the fits are the same either way.
    """
    if keep_recording and recording is None and report_dir is None:
        raise ValueError("keep_recording needs report_dir (or recording=PATH)")
    if isinstance(case, dict):
        case = case_from_dict(case)
    _start_render_early(case, render_workers)
    if report_dir is None:
        return _run_case(case, recording, None, render_workers, render_threads, progress)
    check_folder(report_dir, OUTPUTS, overwrite=overwrite, command="validate")
    with staged_folder(report_dir, OUTPUTS, overwrite=overwrite, command="validate") as tmp:
        rec = recording
        if rec is None and keep_recording:
            rec = tmp / "recording.zarr"
        result = _run_case(case, rec, tmp, render_workers, render_threads, progress)
    if result.recording is not None and Path(result.recording).parent == tmp:
        result = dataclasses.replace(result,
                                     recording=Path(report_dir) / Path(result.recording).name)
    return result


def _simulate(case: Case, timings: dict):
    """The case's trajectory, timed as the stage "simulate"."""
    with _timer(timings, "simulate"):
        return sim.simulate(case.scenario)


def _fit_truth(case: Case, traj, timings: dict):
    """The fit of the trajectory's exact angles (the engine's mu), timed as the stage
    "fit_truth"."""
    setup_truth = case.scenario.setup()
    with _timer(timings, "fit_truth"):
        return fit_mu(traj.t, traj.theta, setup_truth, method=case.fit,
                      offset=case_offset(case, traj.t, traj.theta, setup_truth))


def _start_render_early(case: Case, render_workers: int | None = None) -> bool:
    """Start the fork server the case's render processes will be forked from, now
    (:func:`synth.pipeline.prepare_render`): its imports (~1 s of one core) then run on the
    other core while this process simulates the case (:func:`run_case` calls it first thing;
    ``rollfric validate`` before it imports this module). Whether one runs for the case's
    render."""
    return synth.pipeline.prepare_render(case.scene, case.scenario.n_samples, render_workers)


CASE_SCRATCH = "rollfric-case"


def case_scratch(n_frames: int, folder: str | Path | None = None) -> Path:
    """A new folder for a case's temporary recording of ``n_frames`` frames, deleted after use.

    In RAM where there is room (:func:`synth.store.scratch_dir`: a recording is ~2 files a
    frame), else the system's temporary folder; named as rollfric's temporary paths are
    (``.rollfric-case-XXXXXXXX.part-PID-START``, :func:`rollfric.output.atomic.temp_path`), so that
    the
    folders of runs that were killed (SIGTERM, SIGKILL: no ``finally`` ran; in /dev/shm each
    holds its recording in RAM until the machine restarts) are found and removed here, by the
    next case in that folder.

    Parameters
    ----------
    n_frames : int
        Frames of the recording.
    folder : str or pathlib.Path, optional
        Where (default: as above).

    Returns
    -------
    pathlib.Path
        The new, empty folder (mode 0o700).
    """
    if folder is None:
        folder = scratch_dir(n_frames) or tempfile.gettempdir()
    remove_leftovers(folder, prefix=f".{CASE_SCRATCH}-")
    while True:
        path = temp_path(Path(folder) / f"{CASE_SCRATCH}-{secrets.token_hex(4)}")
        try:
            path.mkdir(mode=0o700)
            return path
        except FileExistsError:
            continue


def _run_case(case, recording, report_tmp, render_workers, render_threads,
              progress) -> CaseResult:
    if isinstance(case, dict):
        case = case_from_dict(case)
    timings: dict = {}
    t_start = time.perf_counter()
    traj = _simulate(case, timings)
    tmpdir = None
    if recording is not None:
        rec_path = Path(recording)
    else:
        tmpdir = case_scratch(len(traj))
        rec_path = tmpdir / "recording.zarr"
    # with render processes filling the cores, the true angles are fitted beside the render
    # (on a thread of this process, which meanwhile only hands the processes their frames);
    # else before it
    beside = synth.pipeline.render_workers(case.scene, len(traj), render_workers) > 1
    try:
        with concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="rollfric-fit") as pool:
            if beside:
                fitting = pool.submit(_fit_truth, case, traj, timings)
            else:
                fit_truth = _fit_truth(case, traj, timings)
            with _timer(timings, "render"):
                synth.render(traj, rec_path, scene=case.scene, sensor=case.sensor,
                             seed=case.render_seed, progress=progress, workers=render_workers,
                             threads=render_threads, overwrite=True, timing=case.timing)
        if beside:
            fit_truth = fitting.result()
        result = _measure_and_score(case, rec_path, traj, fit_truth, timings, t_start,
                                    progress, beside)
        if report_tmp is not None:
            write_report(result, report_tmp)  # while the recording exists (overlay frames)
    finally:
        if tmpdir is not None:
            shutil.rmtree(tmpdir, ignore_errors=True)
    if tmpdir is not None:
        result = dataclasses.replace(result, recording=None)
    return result


def _measure_and_score(case: Case, rec_path: Path, traj, fit_truth, timings: dict,
                       t_start: float, progress: bool, beside: bool = False) -> CaseResult:
    """What follows the render: rollfric measures the recording, the metrics against the
    truth (the recording's truth table and ``traj``), the budget, the stage times
    (``beside``: the fit of the true angles ran during the render)."""
    truth, attrs = read_truth(rec_path)
    with _timer(timings, "measure"):
        track, info, fit, setup, setup_dict = measure_recording(rec_path, case,
                                                                progress=progress)
    with _timer(timings, "metrics"):
        metrics = compute_metrics(case, traj, truth, track, fit, fit_truth, setup)
        metrics.update(mode_metrics(case, info, truth))
        metrics.update(timing_metrics(case, attrs, info))
        if case.data.get("measure", {}).get("budget", True):
            metrics.update(budget_metrics(case, track, info, fit, true_center(metrics)))
    timings["total"] = time.perf_counter() - t_start
    # the stages in the order they start
    order = ("simulate", "fit_truth", "render", "measure", "metrics", "total")
    timings = {k: timings[k] for k in sorted(timings, key=lambda k: (
        order.index(k) if k in order else len(order) - 1))}
    metrics.update({f"t_{k}_s": float(v) for k, v in timings.items()})
    metrics["fit_truth_beside_render"] = bool(beside)
    metrics["n_frames"] = int(len(truth))
    metrics["frame_width_px"] = int(case.scene.camera.width)
    metrics["frame_height_px"] = int(case.scene.camera.height)
    t_render = timings.get("render", math.nan)
    metrics["render_fps"] = len(truth) / t_render if t_render > 0 else math.nan
    return CaseResult(case=case, metrics=metrics, timings=dict(timings), trajectory=traj,
                      truth=truth, track=track, track_info=info, fit=fit, fit_truth=fit_truth,
                      setup=setup, setup_dict=setup_dict, recording=rec_path)


class RecordingMismatch(ValueError):
    """A recording that was not rendered from the case it is re-measured as."""


def remeasure_case(case: Case | dict, recording: str | Path, *,
                   progress: bool = False) -> CaseResult:
    """Measure an existing recording of ``case`` again, with the current code: no render.

    The case is simulated again (deterministic, cheap) for the truth's fit and the metrics;
    rollfric measures the recording as :func:`run_case` does (blind or oracle as the case
    says) and the metrics are :func:`run_case`'s, without ``t_render_s`` (``render_fps``
    NaN). The recording must be the case's: its stored scenario (as built) and render seed
    must be the case's, else :class:`RecordingMismatch`.

    Parameters
    ----------
    case : Case or dict
        The case the recording was rendered from (its ``measure`` table may differ: how it
        is measured now, e.g. ``oracle``).
    recording : str or Path
        The recording (synth's Zarr).
    progress : bool
        Progress bars of the measurement.

    Returns
    -------
    CaseResult
        With ``recording`` the given path.

    Raises
    ------
    RecordingMismatch
        The recording was made from another scenario or render seed.
    """
    if isinstance(case, dict):
        case = case_from_dict(case)
    rec_path = Path(recording)
    attrs = synth.open_recording(rec_path).attrs
    # as synth stores it (JSON: tuples as lists)
    want = json.loads(json.dumps(case.scenario.to_toml_dict(),
                                 default=lambda o: o.tolist() if hasattr(o, "tolist")
                                 else str(o)))
    if attrs.get("scenario") != want or int(attrs.get("seed", -1)) != case.render_seed:
        raise RecordingMismatch(f"{rec_path}: not a recording of this case (its scenario or "
                                "render seed differ from the case's)")
    timings: dict = {}
    t_start = time.perf_counter()
    traj = _simulate(case, timings)
    fit_truth = _fit_truth(case, traj, timings)
    return _measure_and_score(case, rec_path, traj, fit_truth, timings, t_start, progress)


# -- the measurement (rollfric) ---------------------------------------------------------------

def measure_recording(path: Path, case: Case, *, progress: bool = False):
    """rollfric's measurement of a recording: (track DataFrame, TrackInfo, FitResult, Setup,
    setup dict).

    Exactly what ``rollfric measure REC.zarr --setup SETUP.toml`` does: the recording opened
    through rollfric's reader (synth's Zarr entry point) with its background, the case's
    locator and fit method (:func:`rollfric.measurement.measure`). With ``render.video`` the
    recording is first exported as that video (:func:`synth.video.export_video`, to a
    temporary folder) and rollfric reads the video file and the background's one-frame video
    instead. Blind mode: SETUP.toml is the
    lab's (:meth:`validation.case.Case.lab_setup_dict`); oracle mode: the setup the recording
    carries (the renderer's exact geometry and center_px).
    """
    src = io.open_recording(path)
    if case.oracle:
        setup = setup_from_recording(src)
        setup_dict = setup.to_toml_dict()
    else:
        setup_dict = case.lab_setup_dict()
        setup = setup_from_dict(setup_dict, source="the lab's setup")
    if case.video is None:
        track, info, fit = measure(src, setup, method=case.locator,
                                   fit_method=case.fit, offset=case.offset, progress=progress)
        return track, info, fit, setup, setup_dict
    with tempfile.TemporaryDirectory(prefix="rollfric-video-") as tmp:
        # the lab's path: the camera software's video export and its background
        files = export_video(path, tmp, case.video, progress=progress)
        src = io.open_recording(files["frames"])
        background = io.open_recording(files["background"])[0]
        track, info, fit = measure(src, setup, background, method=case.locator,
                                   fit_method=case.fit, offset=case.offset, progress=progress)
    return track, info, fit, setup, setup_dict


def case_offset(case: Case, t, theta, setup) -> bool:
    """The case's offset choice for a fit of theta(t) ("auto": as rollfric decides)."""
    return resolve_offset(case.offset, t, theta, setup, case.fit)[0]


def sim_only_case(case: Case | dict) -> dict:
    """A cheap case: simulate and fit the engine's theta(t) only (no render, no locator).

    Its metrics are the engine-fidelity subset of :func:`run_case`'s (``mu_engine``,
    ``mu_engine_bias_rel``, timings). Sweeps over engines/surfaces/scenarios can use it
    (``[sweep] stages = "sim"``) and the sweep-machinery tests do.
    """
    if isinstance(case, dict):
        case = case_from_dict(case)
    timings: dict = {}
    t0 = time.perf_counter()
    traj = _simulate(case, timings)
    ft = _fit_truth(case, traj, timings)
    timings["total"] = time.perf_counter() - t0
    mu_true = float(case.scenario.mu)
    m = {"case_id": case.case_id, "name": case.name, "mu_true": mu_true,
         "mu_engine": finite(ft.mu), "mu_engine_stderr": finite(ft.mu_stderr),
         "mu_engine_bias_rel": (finite(ft.mu) - mu_true) / mu_true if mu_true > 0 else math.nan,
         "fit_rms_residual_rad": finite(ft.rms_residual), "engine": case.scenario.engine,
         "surface": case.scenario.surface, "fit_method": case.fit,
         "n_frames": int(len(traj))}
    m.update({f"t_{k}_s": float(v) for k, v in timings.items()})
    return m
