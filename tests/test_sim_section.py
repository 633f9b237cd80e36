"""sim: the out-of-round (elliptic) trough and the trough tilted along its length."""

import math

import numpy as np
import pytest

import sim
from rollfric.fit.eom import solve_reference
from sim.engines.reference import solve_section
from sim.errors import ScenarioError
from sim.section import Section

R, r, G = 0.0853, 0.005, 9.81


def _rotated(sec: Section, pts):
    """Points (N, 2) in the ellipse's own frame."""
    ca, sa = math.cos(sec.angle), math.sin(sec.angle)
    return np.column_stack([ca * pts[:, 0] + sa * pts[:, 1], -sa * pts[:, 0] + ca * pts[:, 1]])


@pytest.mark.parametrize("angle", [0.0, 0.4, math.pi / 2])
def test_section_geometry(angle):
    sec = Section(R, 2e-3, angle)
    a, b = sec.semi_axes
    assert (a + b) / 2 == pytest.approx(R) and 2 * (a - b) == pytest.approx(2e-3)
    phi = np.linspace(-1.2, 1.2, 97)
    p = _rotated(sec, sec.contact(phi))
    assert np.allclose(p[:, 0] ** 2 / a**2 + p[:, 1] ** 2 / b**2, 1.0, atol=1e-12)
    # the normal there is the ellipse's gradient (x / a^2, y / b^2), normalised
    grad = np.column_stack([p[:, 0] / a**2, p[:, 1] / b**2])
    grad /= np.linalg.norm(grad, axis=1, keepdims=True)
    n = _rotated(sec, np.column_stack([np.sin(phi), -np.cos(phi)]))
    assert np.allclose(grad, n, atol=1e-12)
    # radius of curvature: |dp/dphi| (p moves along the tangent at speed rho); its slope
    h = 1e-6
    dp = (sec.contact(phi + h) - sec.contact(phi - h)) / (2 * h)
    assert np.allclose(np.linalg.norm(dp, axis=1), sec.curvature_radius(phi), rtol=1e-7)
    drho = (sec.curvature_radius(phi + h) - sec.curvature_radius(phi - h)) / (2 * h)
    assert np.allclose(sec.curvature_radius_slope(phi), drho, rtol=1e-6, atol=1e-9)
    # the outline drawn at polar angles lies on the same ellipse
    q = _rotated(sec, sec.outline(phi))
    assert np.allclose(q[:, 0] ** 2 / a**2 + q[:, 1] ** 2 / b**2, 1.0, atol=1e-12)
    # the ball centre's contact angle found back from the centre, theta <-> phi
    for ph in (-0.6, 0.0, 0.3):
        x, y = sec.centre(ph, r)
        assert sec.phi_of_point(x, y, ph + 0.05) == pytest.approx(ph, abs=1e-13)
        assert sec.phi_of_theta(float(sec.theta(ph, r)), r) == pytest.approx(ph, abs=1e-13)
    if angle == 0.0:
        assert sec.bottom_curvature_radius() == pytest.approx(a * a / b)


def test_section_solver_is_the_circle_equation_in_the_round_limit():
    t = np.arange(3001) / 1000
    phi, om, s, t_stop = solve_section(Section(R), r, math.radians(20), 0.0, 0.0079, t,
                                       gravity=G)
    th, thd, t_stop2 = solve_reference(math.radians(20), 0.0, 0.0079, t, track_radius=R - r,
                                       gravity=G)
    assert np.max(np.abs(phi - th)) < 1e-8 and np.max(np.abs(om - thd)) < 1e-7
    assert np.allclose(s, (R - r) * (phi - phi[0]), atol=1e-9)  # arc length along the path
    # a ball that stops: same rest time
    phi, _, _, t_stop = solve_section(Section(R), r, math.radians(2), 0.0, 0.02, t, gravity=G)
    th, _, t_stop2 = solve_reference(math.radians(2), 0.0, 0.02, t, track_radius=R - r,
                                     gravity=G)
    assert math.isfinite(t_stop) and t_stop == pytest.approx(t_stop2, abs=1e-9)


@pytest.mark.parametrize("angle", [0.0, 0.5])
def test_ellipse_conserves_energy_without_friction(angle):
    sec = Section(R, 1.0e-3, angle)
    t = np.arange(2001) / 1000
    phi, om, _, _ = solve_section(sec, r, math.radians(25), 0.0, 0.0, t, gravity=G)
    c = sec.centre(phi, r)
    v = (sec.curvature_radius(phi) - r) * om
    e = 0.7 * v**2 + G * c[:, 1]
    assert np.ptp(e) < 1e-8 * G * np.ptp(c[:, 1])


@pytest.mark.parametrize("ovality_mm, angle", [(0.5, 0.0), (0.5, math.pi / 2), (2.0, 0.7)])
def test_ellipse_small_oscillation_period_is_the_bottom_curvature(ovality_mm, angle):
    sec = Section(R, ovality_mm * 1e-3, angle)
    t = np.arange(20001) * 1e-4
    phi, _, _, _ = solve_section(sec, r, math.radians(0.2), 0.0, 0.0, t, gravity=G)
    up = np.flatnonzero((phi[:-1] < 0) & (phi[1:] >= 0))
    tc = t[up] - phi[up] * (t[up + 1] - t[up]) / (phi[up + 1] - phi[up])
    period = np.mean(np.diff(tc))
    expect = 2 * math.pi * math.sqrt(7 * (sec.bottom_curvature_radius() - r) / (5 * G))
    assert period == pytest.approx(expect, rel=2e-5)
    # and not the round trough's: the bottom curvature differs from R by ~3/4 of the ovality
    round_period = 2 * math.pi * math.sqrt(7 * (R - r) / (5 * G))
    assert abs(period / round_period - 1) > 0.5 * abs(
        math.sqrt((sec.bottom_curvature_radius() - r) / (R - r)) - 1)


def test_reference_engine_runs_an_ellipse_from_the_camera_angle():
    sc = sim.Scenario(duration=0.5, ovality=0.4e-3, ovality_angle=0.3, theta0=math.radians(15),
                      theta_dot0=0.2)
    tr = sim.simulate(sc)
    assert tr.theta[0] == pytest.approx(sc.theta0, abs=1e-12)
    assert tr.theta_dot[0] == pytest.approx(sc.theta_dot0, rel=1e-9)
    # the centre stays on the offset curve: distance r from the ellipse along the normal
    sec = sc.section
    for i in (0, 100, 400):
        x, y, z = tr.position[i]
        ph = sec.phi_of_point(x, y, math.atan2(x, -y))
        assert np.hypot(*(np.array([x, y]) - sec.contact(ph))) == pytest.approx(r, abs=1e-12)
        assert z == 0.0


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_engines_follow_the_ellipse_reference(engine):
    sc = sim.Scenario(duration=0.8, ovality=0.6e-3, ovality_angle=0.3, engine=engine)
    tr = sim.simulate(sc)
    ref = sim.simulate(sc.replace(engine="reference", engine_options={}))
    rnd = sim.simulate(sc.replace(engine="reference", engine_options={}, ovality=0.0))
    err = np.max(np.abs(tr.theta - ref.theta))
    assert np.degrees(err) < 0.1
    # the ellipse's own effect is larger than the engine's error
    assert np.max(np.abs(rnd.theta - ref.theta)) > 3 * err
    assert np.nanmax(tr.slip_speed) < 0.02 * np.max(np.abs(ref.theta_dot)) * sc.track_radius


def test_tilt_is_refused_by_the_reference_and_naive_surfaces():
    with pytest.raises(ScenarioError, match="3D motion.*mujoco or pybullet"):
        sim.Scenario(tilt=math.radians(0.1))
    with pytest.raises(ScenarioError, match="tangent"):
        sim.Scenario(tilt=math.radians(0.1), engine="mujoco", surface="mesh")
    with pytest.raises(ScenarioError, match="tangent"):
        sim.Scenario(ovality=1e-4, engine="pybullet", surface="heightfield")
    with pytest.raises(ScenarioError, match="ovality"):
        sim.Scenario(ovality=-1e-4)


def test_scenario_toml_keys_round_trip():
    d = {"cylinder": {"radius_mm": 85.3, "ovality_mm": 0.2, "ovality_angle_deg": 30.0,
                      "tilt_deg": 0.25}, "engine": {"name": "pybullet"}}
    sc = sim.scenario.scenario_from_dict(d)
    assert sc.ovality == pytest.approx(2e-4) and sc.tilt == pytest.approx(math.radians(0.25))
    assert sim.scenario.scenario_from_dict(sc.to_toml_dict()) == sc
    assert sim.Scenario.from_dict(sc.to_dict()) == sc
    # a round, level trough writes no new keys (its files are unchanged)
    plain = sim.Scenario()
    assert "ovality" not in plain.to_dict() and "tilt_deg" not in plain.to_toml_dict()["cylinder"]


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_tilted_trough_ball_rolls_down_the_axis(engine):
    tilt = math.radians(0.5)
    # at rest at the bottom: a ball rolling down an incline, z = (5/14) g sin(tilt) t^2
    rest = sim.simulate(sim.Scenario(duration=0.5, engine=engine, mu=0.0, theta0=0.0,
                                     tilt=tilt))
    incline = 5 / 14 * G * math.sin(tilt) * rest.t**2
    # (the engines' first steps, before the contact holds, are a free fall: 5-8 nm ahead)
    acc = 2 * np.polyfit(rest.t[50:], rest.position[50:, 2], 2)[0]
    assert acc == pytest.approx(5 / 7 * G * math.sin(tilt), rel=1e-3)
    assert rest.position[-1, 2] == pytest.approx(incline[-1], rel=2e-3)
    # swinging: it drifts towards the camera (+z) and swings in x-y as before
    tr = sim.simulate(sim.Scenario(duration=0.5, engine=engine, tilt=tilt))
    assert tr.position[-1, 2] > 0.9 * 5 / 14 * G * math.sin(tilt) * 0.25 * 0.5
    assert tr.position[-1, 2] < incline[-1]
    level = sim.simulate(sim.Scenario(duration=0.5, engine=engine))
    assert np.degrees(np.max(np.abs(tr.theta - level.theta))) < 0.5
