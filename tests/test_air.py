"""Room air in the fit (rollfric.fit.air): the drag law, the fit with drag, the budget's air
rows."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rollfric.fit import air
from rollfric.fit import estimate as fit
from rollfric.setup.model import setup_from_dict, thesis_setup
from rollfric.uncertainty import budget as uncertainty
from rollfric.uncertainty.sensitivity import AIR_LAW

SIGMA = 1e-6  # rad: the test's white noise (0 would give a standard error of 0)


def cgw_standard_drag(re):
    """The standard drag curve as Clift, Grace & Weber (1978) Table 5.2 tabulate it by ranges
    (w = log10 Re): the reference the Schiller-Naumann law is checked against."""
    w = math.log10(re)
    if re <= 20:
        return 24 / re * (1 + 10 ** (-0.881 + 0.82 * w - 0.05 * w * w))
    if re <= 260:
        return 24 / re * (1 + 10 ** (-0.7133 + 0.6305 * w))
    return 10 ** (1.6435 - 1.1242 * w + 0.1558 * w * w)


@pytest.mark.parametrize("re", [1.0, 10.0, 50.0, 100.0, 260.0, 500.0, 800.0])
def test_schiller_naumann_against_the_standard_drag_curve(re):
    # Schiller-Naumann lies within -4.6 % .. +5.3 % of CGW's curve over Re 0.1 .. 800
    assert air.cd_sphere(re) == pytest.approx(cgw_standard_drag(re), rel=0.055)


def test_standard_drag_values():
    # the standard curve's well-known points: Cd(100) = 1.09, Cd(1000) = 0.47 (CGW Table 5.2)
    assert cgw_standard_drag(100.0) == pytest.approx(1.09, abs=0.01)
    assert air.cd_sphere(100.0) == pytest.approx(1.09, abs=0.02)


def _truth(setup, mu, theta0_deg, seconds, cd=None, fps=1000.0):
    """theta(t) of the full equation with air, written out here (not rollfric's kernel):
    drag (1/2) rho Cd pi r^2 v^2, buoyancy rho V g, added mass C_a rho V, by DOP853 with an
    event at the turning points (the ball does not stop within ``seconds``)."""
    r, m, L, g = setup.ball_radius, setup.ball_mass, setup.track_radius, setup.gravity
    rho, eta = setup.air_density, setup.air_viscosity
    vol = 4 / 3 * math.pi * r**3
    ma = air.ADDED_MASS_COEFFICIENT * rho * vol

    def drag(v):
        if v == 0 or rho == 0:
            return 0.0
        re = rho * v * 2 * r / eta
        c = cd if cd is not None else air.WALL_FACTOR * 24 / re * (1 + 0.15 * re**0.687)
        return 0.5 * rho * c * math.pi * r * r * v * v

    def rhs(_t, y, s):
        th, w = y
        weight = (m - rho * vol) * g
        normal = weight * math.cos(th) + (m + ma) * L * w * w
        force = -weight * math.sin(th) - s * (mu * normal + drag(L * abs(w)))
        return [w, force / ((1.4 * m + ma) * L)]

    t = np.arange(int(seconds * fps)) / fps
    out = np.empty_like(t)
    t0, y0, s = 0.0, [math.radians(theta0_deg), 0.0], -1.0
    while t0 < t[-1]:
        def ev(_t, y, _s):
            return y[1]

        ev.terminal, ev.direction = True, -s
        sol = solve_ivp(rhs, (t0, t[-1]), y0, args=(s,), method="DOP853", rtol=1e-11,
                        atol=1e-13, events=ev, dense_output=True)
        sel = (t >= t0) & (t <= sol.t[-1])
        out[sel] = sol.sol(t[sel])[0]
        if sol.status != 1:
            break
        t0, y0, s = sol.t_events[0][0], [sol.y_events[0][0][0], 0.0], -s
    return t, out


def _noisy(theta, seed=0):
    return theta + SIGMA * np.random.default_rng(seed).standard_normal(theta.size)


def test_fit_with_drag_recovers_mu():
    setup = thesis_setup("10mm", air_density=1.2)
    mu = 0.0079
    t, th = _truth(setup, mu, 20.0, 3.0)
    res = fit.fit_mu(t, _noisy(th), setup)
    assert res.mu == pytest.approx(mu, rel=1e-4)
    a = res.extra["air"]
    assert a["law"] == "schiller-naumann x wall"
    # the swing's Reynolds number: rho v d / eta at its fastest, the first half-swing's
    # (a cosine of amplitude theta0 - mu about the offset mu: Coulomb's small-angle solution)
    amp = math.radians(20.0) - mu
    v = math.sqrt(10 / 7 * setup.gravity * setup.track_radius * (1 - math.cos(amp)))
    assert a["reynolds_max"] == pytest.approx(1.2 * v * 0.01 / 1.81e-5, rel=0.01)


def test_fit_without_air_takes_the_drag_for_friction():
    # a given Cd: the drag is quadratic damping, theta'' + w^2 theta = -s (w^2 mu + c theta'^2),
    # c = (5/7) k Cd L, k = rho pi r^2 / (2 m); a half-swing of amplitude A loses (4/3) c A^2,
    # Coulomb's loses 2 mu: an airless fit finds mu + (2/3) c A^2
    cd = 1.0
    setup = thesis_setup("10mm", air_density=1.2, air_cd=cd)
    mu, a0 = 0.002, 20.0
    t, th = _truth(setup, mu, a0, 2.0, cd=cd)
    with_air = fit.fit_mu(t, _noisy(th), setup)
    assert with_air.mu == pytest.approx(mu, rel=1e-4)
    airless = fit.fit_mu(t, _noisy(th), setup.replace(air_density=0.0))
    k = 1.2 * math.pi * setup.ball_radius**2 / (2 * setup.ball_mass)
    c = 5 / 7 * k * cd * setup.track_radius
    amp = np.abs(th)
    a_mean = 0.5 * (math.radians(a0) + amp[t > t[-1] - 0.4].max())
    predicted = 2 / 3 * c * a_mean**2
    assert airless.mu - mu == pytest.approx(predicted, rel=0.15)
    assert (airless.mu - mu) / mu > 0.02  # several per cent: more than its U


def test_file_defaults_to_room_air_and_zero_means_none():
    base = {"cylinder": {"radius_mm": 85.3}, "ball": {"diameter_mm": 10.0, "mass_g": 4.07612},
            "camera": {"fps": 1000, "pixel_size_mm": 0.1343}}
    s = setup_from_dict(base)
    assert s.air_density == air.ROOM_AIR_DENSITY
    assert s.u("air_density") == air.ROOM_AIR_DENSITY_U
    vac = setup_from_dict({**base, "environment": {"air_density_kg_m3": 0}})
    assert vac.air_density == 0.0 and vac.u("air_density") is None
    assert not np.any(air.coefficients_of(vac))
    # written back, an airless setup says so (a file without the key would be room air)
    assert setup_from_dict(vac.to_toml_dict()) == vac
    assert setup_from_dict(s.to_toml_dict()) == s


def test_budget_air_rows_match_finite_differences():
    setup = thesis_setup("10mm", air_density=1.2, uncertainty=(("air_density", 0.03),))
    mu = 0.0079
    t, th = _truth(setup, mu, 20.0, 2.0)
    y = _noisy(th)
    res = fit.fit_mu(t, y, setup)
    meas = uncertainty.Measurement(setup=setup, t=t, theta=y)
    b = uncertainty.budget(meas, res)
    rows = {r.source: r for r in b.rows}
    rho_row = rows["environment.air_density_kg_m3"]
    law_row = rows[AIR_LAW]
    # full fits with the input moved: the rows' sensitivities are those central differences
    for row, field, value, u in ((rho_row, "air_density", 1.2, 0.03),
                                 (law_row, "air_wall_factor", air.WALL_FACTOR,
                                  air.WALL_FACTOR_U)):
        hi = fit.fit_mu(t, y, setup.replace(**{field: value + u})).mu
        lo = fit.fit_mu(t, y, setup.replace(**{field: value - u})).mu
        fd = (hi - lo) / (2 * u)
        assert row.sensitivity == pytest.approx(fd, rel=0.02)
        assert row.u_mu == pytest.approx(abs(fd) * u, rel=0.02)
    # physics: more air, more drag taken out of the friction; d mu / d rho < 0, and the drag's
    # share of mu (mu_airless - mu) is about -rho d mu / d rho (drag ~ rho^(0.3..1))
    assert rho_row.sensitivity < 0
    share = fit.fit_mu(t, y, setup.replace(air_density=0.0)).mu - res.mu
    assert 0.3 * share < -1.2 * rho_row.sensitivity < 1.0 * share


def test_the_default_case_is_in_room_air_and_its_lab_states_only_the_density():
    from sim import Scenario
    from validation.case import case_from_dict
    from validation.case_dict import default_case_dict
    from validation.track_level import oracle_setup

    case = case_from_dict(default_case_dict())
    assert case.scenario.air_density == pytest.approx(1.204)
    assert case.scenario.air_drag == "law"
    lab = setup_from_dict(case.lab_setup_dict())
    assert lab.air_density == pytest.approx(1.204)
    assert lab.air_cd is None  # the engine's drag is not the lab's to know
    assert "air_cd" not in case.lab_setup_dict().get("environment", {})
    assert oracle_setup(case).air_density == pytest.approx(1.204)
    # a lab that states no air over a truth in air (its fit then leaves the drag out)
    d = default_case_dict()
    d["lab"] = {"environment": {"air_density_kg_m3": 0.0}}
    blind = case_from_dict(d)
    assert setup_from_dict(blind.lab_setup_dict()).air_density == 0.0
    assert blind.scenario.air_density == pytest.approx(1.204)
    # an airless scenario's setup says so when written (a file without the key is room air)
    written = Scenario().setup().to_toml_dict()
    assert written["environment"]["air_density_kg_m3"] == 0.0
    assert setup_from_dict(written).air_density == 0.0


def test_a_given_cd_is_its_own_budget_row():
    # the lab measured its ball's Cd: its u replaces the drag law's wall factor; the row is
    # the drag's share of mu scaled by u(Cd)/Cd (the drag is linear in a constant Cd)
    cd, u_cd = 1.3, 0.13
    setup = thesis_setup("10mm", air_density=1.2, air_cd=cd,
                         uncertainty=(("air_cd", u_cd),))
    t, th = _truth(setup, 0.0079, 20.0, 2.0, cd=cd)
    y = _noisy(th)
    res = fit.fit_mu(t, y, setup)
    assert res.extra["air"]["law"] == "given" and res.extra["air"]["cd"] == cd
    rows = {r.source: r for r in uncertainty.budget(
        uncertainty.Measurement(setup=setup, t=t, theta=y), res).rows}
    assert AIR_LAW not in rows
    share = fit.fit_mu(t, y, setup.replace(air_density=0.0)).mu - res.mu
    assert rows["environment.air_cd"].u_mu == pytest.approx(share * u_cd / cd, rel=0.05)
