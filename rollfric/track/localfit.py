"""Least-squares polynomials through each sample's neighbours, all samples at once.

The plausibility checks (:mod:`rollfric.track.plausibility`) and the dropped-frame search
(:mod:`rollfric.track.dropped_frames`) predict every frame or step from a low-degree polynomial
through its
neighbours: thousands of tiny fits (4 to 14 points, degree 2 or 3). Here they are solved as one
stack: the same problem as ``numpy.polynomial.polynomial.polyfit`` for each row (the
Vandermonde matrix's columns scaled to unit norm, then least squares), by a batched QR
decomposition instead of one SVD a row. The coefficients agree with ``polyfit``'s to rounding
(about 1e-13 of the data's magnitude).
"""

from __future__ import annotations

import numpy as np


def polyfit_rows(u: np.ndarray, y: np.ndarray, use: np.ndarray, degree: int, *,
                 gain: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """The least-squares polynomial of ``degree`` through the used points of each row.

    Parameters
    ----------
    u : numpy.ndarray
        (m, k) the abscissae of each row's points.
    y : numpy.ndarray
        (m, k) or (m, k, c) their values (c columns share one fit).
    use : numpy.ndarray of bool
        (m, k) which points of each row enter its fit; every row needs at least
        ``degree + 1`` used points at distinct abscissae (NaN in an unused point is ignored).
    degree : int
        The polynomial's degree.
    gain : bool
        Also return each row's noise gain at u = 0.

    Returns
    -------
    numpy.ndarray
        (m, degree + 1) or (m, degree + 1, c): the coefficients of each row, lowest power
        first (as ``numpy.polynomial.polynomial.polyfit``).
    numpy.ndarray
        Only with ``gain``: (m,) the standard deviation of the fitted value at u = 0 (the
        constant coefficient) for independent errors of unit standard deviation in the used
        points, sqrt([(V^T V)^-1]_00): below 1 where the points surround u = 0, several
        where the fit extrapolates to it from one side.

    Raises
    ------
    numpy.linalg.LinAlgError
        A row with too few used points (its fit is singular).
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    use = np.asarray(use, dtype=bool)
    flat = y.ndim == 2
    if flat:
        y = y[..., None]
    m = u.shape[0]
    if m == 0:
        shape = (0, degree + 1) if flat else (0, degree + 1, y.shape[2])
        return (np.zeros(shape), np.zeros(0)) if gain else np.zeros(shape)
    v = np.where(use, u, 0.0)[..., None] ** np.arange(degree + 1)
    v = np.where(use[..., None], v, 0.0)
    rhs = np.where(use[..., None], y, 0.0)
    scl = np.sqrt(np.square(v).sum(axis=1))  # (m, degree + 1), as polyfit scales its columns
    scl[scl == 0] = 1.0
    q, r = np.linalg.qr(v / scl[:, None, :])
    coef = np.linalg.solve(r, np.swapaxes(q, 1, 2) @ rhs) / scl[..., None]
    coef = coef[..., 0] if flat else coef
    if not gain:
        return coef
    # Var(c0) = [(V^T V)^-1]_00 = |row 0 of R^-1|^2 / scl_0^2 (V = Q R scl)
    e0 = np.zeros((m, degree + 1))
    e0[:, 0] = 1.0
    rinv0 = np.linalg.solve(np.swapaxes(r, 1, 2), e0[..., None])[..., 0]  # R^-T e0
    return coef, np.sqrt(np.square(rinv0).sum(axis=1)) / scl[:, 0]
