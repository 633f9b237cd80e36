"""sim: scenarios, bad input, trajectory files, reference kinematics."""

import math

import numpy as np
import pytest

import sim
from rollfric.errors import InputError
from sim.engines.common import slip_speed


def test_defaults_are_the_thesis_10mm_ball():
    sc = sim.Scenario()
    assert sc.ball_diameter == pytest.approx(10e-3)
    assert sc.ball_mass == pytest.approx(4.07612e-3)
    assert sc.cylinder_radius == pytest.approx(85.3e-3)
    assert sc.mu == 0.0079 and sc.engine == "reference" and sc.surface == "tangent"
    assert math.degrees(sc.theta0) == pytest.approx(20.0)
    assert sc.n_samples == 4001
    setup = sc.setup()
    assert setup.pixel_size == pytest.approx(0.1343e-3) and setup.fps == 1000.0
    assert setup.track_radius == pytest.approx(sc.track_radius)


@pytest.mark.parametrize("changes, word", [
    ({"ball_diameter": 0.2}, "ball_diameter"),
    ({"theta0": math.radians(81)}, "theta0"),
    ({"theta0": -math.radians(85)}, "theta0"),
    ({"mu": -0.001}, "mu"),
    ({"engine": "ode"}, "engine"),
    ({"engine": "reference", "surface": "mesh"}, "surface"),
    ({"engine": "mujoco", "engine_options": {"time_step": 1e-4}}, "time_step"),
    ({"engine": "pybullet", "engine_options": {"timestep_s": -1.0}}, "timestep_s"),
    ({"ball_mass": 0.0}, "ball_mass"),
    ({"fps": float("nan")}, "fps"),
])
def test_bad_scenarios_are_refused_with_a_named_input(changes, word):
    with pytest.raises(InputError, match=word):
        sim.Scenario(**changes)


def test_cli_refuses_bad_scenario_and_writes_nothing(tmp_path):
    from rollfric.cli.main import main

    out = tmp_path / "traj.csv"
    assert main(["simulate", "--engine", "mujoco", "--theta0-deg", "85",
                 "--out", str(out)]) == 2
    assert main(["simulate", "--mu", "-0.1", "--out", str(out)]) == 2
    assert not list(tmp_path.iterdir())


def test_cli_writes_csv_and_sidecar(tmp_path):
    from rollfric.cli.main import main

    out = tmp_path / "traj.csv"
    assert main(["simulate", "--engine", "reference", "--mu", "0.0079",
                 "--ball-diameter-mm", "10", "--ball-mass-g", "4.07612", "--theta0-deg", "20",
                 "--seconds", "0.5", "--fps", "1000", "--out", str(out)]) == 0
    traj = sim.read_trajectory(out)
    assert traj.t[:2].tolist() == [0.0, 0.001] and len(traj) == 501
    assert out.read_text().splitlines()[0].startswith("t_s,theta_rad,")
    want = sim.Scenario(duration=0.5).to_dict()
    got = traj.scenario.to_dict()
    assert got.keys() == want.keys()
    for key, value in got.items():
        if isinstance(want[key], float):  # mm/g -> SI on the way in: equal to the last bit or so
            assert value == pytest.approx(want[key], rel=1e-15), key
        else:  # names, seed and engine options: exactly equal
            assert value == want[key] and type(value) is type(want[key]), key


def test_scenario_toml_round_trip(tmp_path):
    sc = sim.Scenario.thesis("1.58mm", engine="mujoco", surface="heightfield", mu=0.0164,
                             theta0=math.radians(12.07), theta_dot0=-0.1, duration=2.5,
                             engine_options={"timestep_s": 2e-4, "noslip_iterations": 30},
                             seed=7)
    path = tmp_path / "s.toml"
    path.write_text(sim.dumps_scenario(sc))
    back = sim.load_scenario(path)
    assert back.engine_options == sc.engine_options
    for f in ("ball_diameter", "ball_mass", "cylinder_radius", "mu", "theta0", "theta_dot0",
              "duration", "fps", "gravity", "pixel_size"):
        assert getattr(back, f) == pytest.approx(getattr(sc, f), rel=1e-14), f
    assert (back.engine, back.surface, back.seed) == ("mujoco", "heightfield", 7)


def test_scenario_file_unknown_key_is_named(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("[motion]\nmu = 0.01\ntheta_deg = 3\n")
    with pytest.raises(InputError, match="motion.theta_deg"):
        sim.load_scenario(path)


def test_csv_round_trip_is_exact(tmp_path):
    traj = sim.simulate(sim.Scenario(duration=0.3))
    path = traj.to_csv(tmp_path / "a" / "traj.csv")
    assert (tmp_path / "a" / "traj.json").is_file()
    back = sim.read_trajectory(path)
    assert np.array_equal(back.table(), traj.table(), equal_nan=True)
    assert back.scenario == traj.scenario
    assert back.meta["engine"] == "reference"


def test_reference_kinematics_roll_without_slipping():
    sc = sim.Scenario.thesis("1.58mm", theta_dot0=0.3, duration=1.0)
    tr = sim.simulate(sc)
    L, r = sc.track_radius, sc.ball_radius
    assert np.allclose(np.linalg.norm(tr.position[:, :2], axis=1), L, rtol=1e-12)
    assert tr.position[0] == pytest.approx([L * math.sin(sc.theta0), -L * math.cos(sc.theta0),
                                            0.0])
    # centre velocity from finite differences of the position; the contact point must be at
    # rest with the reported angular velocity (checks the sign of the spin in the world frame)
    dt = 1 / sc.fps
    vel = np.gradient(tr.position, dt, axis=0, edge_order=2)
    speed = np.linalg.norm(vel, axis=1)
    slip = slip_speed(tr.position, vel, tr.angular_velocity, r)
    assert np.max(slip[2:-2]) < 2e-3 * np.max(speed)
    # the quaternion turns at the reported angular velocity (about +z)
    angle = 2 * np.unwrap(np.arctan2(tr.quaternion[:, 3], tr.quaternion[:, 0]))
    assert np.allclose(np.gradient(angle, dt, edge_order=2)[2:-2],
                       tr.angular_velocity[2:-2, 2], rtol=2e-3, atol=2e-3 * np.max(
                           np.abs(tr.angular_velocity[:, 2])))
    m, g = sc.ball_mass, sc.gravity
    assert tr.normal_force == pytest.approx(m * g * np.cos(tr.theta) + m * L * tr.theta_dot**2)
    assert np.all(tr.slip_speed == 0)


def test_reference_stops_at_rest():
    sc = sim.Scenario(mu=0.0164, theta0=math.radians(10), duration=3.0)
    tr = sim.simulate(sc)
    t_stop = tr.meta["t_stop_s"]
    assert t_stop is not None and t_stop < 2.5
    rest = tr.t > t_stop
    assert np.all(tr.theta[rest] == tr.theta[-1]) and np.all(tr.theta_dot[rest] == 0)
    assert abs(math.tan(tr.theta[-1])) <= sc.mu
