"""The friction-law test (rollfric.uncertainty.law): Coulomb + drag against speed + drag."""

import json
import math

import numpy as np
import pytest

from rollfric.cli.main import main
from rollfric.fit import air, eom
from rollfric.fit.estimate import fit_mu
from rollfric.setup.model import save_setup, thesis_setup
from rollfric.uncertainty.law import detectable, friction_law, judged
from rollfric.uncertainty.measured import Measurement

T4 = np.arange(4000) / 1000.0
ROOM_AIR = (("air_density", air.ROOM_AIR_DENSITY_U), ("air_viscosity", air.AIR_VISCOSITY_U))
MU0, MU1 = 0.008, 3e-4  # a speed law the 10 mm ball's recordings detect (mu1 ~ 200 u)


def room_air(ball="10mm", **changes):
    return thesis_setup(ball, **{"air_density": air.ROOM_AIR_DENSITY, "uncertainty": ROOM_AIR,
                                 **changes})


def track(setup, mu0, mu1=0.0, noise=1e-4, seed=1, true=None):
    """The exact motion (the truth's air: ``true``, else the setup's), plus white noise."""
    true = true or setup
    th, _, _ = eom.solve_reference(math.radians(20.0), 0.0, mu0, T4, mu1=mu1,
                                   track_radius=setup.track_radius,
                                   air=air.coefficients_of(true))
    return th + np.random.default_rng(seed).normal(0.0, noise, T4.size)


def law_of(setup, theta):
    meas = Measurement(setup=setup, t=T4, theta=theta)
    fit = fit_mu(T4, theta, setup)
    return meas, fit, friction_law(meas, fit)


def test_coulomb_and_drag_is_coulomb():
    setup = room_air()
    _, fit, law = law_of(setup, track(setup, MU0))
    assert law.selected == "coulomb"
    assert law.p_value > 0.05
    assert abs(law.mu1) < 2 * law.mu1_u
    assert abs(law.mu0 - MU0) < 2 * law.mu0_u
    assert law.mu1_detectable == pytest.approx(detectable(law.mu1_u))
    assert fit.mu == pytest.approx(MU0, rel=2e-3)


def test_drag_off_by_its_u_is_not_taken_for_a_speed_law():
    # the truth's drag 1 u above the law's (wall factor 1.5 + 0.29): its Stokes part is linear
    # in speed like mu1's; a test without the air's u would find "speed"
    setup = room_air()
    true = setup.replace(air_wall_factor=air.WALL_FACTOR + air.WALL_FACTOR_U)
    _, _, law = law_of(setup, track(setup, MU0, true=true))
    assert law.mu1 / law.mu1_u_statistical > 1.645  # what HAC alone would say
    assert law.mu1_u_inputs > law.mu1_u_statistical
    assert law.selected == "coulomb"
    assert dict(law.inputs)["environment.air_cd (drag law: wall factor)"] > 0


def test_speed_law_found_with_mu0_mu1_within_their_u():
    setup = room_air()
    meas, fit, law = law_of(setup, track(setup, MU0, MU1, noise=1e-5))
    assert law.selected == "speed" and law.p_value < 1e-6
    assert abs(law.mu0 - MU0) < 2 * law.mu0_u
    assert abs(law.mu1 - MU1) < 2 * law.mu1_u
    codes = [r.code for r in fit.quality_reasons]
    assert "residual_structure" in codes  # Coulomb's fit leaves the law's misfit
    after = [r.code for r in judged(meas, fit, law).quality_reasons]
    assert "friction_law" in after and "residual_structure" not in after
    # the speed law's own fit leaves white noise
    assert law.rms_residual == pytest.approx(1e-5, rel=0.05)


def test_short_track_is_not_tested():
    setup = room_air()
    t = T4[:500]
    th = track(setup, MU0)[:500]
    meas = Measurement(setup=setup, t=t, theta=th)
    law = friction_law(meas, fit_mu(t, th, setup))
    assert law.selected is None and "turning points" in law.why
    assert law.to_json()["selected"] is None


def write_track(tmp_path, setup, theta):
    save_setup(setup, tmp_path / "setup.toml")
    lines = ["t_s,theta_rad"] + [f"{a:.17g},{b:.17g}" for a, b in zip(T4, theta, strict=True)]
    (tmp_path / "track.csv").write_text("\n".join(lines) + "\n")
    return [str(tmp_path / "track.csv"), "--setup", str(tmp_path / "setup.toml")]


def test_cli_fit_names_the_speed_law(tmp_path, capsys):
    setup = thesis_setup("10mm")
    args = write_track(tmp_path, setup, track(setup, MU0, MU1, noise=1e-5))
    out = tmp_path / "fit.json"
    assert main(["fit", *args, "--out", str(out)]) == 3
    data = json.loads(out.read_text())
    law = data["friction_law"]
    for key in ("selected", "p_value", "mu0", "mu0_u", "mu1", "mu1_u", "mu1_detectable",
                "detectable_power", "level", "statistic"):
        assert key in law
    assert law["selected"] == "speed" and law["level"] == 0.05
    codes = [r["code"] for r in data["quality_reasons"]]
    assert "friction_law" in codes and "residual_structure" not in codes
    message = next(r["message"] for r in data["quality_reasons"] if r["code"] == "friction_law")
    assert "mu0 = 0.0080" in message and "mu1 = 0.0003" in message
    assert data["mu"] > 0.0085  # mu stays the Coulomb coefficient
    assert "friction law: speed" in capsys.readouterr().out


@pytest.mark.parametrize("model", ["speed", "velocity"])
def test_cli_model_speed_gives_mu0(tmp_path, model):
    setup = thesis_setup("10mm")
    args = write_track(tmp_path, setup, track(setup, MU0, MU1, noise=1e-5))
    out = tmp_path / "fit.json"
    assert main(["fit", *args, "--out", str(out), "--model", model]) == 0
    data = json.loads(out.read_text())
    assert data["model"] == "speed"
    assert abs(data["mu"] - MU0) < data["U_mu"]
    assert data["mu1_s_rad"] == pytest.approx(MU1, rel=1e-3)
    assert data["friction_law"]["selected"] == "speed"


def test_a_radius_off_by_its_u_leaves_the_test_its_power():
    # L = R - r is free in the speed law's fit: with it fixed, a period 0.6 % off drove mu0
    # and mu1 apart (mu1 +-0.004 s/rad, the test blind to Cross's law)
    setup = room_air(uncertainty=ROOM_AIR + (("cylinder_radius", 0.5e-3),))
    true = setup.replace(cylinder_radius=setup.cylinder_radius + 0.5e-3)
    th, _, _ = eom.solve_reference(math.radians(20.0), 0.0, MU0, T4,
                                   track_radius=true.track_radius,
                                   air=air.coefficients_of(true))
    th = th + np.random.default_rng(2).normal(0.0, 1e-4, T4.size)
    _, _, law = law_of(setup, th)
    assert law.selected == "coulomb"
    assert law.mu1_detectable < 3e-5
    assert abs(law.mu0 - MU0) < 2 * law.mu0_u


def test_measure_model_speed(tmp_path):
    import sys
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from measure_data import make_recording
    from test_measure_cli import _write

    rec = make_recording(160, noise=1.0)
    path = _write(rec, tmp_path)
    out = tmp_path / "out"
    assert main(["measure", str(path), "--setup", str(tmp_path / "setup.toml"), "--background",
                 str(tmp_path / "bg.tif"), "--out", str(out), "--no-progress",
                 "--model", "speed"]) == 0
    fit = json.loads((out / "fit.json").read_text())
    assert fit["model"] == "speed"
    assert fit["mu"] == pytest.approx(0.02, rel=0.05)  # mu0 of a Coulomb truth
    assert fit["friction_law"]["selected"] == "coulomb"


def test_the_study_runs_and_summarises(tmp_path):
    from validation.studies import friction_law as study

    assert study.main(["--out", str(tmp_path), "--part", "coverage", "--scale", "0.01"]) == 0
    s = json.loads((tmp_path / "friction_law.json").read_text())
    assert s["coverage"]["n"] == 2
    row = study.run_case(study.draw_case(5, mu1=3e-4, ball="10mm", seconds=2.0,
                                         noise_px=0.02))
    assert row["selected"] == "speed" and abs(row["z1"]) < 3


def test_the_shipped_study_meets_its_targets_and_draws_the_page_figure(tmp_path):
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    data = json.loads((root / "docs" / "data" / "friction_law.json").read_text())
    level = data["level"]["wall_normal"]["rejected"]
    assert level["n"] >= 400 and abs(level["rate"] - 0.05) <= 0.02
    cov = data["coverage"]
    for key in ("mu0_within_U", "mu1_within_U"):
        assert abs(cov[key]["rate"] - 0.95) <= 0.03 + 1e-9
    spec = importlib.util.spec_from_file_location(
        "friction_law_figure", root / "docs" / "scripts" / "friction_law_figure.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.figure(data, tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 20000


def test_a_trough_tilted_within_its_stated_u_is_not_taken_for_a_speed_law():
    # the axial drift of a trough tilted 0.1 deg along its length takes a share of the
    # resistance that grows where the swing is slow: without the tilt's u the test reads it
    # as a resistance growing with speed; with the lab's tilt_deg_u it does not
    from rollfric.uncertainty.asbuilt import tilted_motion

    level = room_air()
    th, _ = tilted_motion(math.radians(20.0), 0.0, MU0, T4, track_radius=level.track_radius,
                          gravity=level.gravity, tilt=math.radians(0.1),
                          air=air.coefficients_of(level))
    th = th + np.random.default_rng(1).normal(0.0, 2e-5, T4.size)
    assert law_of(level, th)[2].selected == "speed"
    stated = level.replace(uncertainty=level.uncertainty + (("cylinder_tilt",
                                                             math.radians(0.1)),))
    law = law_of(stated, th)[2]
    assert law.selected == "coulomb"
    assert "cylinder.tilt_deg" in [s for s, _ in law.inputs]


def test_a_rendered_coulomb_recording_in_room_air_is_coulomb(tmp_path):
    # the rendered part of the study, one case: synth's frames of Coulomb friction with the
    # fitter's drag law, measured by rollfric.measure; the test keeps Coulomb
    from validation.studies import friction_law as study

    case = study.rendered_cases(0.025)[0]
    row = study.run_rendered(case)
    assert "error" not in row, row.get("error")
    assert row["selected"] == "coulomb" and abs(row["mu_coulomb"] / row["mu0"] - 1) < 0.01
