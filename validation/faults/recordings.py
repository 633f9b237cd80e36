"""The lab's faults with a known truth: drawn recordings (fast, no renderer) made faulty as a
lab's are, for the fault study (:mod:`validation.studies.faults`) and the tests.

:func:`clean` draws a ball on the equation of motion (:mod:`synth.drawn.frames`) in a
480 x 280 frame with a 200 px trough whose walls show on both sides (the static scene a
camera's motion is measured on); :func:`faulty` makes one of :data:`FAULTS` of it:

- ``held``: the ball held still at its release angle for ``magnitude`` frames (frames 0 ..
  N - 1 show it at one place), then released from rest;
- ``rest``: the ball at rest from a turning point on (the one nearest ``magnitude`` times
  the frame count), every later frame showing it there;
- ``bump``: the camera moved by ``magnitude`` px (right) from frame ``n // 2`` on;
- ``drift``: the camera drifting to ``magnitude`` px (right and down, 2:1) by the last frame;
- ``yaw``, ``pitch``: the camera turned by ``magnitude`` deg against the trough axis (the
  ball's path an ellipse), the lab's ``center_px`` in the setup;
- ``flicker``: the lamps' 100 Hz mains flicker, a frame gain of 1 + ``magnitude`` sin(...);
- ``timestamps_ms``, ``timestamps_us``: per-frame timestamps in ms or us (``magnitude``: the
  time of frame 0 in s);
- ``fps``, ``radius``: the setup's camera.fps or cylinder radius ``magnitude`` times the true;
- ``gravity``: the setup's gravity ``magnitude`` m/s^2 (the motion has the standard g);
- ``glitches``: ``magnitude`` of the frames each corrupt, swapped, repeated and flashed
  (:func:`validation.faults.glitches.glitch_frames`).

Each returns a :class:`Recording`: the frames as a FrameSource, the setup as the lab would give
it (wrong where the fault is the setup), the background, the true mu and what the fault is
(``truth``). Everything random comes from ``seed``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rollfric.fit import eom
from rollfric.io.source import BaseSource
from rollfric.setup.model import Setup
from synth.drawn.frames import Scene, make_frames
from validation.faults import camera as camera_faults
from validation.faults.glitches import glitch_frames

R = 85.3e-3  # the trough's radius (m), 200 px
PIX = R / 200.0
MAINS_FLICKER_HZ = 100.0  # an AC lamp's brightness swings at twice the 50 Hz mains

FAULTS = ("held", "rest", "bump", "drift", "yaw", "pitch", "flicker", "timestamps_ms",
          "timestamps_us", "fps", "radius", "gravity", "glitches")


class ArraySource(BaseSource):
    """Frames in memory as a FrameSource, with per-frame ``timestamps`` (s, or the unit a
    fault gives them) when given."""

    def __init__(self, frames, *, timestamps=None, name: str = "faults"):
        frames = [np.asarray(f) for f in frames]
        super().__init__(name, len(frames), frames[0].shape, frames[0].dtype)
        self.frames = frames
        self.timestamps = None if timestamps is None else np.asarray(timestamps, float)

    def __getitem__(self, i):
        return self.frames[self._index(i)].copy()


@dataclasses.dataclass
class Recording:
    """A drawn recording and its truth.

    Attributes
    ----------
    source : ArraySource
        The frames (and timestamps) as the measurement reads them.
    setup : rollfric.setup.model.Setup
        The setup the lab gives (wrong where the fault is the setup's).
    background : numpy.ndarray or None
        The background image without the ball; None: the measurement makes its own.
    mu : float
        The true mu.
    theta : numpy.ndarray
        The ball's true angle in each frame (rad).
    centers : numpy.ndarray
        (T, 2): where the ball's centre is drawn in each frame (px, after the camera's faults).
    fault : str
        One of :data:`FAULTS`, or "clean".
    magnitude : float
        The fault's size (its unit in :data:`FAULTS`' description).
    truth : dict
        What the fault is (e.g. ``held_frames``, ``bump_frame``, ``shift_px``).
    scene : synth.drawn.frames.Scene
        The drawn scene.
    """

    source: ArraySource
    setup: Setup
    background: np.ndarray | None
    mu: float
    theta: np.ndarray
    centers: np.ndarray
    fault: str = "clean"
    magnitude: float = 0.0
    truth: dict = dataclasses.field(default_factory=dict)
    scene: Scene | None = None


@dataclasses.dataclass(frozen=True)
class Family:
    """How a clean recording is drawn: the ball, the contrast, the noise, the background."""

    n: int = 400
    mu: float = 0.01
    theta0: float = 0.3
    fps: float = 200.0
    noise: float = 1.0  # DN of 8 bit
    ball_mm: float = 6.0
    ball_level: float = 0.12  # the ball's grey level (the backdrop's is 0.78)
    spot: float = 0.85
    median_background: bool = False  # the measurement makes its own (per-pixel median)


def _motion(theta0, mu, n, fps, setup):
    t = np.arange(n) / fps
    th, _, _ = eom.solve_reference(theta0, 0.0, mu, t, track_radius=setup.track_radius)
    return th


def _setup(fam: Family, center) -> Setup:
    return Setup(cylinder_radius=R, ball_diameter=fam.ball_mm * 1e-3, ball_mass=4e-3,
                 fps=fam.fps, pixel_size=PIX, center_px=center)


def _scene(fam: Family, setup: Setup, center) -> Scene:
    return Scene(width=480, height=280, center=center, R_px=200.0,
                 r_px=setup.ball_radius / PIX, wall_px=20, noise=fam.noise,
                 ball=fam.ball_level, spot=fam.spot)


def _centres(theta, setup, center):
    L = setup.track_radius / PIX
    return np.column_stack([center[0] + L * np.sin(theta), center[1] + L * np.cos(theta)])


def _draw(scene, centers, seed):
    return make_frames(scene, [tuple(map(float, c)) for c in centers], seed=seed)


def clean(family: Family = Family(), *, seed: int = 0, theta=None) -> Recording:
    """A clean drawn recording of ``family`` (the ball's angles ``theta`` if given, else the
    equation of motion from rest at ``family.theta0``), the lab's centre in the setup.

    Parameters
    ----------
    family : Family
        The ball, contrast, noise, frame rate, length and mu.
    seed : int
        Seed of the pixel noise.
    theta : array_like, optional
        The ball's angle in each frame (rad).

    Returns
    -------
    Recording
    """
    center = (240.0, 20.0)
    setup = _setup(family, center)
    th = _motion(family.theta0, family.mu, family.n, family.fps, setup) if theta is None \
        else np.asarray(theta, float)
    scene = _scene(family, setup, center)
    cen = _centres(th, setup, center)
    bg, frames = _draw(scene, cen, seed)
    return Recording(ArraySource(frames), setup, None if family.median_background else bg,
                     family.mu, th, cen, scene=scene)


def faulty(fault: str, magnitude: float, *, seed: int = 0,
           family: Family = Family()) -> Recording:
    """A drawn recording of ``family`` with ``fault`` of size ``magnitude`` (see the module's
    description), its truth in ``Recording.truth``.

    Parameters
    ----------
    fault : str
        One of :data:`FAULTS`.
    magnitude : float
        The fault's size.
    seed : int
        Seed of the pixel noise and of the fault's random parts (flicker phase, glitches).
    family : Family
        The clean recording it starts from.

    Returns
    -------
    Recording

    Raises
    ------
    ValueError
        An unknown fault or a size it cannot have.
    """
    if fault not in FAULTS:
        raise ValueError(f"unknown fault {fault!r} (known: {', '.join(FAULTS)})")
    rng = np.random.default_rng(seed + 7919)
    fam = family
    if fault == "held":
        n_held = int(magnitude)
        if n_held < 1:
            raise ValueError("a held start holds the ball at least 1 frame")
        setup = _setup(fam, (240.0, 20.0))
        # frames 0 .. n_held - 1 at the release angle; the motion's t = 0 at frame n_held - 1
        mov = _motion(fam.theta0, fam.mu, fam.n, fam.fps, setup)
        theta = np.concatenate([np.full(n_held - 1, fam.theta0), mov])
        rec = clean(fam, seed=seed, theta=theta)
        return _with(rec, fault, magnitude, held_frames=n_held, release_frame=n_held - 1)
    if fault == "rest":
        setup = _setup(fam, (240.0, 20.0))
        mov = _motion(fam.theta0, fam.mu, fam.n, fam.fps, setup)
        # a ball stops where its speed is zero: the turning point nearest the asked frame
        turns = np.flatnonzero(np.diff(np.sign(np.diff(mov))) != 0) + 1
        turns = turns[turns >= 3]
        if not turns.size:
            raise ValueError("the motion has no turning point to rest at")
        k = int(turns[np.argmin(np.abs(turns - magnitude * fam.n))])
        theta = np.concatenate([mov[:k + 1], np.full(fam.n - k - 1, mov[k])])
        rec = clean(fam, seed=seed, theta=theta)
        return _with(rec, fault, magnitude, rest_from=k)
    rec = clean(fam, seed=seed)
    n = fam.n
    if fault in ("bump", "drift"):
        frames, shift, truth = moved(rec.source.frames, fault, magnitude)
        rec = dataclasses.replace(rec, source=ArraySource(frames), centers=rec.centers + shift)
        return _with(rec, fault, magnitude, **truth)
    if fault in ("yaw", "pitch"):
        kw = {f"{fault}_deg": float(magnitude)}
        L = rec.setup.track_radius / PIX
        cen = camera_faults.turned_centres(rec.theta, L, rec.scene.center, **kw)
        bg, frames = _draw(rec.scene, cen, seed)
        rec = dataclasses.replace(rec, source=ArraySource(frames), centers=cen,
                                  background=None if rec.background is None else bg)
        return _with(rec, fault, magnitude, **kw)
    if fault == "flicker":
        frames, gain, phase = flickered(rec.source.frames, magnitude, fam.fps, rng)
        rec = dataclasses.replace(rec, source=ArraySource(frames))
        return _with(rec, fault, magnitude, gain=gain.tolist(), phase=phase)
    if fault in ("timestamps_ms", "timestamps_us"):
        unit = fault.split("_")[1]
        stamps = stamped(n, fam.fps, magnitude, unit)
        rec = dataclasses.replace(rec, source=ArraySource(rec.source.frames, timestamps=stamps))
        return _with(rec, fault, magnitude, unit=unit)
    if fault in ("fps", "radius", "gravity"):
        setup, truth = wrong_setup(rec.setup, fault, magnitude)
        rec = dataclasses.replace(rec, setup=setup)
        return _with(rec, fault, magnitude, **truth)
    # glitches

    frames, glitches = glitch_frames(np.stack(rec.source.frames), seed=seed, rate=magnitude,
                                     centers=rec.centers, r_px=rec.scene.r_px)
    rec = dataclasses.replace(rec, source=ArraySource(list(frames)))
    return _with(rec, fault, magnitude, glitched=[(g.frame, g.kind) for g in glitches])


def moved(frames, fault: str, magnitude: float):
    """``frames`` (a list of images) seen by a camera that moved: a ``bump`` of ``magnitude``
    px right from frame ``n // 2`` on, or a ``drift`` to ``magnitude`` px right and half that
    down by the last frame.

    Returns
    -------
    frames : list of numpy.ndarray
    shift : numpy.ndarray
        (T, 2): the camera's shift in each frame (px).
    truth : dict
        ``shift_px`` (and ``bump_frame``).
    """
    n = len(frames)
    if fault == "bump":
        k, px = n // 2, (float(magnitude), 0.0)
        shift = camera_faults.camera_shift(n, bump_at=k, bump_px=px)
        truth = dict(bump_frame=k, shift_px=list(px))
    elif fault == "drift":
        px = (float(magnitude), 0.5 * float(magnitude))
        shift = camera_faults.camera_shift(n, drift_px=px)
        truth = dict(shift_px=list(px))
    else:
        raise ValueError(f"a camera moves by a bump or a drift, not {fault!r}")
    return camera_faults.moved_frames(frames, shift), shift, truth


def flickered(frames, magnitude: float, fps: float, rng):
    """``frames`` under the lamps' mains flicker: frame i's gain 1 + ``magnitude``
    sin(2 pi 100 Hz i / ``fps`` + phase), the phase drawn from ``rng``.

    Returns
    -------
    frames : list of numpy.ndarray
    gain : numpy.ndarray
    phase : float
    """
    phase = float(rng.uniform(0, 2 * math.pi))
    gain = 1.0 + magnitude * np.sin(2 * math.pi * MAINS_FLICKER_HZ * np.arange(len(frames))
                                    / fps + phase)
    full = np.iinfo(np.asarray(frames[0]).dtype).max
    out = [np.clip(np.rint(f.astype(float) * g), 0, full).astype(f.dtype)
           for f, g in zip(frames, gain, strict=True)]
    return out, gain, phase


def stamped(n: int, fps: float, start_s: float, unit: str) -> np.ndarray:
    """Per-frame timestamps of ``n`` frames at ``fps`` from ``start_s`` seconds, written in
    ``unit`` ("ms" or "us") as a camera that logs them so does."""
    scale = {"ms": 1e3, "us": 1e6}[unit]
    return scale * (float(start_s) + np.arange(n) / fps)


def wrong_setup(setup: Setup, fault: str, magnitude: float):
    """``setup`` with one key wrong: ``fps`` or ``radius`` (the cylinder's) ``magnitude`` times
    the true, or ``gravity`` = ``magnitude`` m/s^2.

    Returns
    -------
    setup : Setup
    truth : dict
        ``true_setup`` and the wrong value by its Setup field name.
    """
    if not magnitude > 0:
        raise ValueError(f"a setup's {fault} must be positive")
    wrong = {"fps": dict(fps=setup.fps * magnitude),
             "radius": dict(cylinder_radius=setup.cylinder_radius * magnitude),
             "gravity": dict(gravity=float(magnitude))}[fault]
    return setup.replace(**wrong), dict(true_setup=setup,
                                        **{k: float(v) for k, v in wrong.items()})


def _with(rec: Recording, fault: str, magnitude: float, **truth) -> Recording:
    return dataclasses.replace(rec, fault=fault, magnitude=float(magnitude), truth=truth)
