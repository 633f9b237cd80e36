"""Zero-phase Chebyshev low-pass filtering of theta(t) and its time derivative.

The thesis low-pass filters the measured angles with a Chebyshev filter before it
differentiates them (following Guddei et al. 2013). Here the filter is a type-I Chebyshev
(scipy.signal.cheby1) applied forwards and backwards (sosfiltfilt), so it adds no delay.

The cut-off, when not given, is chosen from the data (:func:`choose_cutoff`): the highest
frequency at which the spectrum of theta still stands clearly above its white-noise floor,
with a margin, so the harmonics that the Coulomb kinks at the turning points put into theta(t)
pass and the locator noise above them does not.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from rollfric.errors import InputError

DEFAULT_ORDER = 5  # odd: unit gain at 0 Hz (even orders sit at -ripple)
DEFAULT_RIPPLE_DB = 0.001  # two passes: at most 0.03 % gain error in the pass band
MIN_SAMPLES = 32


def _fill_gaps(x: np.ndarray) -> np.ndarray:
    """Linear interpolation over NaN samples (frames where the ball was not found)."""
    x = np.asarray(x, dtype=float)
    good = np.isfinite(x)
    if good.all():
        return x
    if good.sum() < 2:
        raise InputError("theta has fewer than two finite samples: nothing to filter")
    idx = np.arange(x.size)
    return np.interp(idx, idx[good], x[good])


def dominant_frequency(theta, fps: float) -> float:
    """Frequency (Hz) of the strongest spectral peak of theta(t) above 0 Hz.

    Parameters
    ----------
    theta : array_like
        Uniformly sampled angle, rad; NaN samples are bridged by linear interpolation.
    fps : float
        Sampling rate, Hz.

    Returns
    -------
    float
        Peak frequency, Hz.

    Raises
    ------
    rollfric.errors.InputError
        If ``theta`` has fewer than two finite samples.
    """
    x = _fill_gaps(theta)
    x = signal.detrend(x, type="linear")
    n = x.size
    nfft = int(2 ** np.ceil(np.log2(max(4 * n, 256))))
    spec = np.abs(np.fft.rfft(x * signal.windows.hann(n), nfft))
    freqs = np.fft.rfftfreq(nfft, 1.0 / fps)
    spec[0] = 0.0
    return float(freqs[int(np.argmax(spec))])


def choose_cutoff(theta, fps: float) -> float:
    """A cut-off (Hz) from the data: where the spectrum meets the noise floor, times 1.5.

    The noise floor is the median Welch power density over the top half of the band; the
    signal band ends at the highest frequency whose (smoothed) density exceeds ten times the
    floor. The result lies between 5 times the oscillation frequency and 0.4 x the sampling
    rate (noiseless data gets the upper bound, i.e. almost no filtering).

    Parameters
    ----------
    theta : array_like
        Uniformly sampled angle, rad; NaN samples are bridged by linear interpolation.
    fps : float
        Sampling rate, Hz.

    Returns
    -------
    float
        Cut-off frequency, Hz.

    Raises
    ------
    rollfric.errors.InputError
        If ``theta`` has fewer than two finite samples or fewer than ``MIN_SAMPLES`` samples.
    """
    x = _fill_gaps(theta)
    if x.size < MIN_SAMPLES:
        raise InputError(f"theta has {x.size} samples; at least {MIN_SAMPLES} are needed "
                         "to choose a filter cut-off")
    f0 = dominant_frequency(x, fps)
    nyq = 0.5 * fps
    nperseg = min(x.size, 1024)
    freqs, psd = signal.welch(signal.detrend(x), fs=fps, nperseg=nperseg)
    floor = np.median(psd[freqs >= 0.5 * nyq])
    smooth = np.convolve(psd, np.ones(3) / 3, mode="same")
    above = np.nonzero(smooth > 10.0 * floor)[0]
    lo = max(5.0 * f0, 2.0 * fps / x.size)
    hi = 0.4 * fps
    if floor <= 0 or above.size == 0:
        return float(hi)
    edge = freqs[above[-1]]
    return float(np.clip(1.5 * edge, lo, hi))


def lowpass(theta, fps: float, cutoff: float | None = None, *, order: int = DEFAULT_ORDER,
            ripple_db: float = DEFAULT_RIPPLE_DB) -> np.ndarray:
    """Zero-phase Chebyshev type-I low-pass of uniformly sampled theta.

    NaN samples are bridged by linear interpolation before filtering and stay NaN in the
    output. ``cutoff`` in Hz; None chooses it from the data.

    Parameters
    ----------
    theta : array_like
        One-dimensional, uniformly sampled angle, rad.
    fps : float
        Sampling rate, Hz.
    cutoff : float or None
        Cut-off frequency, Hz; None chooses it with :func:`choose_cutoff`.
    order : int
        Filter order.
    ripple_db : float
        Pass-band ripple, dB.

    Returns
    -------
    numpy.ndarray
        The filtered angle, rad, NaN where ``theta`` is NaN.

    Raises
    ------
    rollfric.errors.InputError
        If ``theta`` is not one-dimensional or has fewer than two finite samples, ``fps`` is
        not positive, or the cut-off does not lie between 0 and the Nyquist frequency.
    """
    theta = np.asarray(theta, dtype=float)
    if theta.ndim != 1:
        raise InputError("theta must be one-dimensional")
    if not fps > 0:
        raise InputError(f"fps must be positive, got {fps}")
    x = _fill_gaps(theta)
    if cutoff is None:
        cutoff = choose_cutoff(x, fps)
    if not 0 < cutoff < 0.5 * fps:
        raise InputError(f"cut-off {cutoff} Hz must lie between 0 and the Nyquist frequency "
                         f"{0.5 * fps} Hz")
    sos = signal.cheby1(order, ripple_db, cutoff, btype="low", output="sos", fs=fps)
    padlen = min(x.size - 1, 3 * (2 * len(sos) + 1) * 10)
    y = signal.sosfiltfilt(sos, x, padlen=padlen)
    y[~np.isfinite(theta)] = np.nan
    return y


def derivative(theta, fps: float, cutoff: float | None = None, **kw) -> np.ndarray:
    """theta'(t) in rad/s: second-order central differences of the low-passed theta.

    Parameters
    ----------
    theta : array_like
        One-dimensional, uniformly sampled angle, rad.
    fps : float
        Sampling rate, Hz.
    cutoff : float or None
        Cut-off frequency, Hz; None chooses it from the data.
    **kw
        ``order`` and ``ripple_db``, passed to :func:`lowpass`.

    Returns
    -------
    numpy.ndarray
        Angular velocity, rad/s, at every sample (NaN gaps of ``theta`` are interpolated over).

    Raises
    ------
    rollfric.errors.InputError
        As :func:`lowpass`.
    """
    y = lowpass(theta, fps, cutoff, **kw)
    return np.gradient(_fill_gaps(y), 1.0 / fps)


def noise_sigma(theta, orders=(2, 3, 4)) -> float:
    """Standard deviation of the white noise in a uniformly sampled, smooth series.

    The k-th difference of white noise of standard deviation sigma has the standard deviation
    sigma * sqrt(C(2k, k)); that of a smooth signal falls as (omega dt)^k, so at a frame
    rate well above the swing the differences are the noise. Each order gives a robust
    estimate (1.4826 x the median absolute deviation, so the few kinks at turning points and
    stray samples do not count); a signal too coarsely sampled for an order only raises its
    estimate, so the smallest over ``orders`` is taken. Differences are taken only across
    consecutive finite samples (NaN gaps break them). Returns NaN when fewer than 8
    differences of any order exist.

    Parameters
    ----------
    theta : array_like
        Uniformly sampled series (NaN for missing samples).
    orders : sequence of int
        Difference orders to try.

    Returns
    -------
    float
        Noise standard deviation, in the units of ``theta``, or NaN.
    """
    x = np.asarray(theta, dtype=float)
    best = math.inf
    for k in orders:
        d = x
        for _ in range(k):
            d = d[1:] - d[:-1]  # NaN wherever any of the k + 1 samples is missing
        d = d[np.isfinite(d)]
        if d.size < 8:
            continue
        mad = float(np.median(np.abs(d - np.median(d))))
        best = min(best, 1.4826 * mad / math.sqrt(math.comb(2 * k, k)))
    return best if math.isfinite(best) else float("nan")


def on_grid(t: np.ndarray, y: np.ndarray, fps: float) -> np.ndarray:
    """``y`` placed on the uniform frame grid from t[0] (NaN where a frame has no sample).

    Parameters
    ----------
    t : numpy.ndarray
        Sample times, s, increasing.
    y : numpy.ndarray
        Values at ``t``.
    fps : float
        Frame rate of the grid, Hz; each time is rounded to the nearest frame.

    Returns
    -------
    numpy.ndarray
        Values on frames 0 .. round((t[-1] - t[0]) fps).
    """
    idx = np.rint((t - t[0]) * fps).astype(np.int64)
    out = np.full(int(idx[-1]) + 1 if idx.size else 0, np.nan)
    out[idx] = y
    return out
