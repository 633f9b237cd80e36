"""Held starts and resting balls, found from the track.

A ball released from rest at angle theta stays within delta of its start for the natural still
time sqrt(2 delta / a), a = (5/7) g sin(theta) / (R - r) its angular acceleration there (it
rolls); it comes to rest the same way in reverse. A still spell at the start (or the end) of
the track several times longer than that is the ball held before its release (a finger, a
release mechanism), or the ball at rest: those frames are no part of the motion the equation
of motion describes, and are left out of the fit (flagged ``held`` / ``rest``).
"""

from __future__ import annotations

import math

import numpy as np

# a still spell this many times the natural still time is a hold or a rest
STILL_FACTOR = 3.0
# "still": within this many of the track's angle noise (robust, from second differences)
STILL_SIGMAS = 6.0
STILL_FLOOR_RAD = 1e-5
# the still place: the median of this many frames at the spell's end of the track
PLACE_FRAMES = 3


def angle_noise(theta: np.ndarray) -> float:
    """The angle's noise (rad) from its second differences (robust; NaN where too few)."""
    th = theta[np.isfinite(theta)]
    if th.size < 5:
        return math.nan
    d2 = np.diff(th, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


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
