"""Dropped frames found from the motion itself, for recordings without per-frame times.

A camera that loses a frame leaves a recording whose frame k + 1 was really taken two periods
after frame k: the ball's step between them is twice its neighbours'. Every later frame is one
period later than its index says, so a fit on frame / fps would see a phase jump there (four
lost frames in 0.8 s of the small validation case: mu +2.9 %). Here each step of the ball's
centre (px, two axes) is compared with the step its neighbours predict: a quadratic in time
through the per-period steps 2 to ``HALF_WINDOW`` steps away on each side (the step itself and
its two neighbours left out)::

    step_k = c[k + 1] - c[k],   predicted p_k,   residual r_k = |step_k - p_k|

A step far off its prediction (r_k > ``DETECT_SIGMAS`` sigma, the largest of its stretch) that
spans a whole number m >= 2 of periods by its neighbours' fit is taken as m - 1 lost periods:
the later frames are counted that much later and the predictions made again (so the steps
beyond a gap predict in the right time), until nothing new is found. It is kept as a gap when
it then matches m periods to within the noise and the steps before and after it are ordinary
(a located frame that is off - a glitch, a repeated frame - spoils two steps, a gap only one).
sigma is the track's own step noise (the median r / 1.1774: Rayleigh for Gaussian centre
errors; a step whose two frames the locator states less certain is judged against their
errors). A step far off its prediction with ordinary neighbours that is no whole number of
periods, and off along the ball's path (a frame taken at another time is; one off across the
path by more than the noise is a centre located off), is "irregular": the timing cannot be
repaired there.

A gap is seen only where the ball moves: at a turning point the step is below the noise and one
more period there cannot be told (:attr:`Gaps.min_step_px`). ``DETECT_SIGMAS`` = 8: a good step
passes with probability 1 - exp(-32) (1e-14) for Gaussian noise.

The repaired frame positions ``pos`` (the camera's period count of each recorded frame: k plus
the periods lost before it) give the frame times pos / fps.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.ndimage import maximum_filter1d

from rollfric.fit import estimate as fitmod
from rollfric.parallel import first_ordered
from rollfric.setup.model import Setup
from rollfric.track.localfit import polyfit_rows
from rollfric.uncertainty import quality

HALF_WINDOW = 8  # steps on each side that predict a step (2..HALF_WINDOW away)
DEGREE = 2  # the steps are the velocity times dt: a quadratic over 16 ms of a 0.5 s swing
DETECT_SIGMAS = 8.0  # |r| above this many sigma: a step that is no ordinary one
FIT_SIGMAS = 5.0  # a gap of m periods: |step - m p| within this many sigma (and p's error)
NEIGHBOUR_SIGMAS = 5.0  # the steps before and after a gap: within this many sigma of theirs
MAX_GAP = 10  # more periods than this in one step: no gap, something else
SIGMA_FLOOR_PX = 1e-3  # below this the step noise is the locator's rounding
PASSES = 4  # predictions made again without the worst steps, at most this often


@dataclasses.dataclass(frozen=True)
class Gaps:
    """Dropped frames found in a track (:func:`find_gaps`).

    Attributes
    ----------
    pos : numpy.ndarray
        (T,) the camera's period count of each recorded frame (frame k: k + the periods lost
        before it); the frame times are pos / fps.
    dropped : tuple of (int, int)
        (recorded frame k, periods lost between frames k and k + 1), one entry a gap.
    irregular : tuple of (int, float)
        (k, ratio): steps far off their prediction, with ordinary neighbours, that are no whole
        multiple of it (the step / predicted step ratio): timing that cannot be repaired.
    sigma_px : float
        The track's step noise (px, one axis).
    min_step_px : float
        The smallest predicted step at which a gap of one period shows (px): slower than
        this, near the turning points, a lost frame is not seen.
    n_steps : int
        Steps that could be checked (both frames located, neighbours to predict them).
    """

    pos: np.ndarray
    dropped: tuple
    irregular: tuple
    sigma_px: float
    min_step_px: float
    n_steps: int

    @property
    def n_dropped(self) -> int:
        """Periods lost in all (frames dropped)."""
        return int(sum(m for _, m in self.dropped))


def _fits(s: np.ndarray, u: np.ndarray, ok: np.ndarray, use: np.ndarray,
          coef: np.ndarray | None = None, only: np.ndarray | None = None) -> np.ndarray:
    """For each step k that is ``ok``: the coefficients (DEGREE + 1, 2) of a polynomial in the
    time (periods from u[k]) through the per-period steps ``s`` of its ``use`` neighbours
    2..HALF_WINDOW steps away on each side; NaN where fewer than DEGREE + 3 neighbours, or none
    on one side, are usable. With ``coef`` and ``only`` (a mask), just those steps are fitted
    again (in ``coef``, which is returned). All in one batch of least-squares fits
    (:func:`rollfric.track.localfit.polyfit_rows`)."""
    n = len(s)
    if coef is None:
        coef = np.full((n, DEGREE + 1, 2), np.nan)
    todo = np.flatnonzero(ok if only is None else ok & only)
    coef[todo] = np.nan
    off = np.r_[-HALF_WINDOW:-1, 2:HALF_WINDOW + 1]
    nb = todo[:, None] + off
    inside = (nb >= 0) & (nb < n)
    nb = np.clip(nb, 0, n - 1)
    sel = inside & use[nb]
    fit = ((sel.sum(axis=1) >= DEGREE + 3) & sel[:, off < 0].any(axis=1)
           & sel[:, off > 0].any(axis=1))
    k, nb, sel = todo[fit], nb[fit], sel[fit]
    coef[k] = polyfit_rows(u[nb] - u[k][:, None], s[nb], sel, DEGREE)
    return coef


def _expected(coef: np.ndarray, m: np.ndarray) -> np.ndarray:
    """The step over ``m`` periods from the start of each step: m times the per-period step
    the fit gives at the middle of those periods (the fits are about the middle of one
    period, u = start + 1/2)."""
    du = (m - 1.0) / 2.0
    v = coef[:, 0] + coef[:, 1] * du[:, None] + coef[:, 2] * (du ** 2)[:, None]
    return m[:, None] * v


def find_gaps(x, y, found, sigma_px=None) -> Gaps:
    """Find dropped frames (and irregular steps) in a track of ball centres.

    Parameters
    ----------
    x, y : array_like
        (T,) the ball's centre in each recorded frame (px), NaN where not found.
    found : array_like of bool
        (T,) frames where the ball was located.
    sigma_px : array_like, optional
        (T,) the locator's stated centre error of each frame (px, one axis): a step is judged
        against its two frames' errors where they exceed the track's step noise (a ball of a
        few px whose rim half fits: 0.1 px stated, where the track's median is 0.05).

    Returns
    -------
    Gaps
        The gaps found, the repaired frame positions and the noise they were judged against.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok_f = np.asarray(found, dtype=bool) & np.isfinite(x) & np.isfinite(y)
    n = x.size
    empty = Gaps(pos=np.arange(n, dtype=float), dropped=(), irregular=(), sigma_px=math.nan,
                 min_step_px=math.nan, n_steps=0)
    if n < 2 * HALF_WINDOW + 4:
        return empty
    c = np.column_stack([x, y])
    d = np.full((n - 1, 2), np.nan)
    ok = ok_f[:-1] & ok_f[1:]
    d[ok] = c[1:][ok] - c[:-1][ok]
    gaps = np.zeros(n - 1)  # periods lost in each step (0: an ordinary step)
    use = ok.copy()
    sigma, r, coef = math.nan, np.full(n - 1, np.nan), None
    # a step far off spoils its neighbours' predictions too: the worst step of each stretch
    # (the largest |r| within HALF_WINDOW) predicts no other; when it is a whole number of
    # periods, the periods are counted in (later frames that much later) and the predictions
    # made again, until no new step is left out
    changed = None  # the steps whose neighbourhood changed since the last pass (None: all)
    # each step's own noise floor: its two frames' stated errors (0 where none)
    stated = np.zeros(n - 1)
    if sigma_px is not None:
        sp = np.nan_to_num(np.asarray(sigma_px, dtype=float), nan=0.0, posinf=0.0)
        stated = np.hypot(sp[:-1], sp[1:])
    for _ in range(PASSES):
        periods = 1.0 + gaps
        pos = np.r_[0.0, np.cumsum(periods)]
        u = pos[:-1] + 0.5
        coef = _fits(d / periods[:, None], u, ok, use, coef, changed)
        r = np.linalg.norm(d - _expected(coef, periods), axis=1)
        good = ok & np.isfinite(r)
        if good.sum() < 10:
            return empty
        sigma = max(float(np.median(r[good & use])) / 1.1774, SIGMA_FLOOR_PX)
        rr = np.where(good, r / np.maximum(sigma, stated), 0.0) * sigma
        peak = rr >= maximum_filter1d(rr, 2 * HALF_WINDOW + 1, mode="constant")
        bad = good & (rr > DETECT_SIGMAS * sigma) & peak & use
        if not bad.any():
            break
        use = use & ~bad
        for k in np.nonzero(bad)[0]:
            m = _whole_periods(d[k], coef[k])
            if m is not None:
                gaps[k] = m - 1
        # a gap moves the times of every later step: those near it and beyond are fitted again
        # (far beyond, all their neighbours moved alike and the fit, in relative time, is the
        # same)
        changed = maximum_filter1d(bad.astype(np.uint8), 2 * HALF_WINDOW + 3) > 0
    checked = ok & np.isfinite(r)
    z = np.where(checked, r / np.maximum(sigma, stated), 0.0)
    dropped, irregular = [], []
    for k in np.nonzero((gaps > 0) | (z > DETECT_SIGMAS))[0]:
        nbr = [j for j in (k - 1, k + 1) if 0 <= j < n - 1]
        isolated = all(checked[j] and z[j] < NEIGHBOUR_SIGMAS for j in nbr)
        m = int(gaps[k]) + 1
        tol = FIT_SIGMAS * sigma * math.hypot(1.0, 0.5 * m)
        if gaps[k] > 0 and isolated and z[k] * sigma <= tol:
            dropped.append((int(k), m - 1))
            continue
        gaps[k] = 0.0
        if isolated and z[k] > DETECT_SIGMAS:
            v = coef[k, 0]
            vv = float(v @ v)
            # a step taken at another time than its period is off along the ball's path;
            # one off across it by more than the noise allows is a centre located off
            e = d[k] - v
            across = abs(float(e[0] * v[1] - e[1] * v[0])) / math.sqrt(vv) if vv > 0 else 0.0
            if across > FIT_SIGMAS * max(sigma, stated[k]):
                continue
            irregular.append((int(k), float(d[k] @ v) / vv if vv > 0 else math.nan))
    pos = np.r_[0.0, np.cumsum(1.0 + gaps)]
    return Gaps(pos=pos, dropped=tuple(dropped), irregular=tuple(irregular), sigma_px=sigma,
                min_step_px=DETECT_SIGMAS * sigma, n_steps=int(checked.sum()))


def split_irregular(irregular, distrusted) -> tuple[tuple, tuple]:
    """Irregular steps the timing is to blame for, and those among frames the locator got wrong.

    :func:`find_gaps` runs before the per-frame plausibility checks (they need its frame
    times), so it judges every located centre. A ball leaving a deep shadow is located half
    shadowed: its centres jump, the plausibility checks reject them (``residual``,
    ``contrast``, ...) and a step between them fits no whole number of periods although the
    camera kept time. A step with a ``distrusted`` frame at either end, or just before or
    after it (a frame lost next to the step: the shadow's edge), is the locator's.

    Parameters
    ----------
    irregular : sequence of (int, float)
        (k, ratio) of :attr:`Gaps.irregular` (the step from frame k to k + 1).
    distrusted : array_like of bool
        (T,) frames the locator lost or whose centre a check that does not depend on the
        frame times rejected.

    Returns
    -------
    timing, located : tuple of (int, float)
        The steps among trusted frames (the timing's) and the others (the locator's).
    """
    bad = np.asarray(distrusted, dtype=bool)
    n = bad.size
    timing, located = [], []
    for k, ratio in irregular:
        near = bad[max(0, k - 1):min(n, k + 3)].any()
        (located if near else timing).append((int(k), float(ratio)))
    return tuple(timing), tuple(located)


def confirm_irregular(x, y, found, rejected, repeated, irregular, sigma_px=None) -> tuple:
    """The irregular steps found again without the frames the plausibility checks rejected.

    :func:`find_gaps` judges every located centre. A glitched frame (repeated, swapped, a
    flash) spoils the steps beside it, and through them the predictions of the steps up to
    ``HALF_WINDOW`` away; where the ball turns its steps are a few hundredths of a px, and a
    spoiled prediction there made clean steps "irregular" (1.1-1.4 x) next to a repeated
    frame, or hid a real one. The steps are judged again with the rejected frames left out,
    the two frames of each irregular step forward kept (a frame after a slipped clock may be
    rejected as a jump: that step stays) unless repeated; a step back is a glitch's. A step
    into or out of a ``repeated`` frame (the same pixels as the frame before: a recording's
    glitch, the time base intact) is the repeat's, not the timing's.

    Parameters
    ----------
    x, y : array_like
        (T,) the located centres before any was rejected (px).
    found : array_like of bool
        (T,) frames the tracker located.
    rejected : array_like of bool
        (T,) frames the plausibility checks rejected (any flag).
    repeated : array_like of bool
        (T,) frames rejected as repeats of the frame before.
    irregular : sequence of (int, float)
        (k, ratio) of :attr:`Gaps.irregular` over every located frame.
    sigma_px : array_like, optional
        (T,) the locator's stated centre errors (:func:`find_gaps`).

    Returns
    -------
    tuple of (int, float)
        The irregular steps (k, ratio) of the track without its rejected frames.
    """
    found = np.asarray(found, dtype=bool)
    repeated = np.asarray(repeated, dtype=bool)
    keep = found & ~np.asarray(rejected, dtype=bool)
    for k, ratio in irregular:
        # a clock that slipped takes the frame late: a step forward of more than a period; a
        # step back against the motion (a frame swapped with one 40 periods away) is no time's
        if ratio > 0:
            keep[k:k + 2] = found[k:k + 2] & ~repeated[k:k + 2]
    again = irregular if np.array_equal(keep, found) else find_gaps(x, y, keep, sigma_px).irregular
    return tuple((int(k), float(r)) for k, r in again
                 if not (repeated[k] or repeated[min(k + 1, len(repeated) - 1)]))


def _whole_periods(step: np.ndarray, coef: np.ndarray) -> int | None:
    """The whole number m >= 2 of periods a step spans by its neighbours' fit, or None."""
    v = coef[0]
    vv = float(v @ v)
    if not np.all(np.isfinite(v)) or vv <= 0:
        return None
    m = int(round(float(step @ v) / vv))
    if not 2 <= m <= MAX_GAP:
        return None
    return m


# -- gaps where the ball turns: found by the fit ---------------------------------------------
# A frame lost where the ball turns leaves no step of its own, but every later frame is a period
# later than frame / fps: the residual of a fit on frame / fps is then about theta_dot * dt after
# that turning point. Each turning point of the fitted curve is scored by how well the residual
# after it matches theta_dot * dt (a matched filter, screened without re-fitting), and the best
# one is kept when the fit with that period counted in explains the data better by a likelihood
# ratio of TURN_LR_MIN (chi-square with one degree of freedom: 1e-8 by chance).
TURN_LR_MIN = 30.0
TURN_MAX = 5  # gaps at turning points looked for at most
TURN_TRIES = 3  # candidates re-fitted in each round, best score first


def turning_gap_candidates(t, theta, curve, fps: float) -> list:
    """The turning points of the fitted ``curve`` after which the residual looks like one lost
    period, best first.

    Parameters
    ----------
    t, theta : array_like
        The track's times (s) and angles (rad; NaN where not found).
    curve : array_like
        The fitted model at ``t`` (rad).
    fps : float
        The frame rate (Hz).

    Returns
    -------
    list of (int, float)
        (k, z): one period lost after sample k, z > 0 the matched filter's signal-to-noise
        ratio (the residual after k against theta_dot / fps), sorted by z, largest first.
    """
    t = np.asarray(t, dtype=float)
    th = np.asarray(theta, dtype=float)
    cv = np.asarray(curve, dtype=float)
    ok = np.isfinite(th) & np.isfinite(cv)
    if ok.sum() < 10:
        return []
    v = np.zeros(t.size)
    v[ok] = np.gradient(cv[ok], t[ok])
    r = np.where(ok, th - cv, 0.0)
    g = v / fps
    sigma = float(np.std(r[ok]))
    if sigma <= 0:
        return []
    turns = np.nonzero(v[:-1] * v[1:] < 0)[0]
    out = []
    for k in turns:
        gg = g[k + 1:]
        den = math.sqrt(float(gg @ gg)) * sigma
        if den > 0:
            z = float(r[k + 1:] @ gg) / den
            if z > 0:
                out.append((int(k), z))
    return sorted(out, key=lambda c: -c[1])


def likelihood_ratio(ssr0: float, ssr1: float, n: int) -> float:
    """n ln(ssr0 / ssr1): twice the log-likelihood ratio of two least-squares fits with Gaussian
    residuals of unknown variance.

    Parameters
    ----------
    ssr0, ssr1 : float
        Sums of squared residuals without and with the change.
    n : int
        Samples.

    Returns
    -------
    float
    """
    if ssr1 <= 0 or ssr0 <= 0:
        return math.inf if ssr1 < ssr0 else 0.0
    return n * math.log(ssr0 / ssr1)


def turning_gaps(t, theta, result, setup: Setup, offset: bool, fit_kwargs=None):
    """Dropped frames where the ball turns, found by the fit (this module's steps miss them).

    A lost frame at a turning point leaves no step to see, but the later frames are a period
    late: the best-scoring turning point (:func:`turning_gap_candidates`) gets a period counted
    in and the fit is made again (the ``TURN_TRIES`` best, in turn); it is kept when the
    likelihood ratio (with the effective number of samples of a correlated residual) exceeds
    ``TURN_LR_MIN``, then the next is looked for (at most ``TURN_MAX``).

    Parameters
    ----------
    t, theta : array_like
        The track's times (s, frame / fps with the step-found gaps) and angles (rad).
    result : rollfric.fit.estimate.FitResult
        The "lsq" fit of them.
    setup : Setup
        The setup.
    offset : bool
        Whether the fit has the angle offset.
    fit_kwargs : dict or None
        More keywords of :func:`rollfric.fit.estimate.fit_mu`.

    Returns
    -------
    t : numpy.ndarray
        The times with the gaps found counted in.
    result : rollfric.fit.estimate.FitResult
        The fit of them.
    gaps : tuple of (int, int)
        (frame k, 1): a period lost after frame k, one entry a gap found.
    """
    t = np.asarray(t, dtype=float).copy()
    th = np.asarray(theta, dtype=float)
    finite = np.isfinite(th)

    def ssr(res):
        # over every located sample: the fitter may leave a whole stretch out as outliers
        # (the frames before a gap it did not see), a repaired one takes it back
        d = th[finite] - np.asarray(res.curve, dtype=float)[finite]
        return float(np.mean(d[np.isfinite(d)] ** 2))

    def refit(k):
        t2 = t.copy()
        t2[k + 1:] += 1.0 / setup.fps
        return t2, fitmod.fit_mu(t2, th, setup, method="lsq", offset=offset,
                                 **(fit_kwargs or {}))

    def better(k, fitted):
        # correlated residuals (a systematic misfit, not noise) hold fewer independent
        # samples: n (1 - rho) / (1 + rho), rho the lag-1 autocorrelation of the new fit's
        # residual over the samples it used
        r2 = fitted[1]
        res2 = th - np.asarray(r2.curve, dtype=float)
        if r2.used is not None and r2.used.shape == res2.shape:
            res2 = np.where(r2.used, res2, np.nan)
        rho = quality.lag1_autocorrelation(res2)
        rho = min(max(rho, 0.0), 0.999) if math.isfinite(rho) else 0.999
        n = int(finite.sum()) * (1.0 - rho) / (1.0 + rho)
        return likelihood_ratio(ssr(result), ssr(r2), n) >= TURN_LR_MIN

    found = []
    for _ in range(TURN_MAX):
        # the candidates' refits are independent: on the CPUs that are free, the first that
        # passes in their order is the loop's (rollfric.parallel.first_ordered)
        cands = [k for k, _z in turning_gap_candidates(t, th, result.curve,
                                                       setup.fps)[:TURN_TRIES]]
        step = first_ordered(refit, cands, better, name="rollfric-fit")
        if step is None:
            break
        k, (t, result) = step
        found.append((int(k), 1))
    return t, result, tuple(found)
