import json
import math

import numpy as np
import pytest

from rollfric.cli.main import main
from rollfric.errors import InputError
from rollfric.fit import analytic, eom
from rollfric.fit.estimate import fit_mu
from rollfric.setup.model import save_setup, thesis_setup

T4 = np.arange(4000) / 1000.0
BALLS = ["1.58mm", "10mm", "12.69mm"]
MUS = [0.0065, 0.0079, 0.0164]


def truth(setup, mu, theta0_deg, omega0=0.0, t=T4, mu1=0.0):
    th, _, _ = eom.solve_reference(math.radians(theta0_deg), omega0, mu, t,
                                   track_radius=setup.track_radius, mu1=mu1)
    return th


@pytest.mark.parametrize("ball", BALLS)
@pytest.mark.parametrize("mu", MUS)
@pytest.mark.parametrize("theta0_deg", [5, 20, 40])
def test_recovers_mu_from_noiseless_theta(ball, mu, theta0_deg):
    setup = thesis_setup(ball)
    r = fit_mu(T4, truth(setup, mu, theta0_deg), setup)
    assert r.mu == pytest.approx(mu, rel=1e-5)
    assert r.theta0 == pytest.approx(math.radians(theta0_deg), abs=1e-7)
    assert r.rms_residual < 1e-7


@pytest.mark.parametrize("ball", BALLS)
@pytest.mark.parametrize("mu", MUS)
def test_recovers_mu_from_noisy_theta_within_its_uncertainty(ball, mu):
    setup = thesis_setup(ball)
    rng = np.random.default_rng(10 * BALLS.index(ball) + MUS.index(mu))
    for theta0_deg in (5, 25):
        sigma = math.radians(0.02)
        y = truth(setup, mu, theta0_deg) + rng.normal(0, sigma, T4.size)
        r = fit_mu(T4, y, setup)
        assert abs(r.mu / mu - 1) < 0.01
        assert abs(r.mu - mu) < 5 * r.mu_stderr
        assert r.rms_residual == pytest.approx(sigma, rel=0.1)


def test_offset_and_moving_start_and_gaps():
    setup = thesis_setup("10mm")
    t = 0.25 + T4[:3000]
    y = truth(setup, 0.0079, 15, omega0=0.4, t=t) + math.radians(0.4)
    y[500:560] = np.nan  # ball not found in 60 frames
    r = fit_mu(t, y, setup, offset=True)
    assert r.mu == pytest.approx(0.0079, rel=1e-5)
    assert r.offset == pytest.approx(math.radians(0.4), abs=1e-7)
    assert r.omega0 == pytest.approx(0.4, abs=1e-5)
    assert r.n_samples == 2940
    # without the offset term the fit is biased: the offset matters
    assert abs(fit_mu(t, y, setup).mu / 0.0079 - 1) > 1e-3


def test_velocity_dependent_model():
    setup = thesis_setup("12.69mm")
    y = truth(setup, 0.006, 25, mu1=0.002)
    r = fit_mu(T4, y, setup, model="velocity")
    assert r.mu == pytest.approx(0.006, rel=1e-4)
    assert r.mu1 == pytest.approx(0.002, rel=1e-3)


def test_too_few_samples():
    setup = thesis_setup("10mm")
    with pytest.raises(InputError, match="usable samples"):
        fit_mu(T4[:20], np.zeros(20), setup)


def test_paper1_eps_on_its_own_model_finds_eps():
    # data that obey the small-angle model exactly: the iteration lands on eps within a step
    setup = thesis_setup("1.58mm")
    w2 = analytic.omega_squared(setup.track_radius)
    eps = 1.9012
    th, _, _ = analytic.solve_small_angle(math.radians(12.07), 0.0, eps, w2, T4[:1500])
    r = fit_mu(T4[:1500], th, setup, method="paper1_eps")
    assert r.extra["eps_s2"] == pytest.approx(eps, abs=2e-4)
    assert r.mu == pytest.approx(analytic.mu_from_eps(eps, setup.track_radius), rel=1e-4)
    assert r.extra["mu_paper1"] == pytest.approx(
        analytic.paper1_mu_from_eps(eps, math.radians(12.07), setup.track_radius), rel=1e-4)


def test_paper2_grid_finds_the_grid_point_nearest_the_truth():
    setup = thesis_setup("10mm")
    y = truth(setup, 0.0079, 20, t=T4[:1500])
    first = {"mu": 0.0081, "theta0": math.radians(20) + 0.0003, "omega0": 0.02}
    r = fit_mu(T4[:1500], y, setup, method="paper2_grid", first=first,
               grid={"mu": (0.0003, 0.0001), "theta0": (0.0004, 0.0001),
                     "omega0": (0.03, 0.01)})
    assert r.mu == pytest.approx(0.0079, abs=1e-9)
    assert r.theta0 == pytest.approx(math.radians(20), abs=1e-9)
    assert r.omega0 == pytest.approx(0.0, abs=1e-9)


def test_cli_fit_writes_json_and_plot(tmp_path):
    setup = thesis_setup("10mm")
    save_setup(setup, tmp_path / "setup.toml")
    y = truth(setup, 0.0079, 20)
    lines = ["t_s,theta_rad,extra"] + [f"{a:.17g},{b:.17g},x" for a, b in zip(T4, y, strict=True)]
    (tmp_path / "track.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "fit.json"
    assert main(["fit", str(tmp_path / "track.csv"), "--setup", str(tmp_path / "setup.toml"),
                 "--out", str(out), "--plot"]) == 0
    data = json.loads(out.read_text())
    for key in ("mu", "mu_stderr", "theta0_rad", "omega0_rad_s", "rms_residual_rad", "method"):
        assert key in data
    assert data["mu"] == pytest.approx(0.0079, rel=1e-5)
    assert (tmp_path / "fit.png").stat().st_size > 10000


def test_cli_fit_leaves_out_rows_marked_found_0(tmp_path, capsys):
    # audit 2026-11-24: a frame struck out by hand (found = 0, its angle kept) was fitted
    setup = thesis_setup("10mm")
    save_setup(setup, tmp_path / "setup.toml")
    y = truth(setup, 0.0079, 20)
    bad = np.zeros(T4.size, bool)
    bad[1000:1300] = True  # 0.3 s of angles 0.05 rad off, marked found = 0
    y = np.where(bad, y + 0.05, y)
    lines = ["frame,t_s,theta_rad,found"] + [
        f"{i},{a:.17g},{b:.17g},{0 if k else 1}"
        for i, (a, b, k) in enumerate(zip(T4, y, bad, strict=True))]
    (tmp_path / "track.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "fit.json"
    args = ["fit", str(tmp_path / "track.csv"), "--setup", str(tmp_path / "setup.toml"),
            "--out", str(out)]
    assert main(args) == 0
    assert json.loads(out.read_text())["mu"] == pytest.approx(0.0079, rel=1e-5)
    assert "300 row(s) with found = 0 and an angle left out" in capsys.readouterr().err
    # a found that is neither 1 nor 0 is bad input naming the row
    lines[5] = lines[5].rsplit(",", 1)[0] + ",yes"
    (tmp_path / "track.csv").write_text("\n".join(lines) + "\n")
    assert main(args + ["--overwrite"]) == 2
    assert "row 5 has found = 'yes'" in capsys.readouterr().err


def test_cli_fit_bad_input_writes_nothing(tmp_path, capsys):
    save_setup(thesis_setup("10mm"), tmp_path / "setup.toml")
    (tmp_path / "track.csv").write_text("time,angle\n0,0\n")
    out = tmp_path / "fit.json"
    code = main(["fit", str(tmp_path / "track.csv"), "--setup", str(tmp_path / "setup.toml"),
                 "--out", str(out)])
    assert code == 2
    assert "theta_rad" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("seed", range(4))
def test_record_shorter_than_a_quarter_swing(seed):
    # no turning point to measure a decay from: the start must come from the acceleration
    setup = thesis_setup("10mm")
    t = T4[:121]
    y = truth(setup, 0.0079, 8, t=t) + np.random.default_rng(seed).normal(0, 3e-5, t.size)
    r = fit_mu(t, y, setup)
    assert abs(r.mu - 0.0079) < 5 * r.mu_stderr
    assert r.mu_stderr < 1e-4
