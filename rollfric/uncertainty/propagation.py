"""Beyond the budget's first-order law of propagation: the next-order terms (JCGM 100, 5.1.2,
note) and the Monte-Carlo check (JCGM 101), both by re-fits of the measurement with the
uncertain inputs moved (:mod:`rollfric.uncertainty.sensitivity`).
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.setup.model import Setup
from rollfric.uncertainty.sensitivity import Refitter, acts, moved, setup_inputs

SECOND_ORDER = "second order"  # the source name of the next-order terms' budget row


def second_order(evaluate, n: int) -> tuple[float, list]:
    """The next-order terms of the law of propagation for ``n`` independent normal inputs
    (JCGM 100, 5.1.2, note): sum over i, j of [(1/2) (d2f/dxi dxj)^2 + df/dxi d3f/dxi dxj^2]
    u^2(xi) u^2(xj), the derivatives by finite differences over steps of one and two standard
    uncertainties.

    ``evaluate(k)`` is the measurand with input i moved by ``k[i]`` of its standard
    uncertainties (k a tuple of n integers, 0 the estimate). With df_i = f_i u_i, d2_i =
    f_ii u_i^2 and so on, all in the measurand's unit: a pair (i, j), counted for (i, j) and
    (j, i), is m_ij^2 + df_i t_ijj + df_j t_jii (m_ij = f_ij u_i u_j from the four corners
    +-u_i +-u_j, t_ijj = f_ijj u_i u_j^2 from the same corners); a pure term (i = j) is
    d2_i^2 / 2 + (2/3) df_i d3_i (d3 from the steps of +-2 u): the first-order rows are
    secants over +-u, (f_i + f_iii u_i^2 / 6) u_i, whose square already holds a third of
    f_i f_iii u_i^4. So first-order secant rows plus these terms give the variance to the
    fourth order in u, exactly for a polynomial of degree 3 in each input with interactions
    of degree 2 (x_i x_j, x_i x_j^2). The sum may be negative (a curvature that narrows
    the distribution).

    Parameters
    ----------
    evaluate : callable
        k -> the measurand (float) with the inputs moved by k standard uncertainties.
    n : int
        Number of inputs.

    Returns
    -------
    variance : float
        The sum of the terms (the measurand's unit squared).
    terms : list of tuple
        (i, j, term) for every pure (i == j) and pair (i < j) term.
    """
    def f(*moves):
        k = [0] * n
        for i, step in moves:
            k[i] += step
        return float(evaluate(tuple(k)))

    f0 = f()
    df, d2, terms = [], [], []
    for i in range(n):
        hi, lo = f((i, 1)), f((i, -1))
        hi2, lo2 = f((i, 2)), f((i, -2))
        df.append(0.5 * (hi - lo))
        d2.append(hi + lo - 2.0 * f0)
        d3 = 0.5 * (hi2 - 2.0 * hi + 2.0 * lo - lo2)
        terms.append((i, i, 0.5 * d2[i] ** 2 + (2.0 / 3.0) * df[i] * d3))
    for i in range(n):
        for j in range(i + 1, n):
            c = {(a, b): f((i, a), (j, b)) for a in (1, -1) for b in (1, -1)}
            m = 0.25 * (c[1, 1] - c[1, -1] - c[-1, 1] + c[-1, -1])
            # the curvature along j at x_i +- u_i, and along i at x_j +- u_j
            t_ijj = 0.5 * ((c[1, 1] + c[1, -1] - 2.0 * f((i, 1)))
                           - (c[-1, 1] + c[-1, -1] - 2.0 * f((i, -1))))
            t_jii = 0.5 * ((c[1, 1] + c[-1, 1] - 2.0 * f((j, 1)))
                           - (c[1, -1] + c[-1, -1] - 2.0 * f((j, -1))))
            terms.append((i, j, m * m + df[i] * t_ijj + df[j] * t_jii))
    return float(sum(t for _, _, t in terms)), terms



def second_order_row(refit: Refitter, setup: Setup, active: list) -> tuple[float, str]:
    """(u, note) of the budget row of the next-order terms (:func:`second_order`) over the
    acting inputs, each evaluation a re-fit with the inputs moved together; u the root of
    their sum when positive, 0 when the curvature narrows the distribution (the first-order
    rows are then kept as they are: on the safe side). The note names the largest terms."""
    def evaluate(k):
        s = setup
        for (_, field, comp, u, factor), ki in zip(active, k, strict=True):
            if ki:
                s = moved(s, field, comp, ki * u, factor)
        return refit.mu(s)

    var, terms = second_order(evaluate, len(active))
    names = [a[0] for a in active]
    top = sorted(terms, key=lambda t: -abs(t[2]))[:3]
    sign = lambda v: "-" if v < 0 else ""  # noqa: E731
    note = "GUM 5.1.2 note: inputs' interactions and curvature; largest: " + ", ".join(
        (f"{names[i]}" if i == j else f"{names[i]} x {names[j]}")
        + f" {sign(t)}{math.sqrt(abs(t)):.2g}" for i, j, t in top if t != 0.0)
    return math.sqrt(max(var, 0.0)), note


def monte_carlo(refit: Refitter, setup: Setup, mu, u_mu, u_stat, U, n, seed, meas) -> dict:
    """JCGM 101: propagate normal draws of every uncertain input through re-evaluations."""
    rng = np.random.default_rng(seed)
    active = [(f, c, u, k) for _, f, c, _, u, k in setup_inputs(setup)
              if u > 0 and not acts(meas, f)]
    draws = np.empty(n)
    for i in range(n):
        s = setup
        for field, comp, u, factor in active:
            s = moved(s, field, comp, float(rng.normal(0.0, u)), factor)
        draws[i] = refit.mu(s) + rng.normal(0.0, u_stat)
    lo, hi = np.percentile(draws, [2.5, 97.5])
    sd = float(np.std(draws, ddof=1))
    # JCGM 101 section 8: the GUM interval is validated when both endpoints agree with the
    # Monte-Carlo ones within delta, half a unit of the last of two significant digits of u
    delta = 0.5 * 10.0 ** (math.floor(math.log10(u_mu)) - 1) if u_mu > 0 else 0.0
    d_low, d_high = abs(mu - U - lo), abs(mu + U - hi)
    return {"draws": n, "seed": seed, "mean": float(np.mean(draws)), "u_mu": sd,
            "interval_95": [float(lo), float(hi)], "d_low": d_low, "d_high": d_high,
            "delta": delta, "gum_validated": bool(d_low <= delta and d_high <= delta)}

