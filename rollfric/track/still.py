"""Held starts and resting balls, found from the track.

A ball released from rest at angle theta stays within delta of its start for the natural still
time sqrt(2 delta / a), a = (5/7) g sin(theta) / (R - r) its angular acceleration there (it
rolls); it comes to rest the same way in reverse. A still spell at the start (or the end) of
the track several times longer than that is the ball held before its release (a finger, a
release mechanism), or the ball at rest: those frames are no part of the motion the equation
of motion describes, and are left out of the fit (flagged ``held`` / ``rest``). A median
background made while the ball was held or at rest holds it: :func:`median_without_still` makes
it again from the other frames.
"""

from __future__ import annotations

import logging
import math

import cv2
import numpy as np

from rollfric.errors import InputError
from rollfric.io import ballfree
from rollfric.io.background import median, sample

logger = logging.getLogger(__name__)

# a still spell this many times the natural still time is a hold or a rest
STILL_FACTOR = 3.0
# "still": within this many of the track's angle noise (robust, from second differences)
STILL_SIGMAS = 6.0
STILL_FLOOR_RAD = 1e-5
# the still place: the median of this many frames at the spell's end of the track
PLACE_FRAMES = 3
# the ball's acceleration leaving the place, as the track shows it: a quadratic through at
# least ACCEL_MIN_FRAMES frames within ACCEL_SPAN_RAD of the place (where sin(theta), and so
# the acceleration, changes by less than a fifth from 0.3 rad)
ACCEL_SPAN_RAD = 0.05
ACCEL_MIN_FRAMES = 6


def angle_noise(theta: np.ndarray) -> float:
    """The angle's noise (rad) from its second differences (robust; NaN where too few)."""
    th = theta[np.isfinite(theta)]
    if th.size < 5:
        return math.nan
    d2 = np.diff(th, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def _acceleration_seen(t, theta, place: float) -> float | None:
    """|theta''| (rad/s^2) of the track leaving its still ``place``: a quadratic in time
    through the frames (from the last still one) within ACCEL_SPAN_RAD of it; None with fewer
    than ACCEL_MIN_FRAMES of them."""
    near = np.abs(theta - place) <= ACCEL_SPAN_RAD
    k = int(np.argmin(near)) if not near.all() else near.size
    if k < ACCEL_MIN_FRAMES:
        return None
    tt = t[:k] - t[:k].mean()
    return 2.0 * abs(float(np.polyfit(tt, theta[:k], 2)[0]))


def _spell(t, theta, ok, setup, delta):
    """(first moving position in ``ok`` order, natural still time) of the spell at the start of
    the sequence, or None when there is no still spell longer than STILL_FACTOR x natural."""
    idx = np.flatnonzero(ok)
    if idx.size < 2 * PLACE_FRAMES + 2:
        return None
    th = theta[idx]
    place = float(np.median(th[:PLACE_FRAMES]))
    away = np.abs(th - place) > delta
    if not away.any():
        return None
    j = int(np.argmax(away))  # first frame away from the place
    if j < PLACE_FRAMES:
        return None
    a = 5.0 / 7.0 * setup.gravity * abs(math.sin(place)) / setup.track_radius
    # the acceleration the track itself shows leaving the place, where smaller: a setup's g
    # or L that is off (g 98.1 for 9.81) makes a turning ball's stillness look like a hold
    a_seen = _acceleration_seen(t[idx[j - 1:]], th[j - 1:], place)
    if a_seen is not None:
        a = min(a, a_seen)
    if a <= 0:
        return None
    t_nat = math.sqrt(2.0 * delta / a)
    spell = abs(t[idx[j - 1]] - t[idx[0]])
    if spell <= STILL_FACTOR * t_nat:
        return None
    # frames surely before the release: more than t_nat before the last still frame
    cut = abs(t[idx[j - 1]]) - t_nat
    return idx, j, t_nat, cut


def still_spells(t, theta, found, setup) -> dict:
    """The held start and the rest of a track.

    Parameters
    ----------
    t, theta : array_like
        Frame times (s) and angles (rad).
    found : array_like of bool
        Frames located.
    setup : rollfric.setup.model.Setup
        For the ball's acceleration (gravity, track radius).

    Returns
    -------
    dict
        ``held``: bool mask of the frames held before the release (all False: none);
        ``rest``: bool mask of the frames at rest at the end; ``delta_rad``: the still
        tolerance; ``natural_s``: the natural still times (start, end), NaN where none.
    """
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    ok = np.asarray(found, dtype=bool) & np.isfinite(theta) & np.isfinite(t)
    n = t.size
    held = np.zeros(n, dtype=bool)
    rest = np.zeros(n, dtype=bool)
    noise = angle_noise(theta[ok])
    delta = max(STILL_SIGMAS * noise, STILL_FLOOR_RAD) if math.isfinite(noise) else math.nan
    out = {"held": held, "rest": rest, "delta_rad": delta, "natural_s": [math.nan, math.nan]}
    if not math.isfinite(delta):
        return out
    got = _spell(t, theta, ok, setup, delta)
    if got is not None:
        idx, j, t_nat, _ = got
        last_still = t[idx[j - 1]]
        held[idx[:j][t[idx[:j]] < last_still - t_nat]] = True
        out["natural_s"][0] = t_nat
    got = _spell(-t[::-1], theta[::-1], ok[::-1], setup, delta)
    if got is not None:
        idx, j, t_nat, _ = got
        ridx = n - 1 - idx[:j]  # the still frames, in the forward order's numbers
        first_still = t[ridx].min()
        rest[ridx[t[ridx] > first_still + t_nat]] = True
        out["natural_s"][1] = t_nat
    return out


def median_without_still(source, df, bg, r_px: float, median_frames: int, *,
                         full_scale: float | None = None):
    """The median background of the sampled frames whose ball is neither held nor at rest.

    Parameters
    ----------
    source : FrameSource
        The recording.
    df : pandas.DataFrame
        Its track, column ``still`` marked (:func:`mark_still`).
    bg : numpy.ndarray
        The median background it was tracked with.
    r_px : float
        The ball's radius (px).
    median_frames : int
        Frames sampled for the median.
    full_scale : float or None
        The camera's full scale (DN).

    Returns
    -------
    tuple or None
        (background, whether it agrees with ``bg``, frames in it); None when fewer than
        :data:`rollfric.io.ballfree.MIN_CLEAR` are left or it still holds the ball.
    """
    idx, stack = sample(source, median_frames)
    still_rows = df["still"].to_numpy() != ""
    keep = [j for j, i in enumerate(idx) if not still_rows[int(i)]]
    if len(keep) < ballfree.MIN_CLEAR:
        return None
    sub = stack[keep]
    try:
        bg2, _ = ballfree.check_ball_free(sub, median(sub), r_px, full_scale=full_scale)
    except InputError:
        return None
    # a ball's trace is a ball-sized difference: averaged over r x r, above the noise
    d = cv2.blur(np.abs(bg2.astype(np.float32) - bg.astype(np.float32)),
                 (max(1, int(r_px)), max(1, int(r_px))))
    tol = max(2.0, ballfree.noise_sigma(stack))
    return bg2, bool(d.max() <= tol), len(keep)


def mark_still(df, setup) -> list:
    """Frames of a held start or a rest (:func:`still_spells`) marked in the track.

    Parameters
    ----------
    df : pandas.DataFrame
        The track: its column ``still`` is set, "held" / "rest" on those frames (kept out of
        the fit), "" elsewhere.
    setup : rollfric.setup.model.Setup
        The setup.

    Returns
    -------
    list of str
        The warnings saying so (logged too).
    """
    df["still"] = ""
    found = df["found"].to_numpy() == 1
    spells = still_spells(df["t_s"].to_numpy(), df["theta_rad"].to_numpy(), found, setup)
    notes = []
    for name, what in (("held", "held still before its release"),
                       ("rest", "at rest from there on")):
        mask = spells[name] & found
        if not mask.any():
            continue
        k = np.flatnonzero(mask)
        t = df["t_s"].to_numpy()
        nat = spells["natural_s"][0 if name == "held" else 1]
        df.loc[mask, "still"] = name
        notes.append(f"the ball was {what}: frames {int(k[0])}-{int(k[-1])} "
                     f"({t[k[-1]] - t[k[0]]:.3g} s, more than {STILL_FACTOR:g} x the "
                     f"{nat * 1e3:.3g} ms a ball turning there is still), flagged '{name}' and "
                     "left out of the fit")
        logger.warning(notes[-1])
    return notes
