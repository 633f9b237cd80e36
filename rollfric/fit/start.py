"""The fit's self-start: what the data say of the motion before any fit.

Turning points of the low-passed series, mu from the amplitude lost per half-swing (2 mu per
half-swing in the small-angle limit) and from the start's acceleration, theta(t0) and
theta'(t0) from the filtered series, the start of the final rest. The least-squares fit
(:mod:`rollfric.fit.lsq`), the thesis's methods (:mod:`rollfric.fit.thesis`) and the quality
checks start from it; :func:`clean_series` is the check of t, theta they all make first.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from rollfric.errors import InputError
from rollfric.fit import eom, filtering
from rollfric.setup.model import Setup

MIN_SAMPLES = 50  # finite samples a fit needs


def clean_series(t, theta):
    """(t, theta, finite mask) as float arrays, refused (InputError) unless 1-D of one
    length with at least ``MIN_SAMPLES`` finite samples at strictly increasing times."""
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    if t.ndim != 1 or t.shape != theta.shape:
        raise InputError(f"t and theta must be 1-D arrays of one length, got shapes "
                         f"{t.shape} and {theta.shape}")
    good = np.isfinite(t) & np.isfinite(theta)
    if good.sum() < MIN_SAMPLES:
        raise InputError(f"only {int(good.sum())} usable samples of theta(t); at least "
                         f"{MIN_SAMPLES} are needed to fit mu")
    tg = t[good]
    if np.any(np.diff(tg) <= 0):
        raise InputError("times t_s must be strictly increasing")
    return t, theta, good


def sample_rate(t: np.ndarray) -> float:
    """The frame rate of times ``t`` (Hz): one over their median step."""
    dt = np.median(np.diff(t))
    return 1.0 / dt


def turning_points(theta_smooth: np.ndarray, fps: float) -> np.ndarray:
    """Indices of the turning points (extrema) of a low-passed angle series.

    Extrema are peaks of |theta - centre| separated by at least a quarter of the dominant
    period, so locator noise near a turning point gives one extremum, not several.

    Parameters
    ----------
    theta_smooth : numpy.ndarray
        Low-passed, uniformly sampled angle, rad.
    fps : float
        Sampling rate, Hz.

    Returns
    -------
    numpy.ndarray
        Sample indices of alternating maxima and minima, increasing.
    """
    f0 = filtering.dominant_frequency(theta_smooth, fps)
    distance = max(1, int(0.25 * fps / max(f0, 1e-3)))
    centre = np.median(theta_smooth)
    peaks_hi, _ = signal.find_peaks(theta_smooth - centre, distance=distance)
    peaks_lo, _ = signal.find_peaks(centre - theta_smooth, distance=distance)
    idx = np.sort(np.concatenate([peaks_hi, peaks_lo]))
    # keep alternating extrema only (a max followed by a min ...)
    keep = []
    for i in idx:
        if keep and (theta_smooth[i] > centre) == (theta_smooth[keep[-1]] > centre):
            if abs(theta_smooth[i] - centre) > abs(theta_smooth[keep[-1]] - centre):
                keep[-1] = i
            continue
        keep.append(i)
    return np.asarray(keep, dtype=int)


def mu_from_acceleration(t, theta, setup: Setup, *, offset: float = 0.0,
                         span: float | None = None) -> float:
    """mu from the start's acceleration, which the equation of motion splits into gravity and
    friction: a cubic over the first ``span`` seconds (default 0.15 of the small-angle
    period, at least 10 samples) gives theta, theta' and theta'' at t[0]; clipped to [0, 0.5].
    ``offset``: the angle of the trough bottom in the data's frame. NaN samples are skipped.

    Parameters
    ----------
    t : array_like
        Times, s.
    theta : array_like
        Angles, rad.
    setup : Setup
        The trough and ball (``track_radius``, ``gravity``).
    offset : float
        Angle of the trough bottom in the data's frame, rad.
    span : float or None
        Length of the start used for the cubic, s; None: 0.15 of the small-angle period.

    Returns
    -------
    float
        mu in [0, 0.5]; 0 when fewer than 4 samples are finite or the estimate is undefined.
    """
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    good = np.isfinite(t) & np.isfinite(theta)
    tt, yy = t[good], theta[good] - offset
    if tt.size < 4:
        return 0.0
    if span is None:
        span = 0.15 * 2 * math.pi / math.sqrt(eom.omega_squared(setup.track_radius,
                                                                 setup.gravity))
    n_acc = max(min(tt.size, 10), int(np.searchsorted(tt, tt[0] + span)))
    c = np.polynomial.polynomial.polyfit(tt[:n_acc] - tt[0], yy[:n_acc], 3)
    th0, om0, acc = c[0], c[1], 2 * c[2]
    s = math.copysign(1.0, om0) if abs(om0) > 1e-3 else -math.copysign(1.0, th0)
    k = 5.0 / (7.0 * setup.track_radius)
    normal = setup.gravity * math.cos(th0) + setup.track_radius * om0**2
    if not (normal > 0 and math.isfinite(acc)):
        return 0.0
    return float(np.clip((-acc / k - setup.gravity * math.sin(th0)) / (s * normal), 0, 0.5))


def initial_guess(t, theta, setup: Setup) -> dict:
    """Self-start: mu from the amplitude decay per half-swing, theta0/omega0 from the data.

    Amplitudes are half the swing between consecutive turning points (so a constant angle
    offset cancels); in the small-angle limit each half-swing loses 2 mu. ``mu_acc`` is mu
    from the start's acceleration (:func:`mu_from_acceleration`), the only estimate a record
    without turning points has (it is then also ``mu``).

    Parameters
    ----------
    t : array_like
        Times, s, strictly increasing where finite.
    theta : array_like
        Angles, rad (NaN for frames without a ball).
    setup : Setup
        The trough and ball (``track_radius``, ``gravity``).

    Returns
    -------
    dict
        ``mu``, ``mu_acc``, ``theta0`` (rad), ``omega0`` (rad/s), ``offset`` (rad),
        ``turning_points_s`` (s), ``turning_points_theta`` (rad), ``fps`` (Hz), ``t_rest``
        (s, the start of the final rest, inf if none), ``period`` (small-angle period, s).

    Raises
    ------
    rollfric.errors.InputError
        If ``t`` and ``theta`` are not 1-D arrays of one length, fewer than ``MIN_SAMPLES``
        samples are finite, or the finite times are not strictly increasing.
    """
    t, theta, good = clean_series(t, theta)
    fps = sample_rate(t[good])
    # uniform resampling over gaps for the filter
    tt = t[good]
    grid = np.arange(tt[0], tt[-1] + 0.5 / fps, 1.0 / fps)
    x = np.interp(grid, tt, theta[good])
    smooth = filtering.lowpass(x, fps)
    tp = turning_points(smooth, fps)
    mu0 = 0.0
    # without two turning points the record shows no centre of the swing: the camera's zero
    # is the best guess of the trough bottom
    offset = 0.0
    if tp.size >= 3:
        swings = np.abs(np.diff(smooth[tp]))  # peak-to-peak of consecutive half-swings
        # each half-swing loses 2 mu of amplitude; the peak-to-peak of consecutive swings
        # (a_k + a_{k+1}) drops by 4 mu from one to the next
        drops = -np.diff(swings)
        drops = drops[swings[1:] > 0.02 * swings[0]]
        if drops.size:
            mu0 = max(float(np.median(drops)) / 4.0, 0.0)
        offset = float(np.mean(0.5 * (smooth[tp[:-1]] + smooth[tp[1:]])))
    elif tp.size == 2:
        offset = float(0.5 * (smooth[tp[0]] + smooth[tp[1]]))
        a0, a1 = abs(smooth[tp[0]] - offset), abs(smooth[tp[1]] - offset)
        mu0 = max((a0 - a1) / 2.0, 0.0)
    # the ball at rest for good at the end of the record?
    period = 2 * math.pi / math.sqrt(eom.omega_squared(setup.track_radius, setup.gravity))
    noise = 1.4826 * float(np.median(np.abs(x - smooth - np.median(x - smooth))))
    tail = max(20, x.size // 50)
    final = float(np.median(smooth[-tail:]))
    moving = np.nonzero(np.abs(smooth - final) > max(5 * noise, 1e-7))[0]
    t_rest = math.inf
    if moving.size and grid[-1] - grid[moving[-1]] >= 0.25 * period:
        t_rest = float(grid[moving[-1]])
    # theta and theta' at t0 from a local quadratic on the raw samples (the zero-phase filter
    # is least reliable at the ends of the series)
    n_head = min(int(good.sum()), max(10, int(0.03 * fps)))
    coef = np.polynomial.polynomial.polyfit(tt[:n_head] - tt[0], theta[good][:n_head], 2)
    mu_acc = mu_from_acceleration(tt, theta[good], setup, offset=offset,
                                  span=max(0.15 * period, (n_head - 1) / fps))
    if tp.size < 2:
        mu0 = mu_acc  # too short for a decay
    return {
        "mu": mu0,
        "mu_acc": mu_acc,
        "theta0": float(coef[0]),
        "omega0": float(coef[1]),
        "offset": offset,
        "turning_points_s": grid[tp],
        "turning_points_theta": smooth[tp],
        "fps": fps,
        "t_rest": t_rest,
        "period": period,
    }

