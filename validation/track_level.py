"""A case at the track level: the ball's image positions from the exact projection, not a render.

For error sources that do not change how the ball looks to the locator (the geometry the lab
types against the one built, the frame rate, a hand-measured trough centre, camera roll,
physics the fitter does not assume) rendering every frame only adds the locator's small,
already-validated noise. A track-level case (``[sweep] stages = "track"``, or ``stages`` in
one ``[[cases]]`` table) does what ``rollfric measure`` does with the located centres replaced
by the truth:

1. sim simulates the scenario (as built);
2. the ball's located centres are the **silhouette centres** of synth's exact projection
   (:func:`synth.pipeline.truth_table`: the camera's roll, perspective and lens included) plus
   Gaussian noise of ``LOCATOR_SIGMA_PX`` per axis (the default case's measured centre error,
   0.024 px rms), seeded by the case's ``render.seed``;
3. the trough centre is the lab's ``center_px`` when it measured one, else found from the
   contour of the **rendered background** (one frame is rendered, with the case's lens, scale
   and noise; :func:`rollfric.geometry.trough.find_cylinder_center`, as ``rollfric measure`` does);
4. angles (undistorted first when the lab has a lens calibration), times frame / camera.fps of
   the lab's setup, the offset decided and mu fitted by rollfric's own functions.

What it leaves out, so the sources that need it are run rendered (``stages = "full"``): how the
ball's image is located (lighting, noise, blur, defocus, compression, the silhouette bent by a
lens: 0.06 % of mu at k1 = -0.18), frame-level timing (jitter, dropped frames, timestamps) and
rollfric's per-frame plausibility checks. Its metrics are :func:`validation.e2e.run_case`'s
without the uncertainty budget (with it when the case sets ``measure.budget = true``
explicitly: a coverage study at the track level), plus ``stages`` = "track".
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

import sim
import synth
from rollfric.fit.estimate import fit_mu
from rollfric.fit.offset import resolve_offset
from rollfric.geometry.theta import angles
from rollfric.geometry.trough import find_cylinder_center
from rollfric.io import readers as io
from rollfric.io.background_choice import resolve_background
from rollfric.setup.lens import Calibration
from rollfric.setup.model import Setup, setup_from_dict
from synth.pipeline import truth_table
from validation.case import Case, case_from_dict
from validation.e2e import case_offset
from validation.metrics import budget_metrics, compute_metrics, mode_metrics, true_center

LOCATOR_SIGMA_PX = 0.017  # per axis: 0.024 px rms in 2-D, the blind default case's centre error

# the case keys (dotted prefixes) the track level represents exactly: the truth (sim), the lab,
# how rollfric measures, the camera's pose, projection and lens. Any other render.* key changes
# the ball's image or its timing: such a case is run rendered (validation.sweep)
EXACT_KEYS = ("scenario.", "lab.", "measure.", "render.seed", "render.camera.roll_deg",
              "render.camera.lens_distortion", "render.camera.lens_matrix",
              "render.camera.projection", "render.camera.working_distance",
              "render.camera.center_px", "render.camera.width", "render.camera.height")


def exact_at_track_level(keys) -> bool:
    """Whether a case changing these dotted keys is represented exactly at the track level.

    Parameters
    ----------
    keys : iterable of str
        Dotted case keys.

    Returns
    -------
    bool
    """
    return all(any(k == e or k.startswith(e) for e in EXACT_KEYS) for k in keys)


def located_centres(truth: dict, sigma_px: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The silhouette centres of the truth plus the locator's noise (px).

    Parameters
    ----------
    truth : dict
        :func:`synth.pipeline.truth_table`'s columns (``sil_x_px``, ``sil_y_px``).
    sigma_px : float
        Standard deviation per axis, px.
    seed : int
        Seed of the noise.

    Returns
    -------
    x, y : numpy.ndarray
        The located centres, px.
    """
    x = np.asarray(truth["sil_x_px"], float)
    y = np.asarray(truth["sil_y_px"], float)
    rng = np.random.default_rng([int(seed), 0x747261636B])  # "track"
    return x + rng.normal(0.0, sigma_px, x.shape), y + rng.normal(0.0, sigma_px, y.shape)


def oracle_setup(case: Case):
    """The setup synth stores with a recording of ``case`` (exact geometry, center_px, lens)."""
    base = case.scenario.setup()
    cam = case.scene.camera
    return Setup(cylinder_radius=base.cylinder_radius, ball_diameter=base.ball_diameter,
                 ball_mass=base.ball_mass, fps=base.fps, pixel_size=cam.pixel_size,
                 center_px=cam.center_px, gravity=base.gravity, air_density=base.air_density,
                 calibration=None if cam.lens is None else
                 Calibration(cam.lens.matrix, cam.lens.distortion))


def _background_key(case: Case, radius_px: float, lens) -> str:
    """What the contour depends on: the scene (camera, lens, lamps), the sensor and its seed,
    the as-built trough radius, and the setup's radius in px and lens calibration."""
    return json.dumps({"scene": case.scene.to_dict(), "sensor": case.sensor.to_dict(),
                       "seed": case.render_seed, "R": case.scenario.cylinder_radius,
                       "radius_px": radius_px, "lens": lens}, sort_keys=True, default=str)


_CONTOURS: dict = {}  # per process: background key -> (centre, description)
_CONTOURS_MAX = 16


def _contour(case: Case, radius_px: float, lens) -> tuple[tuple[float, float], str]:
    """(centre, description) of the trough contour in the case's rendered background; cached
    per process for the same background and setup."""
    key = _background_key(case, radius_px, lens)
    if key in _CONTOURS:
        return _CONTOURS[key]
    cal = None if lens is None else Calibration(lens["matrix"], lens["distortion"])
    traj = sim.simulate(case.scenario.replace(duration=2.0 / case.scenario.fps))
    tmp = Path(tempfile.mkdtemp(prefix="rollfric-bg-"))
    try:
        rec = synth.render(traj, tmp / "bg.zarr", scene=case.scene, sensor=case.sensor,
                           seed=case.render_seed, frames=1, workers=1, threads=1,
                           overwrite=True)
        src = io.open_recording(rec)
        r_px = case.scenario.ball_radius / case.scene.camera.pixel_size
        bg, _, _ = resolve_background(src, None, r_px=r_px)
        c = find_cylinder_center(bg, radius_px=radius_px,
                                 undistort=None if cal is None else cal.undistort)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    out = (float(c.center[0]), float(c.center[1])), (
        f"contour in the rendered background ({c.n_points} points over {c.arc_deg:.0f} deg, "
        f"radius {c.radius:.1f} px)")
    if len(_CONTOURS) >= _CONTOURS_MAX:
        _CONTOURS.pop(next(iter(_CONTOURS)))
    _CONTOURS[key] = out
    return out


def trough_center(case: Case, setup) -> tuple[tuple[float, float], str]:
    """The trough centre rollfric would use: the setup's ``center_px``, else the contour of the
    case's rendered background (px; undistorted when the setup has a lens calibration).

    Parameters
    ----------
    case : Case
        The case.
    setup : rollfric.setup.model.Setup
        The setup rollfric is given.

    Returns
    -------
    center : tuple of float
        (xc, yc), px.
    source : str
        Where it came from.
    """
    if setup.center_px is not None:
        return tuple(float(v) for v in setup.center_px), "setup center_px"
    cal = setup.calibration
    lens = None if cal is None else {"matrix": [list(map(float, r)) for r in cal.matrix],
                                     "distortion": [float(v) for v in cal.distortion]}
    return _contour(case, float(setup.cylinder_radius / setup.pixel_size), lens)


@dataclasses.dataclass(frozen=True, eq=False)
class TrackCase:
    """What a track-level case measured (arrays kept for plots)."""

    case: Case
    trajectory: object  # sim.Trajectory
    truth: object  # pandas.DataFrame: synth's truth columns
    track: object  # pandas.DataFrame: frame, t_s, x_px, y_px, theta_rad, found
    fit: object  # rollfric.fit.estimate.FitResult
    fit_truth: object  # the same fitter on the engine's theta(t)
    setup: object  # the setup rollfric was given
    center_px: tuple  # the trough centre used (px)
    undistorted: bool
    offset_fitted: bool
    timings: dict


def measure_track(case: Case | dict, *, sigma_px: float = LOCATOR_SIGMA_PX) -> TrackCase:
    """Simulate a case and measure it at the track level (module docstring).

    Parameters
    ----------
    case : Case or dict
        The case.
    sigma_px : float
        The locator's noise per axis, px.

    Returns
    -------
    TrackCase
    """
    if isinstance(case, dict):
        case = case_from_dict(case)
    timings: dict = {}
    t0 = time.perf_counter()
    traj = sim.simulate(case.scenario)
    setup_truth = case.scenario.setup()
    fit_truth = fit_mu(traj.t, traj.theta, setup_truth, method=case.fit,
                       offset=case_offset(case, traj.t, traj.theta, setup_truth))
    timings["simulate"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    cam = case.scene.camera
    truth = truth_table(traj, cam, case.scenario.ball_radius)
    x, y = located_centres(truth, sigma_px, case.render_seed)
    setup = oracle_setup(case) if case.oracle else \
        setup_from_dict(case.lab_setup_dict(), source="the lab's setup")
    center, _ = trough_center(case, setup)
    lens = setup.calibration
    if lens is not None:
        xy = lens.undistort(np.column_stack([x, y]))
        xu, yu = xy[:, 0], xy[:, 1]
    else:
        xu, yu = x, y
    theta = angles(xu, yu, center)
    n = len(theta)
    t = np.arange(n) / setup.fps
    use, _ = resolve_offset(case.offset, t, theta, setup, case.fit)
    fit = fit_mu(t, theta, setup, method=case.fit, offset=use)
    timings["measure"] = time.perf_counter() - t1
    track = pd.DataFrame({"frame": np.arange(n), "t_s": t, "x_px": x, "y_px": y,
                          "theta_rad": theta, "found": np.ones(n, dtype=int)})
    timings["total"] = time.perf_counter() - t0
    return TrackCase(case=case, trajectory=traj, truth=pd.DataFrame(truth), track=track,
                     fit=fit, fit_truth=fit_truth, setup=setup, center_px=center,
                     undistorted=lens is not None, offset_fitted=use, timings=timings)


def run_track_case(case: Case | dict, *, sigma_px: float = LOCATOR_SIGMA_PX) -> dict:
    """One case at the track level (module docstring): its metrics.

    Parameters
    ----------
    case : Case or dict
        The case.
    sigma_px : float
        The locator's noise per axis, px.

    Returns
    -------
    dict
        :func:`validation.metrics.compute_metrics` and :func:`validation.metrics.mode_metrics`, with
        ``stages`` = "track", ``locator_sigma_px`` and the stage times.
    """
    tc = measure_track(case, sigma_px=sigma_px)
    metrics = compute_metrics(tc.case, tc.trajectory, tc.truth, tc.track, tc.fit, tc.fit_truth,
                              tc.setup)
    info = SimpleNamespace(center_px=tc.center_px, undistorted=tc.undistorted,
                           offset_fitted=tc.offset_fitted)
    metrics.update(mode_metrics(tc.case, info, tc.truth))
    if tc.case.data.get("measure", {}).get("budget") is True and tc.fit.method == "lsq":
        # what rollfric.measurement.measure tells the budget (TrackInfo's fields it reads)
        info = SimpleNamespace(**vars(info), setup=tc.setup, angle="atan2",
                               times="frame / camera.fps")
        metrics.update(budget_metrics(tc.case, tc.track, info, tc.fit,  # with t_budget_s
                                      true_center(metrics)))
    metrics.update({f"t_{k}_s": float(v) for k, v in tc.timings.items()})
    cam = tc.case.scene.camera
    metrics.update({"stages": "track", "locator_sigma_px": float(sigma_px),
                    "n_frames": int(len(tc.track)), "frame_width_px": int(cam.width),
                    "frame_height_px": int(cam.height)})
    return metrics
