"""sim.losses: speed-dependent rolling friction and air drag against analytic decay laws, the
fitter's own equation, and the engines (MuJoCo, PyBullet) that apply them per step."""

import math

import numpy as np
import pytest
from scipy.signal import argrelextrema

import sim
from rollfric.fit import eom
from rollfric.fit.estimate import fit_mu
from sim.losses import ROOM_AIR_DENSITY, Losses, reynolds, solve, theta_ddot

R, D, M, G = 0.0853, 0.010, 0.00407612, 9.81
r = D / 2
L = R - r
T = np.arange(0, 3.0, 1e-4)


def _amplitudes(theta):
    """|theta| at the turning points (local extrema), in time order."""
    i = np.sort(np.concatenate([argrelextrema(theta, np.greater)[0],
                                argrelextrema(theta, np.less)[0]]))
    return np.abs(theta[i]), i


def test_quadratic_drag_loses_four_thirds_c_a_squared_per_half_swing():
    # mu = 0, drag only, small angle: theta'' + c theta'|theta'| + w^2 theta = 0 with
    # c = 5 k L / 7, and each half-swing loses (4/3) c A^2 of the amplitude A
    losses = Losses(air_density=1.2, air_cd=2.0)
    th, _, _ = solve(math.radians(2.0), 0.0, 0.0, T, losses, track_radius=L, ball_radius=r,
                     ball_mass=M, gravity=G)
    c = 5 * losses.drag_per_mass(r, M) * L / 7
    amp, _ = _amplitudes(th)
    a = np.concatenate([[math.radians(2.0)], amp])
    loss = -np.diff(a)[:6]
    want = (4 / 3) * c * (0.5 * (a[:-1] + a[1:]))[:6] ** 2
    assert loss == pytest.approx(want, rel=2e-3)


def test_speed_term_is_a_viscous_damping_exp_minus_gamma_t():
    # mu = 0, mu(v) = mu_speed v only: s mu_speed L |theta'| g = mu_speed L g theta', a linear
    # damping; the amplitude decays as exp(-gamma t), gamma = 5 mu_speed g / 14
    mu_speed = 0.05
    th, _, _ = solve(math.radians(1.0), 0.0, 0.0, T, Losses(mu_speed=mu_speed),
                     track_radius=L, ball_radius=r, ball_mass=M, gravity=G)
    amp, i = _amplitudes(th)
    gamma = 5 * mu_speed * G / 14
    fitted = -np.polyfit(T[i], np.log(amp), 1)[0]
    assert fitted == pytest.approx(gamma, rel=2e-3)


def test_energy_decays_at_the_power_of_the_drag_and_the_resistance():
    # dE/dt per unit mass = -(mu(v) N / m + k v^2) v along the solution (large angle, both on)
    losses = Losses(mu_speed=0.01, air_density=ROOM_AIR_DENSITY, air_cd=0.47)
    mu = 0.0079
    t = np.arange(0, 0.5, 1e-4)
    th, om, _ = solve(math.radians(25.0), 0.0, mu, t, losses, track_radius=L, ball_radius=r,
                      ball_mass=M, gravity=G)
    e = eom.energy(th, om, L, G)
    v = L * np.abs(om)
    power = ((mu + losses.mu_speed * v) * (G * np.cos(th) + L * om**2)
             + losses.drag_per_mass(r, M) * v**2) * v
    de = np.gradient(e, t)
    # away from the ends and the turning points (theta'' jumps there with the sign of theta')
    sel = np.zeros(t.size, bool)
    sel[10:-10] = True
    sel &= np.convolve(np.abs(np.diff(np.sign(om), prepend=0)) > 0, np.ones(21), "same") == 0
    assert np.max(np.abs(de[sel] + power[sel])) < 2e-3 * np.max(power)
    # the right-hand side is the same law
    acc = theta_ddot(th, om, mu, losses, track_radius=L, ball_radius=r, ball_mass=M, gravity=G)
    assert np.max(np.abs(np.gradient(om, t)[sel] - acc[sel])) < 1e-3 * np.max(np.abs(acc))


def test_without_losses_it_is_the_fitters_equation():
    t = np.arange(0, 4.0, 1e-3)
    a, _, sa = solve(math.radians(20), 0.0, 0.0079, t, Losses(), track_radius=L, ball_radius=r,
                     ball_mass=M, gravity=G)
    b, _, sb = eom.solve_reference(math.radians(20), 0.0, 0.0079, t, track_radius=L, gravity=G)
    assert np.max(np.abs(a - b)) < 1e-9


def test_speed_term_is_the_fitters_mu1_per_angular_speed():
    # rollfric's "velocity" model writes mu0 + mu1 |theta'|: mu1 = mu_speed L (s/rad)
    t = np.arange(0, 3.0, 1e-3)
    a, _, _ = solve(math.radians(20), 0.0, 0.005, t, Losses(mu_speed=0.02), track_radius=L,
                    ball_radius=r, ball_mass=M, gravity=G)
    b, _, _ = eom.solve_reference(math.radians(20), 0.0, 0.005, t, track_radius=L, gravity=G,
                                  mu1=0.02 * L)
    assert np.max(np.abs(a - b)) < 1e-9


def test_reynolds_number_of_the_thesis_ball():
    # a 10 mm ball released at 20 deg peaks at v = sqrt((10/7) g L (1 - cos 20 deg))
    v = math.sqrt(10 / 7 * G * L * (1 - math.cos(math.radians(20))))
    assert reynolds(v, D) == pytest.approx(1.204 * v * D / 1.81e-5)
    sc = sim.Scenario(mu=0.0, air_density=1.2, duration=0.5)
    meta = sim.simulate(sc).meta["losses"]
    assert meta["max_speed_m_s"] == pytest.approx(v, rel=2e-3)  # drag slows it a little
    assert 150 < meta["max_reynolds"] < 200


def test_scenario_keys_round_trip_and_refuse_negatives():
    d = {"motion": {"mu_speed_s_m": 0.004},
         "environment": {"air_density_kg_m3": 1.2, "air_cd": 0.9}}
    sc = sim.scenario_from_dict(d)
    assert (sc.mu_speed, sc.air_density, sc.air_cd) == (0.004, 1.2, 0.9)
    assert sim.scenario_from_dict(sc.to_toml_dict()) == sc
    with pytest.raises(sim.ScenarioError, match="air_cd"):
        sim.scenario_from_dict({"environment": {"air_cd": -1.0}})
    # off by default: the trajectory is rollfric.fit.eom's, its meta without losses
    assert "losses" not in sim.simulate(sim.Scenario(duration=0.2)).meta


def test_the_fitter_reports_the_drag_as_friction():
    # the constant-mu fit absorbs the drag: mu high by about the drag's share of the losses
    sc = sim.Scenario(duration=2.0, air_density=1.2, air_cd=0.47)
    tr = sim.simulate(sc)
    airless = sc.setup().replace(air_density=0.0)  # a fitter that does not model the air
    f = fit_mu(tr.t, tr.theta, airless, offset=False)
    k = sc.replace(air_density=0.0)
    base = fit_mu(tr.t, sim.simulate(k).theta, airless, offset=False)
    assert base.mu == pytest.approx(0.0079, rel=1e-6)
    # per half-swing the drag takes (4/3) c A^2 against Coulomb's 2 mu (small angles):
    # a mu bias of (2/3) c A^2 / mu, A^2 averaged over the half-swings
    c = 5 * sc.air_density * 0.47 * math.pi * r**2 / (2 * M) * L / 7
    amp, _ = _amplitudes(tr.theta)
    expect = (2 / 3) * c * np.mean(amp**2) / 0.0079
    assert f.mu / 0.0079 - 1 == pytest.approx(expect, rel=0.1)


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_engines_apply_the_losses_like_the_ode(engine):
    # the mu the constant-mu fitter reports moves by the same amount in the engine as in the
    # exact equation (measured 2 s: drag +0.231 % in all three; mu_speed 0.005 s/m:
    # +11.065 % reference, +11.076 % MuJoCo, +11.067 % PyBullet)
    base = sim.Scenario(duration=1.5)
    for kw in ({"air_density": 1.2, "air_cd": 1.0}, {"mu_speed": 0.005}):
        shifts = {}
        for eng in ("reference", engine):
            mus = []
            for sc in (base.replace(engine=eng), base.replace(engine=eng, **kw)):
                tr = sim.simulate(sc)
                # the fitter without air (the setup would carry the density)
                mus.append(fit_mu(tr.t, tr.theta, sc.setup().replace(air_density=0.0),
                                  offset=False).mu)
            shifts[eng] = mus[1] / mus[0] - 1
        assert shifts[engine] == pytest.approx(shifts["reference"], rel=0.03), kw


def test_the_law_engine_is_what_the_fitter_models():
    # air_drag = "law": the reference engine integrates rollfric.fit.air's drag law, buoyancy and
    # added mass (written out in sim.losses); the fitter, told only the air's density by the
    # setup, recovers mu to 1e-5; told no air, it takes the drag for friction
    sc = sim.Scenario(duration=2.0, air_density=1.204, air_drag="law")
    assert sim.scenario_from_dict(sc.to_toml_dict()) == sc
    tr = sim.simulate(sc)
    assert tr.meta["losses"]["air_drag"] == "law"
    setup = sc.setup()
    assert setup.air_density == 1.204 and setup.air_cd is None
    f = fit_mu(tr.t, tr.theta, setup, offset=False)
    assert f.mu == pytest.approx(sc.mu, rel=1e-5)
    airless = fit_mu(tr.t, tr.theta, setup.replace(air_density=0.0), offset=False)
    assert airless.mu / sc.mu - 1 > 0.005
    with pytest.raises(sim.ScenarioError, match="air_drag"):
        sim.scenario_from_dict({"environment": {"air_drag": "quadratic"}})
