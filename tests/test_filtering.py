import numpy as np
import pytest

from rollfric.errors import InputError
from rollfric.fit import filtering

FPS = 1000.0
T = np.arange(4000) / FPS


def test_zero_phase_lowpass_keeps_signal_and_removes_noise():
    sig = 0.3 * np.sin(2 * np.pi * 1.5 * T) + 0.02 * np.sin(2 * np.pi * 4.5 * T)
    noisy = sig + np.random.default_rng(0).normal(0, 3e-3, T.size)
    out = filtering.lowpass(noisy, FPS, cutoff=20.0)
    inner = slice(200, -200)
    assert np.sqrt(np.mean((out - sig)[inner] ** 2)) < 0.3 * 3e-3
    # no lag: the filtered phase equals the signal's phase (cross-correlation peak at 0)
    xc = np.correlate(out[inner] - out[inner].mean(), sig[inner] - sig[inner].mean(), "full")
    assert np.argmax(xc) - (len(out[inner]) - 1) == 0


def test_cutoff_is_chosen_between_signal_and_noise():
    sig = 0.3 * np.sin(2 * np.pi * 1.5 * T)
    noisy = sig + np.random.default_rng(1).normal(0, 1e-3, T.size)
    fc = filtering.choose_cutoff(noisy, FPS)
    assert 5 * 1.5 <= fc < 100
    assert filtering.choose_cutoff(sig, FPS) == pytest.approx(0.4 * FPS)


def test_derivative_of_a_sine():
    sig = 0.3 * np.sin(2 * np.pi * 1.5 * T)
    d = filtering.derivative(sig + np.random.default_rng(2).normal(0, 1e-4, T.size), FPS)
    true = 0.3 * 2 * np.pi * 1.5 * np.cos(2 * np.pi * 1.5 * T)
    assert np.max(np.abs(d - true)[100:-100]) < 0.02 * np.max(true)


def test_gaps_stay_gaps():
    x = np.sin(2 * np.pi * 1.5 * T)
    x[100:120] = np.nan
    y = filtering.lowpass(x, FPS, cutoff=30)
    assert np.all(np.isnan(y[100:120])) and np.all(np.isfinite(y[:100]))


def test_bad_cutoff():
    with pytest.raises(InputError, match="Nyquist"):
        filtering.lowpass(np.zeros(100), FPS, cutoff=600)
