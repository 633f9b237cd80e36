"""The ball's motion as the camera records it: a trajectory loaded (or simulated from a
scenario), cut to the camera's frames (its clock: :mod:`synth.camera_clock`), the ball's
centres at each exposure's sub-frames (motion blur), and the exact truth per frame.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

import sim
from synth.camera import CameraModel
from synth.camera_clock import frame_times, resample
from synth.config import SynthError


def load_trajectory(source):
    """A sim.Trajectory from a Trajectory, a trajectory CSV or a scenario TOML (simulated)."""
    if isinstance(source, sim.Trajectory):
        traj = source
    else:
        path = Path(source)
        if not path.exists():
            raise SynthError(f"trajectory not found: {path}")
        if path.suffix.lower() == ".toml":
            return sim.simulate(sim.load_scenario(path))
        traj = sim.read_trajectory(path)
    for name in ("t", "theta", "theta_dot", "position"):
        if not np.all(np.isfinite(getattr(traj, name))):
            raise SynthError(f"the trajectory has NaN or inf in {name}: it cannot be rendered")
    return traj


def subframe_positions(traj, n_sub: int, exposure: float) -> np.ndarray:
    """(N, n_sub, 3) ball centres at the sub-frame times of each exposure.

    The exposure of frame i is centred on t_i; sub-frame k sits at t_i + ((k + 0.5) / n_sub
    - 0.5) * exposure. Positions between samples follow a cubic Hermite spline through the
    sampled positions with the rolling velocity L theta_dot (cos theta, sin theta, 0); an
    out-of-round or tilted trough (whose ball is not on that circle) uses a cubic spline
    through the positions.
    """
    pos = np.asarray(traj.position, float)
    if n_sub == 1:
        return pos[:, None, :]
    from scipy.interpolate import CubicHermiteSpline, CubicSpline  # ~0.1 s, for motion blur

    t = np.asarray(traj.t, float)
    offs = ((np.arange(n_sub) + 0.5) / n_sub - 0.5) * exposure
    sc = traj.scenario
    if sc.ovality or sc.tilt:
        return CubicSpline(t, pos, axis=0, extrapolate=True)(t[:, None] + offs[None, :])
    L = math.hypot(pos[0, 0], pos[0, 1])
    th, thd = np.asarray(traj.theta), np.asarray(traj.theta_dot)
    vel = L * thd[:, None] * np.column_stack([np.cos(th), np.sin(th), np.zeros_like(th)])
    spline = CubicHermiteSpline(t, pos, vel, axis=0, extrapolate=True)
    return spline(t[:, None] + offs[None, :])


def truth_table(traj, camera: CameraModel, ball_radius: float) -> dict:
    """The truth columns (TRUTH_COLUMNS). Through a lens the ball's positions are the distorted
    ones of its ideal projections (:meth:`CameraModel.recorded`: the sphere centre's and the
    silhouette centre's); the axis (cx_px, cy_px) stays in the ideal (undistorted) image."""
    pos = np.asarray(traj.position, float)
    uv = camera.recorded(camera.project(pos))
    sil, rad = camera.sphere_silhouette(pos, ball_radius)
    sil = camera.recorded(sil)
    n = len(pos)
    return {
        "t_s": np.asarray(traj.t, float),
        "theta_rad": np.asarray(traj.theta, float),
        "theta_dot_rad_s": np.asarray(traj.theta_dot, float),
        "x_px": uv[:, 0], "y_px": uv[:, 1],
        "sil_x_px": sil[:, 0], "sil_y_px": sil[:, 1],
        "r_px": rad,
        "cx_px": np.full(n, camera.center_px[0]), "cy_px": np.full(n, camera.center_px[1]),
    }


def camera_frames(traj, frames=None, timing=None, seed: int = 0):
    """The trajectory at the camera's frames and what its clock did.

    Parameters
    ----------
    traj : sim.Trajectory
        The simulated trajectory.
    frames : int, optional
        Keep only the first ``frames`` frames.
    timing : synth.camera_clock.FrameTiming, optional
        The camera's clock (jitter, dropped frames), drawn with ``seed``; the trajectory is
        then resampled at the real sample times.
    seed : int, optional
        The recording's seed.

    Returns
    -------
    traj : sim.Trajectory
        At the recorded frames.
    timing_attrs : dict or None
        The clock's settings and its dropped frames (None without a clock).
    """
    timing_attrs = None
    if timing is not None:
        times, numbers = frame_times(len(traj), traj.fps, timing, seed)
        if not timing.ideal:
            traj = resample(traj, times)
        lost = np.setdiff1d(np.arange(numbers[-1] + 1), numbers)
        timing_attrs = {**timing.to_dict(), "dropped_frames": lost.tolist()}
    n = len(traj) if frames is None else int(frames)
    if n < 1 or n > len(traj):
        raise SynthError(f"frames must be 1..{len(traj)}, got {frames!r}")
    if n < len(traj):
        traj = _head(traj, n)
    return traj, timing_attrs


def _head(traj, n: int):
    fields = {}
    for f in dataclasses.fields(sim.Trajectory):
        v = getattr(traj, f.name)
        fields[f.name] = v[:n] if isinstance(v, np.ndarray) else v
    return sim.Trajectory(**fields)
