"""The covariance of a least-squares fit's parameters when its residuals are correlated: a
heteroscedasticity-and-autocorrelation-consistent (HAC, Newey-West) sandwich, prewhitened
(Andrews and Monahan, 1992). Used by the uncertainty budget (:mod:`rollfric.uncertainty.budget`,
over
the samples in time) and the contour's circle fit (:mod:`rollfric.geometry.trough`, over the edge
points along the contour)."""

from __future__ import annotations

import math

import numpy as np


def autocorrelation(x: np.ndarray) -> np.ndarray:
    """Sample autocorrelation rho[k], k = 0 .. n-1, of ``x`` about its mean (FFT).

    Parameters
    ----------
    x : numpy.ndarray
        A 1-D series.

    Returns
    -------
    numpy.ndarray
        rho[0 .. n-1], rho[0] = 1; all zeros for a constant series.
    """
    x = np.asarray(x, dtype=float) - np.mean(x)
    n = x.size
    f = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n]
    return acf / acf[0] if acf[0] > 0 else np.zeros(n)


def hac_covariance(jac: np.ndarray, res: np.ndarray, *, lag: int | None = None,
                   dof: int | None = None, max_rho: float = 0.97):
    """Parameter covariance of a least-squares fit: (ordinary, HAC, lag window, rho).

    ``res``: the noise part of the residuals (those of the fit, or of a fit with more free
    nuisance parameters; ``dof`` is then n minus their count, default n - p).
    Ordinary: s^2 (J'J)^-1. HAC: the Newey-West sandwich (J'J)^-1 S (J'J)^-1 of the scores
    g_t = J_t r_t, prewhitened (Andrews and Monahan, 1992): rho, the lag-1 autocorrelation of
    the residuals (at most ``max_rho`` in size), whitens the scores, g_t - rho g_(t-1); their
    long-run covariance is a Bartlett-weighted sum (weights 1 - j/(m+1), lags j <= m) recoloured
    by 1/(1 - rho)^2. ``lag`` None picks m as three times the first lag where the whitened
    residuals' autocorrelation drops below 2/sqrt(n) (at most n/4). Both carry the n/dof
    correction.

    Parameters
    ----------
    jac : numpy.ndarray
        Jacobian of the residuals with respect to the p parameters, shape (n, p).
    res : numpy.ndarray
        Noise residuals, shape (n,).
    lag : int or None
        Bartlett lag window m; None chooses it from the data.
    dof : int or None
        Degrees of freedom of ``res``; None: n - p.
    max_rho : float
        Bound on |rho| of the prewhitening.

    Returns
    -------
    ordinary : numpy.ndarray
        Ordinary covariance, (p, p).
    hac : numpy.ndarray
        HAC covariance, (p, p).
    lag : int
        Lag window used.
    rho : float
        Lag-1 autocorrelation used for prewhitening (NaN, with NaN covariances and lag 0,
        when J'J is singular).
    """
    jac = np.asarray(jac, dtype=float)
    res = np.asarray(res, dtype=float)
    n, p = jac.shape
    dof = max(n - p if dof is None else dof, 1)
    try:
        a = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        nan = np.full((p, p), np.nan)
        return nan, nan, 0, math.nan
    ordinary = a * float(res @ res) / dof
    r = res - res.mean()
    rr = float(r @ r)
    rho = float(np.clip((r[1:] @ r[:-1]) / rr, -max_rho, max_rho)) if rr > 0 else 0.0
    g = jac * res[:, None]
    gw = g[1:] - rho * g[:-1]
    if lag is None:
        ac = autocorrelation(res[1:] - rho * res[:-1])
        below = np.nonzero(ac[1:] < 2.0 / math.sqrt(n))[0]
        first = int(below[0]) + 1 if below.size else n
        lag = min(3 * first, n // 4)
    s = gw.T @ gw
    for j in range(1, lag + 1):
        c = gw[j:].T @ gw[:-j]
        s += (1.0 - j / (lag + 1.0)) * (c + c.T)
    hac = a @ (s / (1.0 - rho) ** 2) @ a * (n / dof)
    return ordinary, hac, int(lag), rho
