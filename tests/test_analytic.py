import math

import numpy as np
import pytest

from rollfric.fit import analytic, eom
from rollfric.setup.model import thesis_setup


def test_paper1_mu_reproduces_the_paper():
    # eps = 1.9012 1/s^2, theta0 = 12.07 deg, R = 85.3 mm, d = 1.58 mm -> 0.0160
    L = thesis_setup("1.58mm").track_radius
    mu1 = analytic.paper1_mu_from_eps(1.9012, math.radians(12.07), L)
    assert round(mu1, 4) == 0.0160
    mu = analytic.mu_from_eps(1.9012, L)
    assert mu == pytest.approx(1.9012 * 7 * L / (5 * 9.81))
    assert analytic.mu_from_paper1_mu(mu1, math.radians(12.07), L) == pytest.approx(mu)


def test_paper1_coefficient_is_five_sevenths_at_small_angles():
    L = 0.08
    assert analytic.paper1_mu_from_mu(0.01, 1e-6, L) / 0.01 == pytest.approx(5 / 7, rel=1e-5)
    assert analytic.eps_from_mu(0.01, L) == pytest.approx(0.01 * 5 * 9.81 / (7 * L))


def test_half_swing_solutions_solve_the_ode():
    w2, eps = 80.0, 1.5
    t = np.linspace(0, 0.15, 2001)
    h = t[1] - t[0]
    for th in (analytic.roll_down(t, 0.2, eps, w2), analytic.climb(t, -1.6, eps, w2)):
        acc = (th[2:] - 2 * th[1:-1] + th[:-2]) / h**2
        v = np.gradient(th, h)[1:-1]
        np.testing.assert_allclose(acc, -w2 * th[1:-1] - eps * np.sign(v), atol=1e-4)
    assert analytic.roll_down(0.0, 0.2, eps, w2) == pytest.approx(0.2)
    assert analytic.climb(0.0, -1.6, eps, w2) == pytest.approx(0.0)


def test_small_angle_solution_decays_linearly_and_stops():
    w2, eps = 82.0, 0.6
    t = np.arange(8000) / 1000.0
    th, om, t_stop = analytic.solve_small_angle(0.1, 0.0, eps, w2, t)
    turns = np.nonzero((np.sign(om[1:]) != np.sign(om[:-1])) & (om[1:] != 0))[0]
    amps = np.abs(th[turns + 1])
    np.testing.assert_allclose(-np.diff(amps), analytic.decay_per_half_swing(eps, w2), atol=1e-4)
    assert math.isfinite(t_stop)
    assert abs(th[-1]) <= eps / w2


def test_small_angle_solution_is_the_limit_of_the_full_equation():
    L = thesis_setup("10mm").track_radius
    mu = 0.0008
    w2 = analytic.omega_squared(L)
    t = np.arange(3000) / 1000.0
    th0 = math.radians(0.3)
    full, _, _ = eom.solve_reference(th0, 0.0, mu, t, track_radius=L)
    small, _, _ = analytic.solve_small_angle(th0, 0.0, analytic.eps_from_mu(mu, L), w2, t)
    # differences are O(theta^3) (sin) and O(theta^2) (cos in the normal force)
    assert np.max(np.abs(full - small)) < 2e-3 * th0
