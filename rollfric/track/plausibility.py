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
  one located on something else, stands out (:mod:`rollfric.track.jumps`);
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

from rollfric.track.jumps import (
    flag_jumps,
    innovations,  # noqa: F401  (importable from here, as before the jump check had its module)
    nearest,
)

FLAGS = ("not_found", "off_track", "contrast", "residual", "radius", "occluded", "jump",
         "duplicate", "off_path", "stuck")

DUPLICATE_PX = 1e-4
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
    after it (k > 0), within :data:`rollfric.track.jumps.MAX_GAP` frames; NaN where there are
    none."""
    out = np.full(v.size, np.nan)
    i = np.flatnonzero(ok)
    j, use = nearest(ok & np.isfinite(v), i, abs(k), (1 if k > 0 else -1,))
    out[i] = _row_median(v[j], use)
    return out


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
    # a lead goes one way: its steps' net displacement at least STUCK_KEEP of their length (a
    # swapped frame's steps there and back, 17 px each, are no motion at full speed)
    gaps = np.lib.stride_tricks.sliding_window_view(np.diff(idx), STUCK_LEAD)
    net = np.hypot(px[STUCK_LEAD:] - px[:-STUCK_LEAD], py[STUCK_LEAD:] - py[:-STUCK_LEAD])
    straight = net >= STUCK_KEEP * np.sum(win * gaps, axis=1)
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
            if v < max(floor, STUCK_KEEP * float(mean[j])) or lo_[j] < STUCK_KEEP * hi_[j] \
                    or not straight[j]:
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
    flag_jumps(x, y, found, ok, flags, sigma, pos)
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
