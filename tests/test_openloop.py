"""The open-loop coverage study (validation.studies.openloop): its truths carry the drawn
physics, its camera compresses the centres, its summary counts right."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from rollfric.fit.air import cd_sphere
from validation.studies import openloop as ol
from validation.studies.coverage import drawn_setups


def _case(seed, family, **changes):
    case = ol.draw_openloop(seed, family)
    case.update(changes)
    return case


def test_tilted_truth_rolls_down_the_axis_as_an_incline():
    """A tilted case's PyBullet trajectory leaves its level twin's: the ball drifts along
    the axis (less than a frictionless incline's (5/14) g sin(tilt) t^2: the rolling
    resistance opposes the drift too) and the swing differs. Without friction and nearly at
    rest it rolls down as on an incline (docs/how/trough.md)."""
    pytest.importorskip("pybullet")
    import sim

    case = _case(0, "tilt", seconds=1.0, tilt_deg=0.2)
    tilted = sim.simulate(ol.truth_scenario(case))
    level = sim.simulate(ol.truth_scenario({**case, "tilt_deg": 0.0}))
    t = tilted.t[-1]
    incline = 5.0 / 14.0 * 9.81 * math.sin(math.radians(0.2)) * t**2
    assert abs(level.position[-1, 2]) < 1e-6
    assert 0.3 * incline < tilted.position[-1, 2] < incline
    assert np.max(np.abs(tilted.theta - level.theta)) > 1e-5
    free = sim.simulate(ol.truth_scenario({**case, "mu": 0.0, "theta0_deg": 1.0}))
    assert free.position[-1, 2] == pytest.approx(incline, rel=0.02)


def test_out_of_round_truth_is_an_ellipse():
    """An ovality case's path is the bore's offset curve, not a circle: its distance from
    the axis varies by about ovality / 2 over the swing (a circle's by nothing)."""
    case = _case(3, "ovality", ovality_mm=0.4, ovality_angle_deg=0.0, theta0_deg=30.0)
    import sim

    traj = sim.simulate(ol.truth_scenario(case))
    rad = np.hypot(traj.position[:, 0], traj.position[:, 1])
    round_ = sim.simulate(ol.truth_scenario({**case, "ovality_mm": 0.0}))
    rad0 = np.hypot(round_.position[:, 0], round_.position[:, 1])
    assert np.ptp(rad0) < 1e-9
    # a = R + ov/4 (horizontal), b = R - ov/4: from the bottom to 30 deg the offset curve's
    # radius grows by (a - b) sin^2(30 deg) to first order
    assert np.ptp(rad) == pytest.approx(0.2e-3 * math.sin(math.radians(30.0)) ** 2, rel=0.1)


def test_camera_compresses_the_centres_by_cos_angle():
    """The yawed and pitched camera's centres are the square camera's compressed about the
    trough centre by cos(yaw) in x and cos(pitch) in y; the path's conic shows that ratio."""
    import sim
    from rollfric.geometry.pathshape import fit_path

    case = _case(4, "camera", yaw_deg=3.0, pitch_deg=-1.0)
    true, _ = drawn_setups(case)
    traj = sim.simulate(ol.truth_scenario(case))
    _, x, y = ol.exact_centres(case, traj, true)
    _, x0, y0 = ol.exact_centres({**case, "yaw_deg": 0.0, "pitch_deg": 0.0}, traj, true)
    cx, cy = true.center_px
    np.testing.assert_allclose(x - cx, (x0 - cx) * math.cos(math.radians(3.0)), atol=1e-9)
    np.testing.assert_allclose(y - cy, (y0 - cy) * math.cos(math.radians(1.0)), atol=1e-9)
    # the square camera's centres lie on the circle of radius L / pixel size
    L_px = true.track_radius / true.pixel_size
    np.testing.assert_allclose(np.hypot(x0 - cx, y0 - cy), L_px, rtol=1e-9)
    a, b = fit_path(x, y, true.center_px).semi_axes
    assert b / a == pytest.approx(math.cos(math.radians(3.0)) / math.cos(math.radians(1.0)),
                                  abs=2e-4)


def test_air_draws_the_law_within_its_stated_u():
    """The air case's constant Cd is the law's free-sphere Cd at the swing's Reynolds number
    times a wall factor within the stated 1 .. 2; the power-weighted Cd lies between the
    free sphere's at the top speed and at half of it; the beyond family reaches outside."""
    d, L, th0, rho = 10e-3, 80.3e-3, math.radians(20.0), 1.2
    cd, re_top = ol.swing_cd(d, L, th0, rho)
    v_top = math.sqrt(10 / 7 * 9.81 * L * (1 - math.cos(th0)))
    assert re_top == pytest.approx(rho * v_top * d / 1.81e-5)
    assert cd_sphere(re_top) < cd < cd_sphere(re_top / 2)
    # over a 4 s record the amplitude decays: slower swings, a larger Cd
    cd_record, _ = ol.swing_cd(d, L, th0, rho, mu=0.01, seconds=4.0)
    assert cd < cd_record < cd_sphere(0.1 * re_top)
    walls = [ol.draw_openloop(s, "air")["wall_factor"] for s in range(40)]
    assert 1.0 <= min(walls) and max(walls) <= 2.0
    beyond = [ol.draw_openloop(s, "air_beyond")["wall_factor"] for s in range(40)]
    assert min(beyond) < 1.0 and max(beyond) > 2.0
    case = ol.draw_openloop(7, "air")
    scen = ol.truth_scenario(case)
    assert scen.air_drag == "constant" and scen.air_density > 1.0
    assert scen.air_cd == pytest.approx(case["wall_factor"] * ol.swing_cd(
        scen.ball_diameter, scen.track_radius, scen.theta0, scen.air_density, mu=scen.mu,
        seconds=case["seconds"])[0])
    lab = ol.lab_setup(case)
    assert lab.air_density == pytest.approx(1.20) and lab.u("air_density") == 0.03
    assert ol.lab_setup(ol.draw_openloop(4, "camera")).air_density == 0.0


def test_speed_law_and_lab_setup():
    """The speed law's term at the top speed is the drawn fraction of mu0; the lab's setup
    is coverage's nominal one with its tolerances."""
    case = ol.draw_openloop(5, "speed")
    L = (case["true_radius_mm"] - case["true_diameter_mm"] / 2) * 1e-3
    v_top = math.sqrt(10 / 7 * 9.81 * L * (1 - math.cos(math.radians(case["theta0_deg"]))))
    assert case["mu_speed_s_m"] * v_top == pytest.approx(case["speed_fraction"] * case["mu"])
    assert ol.truth_scenario(case).mu_speed == case["mu_speed_s_m"]
    lab = ol.lab_setup(case)
    assert lab.cylinder_radius == pytest.approx(85.3e-3)
    assert lab.u("cylinder_radius") == pytest.approx(0.5e-3)
    assert lab.u("center_px") == (2.0, 2.0)


def test_summary_fractions():
    """Within u, within U, their binomial standard errors and the misses' split by the
    physics' own z, on a table with known z."""
    df = pd.DataFrame({"z": [0.5, -1.5, 2.5, 0.1, -3.0], "z_phys": [0.0, 0.0, 2.0, 0.0, 0.5],
                       "bias_phys": [0.0] * 5, "quality": ["ok", "ok", "ok", "ok", "period"]})
    s = ol.coverage_of(df)
    assert s["cases"] == 5
    assert s["within_u"] == pytest.approx(0.4) and s["within_U"] == pytest.approx(0.6)
    assert s["within_U_se"] == pytest.approx(math.sqrt(0.6 * 0.4 / 5))
    assert s["misses_U"] == 2 and s["misses_u"] == 3
    assert s["misses_U_physics"] == 1 and s["misses_U_rest"] == 1
    assert s["suspect"] == 1 and s["within_U_ok"] == pytest.approx(0.75)


def test_smoke_run(tmp_path):
    """Two cases (a tilted trough and a turned camera) through the whole study."""
    pytest.importorskip("pybullet")
    assert ol.main(["--cases", "2", "--families", "tilt", "camera", "--out",
                    str(tmp_path)]) == 0
    df = pd.read_csv(tmp_path / "openloop.csv")
    assert list(df["family"]) == ["tilt", "camera"]
    assert df.loc[0, "tilt_deg"] != 0.0 and df.loc[1, "yaw_deg"] != 0.0
    s = json.loads((tmp_path / "openloop.json").read_text())
    assert s["stated"]["cases"] == 2
    assert s["stated"]["within_U"] == pytest.approx(np.mean(np.abs(df["z"]) <= 2))
    assert set(s["families"]) == {"tilt", "camera"}
    assert (tmp_path / "openloop.png").stat().st_size > 0
