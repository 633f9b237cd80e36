"""The camera's timing: when each recorded frame was really taken.

A lab camera does not take frame k at exactly k / fps: its exposures start with a little jitter,
and a camera (or the link to the computer) can drop a frame now and then, so the recording holds
one frame fewer and every later frame is one period later than its index says. Some formats
carry each frame's time (a Phantom cine's TIME64 block; here the store's ``timestamps`` array),
most (TIFF stacks, image folders, video files) do not.

:class:`FrameTiming` says how the camera misbehaves; :func:`frame_times` draws the real sample
times of the recorded frames from it (seeded) and :func:`resample` evaluates the simulated
trajectory at those times, so synth's truth (``truth/t_s``) holds the real times and the frames
show the ball where it really was::

    timing = FrameTiming(jitter=5e-6, dropped=(120, 640))
    times, numbers = frame_times(n_camera_frames, fps, timing, seed)
    traj_rec = resample(traj, times)

Between the simulated samples (one a camera period) the angle follows a cubic Hermite spline
through theta and theta_dot (its error is below 1e-10 rad for a 5 us shift at 1 kHz: the
fourth derivative's term, dt^4 omega^4 theta / 384).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

import sim
from synth.config import SynthError

# the jitter's standard deviation must stay well below a period (frames keep their order)
MAX_JITTER_PERIODS = 0.1


@dataclasses.dataclass(frozen=True)
class FrameTiming:
    """How the camera's frame times differ from frame / fps.

    Attributes
    ----------
    jitter : float
        Standard deviation of each exposure's start about its nominal time (s); independent
        Gaussian draws, one a frame (0: none).
    drop_rate : float
        Probability that a frame is lost (each frame but the first, independently; 0: none).
    dropped : tuple of int
        The camera frames (numbered as the camera took them, 0 = the first) that are lost, on
        top of the drawn ones.
    timestamps : bool
        Whether the recording carries each frame's real time (the store's ``timestamps``).
    """

    jitter: float = 0.0
    drop_rate: float = 0.0
    dropped: tuple[int, ...] = ()
    timestamps: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.jitter) and self.jitter >= 0):
            raise SynthError(f"timing jitter must be >= 0 s, got {self.jitter!r}")
        if not (math.isfinite(self.drop_rate) and 0 <= self.drop_rate < 0.5):
            raise SynthError(f"timing drop_rate must be in [0, 0.5), got {self.drop_rate!r}")
        d = tuple(sorted({int(v) for v in self.dropped}))
        if any(v < 1 for v in d):
            raise SynthError(f"timing dropped frames must be camera frames >= 1 (frame 0 starts "
                             f"the recording), got {list(self.dropped)}")
        object.__setattr__(self, "dropped", d)
        object.__setattr__(self, "timestamps", bool(self.timestamps))

    @property
    def ideal(self) -> bool:
        """True when every frame is taken at frame / fps (no jitter, no drops)."""
        return self.jitter == 0 and self.drop_rate == 0 and not self.dropped

    def to_dict(self) -> dict:
        """The timing as plain data (the form stored in a recording's attributes).

        Returns
        -------
        dict
        """
        return {"jitter": self.jitter, "drop_rate": self.drop_rate,
                "dropped": list(self.dropped), "timestamps": self.timestamps}


def frame_times(n: int, fps: float, timing: FrameTiming, seed: int = 0):
    """The real times of the frames a camera with ``timing`` records out of ``n`` periods.

    Parameters
    ----------
    n : int
        Frames the camera takes (its periods, dropped ones included).
    fps : float
        The camera's true frame rate (Hz).
    timing : FrameTiming
        Its jitter and dropped frames.
    seed : int
        Seed of the jitter and drop draws (same seed, same times).

    Returns
    -------
    times : numpy.ndarray
        (M,) real time of each recorded frame (s), within 0..(n - 1) / fps: M = n - the
        dropped frames (- the last, when its jitter puts it after the record's end).
    numbers : numpy.ndarray
        (M,) the camera's frame number of each recorded frame.

    Raises
    ------
    SynthError
        A jitter of a tenth of a period or more, a dropped frame beyond the record, or nothing
        left to record.
    """
    if timing.jitter * fps >= MAX_JITTER_PERIODS:
        raise SynthError(f"timing jitter {timing.jitter * 1e6:g} us is {timing.jitter * fps:.2g}"
                         f" of a period at {fps:g} Hz: at most {MAX_JITTER_PERIODS:g}")
    if timing.dropped and timing.dropped[-1] >= n:
        raise SynthError(f"timing dropped frame {timing.dropped[-1]} is beyond the record's "
                         f"{n} frames")
    rng = np.random.default_rng([int(seed), 0x7131])
    keep = rng.random(n) >= timing.drop_rate
    keep[0] = True
    keep[list(timing.dropped)] = False
    jitter = rng.standard_normal(n) * timing.jitter
    numbers = np.nonzero(keep)[0]
    if numbers.size < 2:
        raise SynthError("the timing drops every frame but one")
    times = numbers / fps + jitter[numbers] - jitter[0]  # frame 0 at t = 0
    if np.any(np.diff(times) <= 0):  # cannot happen below MAX_JITTER_PERIODS, checked anyway
        raise SynthError("the timing's jitter put two frames out of order")
    # the motion is known over n periods: a last exposure the jitter puts after its end is not
    # recorded (the camera stopped with it)
    inside = times <= (n - 1) / fps
    return times[inside], numbers[inside]


def resample(traj, times):
    """The trajectory at other times within its span (a new sim.Trajectory).

    theta follows a cubic Hermite spline through (theta, theta_dot); the ball's centre one
    through its positions with the rolling velocity L theta_dot (cos theta, sin theta, v_z)
    (v_z from a spline of the axial position: a 3-D motion along a tilted trough);
    theta_dot, the angular velocity, normal force and slip speed are interpolated linearly and
    the orientation by spherical linear interpolation.

    Parameters
    ----------
    traj : sim.Trajectory
        The simulated trajectory (one sample a camera period).
    times : array_like
        (M,) times (s) within [traj.t[0], traj.t[-1]].

    Returns
    -------
    sim.Trajectory
        The same scenario and meta, sampled at ``times``.

    Raises
    ------
    SynthError
        A time outside the trajectory.
    """
    from scipy.interpolate import CubicHermiteSpline, CubicSpline
    from scipy.spatial.transform import Rotation, Slerp

    t = np.asarray(traj.t, float)
    ts = np.asarray(times, float)
    if ts.size and (ts.min() < t[0] - 1e-12 or ts.max() > t[-1] + 1e-12):
        raise SynthError(f"times {ts.min():g}..{ts.max():g} s lie outside the trajectory's "
                         f"{t[0]:g}..{t[-1]:g} s")
    ts = np.clip(ts, t[0], t[-1])
    th, thd = np.asarray(traj.theta, float), np.asarray(traj.theta_dot, float)
    pos = np.asarray(traj.position, float)
    L = np.hypot(pos[:, 0], pos[:, 1])
    vz = CubicSpline(t, pos[:, 2]).derivative()(t)
    vel = np.column_stack([L * thd * np.cos(th), L * thd * np.sin(th), vz])
    q = np.asarray(traj.quaternion, float)  # wxyz
    rot = Slerp(t, Rotation.from_quat(q[:, [1, 2, 3, 0]]))(ts).as_quat()

    def lin(a):
        a = np.asarray(a, float)
        if a.ndim == 1:
            return np.interp(ts, t, a)
        return np.column_stack([np.interp(ts, t, a[:, k]) for k in range(a.shape[1])])

    return sim.Trajectory(
        t=ts, theta=CubicHermiteSpline(t, th, thd)(ts), theta_dot=lin(thd),
        position=CubicHermiteSpline(t, pos, vel, axis=0)(ts),
        quaternion=rot[:, [3, 0, 1, 2]], angular_velocity=lin(traj.angular_velocity),
        normal_force=lin(traj.normal_force), slip_speed=lin(traj.slip_speed),
        scenario=traj.scenario, meta=dict(getattr(traj, "meta", {})))
