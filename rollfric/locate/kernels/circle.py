"""The robust geometric circle fit of the edge points (Kasa start, Gauss-Newton with Tukey
biweights) and its inlier statistics."""

from __future__ import annotations

import numpy as np

from rollfric.jit import njit


@njit(nogil=True)
def solve3(m, v):
    det = (m[0, 0] * (m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1])
           - m[0, 1] * (m[1, 0] * m[2, 2] - m[1, 2] * m[2, 0])
           + m[0, 2] * (m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]))
    out = np.empty(3)
    if det == 0.0 or not np.isfinite(det):
        out[:] = np.nan
        return out
    for c in range(3):
        mm = m.copy()
        for r in range(3):
            mm[r, c] = v[r]
        out[c] = (mm[0, 0] * (mm[1, 1] * mm[2, 2] - mm[1, 2] * mm[2, 1])
                  - mm[0, 1] * (mm[1, 0] * mm[2, 2] - mm[1, 2] * mm[2, 0])
                  + mm[0, 2] * (mm[1, 0] * mm[2, 1] - mm[1, 1] * mm[2, 0])) / det
    return out


@njit(nogil=True)
def fit_circle(xs, ys, r_known, free, tukey_c, sigma_floor):
    """Robust geometric circle fit: algebraic (Kasa) start, then Gauss-Newton on the
    point-to-circle distances with Tukey biweights (scale from the MAD, floored at
    sigma_floor). Returns cx, cy, r, weights, residuals."""
    n = len(xs)
    ata = np.zeros((3, 3))
    atb = np.zeros(3)
    for i in range(n):
        row = (xs[i], ys[i], 1.0)
        z = xs[i] * xs[i] + ys[i] * ys[i]
        for p in range(3):
            atb[p] += row[p] * z
            for q in range(3):
                ata[p, q] += row[p] * row[q]
    sol = solve3(ata, atb)
    cx = 0.5 * sol[0]
    cy = 0.5 * sol[1]
    r = np.sqrt(max(sol[2] + cx * cx + cy * cy, 1e-12)) if free else r_known
    wts = np.ones(n)
    res = np.zeros(n)
    d = np.zeros(n)
    if not (np.isfinite(cx) and np.isfinite(cy)):
        return np.nan, np.nan, np.nan, wts, res
    for it in range(30):
        for i in range(n):
            d[i] = max(np.hypot(xs[i] - cx, ys[i] - cy), 1e-9)
            res[i] = d[i] - r
        good = res[wts > 0]
        if len(good) < 3:
            return np.nan, np.nan, np.nan, wts, res
        med = np.median(good)
        scale = max(1.4826 * np.median(np.abs(good - med)), sigma_floor)
        jtj = np.zeros((3, 3))
        jtr = np.zeros(3)
        wsum = 0.0
        for i in range(n):
            u = (res[i] - med) / (tukey_c * scale)
            wi = (1.0 - u * u) ** 2 if abs(u) < 1.0 else 0.0
            wts[i] = wi
            wsum += wi
            j0 = -(xs[i] - cx) / d[i]
            j1 = -(ys[i] - cy) / d[i]
            jj = (j0, j1, -1.0)
            for p in range(3):
                jtr[p] += wi * jj[p] * res[i]
                for q in range(3):
                    jtj[p, q] += wi * jj[p] * jj[q]
        if wsum < 3.0:
            return np.nan, np.nan, np.nan, wts, res
        if not free:  # 2 x 2 system
            det = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
            if det == 0.0:
                return np.nan, np.nan, np.nan, wts, res
            s0 = -(jtj[1, 1] * jtr[0] - jtj[0, 1] * jtr[1]) / det
            s1 = -(-jtj[1, 0] * jtr[0] + jtj[0, 0] * jtr[1]) / det
            s2 = 0.0
        else:
            st = solve3(jtj, -jtr)
            s0, s1, s2 = st[0], st[1], st[2]
        if not (np.isfinite(s0) and np.isfinite(s1) and np.isfinite(s2)):
            return np.nan, np.nan, np.nan, wts, res
        cx += s0
        cy += s1
        r += s2
        if abs(s0) + abs(s1) + abs(s2) < 1e-6 and it > 1:
            break
    for i in range(n):
        res[i] = np.hypot(xs[i] - cx, ys[i] - cy) - r
    return cx, cy, r, wts, res


@njit(nogil=True)
def fit_stats(wts, res):
    """Inliers, their median residual and weighted rms residual."""
    inl = wts > 0
    n_in = inl.sum()
    if n_in == 0:
        return 0, np.nan, np.nan
    sw = wts.sum()
    return n_in, np.median(res[inl]), np.sqrt((wts * res * res).sum() / max(sw, 1e-12))
