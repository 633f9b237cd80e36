"""One case end to end: scenario -> sim -> synth -> rollfric -> metrics, with stage timings.

    >>> from validation import case, e2e
    >>> result = e2e.run_case(case.case_from_dict(case.default_case_dict()))
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
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from validation.case import Case, case_from_dict

STAGES = ("simulate", "fit_truth", "render", "measure", "metrics")

# every metric a case reports (run_case; sim_only_case reports a subset): what a sweep's
# ``metrics`` may name. A new metric is added here (tests check run_case's keys against it).
METRICS = frozenset((
    "case_id", "name", "mu_true", "mu_recovered", "mu_stderr", "mu_bias", "mu_bias_rel",
    "mu_engine", "mu_engine_stderr", "mu_engine_bias_rel", "mu_pipeline_bias_rel",
    "mu_true_within_stderr", "mu_true_within_2stderr", "mu_engine_within_stderr", "mu_z",
    "fit_rms_residual_rad", "fit_relative_error", "fit_offset_rad", "fit_quality",
    "fit_quality_reasons", "fit_method", "locator", "engine", "surface",
    "residual_lag1_autocorr", "mu_stderr_ar1", "mu_true_within_stderr_ar1", "found_fraction",
    "n_found", "center_rms_px", "center_max_px", "center_p95_px", "center_median_px",
    "center_bias_x_px", "center_bias_y_px", "center_std_x_px", "center_std_y_px",
    "center_within_1px", "theta_rms_rad", "theta_max_rad", "theta_bias_rad",
    # the centre error along the line from the trough axis (radial, + outward) and across it
    # (tangential, + towards larger theta): a rim that looks different above and below moves
    # the centre radially, which atan2 angles ignore
    "center_radial_bias_px", "center_radial_rms_px", "center_tangential_bias_px",
    "center_tangential_rms_px", "renderer",
    "model_vs_truth_rms_rad", "ball_radius_px", "amplitude0_deg", "n_frames",
    "frame_width_px", "frame_height_px", "render_fps", "fit_truth_beside_render",
    # mode_metrics
    "mode", "lab_center_measured", "lab_draw", "trough_center_x_px", "trough_center_y_px",
    "trough_center_err_x_px", "trough_center_err_y_px", "undistorted", "offset_fitted",
    "camera_roll_deg",
    # validation.track_level (a case measured from the exact projection, not a render)
    "stages", "locator_sigma_px",
    # budget_metrics
    "u_mu", "U_mu", "z_budget", "within_u", "within_U", "u_stat", "z_stat",
    "budget_top_source", "budget_n_sources", "u_second_order", "z_first_order",
    "within_U_first_order", "z_linear",
    # timing_metrics
    "timing_jitter_us", "frames_dropped_true", "frames_dropped_found",
    "frames_dropped_matched", "timing_irregular", "timestamps_used", "video_codec",
    "video_quality"))
# families of metrics named after a stage or a lab key: t_<stage>_s, asbuilt_/lab_/lab_err_<key>
METRIC_PATTERNS = (r"t_[a-z_]+_s", r"(asbuilt|lab|lab_err)_[A-Za-z0-9_]+")


def is_metric(name: str) -> bool:
    """True if ``name`` is a metric a case reports (:data:`METRICS`, :data:`METRIC_PATTERNS`).

    Parameters
    ----------
    name : str
        A metric name, e.g. from a sweep file's ``metrics``.

    Returns
    -------
    bool
        Whether a case can report it.
    """
    import re

    return name in METRICS or any(re.fullmatch(p, name) for p in METRIC_PATTERNS)


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
    _start_render_early(case, render_workers)  # before the imports below
    from rollfric.output.folder import check_folder, staged_folder
    from validation.report import OUTPUTS

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
    import sim

    with _timer(timings, "simulate"):
        return sim.simulate(case.scenario)


def _fit_truth(case: Case, traj, timings: dict):
    """The fit of the trajectory's exact angles (the engine's mu), timed as the stage
    "fit_truth"."""
    from rollfric.fit.estimate import fit_mu

    setup_truth = case.scenario.setup()
    with _timer(timings, "fit_truth"):
        return fit_mu(traj.t, traj.theta, setup_truth, method=case.fit,
                      offset=_offset(case, traj.t, traj.theta, setup_truth))


def _start_render_early(case: Case, render_workers: int | None = None) -> bool:
    """Start the fork server the case's render processes will be forked from, now
    (:func:`synth.pipeline.prepare_render`): its imports (~1 s of one core) then run on the
    other core while this process imports the measurement and the report (:func:`run_case`
    calls it first thing). Whether one runs for the case's render."""
    import synth.pipeline

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
    import secrets

    from rollfric.output.atomic import remove_leftovers, temp_path
    from synth.store import scratch_dir

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
    import synth

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
            from validation.report import write_report

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
    from synth.store import read_truth

    truth, attrs = read_truth(rec_path)
    with _timer(timings, "measure"):
        track, info, fit, setup, setup_dict = measure_recording(rec_path, case,
                                                                progress=progress)
    with _timer(timings, "metrics"):
        metrics = compute_metrics(case, traj, truth, track, fit, fit_truth, setup)
        metrics.update(mode_metrics(case, info, truth))
        metrics.update(timing_metrics(case, attrs, info))
        if case.data.get("measure", {}).get("budget", True):
            metrics.update(budget_metrics(case, track, info, fit, _true_center(metrics)))
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
    import synth

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
    from rollfric.io import readers as io
    from rollfric.measurement import measure
    from rollfric.setup.model import setup_from_dict
    from rollfric.track import tracker as track_mod

    src = io.open_recording(path)
    if case.oracle:
        setup = track_mod.setup_from_recording(src)
        setup_dict = setup.to_toml_dict()
    else:
        setup_dict = case.lab_setup_dict()
        setup = setup_from_dict(setup_dict, source="the lab's setup")
    if case.video is None:
        track, info, fit = measure(src, setup, method=case.locator,
                                             fit_method=case.fit, offset=case.offset,
                                             progress=progress)
        return track, info, fit, setup, setup_dict
    from synth.video import export_video

    with tempfile.TemporaryDirectory(prefix="rollfric-video-") as tmp:
        # the lab's path: the camera software's video export and its background
        files = export_video(path, tmp, case.video, progress=progress)
        src = io.open_recording(files["frames"])
        background = io.open_recording(files["background"])[0]
        track, info, fit = measure(src, setup, background, method=case.locator,
                                             fit_method=case.fit, offset=case.offset,
                                             progress=progress)
    return track, info, fit, setup, setup_dict


def _offset(case: Case, t, theta, setup) -> bool:
    """The case's offset choice for a fit of theta(t) ("auto": as rollfric decides)."""
    from rollfric.fit.offset import resolve_offset

    return resolve_offset(case.offset, t, theta, setup, case.fit)[0]


def mode_metrics(case: Case, info, truth) -> dict:
    """Blind or oracle, the lab's errors and the trough centre rollfric used against the true
    one (px, in the image rollfric measured in)."""
    cx = float(np.asarray(truth["cx_px"], float)[0])
    cy = float(np.asarray(truth["cy_px"], float)[0])
    if not info.undistorted:  # rollfric worked in the recorded image
        cx, cy = (float(v) for v in case.scene.camera.recorded(np.array([cx, cy])))
    used = info.center_px
    m = {"mode": case.mode,
         "lab_center_measured": bool(not case.oracle
                                     and case.lab.center_error_px is not None),
         "lab_draw": bool(case.lab.draw),
         "undistorted": bool(info.undistorted),
         "offset_fitted": bool(info.offset_fitted),
         "camera_roll_deg": math.degrees(case.scene.camera.roll),
         "trough_center_x_px": float(used[0]), "trough_center_y_px": float(used[1]),
         "trough_center_err_x_px": float(used[0]) - cx,
         "trough_center_err_y_px": float(used[1]) - cy}
    for key, value in case.lab.asbuilt.items():
        name = key.replace(".", "_")
        m[f"asbuilt_{name}"] = float(value)
        m[f"lab_{name}"] = float(case.lab.nominal[key])
        m[f"lab_err_{name}"] = 0.0 if case.oracle else float(case.lab.nominal[key] - value)
    return m


def _true_center(metrics: dict) -> tuple[float, float]:
    """The true trough centre (px, in the image rollfric measured in) from mode_metrics'."""
    return (metrics["trough_center_x_px"] - metrics["trough_center_err_x_px"],
            metrics["trough_center_y_px"] - metrics["trough_center_err_y_px"])


def timing_metrics(case: Case, attrs: dict, info) -> dict:
    """The camera's timing and how rollfric saw it: the jitter (us), the camera frames lost
    (``frames_dropped_true``), the ones rollfric found from the motion (``..._found``) and
    how many of those sit where a frame was lost (``..._matched``), the irregular steps, whether
    the recording's timestamps were used; the video codec and quality (or "none", -1)."""
    lost = list((attrs.get("timing") or {}).get("dropped_frames", []))
    # a camera frame lost between recorded frames k and k + 1: k = its number - the frames lost
    # before it - 1
    true_k = {}
    for j, f in enumerate(lost):
        k = int(f) - j - 1
        true_k[k] = true_k.get(k, 0) + 1
    found = {int(k): int(m) for k, m in info.frames_dropped}
    matched = sum(min(m, true_k.get(k, 0)) for k, m in found.items())
    t = case.timing
    return {"timing_jitter_us": 0.0 if t is None else t.jitter * 1e6,
            "frames_dropped_true": len(lost),
            "frames_dropped_found": sum(found.values()),
            "frames_dropped_matched": matched,
            "timing_irregular": len(info.timing_irregular),
            "timestamps_used": info.times != "frame / camera.fps",
            "video_codec": "none" if case.video is None else case.video.codec,
            "video_quality": -1 if case.video is None else case.video.quality}


def budget_metrics(case: Case, track, info, fit, truth_center=None) -> dict:
    """rollfric's uncertainty budget of the measured mu (:mod:`rollfric.uncertainty.budget`) against
    the truth: u_mu, U_mu (k = 2), z_budget = (mu - truth) / u_mu, within_u / within_U (1 or
    0), the statistical part alone (u_stat, z_stat), the largest source and the budget's time;
    with ``measure.second_order = true`` the second-order row (``u_second_order``, else 0) and
    z and within U without it (the first-order budget: ``z_first_order``,
    ``within_U_first_order``). ``z_linear``: the error the budget's
    own first-order model predicts from the case's drawn setup errors, sum of sensitivity x
    (nominal - as built) over its rows, / u_mu (the as-built values of the case's lab, the
    true trough centre ``truth_center``, px); its coverage is what an exactly linear budget
    would reach with these draws. Oracle mode: the setup is exact, the budget is its
    statistical part."""
    from rollfric.uncertainty.budget import SECOND_ORDER, budget, measurement_from_track

    if fit.method != "lsq":
        return {}
    second = bool(case.data.get("measure", {}).get("second_order", False))
    b = budget(measurement_from_track(track, info), fit, order=2 if second else 1)
    mu_true = float(case.scenario.mu)
    u_stat = next(r.u_mu for r in b.rows if r.source == "statistical")
    u2 = next((r.u_mu for r in b.rows if r.source == SECOND_ORDER), 0.0)
    u1 = math.sqrt(max(b.u_mu**2 - u2**2, 0.0))
    truth = dict(case.lab.asbuilt) if case.lab is not None else {}
    if truth_center is not None:
        truth["cylinder.center_px[x]"], truth["cylinder.center_px[y]"] = truth_center
    pred = sum(r.sensitivity * (r.value - truth[r.source]) for r in b.rows
               if r.source in truth and r.sensitivity is not None and r.value is not None)
    return {"u_mu": b.u_mu, "U_mu": b.U_mu, "z_budget": (b.mu - mu_true) / b.u_mu,
            "within_u": float(abs(b.mu - mu_true) <= b.u_mu),
            "within_U": float(abs(b.mu - mu_true) <= b.U_mu),
            "u_stat": u_stat, "z_stat": (b.mu - mu_true) / u_stat if u_stat > 0 else math.nan,
            "budget_top_source": b.rows[0].source, "budget_n_sources":
            sum(r.u_mu > 0 and r.source != SECOND_ORDER for r in b.rows),
            "u_second_order": u2,
            "z_first_order": (b.mu - mu_true) / u1 if u1 > 0 else math.nan,
            "within_U_first_order": float(abs(b.mu - mu_true) <= b.coverage_factor * u1),
            "z_linear": pred / b.u_mu if b.u_mu > 0 else math.nan,
            "t_budget_s": b.seconds}


# -- metrics ----------------------------------------------------------------------------------

def _f(x) -> float:
    return float(x) if x is not None and math.isfinite(float(x)) else math.nan


def compute_metrics(case: Case, traj, truth, track, fit, fit_truth, setup) -> dict:
    """The flat metric dict of one case (see the module docstring and docs/guide/validate.md)."""
    import pandas as pd

    mu_true = float(case.scenario.mu)
    m: dict = {"case_id": case.case_id, "name": case.name, "mu_true": mu_true}
    mu = _f(fit.mu)
    se = _f(fit.mu_stderr)
    mu_eng = _f(fit_truth.mu)
    m.update({
        "mu_recovered": mu,
        "mu_stderr": se,
        "mu_bias": mu - mu_true,
        "mu_bias_rel": (mu - mu_true) / mu_true if mu_true > 0 else math.nan,
        "mu_engine": mu_eng,
        "mu_engine_stderr": _f(fit_truth.mu_stderr),
        "mu_engine_bias_rel": (mu_eng - mu_true) / mu_true if mu_true > 0 else math.nan,
        "mu_pipeline_bias_rel": (mu - mu_eng) / mu_eng if mu_eng > 0 else math.nan,
        "mu_true_within_stderr": bool(abs(mu - mu_true) <= se) if math.isfinite(se) else False,
        "mu_true_within_2stderr": bool(abs(mu - mu_true) <= 2 * se) if math.isfinite(se)
        else False,
        "mu_engine_within_stderr": bool(abs(mu - mu_eng) <= se) if math.isfinite(se)
        else False,
        "mu_z": (mu - mu_true) / se if se > 0 else math.nan,
        "fit_rms_residual_rad": _f(fit.rms_residual),
        "fit_relative_error": _f(getattr(fit, "relative_error", math.nan)),
        "fit_offset_rad": _f(getattr(fit, "offset", 0.0)),
        "fit_method": case.fit,
        # rollfric's own verdict (rollfric.uncertainty.quality): "ok" or "suspect", and the
        # reasons' codes
        "fit_quality": getattr(fit, "quality", "ok"),
        "fit_quality_reasons": ",".join(r.code for r in getattr(fit, "quality_reasons", ())),
        "locator": case.locator, "renderer": case.scene.renderer,
        "engine": case.scenario.engine,
        "surface": case.scenario.surface,
    })
    # is the stated uncertainty honest? The fit's stderr assumes white residuals; locator
    # errors are correlated from frame to frame. Inflate by the AR(1) factor of the residuals
    # (effective sample size n (1 - rho) / (1 + rho)); never below the formal stderr.
    rho = _lag1_autocorr(np.asarray(track["theta_rad"], float) - np.asarray(fit.curve, float)) \
        if len(track) == len(fit.curve) else math.nan
    k = math.sqrt((1 + max(rho, 0.0)) / (1 - max(rho, 0.0))) \
        if math.isfinite(rho) and rho < 1 else math.nan
    se_ar = se * k if math.isfinite(k) else math.nan
    m.update({
        "residual_lag1_autocorr": rho,
        "mu_stderr_ar1": se_ar,
        "mu_true_within_stderr_ar1": bool(abs(mu - mu_true) <= se_ar)
        if math.isfinite(se_ar) else False,
    })
    # per-frame comparison, aligned on the frame number
    tr = track.set_index("frame") if "frame" in track.columns else track
    tt = truth
    n = len(tt)
    found = np.zeros(n, dtype=bool)
    fx = np.full(n, np.nan)
    fy = np.full(n, np.nan)
    fth = np.full(n, np.nan)
    idx = np.asarray(tr.index, dtype=int)
    ok = (idx >= 0) & (idx < n)
    idx = idx[ok]
    f_found = np.asarray(tr["found"], dtype=bool)[ok] if "found" in tr.columns \
        else np.isfinite(np.asarray(tr["x_px"], float))[ok]
    found[idx] = f_found
    fx[idx] = np.asarray(tr["x_px"], float)[ok]
    fy[idx] = np.asarray(tr["y_px"], float)[ok]
    fth[idx] = np.asarray(tr["theta_rad"], float)[ok]
    good = found & np.isfinite(fx) & np.isfinite(fy)
    tx = np.asarray(tt["sil_x_px"], float)
    ty = np.asarray(tt["sil_y_px"], float)
    ex, ey = fx - tx, fy - ty
    e = np.hypot(ex, ey)
    m["found_fraction"] = float(good.mean()) if n else math.nan
    m["n_found"] = int(good.sum())
    if good.any():
        eg = e[good]
        m.update({
            "center_rms_px": float(np.sqrt(np.mean(eg ** 2))),
            "center_max_px": float(np.max(eg)),
            "center_p95_px": float(np.percentile(eg, 95)),
            "center_median_px": float(np.median(eg)),
            "center_bias_x_px": float(np.mean(ex[good])),
            "center_bias_y_px": float(np.mean(ey[good])),
            "center_std_x_px": float(np.std(ex[good])),
            "center_std_y_px": float(np.std(ey[good])),
            "center_within_1px": float(np.mean(eg <= 1.0)),
        })
        ax, ay = np.asarray(tt["cx_px"], float), np.asarray(tt["cy_px"], float)
        rx, ry = tx - ax, ty - ay
        rn = np.hypot(rx, ry)
        rx, ry = rx / rn, ry / rn  # unit vector from the trough axis to the ball
        er = (ex * rx + ey * ry)[good]
        et_ = (ex * ry - ey * rx)[good]  # (ry, -rx): the direction theta grows in the image
        m.update({"center_radial_bias_px": float(np.mean(er)),
                  "center_radial_rms_px": float(np.sqrt(np.mean(er ** 2))),
                  "center_tangential_bias_px": float(np.mean(et_)),
                  "center_tangential_rms_px": float(np.sqrt(np.mean(et_ ** 2)))})
    else:
        for k in ("center_rms_px", "center_max_px", "center_p95_px", "center_median_px",
                  "center_bias_x_px", "center_bias_y_px", "center_std_x_px",
                  "center_std_y_px", "center_within_1px", "center_radial_bias_px",
                  "center_radial_rms_px", "center_tangential_bias_px",
                  "center_tangential_rms_px"):
            m[k] = math.nan
    th_true = np.asarray(tt["theta_rad"], float)
    et = fth - th_true
    gt = good & np.isfinite(et)
    if gt.any():
        m.update({
            "theta_rms_rad": float(np.sqrt(np.mean(et[gt] ** 2))),
            "theta_max_rad": float(np.max(np.abs(et[gt]))),
            "theta_bias_rad": float(np.mean(et[gt])),
        })
    else:
        m.update(theta_rms_rad=math.nan, theta_max_rad=math.nan, theta_bias_rad=math.nan)
    # the fitted model against the true angle (what the fit would have to reproduce)
    curve = np.asarray(fit.curve, float)
    if curve.shape == th_true.shape:
        d = curve - th_true
        d = d[np.isfinite(d)]
        m["model_vs_truth_rms_rad"] = float(np.sqrt(np.mean(d ** 2))) if d.size else math.nan
    m["ball_radius_px"] = float(setup.ball_radius / setup.pixel_size)
    m["amplitude0_deg"] = float(np.degrees(abs(case.scenario.theta0)))
    _ = pd  # pandas is used through the DataFrames' methods
    return m


def _lag1_autocorr(r: np.ndarray) -> float:
    """Lag-1 autocorrelation of a residual series (NaN gaps split the pairs)."""
    a, b = r[:-1], r[1:]
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 10:
        return math.nan
    a, b = a[ok] - np.mean(r[np.isfinite(r)]), b[ok] - np.mean(r[np.isfinite(r)])
    den = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / den if den > 0 else math.nan


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
         "mu_engine": _f(ft.mu), "mu_engine_stderr": _f(ft.mu_stderr),
         "mu_engine_bias_rel": (_f(ft.mu) - mu_true) / mu_true if mu_true > 0 else math.nan,
         "fit_rms_residual_rad": _f(ft.rms_residual), "engine": case.scenario.engine,
         "surface": case.scenario.surface, "fit_method": case.fit,
         "n_frames": int(len(traj))}
    m.update({f"t_{k}_s": float(v) for k, v in timings.items()})
    return m
