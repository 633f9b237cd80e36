"""validation.track_level: a case measured from the exact projection (no rendering: the lab
gives the trough centre), against known geometry; and the thesis reproduction's tables."""

import math

import numpy as np
import pytest

from validation.case_dict import apply_overrides, small_case_dict
from validation.studies import thesis_error
from validation.track_level import located_centres, measure_track, run_track_case


def _case(**over):
    d = small_case_dict(seconds=1.5)
    d["scenario"]["motion"]["theta0_deg"] = 15.0
    return apply_overrides(d, over)


def test_no_error_recovers_mu_and_the_angles_to_the_locator_noise():
    m = run_track_case(_case(), sigma_px=0.017)
    assert m["stages"] == "track" and m["mode"] == "blind"
    assert abs(m["mu_bias_rel"]) < 2e-4
    # angle noise: sigma (per axis, across the path) / L in px
    L_px = (0.0853 - 0.005) / 0.1343e-3
    assert m["theta_rms_rad"] == pytest.approx(0.017 / L_px, rel=0.15)
    assert m["center_rms_px"] == pytest.approx(0.017 * math.sqrt(2), rel=0.1)


def test_camera_roll_is_the_fitted_offset():
    # a camera rolled by 0.5 deg puts the trough bottom at theta = +0.5 deg: the fit's offset
    tc = measure_track(_case(**{"render.camera.roll_deg": 0.5, "measure.offset": True}))
    assert math.degrees(tc.fit.offset) == pytest.approx(0.5, abs=2e-3)
    assert tc.fit.mu == pytest.approx(0.0079, rel=2e-3)
    # without the offset, the measured angles are the true ones + 0.5 deg
    tc2 = measure_track(_case(**{"render.camera.roll_deg": 0.5, "measure.offset": False}))
    d = tc2.track["theta_rad"].to_numpy() - tc2.truth["theta_rad"].to_numpy()
    assert math.degrees(np.mean(d)) == pytest.approx(0.5, abs=2e-3)


def test_located_centres_are_seeded():
    truth = {"sil_x_px": np.zeros(1000), "sil_y_px": np.zeros(1000)}
    a = located_centres(truth, 0.1, 3)
    b = located_centres(truth, 0.1, 3)
    assert np.array_equal(a[0], b[0]) and np.std(a[0]) == pytest.approx(0.1, rel=0.1)
    assert not np.array_equal(a[0], located_centres(truth, 0.1, 4)[0])


def test_thesis_reproduction_tables_from_a_fixture():
    single = [{"source": "camera roll", "unit": "deg", "plausible": 1.0, "why": "by eye",
               "max_magnitude": 3.0, "magnitude": 0.55, "relative_error": 0.0584,
               "mu_bias_rel": 0.0057},
              {"source": "air drag, Cd (room air)", "unit": "1", "plausible": 4.0,
               "why": "Re", "max_magnitude": 10.0, "magnitude": None,
               "relative_error": 0.0012, "mu_bias_rel": 0.05}]
    ball = {"mu": 0.0079, "target": 0.058372, "single": single,
            "combination": {"relative_error": 0.031, "mu_bias_rel": 0.004},
            "no_error": {"relative_error": 0.0001, "mu_bias_rel": 0.0}}
    md = thesis_error.render_markdown({"meta": {"date": "2026-11-23", "theta0_deg": 20.0,
                                                "seconds": 4.0,
                                                "combination": {"camera roll": 0.3}},
                                       "balls": {"10mm": ball}})
    assert "| camera roll | **0.55 deg** (+0.57 %) | up to 1 deg (by eye) |" in md
    assert "not reached: 0.12 % at 10" in md
    assert "relative error 3.10 %" in md
    # a case the reproduction builds is valid, blind, without the offset
    c = thesis_error.thesis_case("12.69mm")
    assert c["measure"]["offset"] is False and c["scenario"]["motion"]["mu"] == 0.0065
