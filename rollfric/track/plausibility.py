"""Per-frame plausibility: which located frames may enter the fit, and why not.

After the tracker has located the ball in every frame, each located frame is checked against
what the recording itself says (no camera-specific threshold):

- ``contrast``: the frame's brightness around the ball (its ratio to the background in a ring
  just outside the ball) differs by more than ``CONTRAST_TOL`` from its neighbours' (a flash,
  a dropped exposure);
- ``residual``: the centre's standard error from the circle fit is far above the track's
  typical one (the rim is spoiled: a band of corrupt rows, an object over the ball);
- ``radius``: the ball's apparent radius is off the calibrated one;
- ``occluded``: far less of the rim fits a circle than in the frames around it (a bar across
  the ball);
- ``jump``: the centre is far from where its neighbours on both sides (up to ``HALF_WINDOW``
  frames each; one side at the ends of a run) put the ball at that frame's time, by a
  polynomial through them, judged against that prediction's own error; a swapped frame, or
  one located on something else, stands out;
- ``duplicate``: a ``jump`` whose centre equals the previous frame's (a repeated frame);
- ``stuck``: a run of frames located at one place, entered or left at full speed (the ball
  slows to a halt or speeds up from one; a place that stays put while the motion goes on is
  something else: the ball's ghost in a background that holds it);
- ``off_path``: the centre is off the path the other frames trace about the trough centre
  (its distance from the centre against a + b sin(theta) + c cos(theta) fitted to all frames:
  the trough's circle seen about a centre that may be off by a few pixels). It catches a
  frame located on something else where too few neighbours are near to predict it (a lone
  frame between runs the locator lost).

A frame that fails is reported not found with its flag; ``not_found`` (the locator found no
ball) and ``off_track`` (a ball found off the trough's circle) are the tracker's own flags.
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.track.localfit import polyfit_rows

FLAGS = ("not_found", "off_track", "contrast", "residual", "radius", "occluded", "jump",
         "duplicate", "off_path", "stuck")

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
DUPLICATE_PX = 1e-4
MAX_GAP = 12  # neighbours farther than this many frames away do not predict
# contrast: lamp flicker moves the brightness by up to 10 % (measured in the flicker tests);
# twice that is not the same exposure
CONTRAST_TOL = 0.2
# the neighbours within +-CONTRAST_WINDOW frames; the reference is the mean of the median of
# those an odd number of frames away and of those an even number away (mains flicker sampled
# at twice its rate alternates the frames: the median of all +-5 held 6 of the other kind and
# 4 of the own, and 10 % flicker read as 22 % on every brighter frame)
CONTRAST_WINDOW = 5
# residual: the centre error is robust-z > RESIDUAL_SIGMAS above the track's median and more
# than RESIDUAL_RATIO x it (a spoiled rim, not the rim's ordinary variation along the path)
RESIDUAL_SIGMAS = 8.0
RESIDUAL_RATIO = 3.0
# radius: the apparent radius more than RADIUS_TOL (relative) off the calibrated one, or
# RADIUS_SIGMAS of its frame-to-frame scatter, whichever is larger
RADIUS_TOL = 0.02
RADIUS_SIGMAS = 8.0
# occluded: a fitted share of the rim below OCCLUDED_RATIO x the median of the 3 frames just
# before it or of the 3 just after it (an object entering or leaving the ball), and below it
# by more than OCCLUDED_SIGMAS robust sigmas of the track's own frame-to-frame scatter of that
# share (a ball of a few px has few rim pixels: its share varies by ~0.07 from frame to frame)
OCCLUDED_RATIO = 0.7
OCCLUDED_WINDOW = 3
OCCLUDED_SIGMAS = 5.0
# off_path: the distance from the trough centre more than OFF_PATH_SIGMAS robust sigmas of the
# track's own scatter about its fitted path, and more than OFF_PATH_FLOOR of the ball's radius
# (the scatter of a clean track is the locator's, ~0.02 px: a lens or a pinhole bends the path
# by more than that, a ball located on something else is off by a good part of its radius)
OFF_PATH_SIGMAS = 8.0
OFF_PATH_FLOOR = 0.1
# stuck: at least STUCK_FRAMES frames in a row whose steps are all below STUCK_FRAC of the
# speed the STUCK_LEAD steps before (or after) them keep up to the run (steady: none below
# STUCK_KEEP of the largest; their line's value there at least STUCK_KEEP of their mean, and
# at least STUCK_MIN_STEP_PX a frame): the ball
# does not stop dead from full speed, it slows to a halt (a rest) or speeds up from one (a
# release), so such a run is a place the locator is stuck on (a ghost of the ball in the
# background) while the ball moves on
STUCK_FRAMES = 4
STUCK_FRAC = 0.1
STUCK_LEAD = 3
STUCK_KEEP = 0.5
STUCK_MIN_STEP_PX = 0.5
# ... and above STUCK_ACC_FACTOR x the track's step change (this percentile of |change of the
# step| from frame to frame): a speed lost in so few changes is no real halt
STUCK_ACC_PERCENTILE = 90.0
STUCK_ACC_FACTOR = 4.0


def _robust(v: np.ndarray) -> tuple[float, float]:
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    med = float(np.median(v))
    return med, 1.4826 * float(np.median(np.abs(v - med)))


def _row_median(vals: np.ndarray, use: np.ndarray) -> np.ndarray:
    """The median of each row's used values (NaN for a row without any): the same number as
    ``numpy.median`` of them (the middle one, or the mean of the two middle ones)."""
    out = np.full(vals.shape[0], np.nan)
    cnt = use.sum(axis=1)
    rows = np.flatnonzero(cnt)
    if rows.size:
        s = np.sort(np.where(use[rows], vals[rows], np.inf), axis=1)
        c = cnt[rows]
        out[rows] = (s[np.arange(rows.size), (c - 1) // 2] + s[np.arange(rows.size), c // 2]) / 2
    return out


def _nearest(ok: np.ndarray, i: np.ndarray, k: int, sides: tuple[int, ...] = (-1, 1)):
    """For each frame of ``i``: up to ``k`` of the ``ok`` frames nearest it on each side in
    ``sides`` (-1 before, +1 after; itself left out), within MAX_GAP frames. Returns (j, use):
    (len(i), k * len(sides)) frame numbers, nearest first on each side, and which are there."""
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


def _neighbour_median(v: np.ndarray, ok: np.ndarray, half: int,
                      parity: int | None = None) -> np.ndarray:
    """For each frame, the median of ``v`` over the ok frames within +-half, itself left out
    (with ``parity``, only those an odd (1) or even (0) number of frames away)."""
    n = v.size
    out = np.full(n, np.nan)
    i = np.flatnonzero(ok)
    off = np.r_[-half:0, 1:half + 1]
    if parity is not None:
        off = off[np.abs(off) % 2 == parity]
    j = i[:, None] + off
    inside = (j >= 0) & (j < n)
    j = np.clip(j, 0, n - 1)
    use = inside & ok[j] & np.isfinite(v[j])
    out[i] = _row_median(v[j], use)
    return out


def _side_median(v: np.ndarray, ok: np.ndarray, k: int) -> np.ndarray:
    """For each frame, the median of ``v`` over the |k| ok frames just before it (k < 0) or just
    after it (k > 0), within MAX_GAP frames; NaN where there are none."""
    out = np.full(v.size, np.nan)
    i = np.flatnonzero(ok)
    j, use = _nearest(ok & np.isfinite(v), i, abs(k), (1 if k > 0 else -1,))
    out[i] = _row_median(v[j], use)
    return out


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
    j, use = _nearest(ok, i, HALF_WINDOW)
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


def off_path(x, y, ok, center, r_ball: float) -> np.ndarray:
    """Which ``ok`` frames' centres lie off the path the track traces about ``center``.

    The distance d of each centre from ``center`` is fitted with a + b sin(theta) +
    c cos(theta) (theta = atan2(x - cx, y - cy)): a circle seen about a centre that is off by
    a few pixels, to first order. Twice: the frames beyond the tolerance of the first fit are
    left out of the second.

    Parameters
    ----------
    x, y : array_like
        Centres (px).
    ok : array_like of bool
        The frames to judge (and to fit the path with).
    center : sequence of 2 floats
        The trough centre (px) the angles are taken about.
    r_ball : float
        The ball's apparent radius (px): the floor of the tolerance is OFF_PATH_FLOOR of it.

    Returns
    -------
    numpy.ndarray of bool
        True for an ``ok`` frame more than max(OFF_PATH_SIGMAS robust sigmas,
        OFF_PATH_FLOOR * r_ball) off the fitted path.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.asarray(ok, dtype=bool) & np.isfinite(x) & np.isfinite(y)
    out = np.zeros(x.size, dtype=bool)
    if ok.sum() < 10:
        return out
    dx, dy = x - center[0], y - center[1]
    d = np.hypot(dx, dy)
    th = np.arctan2(dx, dy)
    A = np.stack([np.ones_like(d), np.sin(th), np.cos(th)], axis=1)
    use = ok.copy()
    floor = OFF_PATH_FLOOR * float(r_ball)
    for _ in range(2):
        coef = np.linalg.lstsq(A[use], d[use], rcond=None)[0]
        res = d - A @ coef
        _, s = _robust(res[use])
        tol = max(OFF_PATH_SIGMAS * s, floor) if math.isfinite(s) else floor
        out = ok & (np.abs(res) > tol)
        use = ok & ~out
        if use.sum() < 10:
            return np.zeros(x.size, dtype=bool)
    return out


def stuck(x, y, ok) -> np.ndarray:
    """Frames in a run located at one place that the motion enters or leaves at full speed.

    Over the ``ok`` frames (steps per frame between successive ones): a run of at least
    STUCK_FRAMES frames whose steps are all below STUCK_FRAC of the speed v of the steady
    motion next to it, where v is the value at the run of a line through the STUCK_LEAD steps
    before it (or after it; none below STUCK_KEEP of the largest), at least STUCK_KEEP of their
    mean, STUCK_MIN_STEP_PX and STUCK_ACC_FACTOR x the track's typical step change (its
    STUCK_ACC_PERCENTILE: acceleration, noise, rounding): a ball slowing to a halt (a rest)
    or speeding up from one (a release) has that line near zero there.

    Parameters
    ----------
    x, y : array_like
        Centres (px), one a frame.
    ok : array_like of bool
        Frames to judge (the others are skipped).

    Returns
    -------
    numpy.ndarray of bool
        The stuck frames.
    """
    x = np.asarray(x, dtype=float)
    ok = np.asarray(ok, dtype=bool)
    out = np.zeros(x.size, dtype=bool)
    idx = np.flatnonzero(ok & np.isfinite(x) & np.isfinite(np.asarray(y, dtype=float)))
    if idx.size < STUCK_FRAMES + STUCK_LEAD + 1:
        return out
    px, py = x[idx], np.asarray(y, dtype=float)[idx]
    st = np.hypot(np.diff(px), np.diff(py)) / np.diff(idx)  # st[k]: idx[k] -> idx[k + 1]
    m = idx.size
    n_run = STUCK_FRAMES - 1  # steps inside a run
    # the track's own step changes (its acceleration, its noise and rounding): a speed that
    # could be lost in a few such changes may be a real halt
    acc = float(np.percentile(np.abs(np.diff(st)), STUCK_ACC_PERCENTILE))

    # the speed a line through STUCK_LEAD steps (oldest first) reaches one step on: a fixed
    # weighting of the steps (the least-squares line's value there), for every window at once
    t = np.arange(STUCK_LEAD, dtype=float)
    tc = t - t.mean()
    weights = 1.0 / STUCK_LEAD + tc * (STUCK_LEAD - t.mean()) / float(tc @ tc)
    win = np.lib.stride_tricks.sliding_window_view(st, STUCK_LEAD)  # win[j] = st[j:j + LEAD]
    leads = {"before": (win @ weights, win.mean(axis=1), win.min(axis=1), win.max(axis=1)),
             "after": (win[:, ::-1] @ weights, win.mean(axis=1), win.min(axis=1),
                       win.max(axis=1))}
    floor = max(STUCK_MIN_STEP_PX, STUCK_ACC_FACTOR * acc)
    for k in range(m - n_run):
        run_max = st[k:k + n_run].max()  # steps of frames idx[k] .. idx[k + n_run]
        # entered: the steps before the one into the run; left: those after the one out of it
        for side, j in (("before", k - 1 - STUCK_LEAD), ("after", k + n_run + 1)):
            if j < 0 or j >= win.shape[0]:
                continue
            v_all, mean, lo_, hi_ = leads[side]
            v = float(v_all[j])
            # a steady motion (no stuck place or jump among the lead's steps either)
            if v < max(floor, STUCK_KEEP * float(mean[j])) or lo_[j] < STUCK_KEEP * hi_[j]:
                continue
            if run_max < STUCK_FRAC * v:
                # the whole still run: on while the steps stay below STUCK_FRAC v
                lo, hi = k, k + n_run
                while lo > 0 and st[lo - 1] < STUCK_FRAC * v:
                    lo -= 1
                while hi < m - 1 and st[hi] < STUCK_FRAC * v:
                    hi += 1
                out[idx[lo:hi + 1]] = True
    return out


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


def flag_frames(x, y, found, *, same_pixels=None, sigma=None, radius=None, inlier_frac=None,
                gain=None, r_ref: float | None = None,
                r_rel_sigma: float | None = None, pos=None, center=None,
                r_ball: float | None = None) -> np.ndarray:
    """The flag of every frame ('' for a good one) from the located centres and the locator's
    per-frame figures (any may be None: that check is skipped). ``found``: frames the tracker
    located; ``same_pixels``: frames whose ball pixels equal the previous frame's; ``r_ref``:
    the calibrated apparent radius (px) and ``r_rel_sigma`` its relative frame-to-frame
    scatter; ``pos``: each frame's time in camera periods (None: its number; see
    :mod:`rollfric.track.dropped_frames`: after a dropped frame the later ones are a period later);
    ``center`` and ``r_ball``: the trough centre and the ball's apparent radius (px) for the
    ``off_path`` check (:func:`off_path`; skipped when either is None). Frames already not
    found keep an empty flag here (the tracker names them)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    found = np.asarray(found, dtype=bool)
    ok = found.copy()
    n = x.size
    flags = np.array([""] * n, dtype=object)

    def reject(mask, name):
        mask = mask & ok
        flags[mask] = name
        ok[mask] = False

    if gain is not None:
        reject(_contrast_outliers(gain, ok), "contrast")
    if sigma is not None:
        reject(_residual_outliers(sigma, ok), "residual")
    if radius is not None and r_ref:
        reject(_radius_outliers(radius, r_ref, r_rel_sigma), "radius")
    if inlier_frac is not None:
        reject(_occluded(inlier_frac, ok), "occluded")
    if center is not None and r_ball:
        reject(off_path(x, y, ok, center, r_ball), "off_path")
    reject(stuck(x, y, ok), "stuck")
    reject(_repeated(x, y, found, ok, same_pixels), "duplicate")
    _flag_jumps(x, y, found, ok, flags, sigma, pos)
    return flags


def _contrast_outliers(gain, ok: np.ndarray) -> np.ndarray:
    """Frames whose contrast figure ``gain`` is off its neighbours' median by more than
    CONTRAST_TOL."""
    g = np.asarray(gain, dtype=float)
    even, odd = (_neighbour_median(g, ok, CONTRAST_WINDOW, parity=p) for p in (0, 1))
    ref = np.where(np.isfinite(even) & np.isfinite(odd), 0.5 * (even + odd),
                   np.where(np.isfinite(even), even, odd))
    return np.isfinite(g) & np.isfinite(ref) & (np.abs(g / ref - 1) > CONTRAST_TOL)


def _residual_outliers(sigma, ok: np.ndarray) -> np.ndarray:
    """Frames whose centre error ``sigma`` is far above the good frames' typical one."""
    s = np.asarray(sigma, dtype=float)
    med, mad = _robust(s[ok])
    if not math.isfinite(med):
        return np.zeros(s.shape, dtype=bool)
    return np.isfinite(s) & (s > max(RESIDUAL_RATIO * med, med + RESIDUAL_SIGMAS * mad))


def _radius_outliers(radius, r_ref: float, r_rel_sigma: float | None) -> np.ndarray:
    """Frames whose fitted radius is off the calibrated one ``r_ref`` by more than its
    tolerance."""
    r = np.asarray(radius, dtype=float)
    tol = max(RADIUS_TOL, RADIUS_SIGMAS * (r_rel_sigma or 0.0)) * r_ref
    return np.isfinite(r) & (np.abs(r - r_ref) > tol)


def _occluded(inlier_frac, ok: np.ndarray) -> np.ndarray:
    """Frames with an abrupt loss of rim (``inlier_frac``) against the frames just before or
    just after them (a slow change, the ball rolling into a shadow or against the trough, is
    no occlusion), and by more than the track's own scatter of it (:data:`OCCLUDED_SIGMAS`)."""
    f = np.asarray(inlier_frac, dtype=float)
    before = _side_median(f, ok, -OCCLUDED_WINDOW)
    after = _side_median(f, ok, OCCLUDED_WINDOW)
    ref = np.fmax(before, after)
    d = ref - f
    fin = ok & np.isfinite(d)
    # the drop's robust sigma (MAD about the median) over the track's frames
    scatter = 1.4826 * float(np.median(np.abs(d[fin] - np.median(d[fin])))) if fin.any() else 0.0
    return np.isfinite(f) & np.isfinite(ref) & (f < OCCLUDED_RATIO * ref) & \
        (d > OCCLUDED_SIGMAS * scatter)


def _repeated(x, y, found, ok: np.ndarray, same_pixels) -> np.ndarray:
    """Repeated frames: the ball's pixels equal the frame before's (``same_pixels``; without
    it the same centre to 1e-4 px: a locator's answers for two exposures differ by its
    noise), while the ball moved between the frames around it (the frames of a resting ball
    drawn without noise may be alike)."""
    n = x.size
    rep = np.zeros(n, dtype=bool)
    for i in np.nonzero(ok)[0]:
        if 0 < i < n - 1 and found[i - 1] and found[i + 1]:
            same = bool(same_pixels[i]) if same_pixels is not None else \
                math.hypot(x[i] - x[i - 1], y[i] - y[i - 1]) < DUPLICATE_PX
            moved = math.hypot(x[i + 1] - x[i - 1], y[i + 1] - y[i - 1]) > 10 * DUPLICATE_PX
            rep[i] = same and moved
    return rep


def _flag_jumps(x, y, found, ok: np.ndarray, flags: np.ndarray, sigma, pos) -> None:
    """Flag the jumps (in ``flags`` and ``ok``, in place): the worst first, its neighbours'
    predictions again without it, until none is left.

    A residual's scale is the frame's own centre error (the track's, or the frame's when
    larger: partial arcs) and the prediction's: the neighbours' errors through the fit (its
    noise gain: at the ends of a run the quadratic extrapolates from one side and its error
    is 2.8 centre errors, against 0.6 between neighbours on both sides) and its model error
    (twice what the cubic says: the neglected terms' share is of its order). A jump to the
    place of a frame just before is a duplicate."""
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
