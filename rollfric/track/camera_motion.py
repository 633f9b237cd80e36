"""A camera that moved during the recording, found from the static scene around the ball.

Frames sampled over the recording are compared with the background over the static scene
(:func:`rollfric.track.scene_shift.frame_shift`). A shift that stands out from the samples'
own noise (each measured again on its neighbouring frame) and from what the ball hides of the
scene (their scatter from sample to sample) is a motion: a step between two samples, narrowed
down to its frame by bisection (a bump), or a steady drift (the Theil-Sen line through the
samples, :func:`drift_line`). The recording is then tracked again with its frames moved back
into the background's frame (:func:`correct_for_motion`, a step of
:func:`rollfric.measurement.measure`); the correction's own uncertainty is a row of the
budget (:mod:`rollfric.uncertainty.motion`).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
from scipy import stats

from rollfric.geometry.theta import angles
from rollfric.io.source import RecordingError
from rollfric.track.scene_shift import frame_shift, reference, search_level
from rollfric.track.timestamps import irregular_message, located_irregular_message

logger = logging.getLogger(__name__)

SAMPLES = 12  # frames compared with the background over the recording (a bump: then bisected)
# a shift below this is not acted on: 0.1 px on the 200-600 px path radius of a lab's camera
# moves the angles by 2e-4 to 5e-4 rad, below the locators' own systematic errors
MOTION_MIN_PX = 0.1
# a bump: the samples before and after it agree within this (px), or STEP_NOISE_FACTOR
# times the shifts' own noise where that is more; otherwise a drift
STEP_SCATTER_PX = 0.05
STEP_NOISE_FACTOR = 3.0
# a drift: its samples spread about their median by more than this many times the shifts'
# own noise (the largest of 12 normal deviates is rarely beyond 3 standard deviations)
DRIFT_NOISE_FACTOR = 4.0
# the quick look: a camera whose samples at reduced size stay within QUICK_STILL_PX of each
# other is still (a quarter-size shift is good to ~0.01 px there)
QUICK_STILL_PX = 0.05
# a bump is checked on up to MATCHES samples after it against the frame before it with the
# ball nearest to where it is, within MATCH_RADII ball radii
MATCHES = 3
MATCH_RADII = 0.1
# the sampled frames whose shift the scene tells (scene_shift.SHIFT_MAX_SE_PX): at least this
# share, else the motion is unknown
MEASURED_SHARE = 0.8

@dataclasses.dataclass(frozen=True)
class CameraMotion:
    """The camera's image shift over the recording.

    Attributes
    ----------
    kind : str
        "still", "bump" (a step at ``frame``), "drift", or "unknown" (the static scene
        too plain to measure a shift in most sampled frames: nothing corrected).
    frames : numpy.ndarray
        The frames compared with the background.
    shifts : numpy.ndarray
        (K, 2) px: the scene's shift (dx right, dy down) in those frames against the
        background.
    frame : int or None
        The bump's first moved frame.
    size_px : tuple of float
        The bump's (dx, dy), or the drift's from the first sample to the last, px.
    before_px : tuple of float
        A bump's shift against the background before it (px).
    """

    kind: str
    frames: np.ndarray
    shifts: np.ndarray
    frame: int | None = None
    size_px: tuple[float, float] = (0.0, 0.0)
    before_px: tuple[float, float] = (0.0, 0.0)

    def per_frame(self, n: int) -> np.ndarray:
        """(n, 2) px: the shift of every frame (a step for a bump, interpolated otherwise)."""
        if self.kind in ("still", "unknown"):
            return np.zeros((n, 2))
        if self.kind == "bump":
            s = np.tile(np.asarray(self.before_px, dtype=float), (n, 1))
            s[self.frame:] += self.size_px
            return s
        # a steady drift: the line through the samples (each sample's error depends on where
        # the ball hides the scene, up to a quarter of a pixel on a small frame; the line
        # averages it, where joining the samples would copy it)
        return drift_line(self.frames, self.shifts)(np.arange(n))

    def message(self) -> str:
        """What was found, for a warning or a reason."""
        dx, dy = self.size_px
        if self.kind == "bump":
            return (f"the camera moved by ({dx:+.2f}, {dy:+.2f}) px at frame {self.frame} "
                    "(the trough and the backdrop moved with it)")
        return (f"the camera drifted by ({dx:+.2f}, {dy:+.2f}) px from frame "
                f"{int(self.frames[0])} to frame {int(self.frames[-1])} (the trough and the "
                "backdrop moved with it)")

    def to_dict(self) -> dict:
        """The fit.json form."""
        return {"kind": self.kind, "frame": self.frame, "size_px": list(self.size_px),
                "frames": [int(v) for v in self.frames],
                "shifts_px": [[float(a), float(b)] for a, b in self.shifts]}


def drift_line(frames, shifts):
    """The steady drift through the samples ``shifts`` ((K, 2) px at ``frames``): the
    Theil-Sen line of each axis (``scipy.stats.theilslopes``: a sample or two far off, where
    the ball hid most of the scene, do not tilt it), through the median of the samples less
    it. Returns a function of the frame numbers
    giving (T, 2) px."""
    f = np.asarray(frames, dtype=float)
    s = np.asarray(shifts, dtype=float).reshape(-1, 2)
    lines = []
    for k in range(2):
        slope = stats.theilslopes(s[:, k], f)[0]
        lines.append((slope, float(np.median(s[:, k] - slope * f))))  # the residuals' median

    def at(frame):
        frame = np.asarray(frame, dtype=float)
        return np.column_stack([b + a * frame for a, b in lines])
    return at


def drift_scatter(frames, shifts) -> tuple[np.ndarray, float]:
    """The samples' scatter about their drift line (:func:`drift_line`): (sigma, Sxx), sigma
    (2,) px the standard deviation of x and y about it (K - 2 degrees of freedom), Sxx the
    frames' sum of squares about their mean (the line's slope has standard error sigma /
    sqrt(Sxx))."""
    f = np.asarray(frames, dtype=float)
    s = np.asarray(shifts, dtype=float).reshape(-1, 2)
    dev = s - drift_line(f, s)(f)
    sigma = np.sqrt(np.sum(dev ** 2, axis=0) / max(1, len(f) - 2))
    return sigma, float(np.sum((f - f.mean()) ** 2))


def find_motion(source, background, centres, r_px: float, *, samples: int = SAMPLES,
                usable=None) -> CameraMotion:
    """The camera's motion over ``source`` (:class:`CameraMotion`).

    Parameters
    ----------
    source : FrameSource
        The recording (frames read whole).
    background : numpy.ndarray
        The background image.
    centres : numpy.ndarray
        (T, 2) ball centres px (NaN: none), to mask the ball.
    r_px : float
        The ball's radius, px.
    samples : int, optional
        Frames compared over the recording.
    usable : numpy.ndarray or None
        (T,) bool: the frames to sample (not those the tracking's checks rejected: a flash,
        a repeated or corrupt frame); None: all.

    Returns
    -------
    CameraMotion
    """
    n = len(source)
    # a quick look at reduced size tells a still camera (the usual case) within
    # MOTION_MIN_PX; a moving one is measured again at full size
    shift = _Shifts(source, background, centres, r_px,
                    search_level(np.asarray(background).shape))
    pool = np.flatnonzero(usable) if usable is not None else np.arange(n)
    if pool.size < 3:
        pool = np.arange(n)
    idx = np.unique(pool[np.linspace(0, pool.size - 1, min(samples, pool.size)).round()
                         .astype(int)])
    s = np.array([shift(i) for i in idx])
    finite = np.isfinite(s).all(axis=1)
    ok = finite & ~_off_both_neighbours(s)
    # a scene that tells the shift in some frames only is one whose structure the ball hides
    # in the others: its shifts there are biased by where the ball is (a dim scene: 0.4-0.7 px)
    if finite.sum() < MEASURED_SHARE * len(idx) or ok.sum() < max(3, 0.5 * len(idx)):
        return CameraMotion("unknown", idx, s)
    idx, s = idx[ok], s[ok]
    if _largest(s - s[0]) < (QUICK_STILL_PX if shift.level else MOTION_MIN_PX):
        return CameraMotion("still", idx, s)
    if shift.level:  # it moved, or may have: every sample again at full size
        shift.full_size()
        s = np.array([shift(i) for i in idx])
        keep = np.isfinite(s).all(axis=1)
        if keep.sum() < 3:
            return CameraMotion("unknown", idx, s)
        idx, s = idx[keep], s[keep]
        if _largest(s - s[0]) < MOTION_MIN_PX:
            return CameraMotion("still", idx, s)
    # a motion must stand out from the shifts' own noise: each sample measured again on its
    # neighbouring frame (the camera does not move between two frames), the pairs'
    # differences giving that noise (a dim scene's shifts scatter 0.15 px with the camera
    # still, which a drift of MOTION_MIN_PX took for motion and "corrected")
    pair = np.array([shift(i + 1 if i + 1 < n else i - 1) for i in idx])
    d = (pair - s)[np.isfinite(pair).all(axis=1)]
    noise = _robust_sd(d) / math.sqrt(2.0) if len(d) >= 3 else 0.0
    if noise > MOTION_MIN_PX:  # shifts too noisy to tell a still camera from a moving one
        return CameraMotion("unknown", idx, s)
    # and from what the ball hides of the scene, which differs from sample to sample (the
    # successive samples' differences, a drift's steady part and a bump's one step aside:
    # 0.1 px on a small dark frame, where a still camera "drifted" by it)
    noise = max(noise, _robust_sd(np.diff(s, axis=0)) / math.sqrt(2.0))
    if _largest(s - np.median(s, axis=0)) < DRIFT_NOISE_FACTOR * noise:
        return CameraMotion("still", idx, s)
    bump = _step(shift, idx, s, max(STEP_SCATTER_PX, STEP_NOISE_FACTOR * noise))
    if bump is not None:
        return bump
    # a drift: the line through the samples must rise above its own standard error
    line = drift_line(idx, s)
    total = line(idx[-1:])[0] - line(idx[:1])[0]
    sigma, sxx = drift_scatter(idx, s)
    se = math.sqrt(float(np.mean(sigma ** 2))) * float(idx[-1] - idx[0]) / math.sqrt(sxx)
    if math.hypot(*total) < DRIFT_NOISE_FACTOR * se:
        return CameraMotion("still", idx, s)
    return CameraMotion("drift", idx, s, size_px=(float(total[0]), float(total[1])))


def _robust_sd(d) -> float:
    """The robust standard deviation of the rows of ``d`` about their median (the larger of
    x and y's): 1.4826 x the median absolute deviation."""
    d = np.asarray(d, dtype=float).reshape(-1, 2)
    if len(d) < 3:
        return 0.0
    return 1.4826 * float(np.max(np.median(np.abs(d - np.median(d, axis=0)), axis=0)))


class _Shifts:
    """:func:`frame_shift` of frame i of a recording at a level, remembered (the frames are
    read again for the full size: a few, and rarely)."""

    def __init__(self, source, background, centres, r_px, level):
        self.source, self.r_px = source, r_px
        # the background's sizes, gradients and noise, made once for all samples
        self.background = reference(background, search_level(np.asarray(background).shape))
        # a frame whose ball the checks rejected (a jump at the bump's frame) still shows it:
        # masked where its neighbours put it
        c = np.array(centres, dtype=float).reshape(-1, 2)
        ok = np.isfinite(c).all(axis=1)
        self.located = ok  # the frames whose ball was located (not a glitch's)
        if ok.any() and not ok.all():
            idx = np.arange(len(c))
            c[~ok] = np.column_stack([np.interp(idx[~ok], idx[ok], c[ok, k]) for k in range(2)])
        self.centres = c
        self.level = level
        self.cache: dict[int, np.ndarray] = {}

    def full_size(self):
        self.level = 0
        self.cache.clear()

    def __call__(self, i: int) -> np.ndarray:
        if i not in self.cache:
            try:
                frame = self.source[i]
            except (RecordingError, OSError, ValueError):  # a corrupt frame: no sample
                self.cache[i] = np.full(2, np.nan)
            else:
                self.cache[i] = np.array(frame_shift(frame, self.background, self.centres[i],
                                                     self.r_px, level=self.level))
        return self.cache[i]


def _largest(v) -> float:
    return float(np.max(np.hypot(v[:, 0], v[:, 1])))


def _off_both_neighbours(s) -> np.ndarray:
    """The samples off both their neighbours, which agree (a glitched frame the checks
    missed: no motion)."""
    off = np.zeros(len(s), dtype=bool)
    for k in range(1, len(s) - 1):
        off[k] = (min(np.hypot(*(s[k] - s[k - 1])), np.hypot(*(s[k] - s[k + 1])))
                  > MOTION_MIN_PX and np.hypot(*(s[k - 1] - s[k + 1])) < MOTION_MIN_PX)
    return off


def _step(shift, idx, s, tol: float) -> CameraMotion | None:
    """A bump: the split of the samples that leaves the least scatter on both sides (one
    sample aside), if that is within ``tol`` px, its frame narrowed down by bisection; None
    otherwise."""
    best = None
    # a step is seen in two samples on each side at least: one sample off its neighbours at
    # an end of the recording is as likely where the ball was as where the camera went
    for j in range(2, len(idx) - 1):
        left, right = s[:j], s[j:]
        dev = np.concatenate([np.abs(left - np.median(left, axis=0)).max(axis=1),
                              np.abs(right - np.median(right, axis=0)).max(axis=1)])
        # one sample may be off (where the ball hid most of the scene: 0.5 px on a dim one),
        # by less than half the step (else it is on the other side of it)
        step = float(np.abs(np.median(right, axis=0) - np.median(left, axis=0)).max())
        top = np.sort(dev)
        sc = float(top[-2]) if len(dev) >= 6 and top[-1] < 0.5 * step else float(top[-1])
        if best is None or sc < best[0]:
            best = (sc, j)
    if best is None or best[0] > tol:
        return None
    sc, j = best
    before, after = np.median(s[:j], axis=0), np.median(s[j:], axis=0)
    lo, hi = int(idx[j - 1]), int(idx[j])  # lo like before, hi like after
    while hi - lo > 1:
        mid = (lo + hi) // 2
        d = shift(mid)
        if not np.isfinite(d).all():
            break
        if np.hypot(*(d - before)) < np.hypot(*(d - after)):
            lo = mid
        else:
            hi = mid
    size = after - before
    # a bump is a step: the frames just before it at the level before, those just after at
    # the level after (one of three each: a glitched frame may sit there). A shift that
    # changes smoothly from frame to frame is the ball's doing (its long shadow under a
    # grazing light moved the first samples by 2.3 px, fading over 30 frames)
    near = max(tol, 0.25 * float(np.hypot(*size)))
    n = len(shift.source)
    if hi - lo == 1 and not (
            _any_near(shift, range(max(0, lo - 2), lo + 1), before, near)
            and _any_near(shift, range(hi, min(n, hi + 3)), after, near)):
        return None
    if not _seen_at_the_same_place(shift, idx[j:], hi, size, near):
        return None
    return CameraMotion("bump", idx, s, frame=hi, size_px=(float(size[0]), float(size[1])),
                        before_px=(float(before[0]), float(before[1])))


def _seen_at_the_same_place(shift, after, frame: int, size, tol: float) -> bool:
    """Whether the step of ``size`` px at ``frame`` is there where the ball is at the same
    place before and after it: for up to MATCHES samples ``after`` it, the located frame before
    ``frame`` with the ball nearest to where it is (within MATCH_RADII radii), their shifts'
    difference within ``tol`` of ``size`` in most of the pairs. What the ball hides of the
    scene biases a shift alike at one place, so the difference is the camera's alone (a dim
    scene's release frame, the ball at its held place, read 0.7 px off the later samples).
    True where no pair is found (a bump before the ball had been anywhere else)."""
    c = shift.centres
    before = np.flatnonzero(shift.located[:frame])
    if not before.size:
        return True
    agree = []
    for b in after[:: max(1, len(after) // MATCHES)][:MATCHES]:
        dist = np.hypot(*(c[before] - c[b]).T)
        k = int(np.argmin(dist))
        if dist[k] > MATCH_RADII * shift.r_px:
            continue
        d = shift(int(b)) - shift(int(before[k]))
        if np.isfinite(d).all():
            agree.append(np.hypot(*(d - size)) <= tol)
    return not agree or 2 * sum(agree) > len(agree)


def _any_near(shift, frames, level, tol: float) -> bool:
    """Whether any of ``frames``' shifts lies within ``tol`` px of ``level``."""
    return any(np.isfinite(d).all() and np.hypot(*(d - level)) <= tol
               for d in (shift(i) for i in frames))


def correct_for_motion(source, bg, df, info, setup, angle, *, retrack=None):
    """The camera's motion from the static scene (:func:`find_motion`) taken out of a track.

    With ``retrack``, the recording is tracked again with its frames moved back
    (``retrack(shifts)``, shifts (T, 2) px: see :mod:`rollfric.track.steadied`), the ball
    located against a background that matches every frame. Without it, the centres in ``df``
    are moved back into the background's frame and the angles taken again; the steps the
    motion made are no timing's (left out of ``timing_irregular`` and ``located_irregular``).

    Parameters
    ----------
    source : FrameSource
        The recording.
    bg : numpy.ndarray
        The background image.
    df : pandas.DataFrame
        The track (changed in place where the camera moved).
    info : rollfric.track.track_info.TrackInfo
        The track's.
    setup : rollfric.setup.model.Setup
        The setup (the path's radius for the arcsin angle).
    angle : str
        The angle formula (:func:`rollfric.geometry.theta.angles`).
    retrack : callable, optional
        ``retrack(shifts) -> (df, info)``: the recording tracked again with each frame moved
        back by its shift.

    Returns
    -------
    df : pandas.DataFrame
        The track.
    info : rollfric.track.track_info.TrackInfo
        With ``camera_motion`` set (unless the motion could not be looked for) and, for a
        moved camera, its warning (logged too).
    """
    found = df["found"].to_numpy() == 1
    xy = np.column_stack([df["x_px"].to_numpy(float), df["y_px"].to_numpy(float)])
    try:
        # frames the checks rejected (flash, repeated, ...) are not sampled
        usable = df["flag"].astype(str).to_numpy() == ""
        # nor frames of a held start or a rest: the fit leaves them out, and each shows the
        # ball at one place, whose part of the scene it hides biases their shifts alike (a dim
        # scene's rest read as a 0.35 px bump)
        if "still" in df.columns:
            usable &= df["still"].astype(str).to_numpy() == ""
        motion = find_motion(source, bg, xy, info.ball_radius_px, usable=usable)
    except (RecordingError, ValueError) as exc:
        logger.info(f"the camera's motion was not looked for: {exc}")
        return df, info
    if motion.kind in ("still", "unknown"):
        if motion.kind == "unknown":
            logger.info("the camera's motion could not be measured: the scene around the "
                        "ball is too plain")
        return df, dataclasses.replace(info, camera_motion=motion.to_dict())
    per = motion.per_frame(len(df))
    if retrack is not None:
        df, again = retrack(per)
        msg = (f"{motion.message()}: the frames were moved back into the background's frame "
               "and the ball located again")
        stale = [w for w in info.warnings if w not in again.warnings]
        if stale:  # said while tracking the moved frames (a bump read as dropped frames)
            msg += ("; what the first pass over the moved frames warned of no longer holds: "
                    + " | ".join(w.split(":")[0] for w in stale))
        logger.warning(msg)
        return df, dataclasses.replace(again, camera_motion=motion.to_dict(),
                                       warnings=again.warnings + (msg,))
    cols = [("x_px", "y_px")] + ([("xu_px", "yu_px")] if "xu_px" in df.columns else [])
    for cx, cy in cols:
        df[cx] = df[cx].to_numpy(float) - per[:, 0]
        df[cy] = df[cy].to_numpy(float) - per[:, 1]
    ax, ay = cols[-1]
    th = np.full(len(df), np.nan)
    th[found] = angles(df[ax].to_numpy(float)[found], df[ay].to_numpy(float)[found],
                       info.center_px, method=angle,
                       track_radius_px=setup.track_radius / setup.pixel_size)
    df["theta_rad"] = th
    warnings = list(info.warnings)
    kept = {}
    for name, text_of in (("timing_irregular", irregular_message),
                          ("located_irregular", located_irregular_message)):
        old = getattr(info, name)
        new = tuple(e for e in old if motion.kind != "bump" or abs(e[0] - motion.frame) > 1)
        if old and new != old and text_of(old) in warnings:
            warnings.remove(text_of(old))
            if new:
                warnings.append(text_of(new))
        kept[name] = new
    msg = (f"{motion.message()}: the centres were moved back into the background's frame "
           "and the angles taken again")
    logger.warning(msg)
    return df, dataclasses.replace(info, camera_motion=motion.to_dict(),
                                   warnings=tuple(warnings) + (msg,), **kept)
