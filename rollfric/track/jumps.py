"""The jump check of the per-frame plausibility: each frame against its neighbours' prediction.

A located centre is compared with where its neighbours on both sides (up to
:data:`HALF_WINDOW` frames each, within :data:`MAX_GAP`; one side at the ends of a run) put
the ball at that frame's time, by a polynomial through them (:func:`innovations`), judged
against that prediction's own error; the worst frame is flagged ``jump`` (``duplicate`` when it
sits where a frame just before was) and its neighbours predicted again without it, until none
is left (:func:`flag_jumps`). A swapped frame, or one located on something else, stands out.
:func:`rollfric.track.plausibility.flag_frames` runs this check after the others.
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.track.localfit import polyfit_rows

# jump: the prediction's residual |e| of a frame, for Gaussian centre errors of sigma per
# axis, is Rayleigh-distributed: P(|e| > k sigma_e) = exp(-k^2 / 2), so at 6 sigma one good
# frame in 66 million is rejected; sigma_e^2 = s^2 + (gain sigma)^2 + (2 model)^2: s the
# frame's own centre error (the track's sigma, or the locator's for that frame when larger:
# partial arcs), gain the prediction's noise gain (one-sided at a run's ends), sigma the
# track's own (the median of |e| / sqrt(1 + gain^2), / 1.1774)
JUMP_SIGMAS = 6.0
JUMP_FLOOR_PX = 0.01  # below this the scatter is the locator's rounding, not noise
HALF_WINDOW = 4  # neighbours on each side of the frame that predict it
DEGREE = 2  # a quadratic over 8 frames: the ball's jerk over them is below 1e-4 px
MAX_GAP = 12  # neighbours farther than this many frames away do not predict


def nearest(ok: np.ndarray, i: np.ndarray, k: int, sides: tuple[int, ...] = (-1, 1)):
    """For each frame of ``i``: up to ``k`` of the ``ok`` frames nearest it on each side in
    ``sides`` (-1 before, +1 after; itself left out), within MAX_GAP frames.

    Parameters
    ----------
    ok : numpy.ndarray of bool
        The frames that may be neighbours.
    i : array_like of int
        The frames whose neighbours are wanted.
    k : int
        Neighbours on each side.
    sides : tuple of int
        -1 (before), +1 (after) or both.

    Returns
    -------
    j, use : numpy.ndarray
        (len(i), k * len(sides)) frame numbers, nearest first on each side, and which are
        there.
    """
    idx = np.flatnonzero(ok)
    i = np.asarray(i, dtype=np.intp)
    off = np.arange(k)
    cols = []
    for side in sides:
        if side < 0:
            cols.append(np.searchsorted(idx, i, side="left")[:, None] - 1 - off)
        else:
            cols.append(np.searchsorted(idx, i, side="right")[:, None] + off)
    at = np.concatenate(cols, axis=1)
    use = (at >= 0) & (at < idx.size)
    j = idx[np.clip(at, 0, idx.size - 1)] if idx.size else np.zeros_like(at)
    use &= np.abs(j - i[:, None]) <= MAX_GAP
    return j, use


def _predict(i, x: np.ndarray, y: np.ndarray, ok: np.ndarray,
             pos: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, model error, noise gain) at each frame of ``i`` from up to HALF_WINDOW ok frames
    on each side (the frame left out): a quadratic in the frame number (or in ``pos``, the
    frames' times in periods: a recording with dropped frames or its own timestamps), how far
    a cubic's prediction differs from it (the polynomial's own error where the neighbours are
    far or one-sided: near a gap, at a low frame rate), and the prediction's standard
    deviation per unit centre error of the neighbours (~0.6 between neighbours on both sides,
    2.8 at the end of a run, where the quadratic extrapolates from 4 frames). NaN where fewer than
    DEGREE + 2 neighbours, model error 0 where fewer than DEGREE + 4. All frames in one batch
    of least-squares fits (:func:`rollfric.track.localfit.polyfit_rows`)."""
    i = np.asarray(i, dtype=np.intp)
    px, py, model, gain = (np.full(i.size, np.nan) for _ in range(4))
    j, use = nearest(ok, i, HALF_WINDOW)
    cnt = use.sum(axis=1)
    fit = cnt >= DEGREE + 2
    if not fit.any():
        return px, py, model, gain
    j, use, ii = j[fit], use[fit], i[fit]
    u = (j - ii[:, None]).astype(float) if pos is None else pos[j] - pos[ii][:, None]
    xy = np.stack([x[j], y[j]], axis=-1)  # x and y share one least-squares solve
    p, g = polyfit_rows(u, xy, use, DEGREE, gain=True)
    p0 = p[:, 0]
    m = np.zeros(ii.size)
    cubic = cnt[fit] >= DEGREE + 4
    if cubic.any():
        q0 = polyfit_rows(u[cubic], xy[cubic], use[cubic], DEGREE + 1)[:, 0]
        m[cubic] = np.hypot(q0[:, 0] - p0[cubic, 0], q0[:, 1] - p0[cubic, 1])
    px[fit], py[fit], model[fit], gain[fit] = p0[:, 0], p0[:, 1], m, g
    return px, py, model, gain


def innovations(x, y, ok, pos=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(|centre - prediction|, the prediction's model error, its noise gain) for each ok frame
    (px, px, per unit centre error), the prediction from the neighbours on both sides
    (one-sided at the ends of a run; NaN where too few neighbours); ``pos``: the frames'
    times in periods (None: the frame numbers). For independent centre errors of sigma, the
    residual's own standard deviation is sigma * sqrt(1 + gain^2) (plus the model error)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.asarray(ok, dtype=bool)
    pos = None if pos is None else np.asarray(pos, dtype=float)
    e, m, g = (np.full(x.size, np.nan) for _ in range(3))
    i = np.flatnonzero(ok)
    px, py, m[i], g[i] = _predict(i, x, y, ok, pos)
    e[i] = np.hypot(x[i] - px, y[i] - py)
    return e, m, g


def _culprit(i: int, z: np.ndarray, x, y, ok: np.ndarray, pos, zscore) -> int:
    """Which frame to reject for the worst residual ``z[i]``: of the frames near i (within
    MAX_GAP) above JUMP_SIGMAS, the one whose removal leaves the others' largest z smallest.
    A frame off by d moves its neighbours' predictions too, by their fit's weight on it; in a
    run that weight is below 1 and the frame itself is the worst, but at a run's end a frame
    predicted from one side has the larger error and its neighbour, which it predicts nearly
    alone from its side, can show the larger z."""
    near = np.flatnonzero(ok & (z > JUMP_SIGMAS))
    near = near[np.abs(near - i) <= MAX_GAP]
    if near.size < 2:
        return i
    best, best_left = i, math.inf
    for c in near[np.argsort(-z[near], kind="stable")]:
        others = near[near != c]
        ok_c = ok.copy()
        ok_c[c] = False
        px, py, model, g = _predict(others, x, y, ok_c, pos)
        e = np.hypot(x[others] - px, y[others] - py)
        left = float(np.max(zscore(others, e, np.nan_to_num(model), np.nan_to_num(g))))
        if left < best_left:
            best, best_left = int(c), left
    return best


def flag_jumps(x, y, found, ok: np.ndarray, flags: np.ndarray, sigma, pos) -> None:
    """Flag the jumps (in ``flags`` and ``ok``, in place): the worst first, its neighbours'
    predictions again without it, until none is left.

    A residual's scale is the frame's own centre error (the track's, or the frame's when
    larger: partial arcs) and the prediction's: the neighbours' errors through the fit (its
    noise gain: at the ends of a run the quadratic extrapolates from one side and its error
    is 2.8 centre errors, against 0.6 between neighbours on both sides) and its model error
    (twice what the cubic says: the neglected terms' share is of its order). A jump to the
    place of a frame just before is a duplicate.

    Parameters
    ----------
    x, y : numpy.ndarray
        Centres (px), one a frame.
    found : numpy.ndarray of bool
        The frames the tracker located (a jump onto one of them just before is a duplicate).
    ok : numpy.ndarray of bool
        The frames still judged good; the jumps are set False.
    flags : numpy.ndarray of object
        Each frame's flag; the jumps' set to "jump" or "duplicate".
    sigma : array_like or None
        The locator's centre error per frame (px); None: the track's alone.
    pos : array_like or None
        Each frame's time in camera periods (None: its number).
    """
    n = x.size
    s_loc = np.asarray(sigma, dtype=float) if sigma is not None else np.zeros(n)
    s_loc = np.where(np.isfinite(s_loc), s_loc, 0.0)
    pos = None if pos is None else np.asarray(pos, dtype=float)
    e, model, g = innovations(x, y, ok, pos)
    # the track's centre error: the median residual over its own scale (Rayleigh: median
    # 1.1774 sigma per axis)
    en = e / np.sqrt(1.0 + np.square(g))
    scale = max(float(np.nanmedian(en[ok])) / 1.1774 if np.any(ok & np.isfinite(en)) else 0.0,
                JUMP_FLOOR_PX)

    def zscore(js, e_js, model_js, g_js):
        sd = np.sqrt(np.square(np.maximum(scale, s_loc[js])) + np.square(scale * g_js)
                     + np.square(2.0 * model_js))
        return np.where(np.isfinite(e_js), e_js / sd, 0.0)

    every = np.arange(n)
    for _ in range(n):
        z = np.where(ok, zscore(every, e, np.nan_to_num(model), np.nan_to_num(g)), 0.0)
        i = int(np.argmax(z))
        if z[i] <= JUMP_SIGMAS:
            break
        i = _culprit(i, z, x, y, ok, pos, zscore)
        prev = [j for j in range(i - 1, max(-1, i - 3), -1) if found[j]]
        same = prev and math.hypot(x[i] - x[prev[0]], y[i] - y[prev[0]]) < 1e-3
        flags[i] = "duplicate" if same else "jump"
        ok[i] = False
        e[i] = np.nan
        lo = max(0, i - MAX_GAP)
        js = lo + np.flatnonzero(ok[lo:i + MAX_GAP + 1])
        px, py, model[js], g[js] = _predict(js, x, y, ok, pos)
        e[js] = np.hypot(x[js] - px, y[js] - py)
