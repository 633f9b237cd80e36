"""The metrics of one case: the measurement against the simulation's and the render's truth.

The measured mu against the configured one and the engine's (:func:`compute_metrics`), the
located ball centre and angle frame by frame against the rendered silhouette's, how the case
was measured (:func:`mode_metrics`: blind or oracle, the lab's errors, the trough centre used),
the camera's timing as rollfric saw it (:func:`timing_metrics`) and rollfric's uncertainty
budget against the truth (:func:`budget_metrics`). Their names: :data:`METRICS`.
"""

from __future__ import annotations

import math
import re

import numpy as np

from rollfric.uncertainty.budget import SECOND_ORDER, budget
from rollfric.uncertainty.measured import measurement_from_track
from validation.case import Case

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
    return name in METRICS or any(re.fullmatch(p, name) for p in METRIC_PATTERNS)


def finite(x) -> float:
    """``x`` as a float, NaN for None or a value that is not finite."""
    return float(x) if x is not None and math.isfinite(float(x)) else math.nan


def compute_metrics(case: Case, traj, truth, track, fit, fit_truth, setup) -> dict:
    """The flat metric dict of one case (see :mod:`validation.e2e` and docs/guide/validate.md)."""
    mu_true = float(case.scenario.mu)
    m: dict = {"case_id": case.case_id, "name": case.name, "mu_true": mu_true}
    m.update(_mu_metrics(case, track, fit, fit_truth))
    m.update(_frame_metrics(truth, track, fit))
    m["ball_radius_px"] = float(setup.ball_radius / setup.pixel_size)
    m["amplitude0_deg"] = float(np.degrees(abs(case.scenario.theta0)))
    return m


def _mu_metrics(case: Case, track, fit, fit_truth) -> dict:
    """The measured mu against the configured one and the engine's, the fit's own figures, and
    whether its stderr (also inflated for correlated residuals) covers the truth."""
    mu_true = float(case.scenario.mu)
    m: dict = {}
    mu = finite(fit.mu)
    se = finite(fit.mu_stderr)
    mu_eng = finite(fit_truth.mu)
    m.update({
        "mu_recovered": mu,
        "mu_stderr": se,
        "mu_bias": mu - mu_true,
        "mu_bias_rel": (mu - mu_true) / mu_true if mu_true > 0 else math.nan,
        "mu_engine": mu_eng,
        "mu_engine_stderr": finite(fit_truth.mu_stderr),
        "mu_engine_bias_rel": (mu_eng - mu_true) / mu_true if mu_true > 0 else math.nan,
        "mu_pipeline_bias_rel": (mu - mu_eng) / mu_eng if mu_eng > 0 else math.nan,
        "mu_true_within_stderr": bool(abs(mu - mu_true) <= se) if math.isfinite(se) else False,
        "mu_true_within_2stderr": bool(abs(mu - mu_true) <= 2 * se) if math.isfinite(se)
        else False,
        "mu_engine_within_stderr": bool(abs(mu - mu_eng) <= se) if math.isfinite(se)
        else False,
        "mu_z": (mu - mu_true) / se if se > 0 else math.nan,
        "fit_rms_residual_rad": finite(fit.rms_residual),
        "fit_relative_error": finite(getattr(fit, "relative_error", math.nan)),
        "fit_offset_rad": finite(getattr(fit, "offset", 0.0)),
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
    return m


def _aligned_track(track, n: int):
    """The track on the truth's ``n`` frames, aligned on the frame number: (found, x_px, y_px,
    theta_rad), NaN (not found) where the track has no row."""
    tr = track.set_index("frame") if "frame" in track.columns else track
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
    return found, fx, fy, fth


def _frame_metrics(truth, track, fit) -> dict:
    """The located centre and angle frame by frame against the truth (the rendered
    silhouette's centre, the true angle), and the fitted model against the true angle."""
    tt = truth
    n = len(tt)
    found, fx, fy, fth = _aligned_track(track, n)
    m: dict = {}
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


def true_center(metrics: dict) -> tuple[float, float]:
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
