"""The fitter's multi-start and robust stages, and the quality checks after every fit."""

import json
import math

import numpy as np
import pytest

from rollfric.cli.main import main
from rollfric.errors import InputError
from rollfric.fit import eom, filtering
from rollfric.fit.estimate import fit_mu
from rollfric.fit.lsq import fit_lsq
from rollfric.setup.model import save_setup, thesis_setup
from rollfric.uncertainty import quality
from rollfric.uncertainty.period import half_period_frictionless

T4 = np.arange(4000) / 1000.0


def truth(setup, mu, theta0_deg, t=T4, mu1=0.0):
    th, _, _ = eom.solve_reference(math.radians(theta0_deg), 0.0, mu, t,
                                   track_radius=setup.track_radius, mu1=mu1)
    return th


def codes(result):
    return {r.code for r in result.quality_reasons}


@pytest.mark.parametrize("theta0_deg", [2, 5, 8])
def test_short_track_with_free_offset_finds_mu(theta0_deg):
    # 0.3 s from rest, no turning point: mu and the offset are interchangeable to first order;
    # the fit used to stall at mu ~ 1e-12 (a Jacobian column of zero near mu = 0)
    setup = thesis_setup("1.58mm")
    t = T4[:300]
    y = truth(setup, 0.0164, theta0_deg, t)
    r = fit_mu(t, y, setup, offset=True)
    assert r.mu == pytest.approx(0.0164, rel=1e-4)
    # ... but with the offset free one half-swing cannot tell them apart in noisy data
    assert "half_swings" in codes(r)
    r = fit_mu(t, y, setup)
    assert r.mu == pytest.approx(0.0164, rel=1e-6)
    assert r.quality == "ok"


def test_stderr_is_finite_for_a_ball_released_from_rest():
    # omega0 = 0 at the optimum: SciPy's relative difference step would be 0 * 1e-7
    setup = thesis_setup("1.58mm")
    t = T4[:300]
    y = truth(setup, 0.0164, 12, t) + np.random.default_rng(0).normal(0, 1e-5, t.size)
    r = fit_mu(t, y, setup)
    assert all(math.isfinite(v) and v > 0 for v in r.stderr.values())
    assert abs(r.mu - 0.0164) < 5 * r.mu_stderr


@pytest.mark.parametrize("seed", range(3))
def test_clean_noisy_fits_pass_every_check(seed):
    rng = np.random.default_rng(seed)
    for ball, mu, th0 in (("1.58mm", 0.0164, 12), ("10mm", 0.0079, 20), ("12.69mm", 0.0065, 35)):
        setup = thesis_setup(ball)
        sigma = 10 ** rng.uniform(-5.5, -3.5)
        r = fit_mu(T4, truth(setup, mu, th0) + rng.normal(0, sigma, T4.size), setup)
        assert r.quality == "ok", [q.message for q in r.quality_reasons]
        assert r.extra["noise_rad"] == pytest.approx(sigma, rel=0.1)


def test_degrees_are_refused_quickly():
    setup = thesis_setup("10mm")
    y = np.degrees(truth(setup, 0.0079, 20, T4[:2000]))
    with pytest.raises(InputError, match="degrees"):
        fit_mu(T4[:2000], y, setup)
    with pytest.raises(InputError, match="not angles"):
        fit_mu(T4[:2000], 10 * y, setup)


def test_period_names_the_frame_rate_or_the_radius():
    setup = thesis_setup("10mm")
    y = truth(setup, 0.0079, 20) + np.random.default_rng(1).normal(0, 3e-5, T4.size)
    r = fit_mu(T4 / 2, y, setup)  # frames taken at 500 Hz, the setup says 1000
    (p,) = [q for q in r.quality_reasons if q.code == "period"]
    assert "500 Hz" in p.message and "camera.fps" in p.message
    assert {"residual_noise", "residual_structure"} <= codes(r)
    r = fit_mu(T4, y, setup.replace(cylinder_radius=setup.cylinder_radius * 1.08))
    (p,) = [q for q in r.quality_reasons if q.code == "period"]
    assert "cylinder.radius_mm" in p.message
    assert "80.3" in p.message  # the L the swings fit (mm)


@pytest.mark.parametrize("change, says", [
    ({"gravity": 9.6}, "environment.gravity_m_s2 = 9.6 m/s^2 is not the local gravity"),
    ({"cylinder_radius": 85.3e-3 * 1.02}, "cylinder.radius_mm or ball.diameter_mm is off")])
def test_a_period_1_percent_off_behind_a_misfit_is_named_not_taken_for_degrees(change, says):
    # the rendered fault study (1.2 s from 11 deg): g 9.6 for 9.81 m/s^2 or a trough radius
    # 2 % large put the period 1.0-1.1 % off, inside the check's 3 %, and the fit's residual
    # at 50-100 x its noise; the period said "the angles look like degrees" (at 0.19 rad the
    # degrees' small-angle period is as near) or nothing. Where the residuals fail the period
    # is held to what the turning points tell; degrees need the radians' period off by 3 %
    setup = thesis_setup("10mm")
    t = np.arange(1200) / 1000.0
    y = truth(setup, 0.0066, 11, t=t) + np.random.default_rng(4).normal(0, 1e-4, t.size)
    r = fit_mu(t, y, setup.replace(**change))
    assert {"residual_noise", "residual_structure"} <= codes(r)
    (p,) = [q for q in r.quality_reasons if q.code == "period"]
    assert says in p.message and "degrees" not in p.message
    assert "period" not in codes(fit_mu(t, y, setup))


def test_a_gap_over_whole_swings_is_no_period_error():
    # audit 2026-11-24: a track missing 1.5 s (the turning points in it unseen) was suspect
    # with "period" (+100 %, "check camera.fps") though every sample fitted the truth
    setup = thesis_setup("10mm")
    y = truth(setup, 0.0079, 20) + np.random.default_rng(1).normal(0, 3e-5, T4.size)
    keep = (T4 < 1.0) | (T4 >= 2.5)
    r = fit_mu(T4[keep], y[keep], setup)
    assert r.quality == "ok", [q.message for q in r.quality_reasons]
    assert r.mu == pytest.approx(0.0079, rel=1e-3)
    # the same gap as empty angles (a track's lost frames)
    assert fit_mu(T4, np.where(keep, y, np.nan), setup).quality == "ok"
    # a wrong radius is still found in the half-swings the samples cover
    late = np.where((T4 < 3.0) | (T4 >= 3.5), y, np.nan)
    r = fit_mu(T4, late, setup.replace(cylinder_radius=setup.cylinder_radius * 1.08))
    (p,) = [q for q in r.quality_reasons if q.code == "period"]
    assert "cylinder.radius_mm" in p.message


def test_a_model_that_does_not_describe_the_data_is_suspect():
    setup = thesis_setup("12.69mm")
    y = truth(setup, 0.005, 25, mu1=0.004) + np.random.default_rng(2).normal(0, 3e-5, T4.size)
    r = fit_mu(T4, y, setup)
    assert {"residual_noise", "residual_structure"} <= codes(r)
    r = fit_mu(T4, y, setup, model="velocity")
    assert r.quality == "ok" and r.mu1 == pytest.approx(0.004, rel=0.02)


def test_no_friction_is_at_the_bound():
    setup = thesis_setup("10mm")
    r = fit_mu(T4, truth(setup, 0.0, 20) + np.random.default_rng(3).normal(0, 3e-5, T4.size),
               setup)
    assert "mu_bound" in codes(r)


def test_outliers_are_found_by_the_robust_fit():
    setup = thesis_setup("10mm")
    rng = np.random.default_rng(4)
    y = truth(setup, 0.0079, 20) + rng.normal(0, 3e-5, T4.size)
    bad = rng.choice(T4.size, 60, replace=False)
    y[bad] += rng.choice([-1, 1], 60) * rng.uniform(2e-3, 0.05, 60)
    r = fit_lsq(T4, y, setup)
    assert r.extra["n_outliers"] == 60 and r.n_samples == T4.size - 60
    assert not r.used[bad].any()
    assert r.mu == pytest.approx(0.0079, rel=1e-4)
    assert abs(r.mu - 0.0079) < 4 * r.mu_stderr
    plain = fit_lsq(T4, y, setup, robust=False)
    assert abs(plain.mu - 0.0079) > 10 * r.mu_stderr  # the outliers do bias a plain fit
    # too many outliers are a reason of their own
    more = rng.choice(T4.size, 400, replace=False)
    y[more] += rng.choice([-1, 1], 400) * 0.05
    assert "outliers" in codes(fit_mu(T4, y, setup))


def test_angle_beyond_90_degrees_is_a_reason():
    setup = thesis_setup("10mm")
    y = truth(setup, 0.0079, 20) + np.random.default_rng(5).normal(0, 3e-5, T4.size)
    y[[100, 2000]] = 2.0
    r = fit_mu(T4, y, setup)
    assert "angle_range" in codes(r)
    assert r.mu == pytest.approx(0.0079, rel=1e-4)


def test_noise_sigma_from_differences():
    rng = np.random.default_rng(6)
    sig = 0.3 * np.cos(2 * np.pi * 1.5 * T4)
    for sigma in (1e-5, 1e-3):
        x = sig + rng.normal(0, sigma, T4.size)
        x[500:520] = np.nan
        assert filtering.noise_sigma(x) == pytest.approx(sigma, rel=0.05)
    assert filtering.noise_sigma(sig) < 1e-6


def test_half_period_matches_the_integrated_swing():
    setup = thesis_setup("10mm")
    t = np.linspace(0, 2, 200001)
    th, om, _ = eom.solve_reference(math.radians(40), 0.0, 0.0, t,
                                    track_radius=setup.track_radius)
    turn = t[1:-1][(np.sign(om[1:-1]) != np.sign(om[2:])) & (np.abs(th[1:-1]) > 0.5)]
    expected = half_period_frictionless(math.radians(40), setup.track_radius, 9.81)
    assert np.diff(turn)[0] == pytest.approx(expected, abs=2e-5)


def _csv(path, t, y):
    lines = ["t_s,theta_rad"] + [f"{a:.17g},{b:.17g}" for a, b in zip(t, y, strict=True)]
    path.write_text("\n".join(lines) + "\n")


def test_cli_fit_exit_3_writes_the_reasons(tmp_path, capsys):
    setup = thesis_setup("10mm")
    save_setup(setup, tmp_path / "setup.toml")
    y = truth(setup, 0.0079, 20) + np.random.default_rng(7).normal(0, 3e-5, T4.size)
    _csv(tmp_path / "track.csv", T4 / 2, y)
    out = tmp_path / "fit.json"
    code = main(["fit", str(tmp_path / "track.csv"), "--setup", str(tmp_path / "setup.toml"),
                 "--out", str(out)])
    assert code == 3
    data = json.loads(out.read_text())
    assert data["quality"] == "suspect"
    assert "period" in {r["code"] for r in data["quality_reasons"]}
    assert "[period]" in capsys.readouterr().err
    _csv(tmp_path / "good.csv", T4, y)
    assert main(["fit", str(tmp_path / "good.csv"), "--setup", str(tmp_path / "setup.toml"),
                 "--out", str(tmp_path / "good.json")]) == 0
    data = json.loads((tmp_path / "good.json").read_text())
    assert data["quality"] == "ok" and data["quality_reasons"] == []


def test_cli_fit_degrees_exit_2_writes_nothing(tmp_path, capsys):
    setup = thesis_setup("10mm")
    save_setup(setup, tmp_path / "setup.toml")
    _csv(tmp_path / "track.csv", T4, np.degrees(truth(setup, 0.0079, 20)))
    out = tmp_path / "fit.json"
    code = main(["fit", str(tmp_path / "track.csv"), "--setup", str(tmp_path / "setup.toml"),
                 "--out", str(out)])
    assert code == 2 and not out.exists()
    assert "degrees" in capsys.readouterr().err


def test_swing_coverage_counts_the_outer_half_of_each_side():
    setup = thesis_setup("10mm")
    t = T4[:2000]
    y = truth(setup, 0.0079, 10, t)
    r = fit_mu(t, y, setup)
    whole = np.ones(t.size, bool)
    cov = quality.swing_coverage(whole, r, setup)
    assert cov["right"][0] == cov["right"][1] > 200 and cov["left"][0] == cov["left"][1] > 200
    assert quality.swing_coverage_reason(whole, r, setup) is None
    # the outer half of a half-swing: |theta| >= half its extreme (the model's, not the data's)
    right = y > 0
    ext = {}
    for seg in np.split(np.arange(t.size), np.flatnonzero(np.diff(np.sign(y)) != 0) + 1):
        ext.update({i: np.abs(y[seg]).max() for i in seg})
    e = np.array([ext[i] for i in range(t.size)])
    outer = np.abs(y) >= 0.5 * e
    keep = ~(right & (y > 0.7 * e))  # the right turning points lost
    cov = quality.swing_coverage(keep, r, setup)
    assert cov["right"][1] == int((outer & right).sum())
    assert cov["right"][0] == int((outer & right & keep).sum())
    reason = quality.swing_coverage_reason(keep, r, setup)
    assert reason is not None and reason.code == "swing_coverage"
    assert "right of the bottom" in reason.message
    left_lost = ~((y < 0) & (np.abs(y) > 0.7 * e))
    assert "left of the bottom" in quality.swing_coverage_reason(left_lost, r, setup).message


def test_swing_coverage_counts_a_release_lost_before_the_first_located_frame():
    setup = thesis_setup("10mm")
    t = T4[:2000]
    y = truth(setup, 0.0079, 10, t)
    k = int(np.argmax(y < 0.5 * y[0]))  # the ball lost from its release until half way in
    keep = np.ones(t.size, bool)
    keep[:k] = False
    r = fit_mu(t, np.where(keep, y, np.nan), setup)
    full = quality.swing_coverage(np.ones(t.size, bool), fit_mu(t, y, setup), setup)
    cov = quality.swing_coverage(keep, r, setup)
    # the k frames before the first located one are lost frames of the right side's outer half
    assert cov["right"][1] - cov["right"][0] == k
    assert cov["left"] == full["left"]


@pytest.mark.filterwarnings("error::RuntimeWarning")
@pytest.mark.parametrize("method", ["lsq", "paper2_grid"])
def test_a_ball_that_never_moved_is_suspect_without_a_numpy_warning(method):
    # audit 2026-11-24: angles all 0 printed NumPy's "invalid value encountered in scalar
    # divide" (the thesis's relative error, sum |model - data| / sum |data|) on stderr
    setup = thesis_setup("10mm")
    r = fit_mu(T4[:1000], np.zeros(1000), setup, method=method)
    assert r.quality == "suspect" and "mu_bound" in codes(r)
    assert math.isnan(r.relative_error)
