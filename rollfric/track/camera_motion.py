"""A camera that moved during the recording, found from the static scene around the ball.

The trough and the backdrop do not move; a bumped or drifting camera moves all of them in the
image. Frames sampled over the recording are compared with the background by phase
correlation (``cv2.phaseCorrelate``, sub-pixel), the ball's disc (and a margin) replaced by
the background's pixels so that only the static scene counts. A step between two samples is
narrowed down to its frame by bisection. The located centres are then moved back into the
background's frame (a step from the bump's frame on, or the drift interpolated between the
samples), so the angles are taken about the same trough axis throughout
(:func:`correct_for_motion`, a step of :func:`rollfric.measurement.measure`).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import cv2
import numpy as np

from rollfric.geometry.theta import angles
from rollfric.io.source import RecordingError
from rollfric.track.timestamps import irregular_message, located_irregular_message

logger = logging.getLogger(__name__)

SAMPLES = 12  # frames compared with the background over the recording (a bump: then bisected)
# a shift below this is not acted on: 0.1 px on the 200-600 px path radius of a lab's camera
# moves the angles by 2e-4 to 5e-4 rad, below the locators' own systematic errors
MOTION_MIN_PX = 0.1
# a bump: the samples before and after it agree within this (px); otherwise a drift
STEP_SCATTER_PX = 0.05
# a drift: its samples spread about their median by more than this many times the shifts'
# own noise (the largest of 12 normal deviates is rarely beyond 3 standard deviations)
DRIFT_NOISE_FACTOR = 4.0
BALL_MARGIN = 2.0  # the ball's disc and its shadow: this many ball radii masked
ECC_STEPS = 30  # iterations of the ECC refinement at most
# the quick look: images halved this many times; a camera whose samples there stay within
# QUICK_STILL_PX of each other is still (a quarter-size shift is good to ~0.01 px here)
QUICK_LEVEL = 2
QUICK_STILL_PX = 0.05
# the phase correlation's sub-pixel bias is a few tenths of a pixel; an ECC result farther
# from it than this has wandered off in a scene with too little structure
PHASE_AGREE_PX = 0.5
# the phase correlation's peak: 0.9-1.0 on drawn scenes with the trough in view, 0.2-0.3 on
# a plain backdrop with noise, where no shift can be measured
PHASE_MIN_RESPONSE = 0.5


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
        idx = np.arange(n)
        return np.column_stack([np.interp(idx, self.frames, self.shifts[:, k])
                                for k in range(2)])

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


def _window(shape):
    return cv2.createHanningWindow((shape[1], shape[0]), cv2.CV_64F)


def frame_shift(frame, background, ball=None, r_px: float = 0.0, window=None, *,
                level: int = 0):
    """The scene's shift (dx, dy) px in ``frame`` against ``background``, the ball at
    ``ball`` = (x, y) px masked (NaN when the phase correlation's peak is below
    PHASE_MIN_RESPONSE or the two estimates below disagree by more than PHASE_AGREE_PX: a
    scene without the structure to measure it): phase correlation
    (``cv2.phaseCorrelate``, whose sub-pixel peak is biased by a few tenths of a pixel),
    refined by the enhanced correlation coefficient's translation (``cv2.findTransformECC``)
    over the pixels outside the ball. ``level``: both images halved that many times first
    (``cv2.pyrDown``; the shift is given in the full images' pixels), for a quick look;
    ``window``: a Hanning window of the (halved) images' shape, or None."""
    f = np.asarray(frame, dtype=np.float32)
    b = np.asarray(background, dtype=np.float32)
    if f.ndim == 3:
        f = f.mean(axis=2)
    if b.ndim == 3:
        b = b.mean(axis=2)
    mask = np.ones(f.shape, dtype=np.uint8)
    if ball is not None and np.all(np.isfinite(ball)):
        h, w = f.shape
        rad = BALL_MARGIN * r_px + 2
        y0, y1 = max(0, int(ball[1] - rad)), min(h, int(ball[1] + rad) + 1)
        x0, x1 = max(0, int(ball[0] - rad)), min(w, int(ball[0] + rad) + 1)
        f = f.copy()
        f[y0:y1, x0:x1] = b[y0:y1, x0:x1]
        mask[y0:y1, x0:x1] = 0
    for _ in range(level):
        f, b = cv2.pyrDown(f), cv2.pyrDown(b)
        mask = (cv2.resize(mask, (f.shape[1], f.shape[0]), interpolation=cv2.INTER_AREA)
                > 0).astype(np.uint8)
    if window is None or window.shape != f.shape:
        window = _window(f.shape)
    scale = float(2 ** level)
    # copies: cv2.phaseCorrelate applies its window to its inputs in place
    (dx, dy), response = cv2.phaseCorrelate(b.astype(np.float64), f.astype(np.float64), window)
    if not response >= PHASE_MIN_RESPONSE:
        return math.nan, math.nan
    warp = np.array([[1, 0, dx], [0, 1, dy]], dtype=np.float32)
    # the rho increment ends it: from the phase estimate it is small at once, so a tiny one
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, ECC_STEPS, 1e-7)
    try:
        _, warp = cv2.findTransformECC(b, f, warp, cv2.MOTION_TRANSLATION, crit, mask, 1)
    except cv2.error as exc:  # a featureless scene
        logger.debug(f"ECC failed: {exc}")
        return math.nan, math.nan
    ex, ey = float(warp[0, 2]), float(warp[1, 2])
    if abs(ex - dx) > PHASE_AGREE_PX or abs(ey - dy) > PHASE_AGREE_PX:
        return math.nan, math.nan  # the two disagree: a scene without the structure to tell
    return ex * scale, ey * scale


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
    bg_shape = np.asarray(background).shape[:2]
    # a quick look at a quarter of the size tells a still camera (the usual case) within
    # MOTION_MIN_PX; a moving one is measured again at full size
    level = QUICK_LEVEL if min(bg_shape) >= 64 * 2 ** QUICK_LEVEL else 0
    cache: dict[int, np.ndarray] = {}

    def shift(i):  # the frames are read again for the full size: a few, and rarely
        if i not in cache:
            try:
                frame = source[i]
            except (RecordingError, OSError, ValueError):  # a corrupt frame: no sample
                cache[i] = np.full(2, np.nan)
            else:
                cache[i] = np.array(frame_shift(frame, background, centres[i], r_px,
                                                level=level))
        return cache[i]

    pool = np.flatnonzero(usable) if usable is not None else np.arange(n)
    if pool.size < 3:
        pool = np.arange(n)
    idx = np.unique(pool[np.linspace(0, pool.size - 1, min(samples, pool.size)).round()
                         .astype(int)])
    s = np.array([shift(i) for i in idx])
    ok = np.isfinite(s).all(axis=1)
    # a sample off both its neighbours (a glitched frame the checks missed) is no motion
    for k in range(1, len(idx) - 1):
        if ok[k - 1] and ok[k + 1] and min(np.hypot(*(s[k] - s[k - 1])),
                                           np.hypot(*(s[k] - s[k + 1]))) > MOTION_MIN_PX \
                and np.hypot(*(s[k - 1] - s[k + 1])) < MOTION_MIN_PX:
            ok[k] = False
    if ok.sum() < max(3, 0.5 * len(idx)):
        return CameraMotion("unknown", idx, s)
    idx, s = idx[ok], s[ok]
    rel = s - s[0]
    if np.max(np.hypot(rel[:, 0], rel[:, 1])) < QUICK_STILL_PX or (
            level == 0 and np.max(np.hypot(rel[:, 0], rel[:, 1])) < MOTION_MIN_PX):
        return CameraMotion("still", idx, s)
    if level:  # it moved, or may have: every sample again at full size
        level = 0
        cache.clear()
        s = np.array([shift(i) for i in idx])
        keep = np.isfinite(s).all(axis=1)
        if keep.sum() < 3:
            return CameraMotion("unknown", idx, s)
        idx, s = idx[keep], s[keep]
        rel = s - s[0]
        if np.max(np.hypot(rel[:, 0], rel[:, 1])) < MOTION_MIN_PX:
            return CameraMotion("still", idx, s)
    # one step: the split that leaves the least scatter on both sides
    best = None
    for j in range(1, len(idx)):
        left, right = s[:j], s[j:]
        sc = max(np.max(np.abs(left - np.median(left, axis=0))),
                 np.max(np.abs(right - np.median(right, axis=0))))
        if best is None or sc < best[0]:
            best = (sc, j)
    sc, j = best
    if sc <= STEP_SCATTER_PX:
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
        return CameraMotion("bump", idx, s, frame=hi, size_px=(float(size[0]), float(size[1])),
                            before_px=(float(before[0]), float(before[1])))
    # a drift must stand out from the shifts' own noise: each sample measured again on its
    # neighbouring frame (the camera does not move between two frames), the pairs'
    # differences giving that noise (a dim scene's shifts scatter 0.15 px with the camera
    # still, which a drift of MOTION_MIN_PX took for motion and "corrected")
    pair = np.array([shift(i + 1 if i + 1 < n else i - 1) for i in idx])
    d = (pair - s)[np.isfinite(pair).all(axis=1)]
    if len(d) >= 3:
        noise = 1.4826 * float(np.median(np.abs(d - np.median(d, axis=0)))) / math.sqrt(2.0)
        spread = float(np.max(np.hypot(*(s - np.median(s, axis=0)).T)))
        if noise > MOTION_MIN_PX:  # shifts too noisy to tell a still camera from a moving one
            return CameraMotion("unknown", idx, s)
        if spread < DRIFT_NOISE_FACTOR * noise:
            return CameraMotion("still", idx, s)
    return CameraMotion("drift", idx, s, size_px=(float(rel[-1, 0]), float(rel[-1, 1])))


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
        flags = df["flag"].astype(str).to_numpy()
        motion = find_motion(source, bg, xy, info.ball_radius_px,
                                usable=flags == "")
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
