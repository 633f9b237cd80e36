import math

import numpy as np
import pytest

from rollfric.fit import eom
from rollfric.setup.model import thesis_setup

L10 = thesis_setup("10mm").track_radius
T4 = np.arange(4000) / 1000.0


@pytest.mark.parametrize("solver", [eom.solve_reference, eom.solve])
def test_energy_conserved_without_friction(solver):
    th, om, t_stop = solver(math.radians(35), 0.0, 0.0, T4, track_radius=L10)
    e = eom.energy(th, om, L10)
    assert t_stop == math.inf
    assert np.max(np.abs(e / e[0] - 1)) < 1e-9


def test_energy_lost_equals_work_of_rolling_resistance():
    # power lost per unit mass = M * ball spin / m = mu N/m * L |theta'|
    mu = 0.0164
    t = np.linspace(0, 2.0, 200001)
    th, om, _ = eom.solve_reference(math.radians(30), 0.0, mu, t, track_radius=L10)
    e = eom.energy(th, om, L10)
    power = mu * (9.81 * np.cos(th) + L10 * om**2) * L10 * np.abs(om)
    work = np.concatenate([[0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    assert np.max(np.abs((e[0] - e) - work)) < 1e-6 * e[0]


@pytest.mark.parametrize("mu, theta0_deg", [(0.0, 40), (0.0079, 20), (0.0164, 5), (0.0065, 35)])
def test_fast_solver_matches_reference(mu, theta0_deg):
    ref, ref_om, ref_stop = eom.solve_reference(math.radians(theta0_deg), 0.0, mu, T4,
                                                track_radius=L10)
    fast, fast_om, fast_stop = eom.solve(math.radians(theta0_deg), 0.0, mu, T4,
                                         track_radius=L10)
    assert np.max(np.abs(fast - ref)) < 1e-8
    assert np.max(np.abs(fast_om - ref_om)) < 1e-7
    if math.isfinite(ref_stop):
        assert fast_stop == pytest.approx(ref_stop, abs=1e-8)


@pytest.mark.parametrize("solver", [eom.solve_reference, eom.solve])
def test_sticks_for_good_when_tan_theta_below_mu(solver):
    mu = 0.05
    # released inside the sticking cone: never moves
    th, om, t_stop = solver(0.9 * math.atan(mu), 0.0, mu, T4, track_radius=L10)
    assert t_stop == T4[0] and np.all(th == th[0]) and np.all(om == 0)
    # released outside: moves, and the final rest is inside the cone while the turning
    # point before it was outside
    th, om, t_stop = solver(math.radians(10), 0.0, mu, T4, track_radius=L10)
    assert 0 < t_stop < T4[-1]
    rest = T4 > t_stop
    assert np.all(om[rest] == 0) and np.ptp(th[rest]) == 0
    assert abs(math.tan(th[-1])) <= mu
    turns = np.nonzero(np.sign(om[1:]) != np.sign(om[:-1]))[0]
    moving_turns = [i for i in turns if T4[i] < t_stop - 0.01]
    assert abs(math.tan(th[moving_turns[-1]])) > mu


def test_small_angle_amplitude_decay_is_linear():
    # amplitude drops by 2 eps/omega^2 = 2 mu per half-swing at small angles
    mu = 0.0005
    theta0 = math.radians(0.5)
    t = np.arange(20000) / 5000.0
    th, om, _ = eom.solve_reference(theta0, 0.0, mu, t, track_radius=L10)
    turns = np.nonzero((np.sign(om[1:]) != np.sign(om[:-1])) & (om[1:] != 0))[0]
    amps = np.abs(th[turns])
    drops = -np.diff(amps)
    assert drops.size >= 4
    np.testing.assert_allclose(drops, 2 * mu, rtol=2e-3)


def test_velocity_dependent_friction_damps_faster_at_speed():
    a, _, _ = eom.solve_reference(math.radians(20), 0.0, 0.005, T4, track_radius=L10)
    b, _, _ = eom.solve_reference(math.radians(20), 0.0, 0.005, T4, track_radius=L10, mu1=0.005)
    c, _, _ = eom.solve(math.radians(20), 0.0, 0.005, T4, track_radius=L10, mu1=0.005)
    assert np.max(np.abs(b - c)) < 1e-8
    assert np.max(np.abs(b[-500:])) < np.max(np.abs(a[-500:]))


def test_rhs_sign_convention():
    # right of the bottom and at rest the ball accelerates to the left; moving right,
    # friction decelerates it further
    assert eom.theta_ddot(0.1, 0.0, 0.01, L10) < 0
    assert eom.theta_ddot(0.0, 1.0, 0.01, L10) < 0
    assert eom.theta_ddot(0.0, -1.0, 0.01, L10) > 0


def test_bad_inputs():
    with pytest.raises(ValueError, match="increasing"):
        eom.solve(0.1, 0, 0.01, [0, 2, 1], track_radius=L10)
    with pytest.raises(ValueError, match="mu"):
        eom.solve_reference(0.1, 0, -0.01, T4, track_radius=L10)


@pytest.mark.parametrize("solver", [eom.solve_reference, eom.solve])
def test_a_ball_over_the_top_keeps_rolling_down(solver):
    # beyond +-90 deg (a fit's trial parameters can get there) gravity pulls towards the
    # bottom and no rolling resistance holds the ball: it leaves rest downwards, and an angle
    # wound past +-pi is the same place (this used to loop for ever at a turning point)
    mu = 0.3
    t = np.arange(1500) / 1000.0
    th, om, _ = solver(1.9, 0.0, mu, t, track_radius=L10)
    assert om[1] < 0 and th[-1] < 1.9
    ref, _, _ = solver(0.6, 25.0, mu, t, track_radius=L10)  # over the top and round again
    wound, _, _ = solver(0.6 + 2 * math.pi, 25.0, mu, t, track_radius=L10)
    assert np.max(np.abs(wound - 2 * math.pi - ref)) < 1e-8
    assert np.ptp(ref) > math.pi


def test_sticks_rule_over_the_whole_circle():
    assert eom.sticks(0.9 * math.atan(0.05), 0.05) and not eom.sticks(0.1, 0.05)
    assert not eom.sticks(1.7, 0.9) and not eom.sticks(-2.5, 0.9)
    assert eom.sticks(0.0, 0.0) and eom.sticks(2 * math.pi, 0.01)
