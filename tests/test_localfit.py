"""Batched local polynomial fits: exact polynomials recovered, numpy's polyfit reproduced."""

import numpy as np
import pytest

from rollfric.track.localfit import polyfit_rows
from rollfric.track.plausibility import innovations


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_rows_recover_exact_polynomials(degree):
    rng = np.random.default_rng(degree)
    m, k = 50, 9
    u = np.sort(rng.uniform(-6, 6, (m, k)), axis=1)
    coef = rng.normal(0, 3, (m, degree + 1, 2))
    y = np.stack([np.polynomial.polynomial.polyval(u[i], coef[i]).T for i in range(m)])
    use = rng.random((m, k)) < 0.8
    use[:, :degree + 1] = True  # enough points in every row
    y[~use] = np.nan  # points left out do not enter the fit
    got = polyfit_rows(u, y, use, degree)
    np.testing.assert_allclose(got, coef, rtol=0, atol=1e-9)
    # one column: the same as the first of two
    np.testing.assert_allclose(polyfit_rows(u, y[..., 0], use, degree), got[..., 0], atol=1e-12)


def test_rows_equal_numpy_polyfit_on_noisy_data():
    rng = np.random.default_rng(7)
    m = 200
    u = np.tile(np.r_[-4, -3, -2, -1, 1, 2, 3, 4].astype(float), (m, 1))
    y = 600 + rng.normal(0, 20, (m, 8, 2))
    use = rng.random((m, 8)) < 0.85
    use[:, [0, 3, 4, 7]] = True
    got = polyfit_rows(u, y, use, 2)
    for i in range(m):
        ref = np.polynomial.polynomial.polyfit(u[i][use[i]], y[i][use[i]], 2)
        np.testing.assert_allclose(got[i], ref, rtol=0, atol=1e-10)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_gain_is_the_fitted_values_standard_deviation(degree):
    # sqrt([(V^T V)^-1]_00) for the used points of each row, and the scatter of the fitted
    # value over many noise draws
    rng = np.random.default_rng(10 + degree)
    m, k = 30, 8
    u = np.sort(rng.uniform(-5, 5, (m, k)), axis=1)
    u[:5] = np.arange(1, k + 1)  # one-sided rows: the fit extrapolates to u = 0
    use = rng.random((m, k)) < 0.8
    use[:, :degree + 2] = True
    _, g = polyfit_rows(u, np.zeros((m, k)), use, degree, gain=True)
    for i in range(m):
        v = np.vander(u[i][use[i]], degree + 1, increasing=True)
        assert g[i] == pytest.approx(np.sqrt(np.linalg.inv(v.T @ v)[0, 0]), rel=1e-10)
    draws = rng.normal(0, 1, (4000, k))
    c0 = np.array([polyfit_rows(np.tile(u[0], (4000, 1)), draws, np.tile(use[0], (4000, 1)),
                                degree)[:, 0]]).ravel()
    assert np.std(c0) == pytest.approx(g[0], rel=0.05)  # 4000 draws: ~1.1 % standard error
    # extrapolated from one side: more than twice the error of a fit through as many
    # points on both sides
    v = np.vander(np.r_[-4:0, 1:5].astype(float), degree + 1, increasing=True)
    assert g[:5].min() > 2 * np.sqrt(np.linalg.inv(v.T @ v)[0, 0])


def test_rows_empty_and_singular():
    assert polyfit_rows(np.zeros((0, 4)), np.zeros((0, 4, 2)), np.zeros((0, 4), bool),
                        2).shape == (0, 3, 2)
    coef, g = polyfit_rows(np.zeros((0, 4)), np.zeros((0, 4)), np.zeros((0, 4), bool), 2,
                           gain=True)
    assert coef.shape == (0, 3) and g.shape == (0,)
    with pytest.raises(np.linalg.LinAlgError):
        polyfit_rows(np.arange(4.0)[None], np.ones((1, 4)), np.array([[1, 1, 0, 0]], bool), 2)


def test_innovations_are_the_neighbours_polynomial_prediction():
    # the centre of a ball on a quadratic path is predicted exactly; a displaced frame by its
    # displacement (its neighbours do not see it), its neighbours by the polynomial's leverage
    n = 40
    f = np.arange(n, dtype=float)
    x = 100 + 2.5 * f - 0.03 * f ** 2
    y = 50 + 0.5 * f + 0.01 * f ** 2
    ok = np.ones(n, bool)
    ok[[7, 8, 20]] = False
    e, model, _ = innovations(x, y, ok)
    assert np.all(np.isnan(e[~ok]))
    np.testing.assert_allclose(e[ok], 0, atol=1e-9)
    np.testing.assert_allclose(model[ok], 0, atol=1e-9)
    x2 = x.copy()
    x2[30] += 1.0
    e2, _, _ = innovations(x2, y, ok)
    assert abs(e2[30] - 1.0) < 1e-9
    # frame 26 is predicted from 22..25 and 27..30: frame 30 at u = 4 carries the displacement
    u = np.r_[-4, -3, -2, -1, 1, 2, 3, 4].astype(float)
    w = np.linalg.pinv(np.vander(u, 3, increasing=True))[0]
    assert abs(e2[26] - abs(w[-1])) < 1e-9
