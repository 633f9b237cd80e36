"""Checks that say when a fitted mu cannot be trusted, each with a named reason.

After every fit (:func:`check_fit`) and, for a measurement from a recording, on the track
(:func:`check_track`). A result with any reason is "suspect": ``rollfric fit`` and ``rollfric
measure`` still write it (fit.json ``quality`` and ``quality_reasons``) and exit with status 3.
Every threshold is derived in a comment beside it. The noise a residual is compared with is
measured from the data themselves (:func:`rollfric.fit.filtering.noise_sigma`), so no threshold
assumes a camera or a locator.

Reason codes:

- ``not_converged``: the least-squares search ran out of its evaluation budget.
- ``mu_bound``: mu at (or within two standard errors of) its bound 0, or near its upper bound.
- ``residual_noise``: the residual is far above the noise of the data.
- ``residual_structure``: the residual is not white: the model does not describe the data.
- ``outliers``: many samples lay far off the model and were left out by the robust fit.
- ``angle_range``: angles beyond +-90 deg.
- ``period``: the swings' period disagrees with L = R - r (wrong fps, radius, or units).
- ``half_swings``: too few half-swings for the parameters fitted.
- track checks: ``center`` (the ball's path is not a circle about the centre used),
  ``track_radius`` (the path's radius differs from L = R - r in pixels), ``flagged_frames``
  (many frames rejected), ``background_repaired``, ``ball_radius``, ``timing`` (steps that fit
  no whole number of frame periods), ``located_frames`` (such steps among frames the locator
  lost or got wrong: the located centres', not the timing's), ``swing_coverage`` (the located
  frames cover little of the outer half of the swing on one side of the bottom),
  ``camera_orientation`` (the ball's path is an ellipse that a tilted camera and an
  out-of-round bore explain alike, with mu readings apart: :mod:`rollfric.geometry.pathreading`).
- ``uncertainty`` (``fit``, ``measure``: :func:`rollfric.uncertainty.report.budget_reason`): the
  budget's expanded uncertainty reaches mu.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from rollfric.fit import eom, filtering
from rollfric.fit.air import coefficients_of
from rollfric.fit.filtering import on_grid
from rollfric.uncertainty.period import TRACK_RADIUS_TOL, period_cause, period_reason
from rollfric.uncertainty.reasons import Reason

# --- thresholds -------------------------------------------------------------------------
# residual_noise: a model that describes the data leaves the noise: rms / noise ~ 1 (1.0-1.3
# on drawn and rendered recordings, where locator errors are slightly correlated from frame to
# frame). Three times the noise means two thirds of the residual's variance... 8/9 of it is
# something the model does not explain.
RESIDUAL_RATIO_MAX = 3.0
# residual_structure: for white residuals the lag-1 autocorrelation r1 is ~ N(0, 1/n); a
# systematic misfit (a smooth residual) drives r1 towards 1. Above 0.5 the smooth part of the
# residual carries more variance than its white part (r1 = var_smooth / var_total), and it is
# suspect only when that smooth part also stands out of the noise (the rms check's factor 3 on
# its own share: rms * sqrt(r1) > STRUCTURE_NOISE_MAX * noise).
STRUCTURE_R1_MAX = 0.5
STRUCTURE_NOISE_MAX = 3.0
GEOMETRY_KEYS = ("cylinder_radius", "ball_diameter", "center_px", "fps", "pixel_size")
# outliers: the robust fit left out more than this share of the samples
OUTLIER_FRACTION_MAX = 0.05
# mu_bound: mu within this many standard errors of 0 is not a measured friction
MU_SIGMAS_MIN = 2.0
MU_UPPER_NEAR = 0.9  # of the fitter's upper bound
# center: the ball's centres lie on a circle of radius L about the trough axis; a horizontal
# offset of the centre used of 0.3 % of L (2 px on the thesis camera's 630 px) biased mu by
# -0.24 % on drawn recordings (NOTES); its radius: rollfric.uncertainty.period.TRACK_RADIUS_TOL
CENTER_TOL_REL = 0.003
# flagged_frames: a lab recording with more rejected frames than this has a problem
FLAGGED_FRACTION_MAX = 0.10
# swing_coverage: the share of the frames in the outer half of each half-swing (|theta - offset|
# at least half that half-swing's extreme, by the fitted model) that were located, side by side.
# A fit that sees one side's turning points only trades mu for the setup's errors: a trough
# radius 0.5 mm off (its usual _u) moved mu by 0.2 % with both sides located, by 1.7 % with 72
# %, 4.5 % with 46 % and 12 % with 3 % of one side's outer half located (the 1.58 mm ball's
# exact track at 15 deg, mu = 0.005, 1 s; 8 deg: 0.3 % -> 0.5-1.3 % at 85-45 %); the harsh
# lamp's shadow left 0-3 % of one side located in synth's renders, and mu -39 % with the lab's
# setup. Both sides alike: 1.1 % with 75-84 %, 4 % with 35-44 % located. Below 80 % on either
# side (about 5x the full track's sensitivity) the measurement is suspect.
SIDE_COVERAGE_MIN = 0.8
SIDE_COVERAGE_FRAMES = 20  # frames in a side's outer half before its coverage is judged

def lag1_autocorrelation(res: np.ndarray) -> float:
    """Lag-1 autocorrelation of a series with NaN gaps (pairs across a gap are skipped).

    Parameters
    ----------
    res : array_like
        The series (e.g. a fit's residuals, rad), NaN where there is no sample.

    Returns
    -------
    float
        The correlation of each sample with the next about the series' mean, in [-1, 1];
        NaN with fewer than 8 pairs or a constant series.
    """
    r = np.asarray(res, dtype=float)
    a, b = r[:-1], r[1:]
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 8:
        return float("nan")
    m = float(np.nanmean(r))
    a, b = a[ok] - m, b[ok] - m
    den = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / den if den > 0 else float("nan")

def period_with_image(reason: Reason, setup, track_radius_seen: float) -> Reason:
    """A ``period`` reason judged again with the ball's path in the image (see
    :func:`period_cause`); any other reason as it is.

    Parameters
    ----------
    reason : Reason
        A quality reason of :func:`check_fit`.
    setup : rollfric.setup.model.Setup
        The setup the fit used.
    track_radius_seen : float
        L = R - r as the image shows it (m).

    Returns
    -------
    Reason
    """
    d = reason.detail
    if reason.code != "period" or not d:
        return reason
    cause = period_cause(d["rho"], d["rho_deg"], setup, d["unit_fps"], track_radius_seen)
    return Reason("period", d["head"] + cause, d)


def check_fit(t, theta, result, setup, *, offset: bool = False, model: str = "coulomb",
              guess: dict | None = None, mu_max: float = 1.0,
              noise_floor: float = 1e-8) -> list[Reason]:
    """The quality reasons of a fit ``result`` (:class:`rollfric.fit.result.FitResult`) of
    theta(t).

    ``offset``, ``model``: what was fitted (they set how many half-swings are needed).
    ``guess``: the fitter's self-start of the data (:func:`rollfric.fit.start.initial_guess`: the
    turning points; None skips the swing checks); ``mu_max``: the fitter's upper bound of mu;
    ``noise_floor``: the smallest noise (rad) a residual is compared with.

    Parameters
    ----------
    t, theta : array_like
        The track: times (s) and angles (rad), NaN where the ball was not found.
    result : rollfric.fit.result.FitResult
        The fit of theta(t).
    setup : rollfric.setup.model.Setup
        The setup the fit used.
    offset : bool
        Whether the angle offset of the trough's bottom was fitted.
    model : str
        The friction model fitted ("coulomb", ...).
    guess : dict or None
        The fitter's self-start; None skips the swing checks.
    mu_max : float
        The fitter's upper bound of mu.
    noise_floor : float
        The smallest noise (rad) a residual is compared with.

    Returns
    -------
    list of Reason
        The checks that failed; an empty list means the fit passed every check.
    """

    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    good = np.isfinite(t) & np.isfinite(theta)
    used = result.used if result.used is not None else good & np.isfinite(result.curve)
    reasons = _search_reasons(result, mu_max)
    # angles beyond the trough's side
    n_out = int(np.sum(np.abs(theta[good]) > math.pi / 2))
    if n_out:
        reasons.append(Reason("angle_range", f"{n_out} angle(s) beyond +-90 deg (up to "
                              f"{math.degrees(float(np.max(np.abs(theta[good])))):.0f} deg): a "
                              "ball in a trough stays below its axis; check the units and the "
                              "located frames"))
    reasons += _residual_reasons(t, theta, good, used, result, setup, noise_floor)
    n_outliers = int(result.extra.get("n_outliers", 0) or 0)
    n_fit = n_outliers + int(result.n_samples)
    if n_fit and n_outliers > OUTLIER_FRACTION_MAX * n_fit:
        reasons.append(Reason("outliers", f"{n_outliers} of {n_fit} samples lay far off the "
                              "model and were left out of the fit"))
    if guess is not None:
        misfit = any(r.code in ("residual_noise", "residual_structure") for r in reasons)
        reasons += _swing_reasons(t[good], guess, setup, offset=offset, model=model,
                                  misfit=misfit)
    return reasons


def _search_reasons(result, mu_max: float) -> list[Reason]:
    """``not_converged`` and ``mu_bound``: what the least-squares search says of mu."""
    reasons = []
    if result.extra.get("converged") is False:
        reasons.append(Reason("not_converged", "the fit did not converge within its budget of "
                              f"{result.extra.get('nfev')} evaluations: mu is not a minimum"))
    # mu at a bound
    se = result.mu_stderr
    if result.mu <= 1e-9:
        reasons.append(Reason("mu_bound", f"mu came out at its lower bound (mu = {result.mu:.2g}):"
                              " the data show no friction the model can fit"))
    elif math.isfinite(se) and result.mu < MU_SIGMAS_MIN * se:
        reasons.append(Reason("mu_bound", f"mu = {result.mu:.3g} +- {se:.2g} is not "
                              "distinguishable from 0: the record does not determine mu"))
    elif result.mu >= MU_UPPER_NEAR * mu_max:
        reasons.append(Reason("mu_bound", f"mu = {result.mu:.3g} is at the fitter's upper bound "
                              f"{mu_max:g}"))
    return reasons


def _residual_reasons(t, theta, good, used, result, setup, noise_floor: float) -> list[Reason]:
    """``residual_noise`` and ``residual_structure``: the residual of the samples ``used``
    against the noise of the data, once the smooth map a setup error makes is taken out."""
    reasons = []
    # the residual against the noise of the data
    fps = 1.0 / float(np.median(np.diff(t[good]))) if good.sum() > 1 else 1.0
    tg = t[good]
    noise = filtering.noise_sigma(on_grid(tg, theta[good], fps))
    noise = max(noise, noise_floor) if math.isfinite(noise) else noise_floor
    res = np.where(used, theta - result.curve, np.nan)[good]
    # what a setup error does to the angles (a wrong centre, radius, pixel scale, a lens: a
    # smooth map of the true angle, to third order off + (1 + g1) th + g2 th^2 + g3 th^3) is
    # the uncertainty budget's to cover, not a model that fails: it is taken out first
    fin = np.isfinite(res)
    if fin.sum() > 8:
        m = result.curve[good][fin]
        basis = np.stack([np.ones_like(m), m, m * m, m * m * m], axis=1)
        coef, *_ = np.linalg.lstsq(basis, res[fin], rcond=None)
        res[fin] = res[fin] - basis @ coef
    rg = res[np.isfinite(res)]
    if rg.size:
        rms = float(np.sqrt(np.mean(rg**2)))
        r1 = lag1_autocorrelation(on_grid(tg, res, fps))
        # a setup with stated uncertainties (radius, centre, fps, pixel size) leaves a misfit
        # of the size they allow (0.5 mm of radius: a 0.3 % period, 1e-3 rad over 4 s): the
        # uncertainty budget's re-fits cover it, so the residual alone does not make it suspect
        # (the period and the other checks still apply)
        covered = any(setup.u(k) is not None for k in GEOMETRY_KEYS)
        if covered:
            pass
        elif rms > RESIDUAL_RATIO_MAX * noise:
            reasons.append(Reason("residual_noise", f"the fit's rms residual {rms:.3g} rad is "
                                  f"{rms / noise:.1f} x the noise of the data ({noise:.2g} rad, "
                                  "from their differences): the model does not follow the data"))
        if (not covered and math.isfinite(r1) and r1 > STRUCTURE_R1_MAX
                and rms * math.sqrt(r1) > STRUCTURE_NOISE_MAX * noise):
            reasons.append(Reason("residual_structure", f"the residual is not white (lag-1 "
                                  f"autocorrelation {r1:.2f}, its smooth part {rms * r1**0.5:.2g}"
                                  f" rad vs noise {noise:.2g} rad): the model does not describe "
                                  "the data (friction law, angle offset, setup, or located "
                                  "frames)"))
    return reasons


def _swing_reasons(t_good, guess: dict, setup, *, offset: bool, model: str,
                   misfit: bool = False) -> list[Reason]:
    """``half_swings`` and ``period``: the swings the self-start ``guess`` found before the
    rest, their number against the parameters fitted and their period against L = R - r
    (held closer where the residuals say the model ``misfit``s); ``t_good``: the times of
    the located samples."""
    reasons = []
    t_end = guess["t_rest"] - 0.25 * guess["period"]
    tp_t = np.asarray(guess["turning_points_s"])
    tp_y = np.asarray(guess["turning_points_theta"])[tp_t < t_end]
    tp_t = tp_t[tp_t < t_end]
    need = 1 + int(offset) + int(model == "velocity")
    if tp_t.size + 1 < need:
        what = " and ".join(["mu"] + (["the angle offset"] if offset else [])
                            + (["mu1"] if model == "velocity" else []))
        reasons.append(Reason("half_swings", f"the record has {tp_t.size + 1} half-swing(s),"
                              f" {need} are needed to tell {what} apart (without a turning "
                              "point the friction shifts the swing's centre just as an "
                              "offset does): record longer"))
    period = period_reason(tp_t, tp_y, setup, setup.fps, t_data=t_good, misfit=misfit)
    if period is not None:
        reasons.append(period)
    return reasons


def circle_center(x, y, radius: float, start) -> tuple[float, float, float]:
    """The centre of the circle of the given radius nearest to the points (least squares).

    Parameters
    ----------
    x, y : array_like
        The points (px).
    radius : float
        The circle's radius (px).
    start : sequence of 2 floats
        The first guess of the centre (px).

    Returns
    -------
    tuple of float
        (xc, yc, rms): the centre (px) and the RMS distance of the points from the circle (px).
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)

    def res(c):
        return np.hypot(x - c[0], y - c[1]) - radius

    sol = optimize.least_squares(res, np.asarray(start, dtype=float), x_scale=1.0)
    return float(sol.x[0]), float(sol.x[1]), float(np.sqrt(np.mean(sol.fun**2)))


def check_track(df, setup, center, *, warnings=(), flag_counts=None) -> list[Reason]:
    """Quality reasons of a measured track (a DataFrame of :func:`rollfric.measurement.measure`).

    ``center``: the trough centre (px) the angles were taken about; ``warnings``: the
    measurement's warnings with codes (``[(code, text), ...]``); ``flag_counts``: rejected frames
    by flag.

    Parameters
    ----------
    df : pandas.DataFrame
        The track (columns found, x_px, y_px; xu_px, yu_px when a lens calibration was applied).
    setup : rollfric.setup.model.Setup
        The setup used.
    center : sequence of 2 floats
        The trough centre (px) the angles were taken about.
    warnings : sequence of (str, str)
        The measurement's warnings as (code, text); each becomes a reason.
    flag_counts : dict or None
        Frames by plausibility flag (rollfric.track.plausibility); not_found and off_track are not
        counted as rejected.

    Returns
    -------
    list of Reason
        Centre off the ball's circle ("center"), track radius off L = R - r ("track_radius"),
        more than FLAGGED_FRACTION_MAX of the frames rejected ("flagged_frames"), then the
        warnings; empty when the track passed.
    """
    reasons: list[Reason] = []
    found = df["found"].to_numpy() == 1
    # the undistorted centres when a lens calibration was applied (the angles' own)
    cx_col, cy_col = ("xu_px", "yu_px") if "xu_px" in df.columns else ("x_px", "y_px")
    x = df[cx_col].to_numpy()[found]
    y = df[cy_col].to_numpy()[found]
    L_px = setup.track_radius / setup.pixel_size
    if x.size >= 10:
        xc, yc, _ = circle_center(x, y, L_px, center)
        d = np.hypot(x - center[0], y - center[1])
        dist = float(np.median(d))
        theta = np.arctan2(x - center[0], y - center[1])
        # the horizontal offset is what biases mu; it is only seen when the ball swings
        # sideways enough (sin theta spread): its error is the distance scatter over it
        spread = float(np.std(np.sin(theta)))
        # an offset within three of the lab's stated standard uncertainties is expected
        u_c = setup.u("center_px") if setup.center_px is not None else None
        u_x = float(np.ravel(u_c)[0]) if u_c is not None else 0.0
        if spread > 0.02 and abs(xc - center[0]) > max(CENTER_TOL_REL * L_px, 3 * u_x):
            reasons.append(Reason("center", f"the ball's centres lie on a circle about "
                                  f"({xc:.1f}, {yc:.1f}) px, the angles were taken about "
                                  f"({center[0]:.1f}, {center[1]:.1f}) px ("
                                  f"{xc - center[0]:+.1f} px sideways): check center_px"))
        if abs(dist / L_px - 1) > TRACK_RADIUS_TOL:
            reasons.append(Reason("track_radius", f"the ball's centres lie {dist:.1f} px from the"
                                  f" centre used, L = R - r is {L_px:.1f} px "
                                  f"({100 * (dist / L_px - 1):+.1f} %): check center_px (its "
                                  "height), camera.pixel_size_mm, cylinder.radius_mm"))
    n = len(df)
    # the plausibility checks' rejections (frames without a ball are counted in n_found)
    rejected = {k: v for k, v in (flag_counts or {}).items()
                if k not in ("not_found", "off_track")}
    flagged = sum(rejected.values())
    if n and flagged > FLAGGED_FRACTION_MAX * n:
        kinds = ", ".join(f"{k} {v}" for k, v in sorted(rejected.items()))
        reasons.append(Reason("flagged_frames", f"{flagged} of {n} frames were rejected "
                              f"({kinds}): check the recording"))
    for code, text in warnings:
        reasons.append(Reason(code, text))
    return reasons


def track_radius_seen(df, setup, center) -> float | None:
    """L = R - r as the image shows it (m): the found centres' median distance from the
    trough centre (px, undistorted where a lens calibration was applied) times
    camera.pixel_size_mm; None with fewer than 10 found frames.

    Parameters
    ----------
    df : pandas.DataFrame
        The track (columns found, x_px, y_px; xu_px, yu_px when undistorted).
    setup : rollfric.setup.model.Setup
        The setup used.
    center : sequence of 2 floats
        The trough centre (px) the angles were taken about.

    Returns
    -------
    float or None
    """
    found = df["found"].to_numpy() == 1
    cx_col, cy_col = ("xu_px", "yu_px") if "xu_px" in df.columns else ("x_px", "y_px")
    x, y = df[cx_col].to_numpy()[found], df[cy_col].to_numpy()[found]
    if x.size < 10:
        return None
    return float(np.median(np.hypot(x - center[0], y - center[1]))) * setup.pixel_size


def swing_coverage(found, result, setup) -> dict:
    """The located share of the outer half of the swing on either side of the bottom.

    The fitted model (:func:`rollfric.fit.result.model_theta`, by :func:`rollfric.fit.eom.solve`)
    from
    the fit's first sample on is cut into half-swings (the model's sign changes about its
    offset); a frame is in a half-swing's outer half when |theta - offset| is at least half
    that half-swing's extreme. The frames before the first located one count as lost frames of
    the first side's outer half when the ball comes in from there (it was farther out).

    Parameters
    ----------
    found : array_like of bool
        Which frames were located and kept, one a sample of ``result.t``.
    result : rollfric.fit.result.FitResult
        The fit.
    setup : rollfric.setup.model.Setup
        The setup fitted with.

    Returns
    -------
    dict
        ``{"right": (located, frames), "left": (located, frames)}``: right is theta > 0
        (right of the bottom in the image); empty when the model cannot be evaluated.
    """
    t = np.asarray(result.t, dtype=float)
    found = np.asarray(found, dtype=bool)
    if t.shape != found.shape or not (math.isfinite(result.mu) and math.isfinite(result.theta0)
                                      and math.isfinite(result.omega0)):
        return {}
    after = np.isfinite(t) & (t >= result.t0)
    if after.sum() < 3 or np.any(np.diff(t[after]) <= 0):
        return {}
    try:
        # rollfric.fit.result.model_theta less its offset (quality may not import fit)
        model, _, _ = eom.solve(result.theta0 - result.offset, result.omega0, result.mu,
                                t[after], track_radius=setup.track_radius,
                                gravity=setup.gravity, mu1=result.mu1,
                                air=coefficients_of(setup))
    except (ValueError, FloatingPointError):
        return {}
    got = found[after]
    out = {"right": [0, 0], "left": [0, 0]}
    sign = np.sign(model)
    # the frames before the first located one, while the ball comes in towards the bottom
    # (a release in a shadow): farther out than that frame, lost on its side's outer half
    before = int(np.sum(np.isfinite(t) & (t < result.t0)))
    if before and sign[0] != 0 and result.omega0 * sign[0] < 0:
        out["right" if sign[0] > 0 else "left"][1] += before
    for seg in np.split(np.arange(model.size), np.flatnonzero(np.diff(sign) != 0) + 1):
        if seg.size == 0 or sign[seg[0]] == 0:
            continue
        a = np.abs(model[seg])
        outer = seg[a >= 0.5 * a.max()]
        side = out["right" if sign[seg[0]] > 0 else "left"]
        side[0] += int(got[outer].sum())
        side[1] += int(outer.size)
    return {k: (v[0], v[1]) for k, v in out.items()}


def swing_coverage_reason(found, result, setup) -> Reason | None:
    """The quality reason ``swing_coverage``: one side of the swing's outer half mostly lost.

    Parameters
    ----------
    found : array_like of bool
        Which frames were located and kept (one a sample of the fit).
    result : rollfric.fit.result.FitResult
        The fit.
    setup : rollfric.setup.model.Setup
        The setup fitted with.

    Returns
    -------
    Reason or None
        When a side with at least SIDE_COVERAGE_FRAMES frames in its outer half has less
        than SIDE_COVERAGE_MIN of them located.
    """
    cov = swing_coverage(found, result, setup)
    frac = {k: v[0] / v[1] for k, v in cov.items() if v[1] >= SIDE_COVERAGE_FRAMES}
    if not frac:
        return None
    worst = min(frac, key=frac.get)
    if frac[worst] >= SIDE_COVERAGE_MIN:
        return None
    other = "left" if worst == "right" else "right"
    sign = ">" if worst == "right" else "<"
    rest = (f", {100 * frac[other]:.0f} % on the {other}" if other in frac else "")
    return Reason("swing_coverage", (
        f"the ball was located in only {100 * frac[worst]:.0f} % of the outer half of the "
        f"swing {worst} of the bottom (theta {sign} 0; {cov[worst][0]} of {cov[worst][1]} "
        f"frames{rest}): a fit that misses the turning points turns errors "
        "of the setup (cylinder.radius_mm, camera.fps, center_px) into mu many times over (a "
        "trough radius 0.5 mm off: mu 4.5 % off with 46 % of one side located, 0.2 % with "
        "both sides whole); check the lighting on that side (the ball in a shadow) and the "
        "field of view (track.csv, the overlays)"))
