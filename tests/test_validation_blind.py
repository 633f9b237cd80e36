"""Blind mode: the lab's nominal setup against the as-built truth (validation.lab), and one
blind case end to end (trough centre from the contour, nominal setup)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from validation import case as C
from validation import case_dict as CD
from validation import e2e
from validation import lab as L


def test_default_case_is_blind_with_the_scenario_as_nominal_and_no_center():
    c = C.case_from_dict(CD.default_case_dict())
    assert c.mode == "blind" and not c.oracle
    s = c.lab_setup_dict()
    assert "center_px" not in s["cylinder"]
    assert s["cylinder"]["radius_mm"] == pytest.approx(c.scenario.cylinder_radius * 1e3)
    assert s["camera"]["pixel_size_mm"] == pytest.approx(c.scene.camera.pixel_size * 1e3)
    assert all(v == 0 for v in c.lab.errors().values())
    o = C.case_from_dict(CD.apply_overrides(CD.default_case_dict(), {"measure.oracle": True}))
    assert o.mode == "oracle" and o.case_id != c.case_id


def test_nominal_differs_from_as_built_by_case_keys():
    d = CD.apply_overrides(CD.default_case_dict(), {
        "scenario.cylinder.radius_mm": 85.8, "lab.cylinder.radius_mm": 85.3,
        "lab.ball.diameter_mm": 10.01, "lab.center_error_px": [0.5, -0.25]})
    c = C.case_from_dict(d)
    assert c.scenario.cylinder_radius == pytest.approx(0.0858)  # the truth simulated
    s = c.lab_setup_dict()
    assert s["cylinder"]["radius_mm"] == 85.3 and s["ball"]["diameter_mm"] == 10.01
    cx, cy = c.scene.camera.center_px
    assert s["cylinder"]["center_px"] == [cx + 0.5, cy - 0.25]
    assert c.lab.errors()["cylinder.radius_mm"] == pytest.approx(-0.5)
    assert c.lab.errors()["ball.diameter_mm"] == pytest.approx(0.01)


def test_as_built_drawn_from_the_tolerances_with_the_case_seed():
    toml = C.case_from_dict(CD.default_case_dict()).scenario.to_toml_dict()
    table = {"draw": True, "cylinder": {"radius_mm": 85.3, "radius_mm_u": 0.2},
             "camera": {"pixel_size_mm_u": 0.0004}}
    a, over_a = L.parse_lab(table, toml, default_seed=7)
    b, _ = L.parse_lab(table, toml, default_seed=7)
    c, _ = L.parse_lab(table, toml, default_seed=8)
    assert a.asbuilt == b.asbuilt and a.asbuilt != c.asbuilt
    assert set(over_a) == {"cylinder.radius_mm", "camera.pixel_size_mm"}
    assert a.nominal["cylinder.radius_mm"] == 85.3  # the lab still types the nominal
    assert a.asbuilt["ball.diameter_mm"] == 10.0  # no tolerance, no draw
    # each key its own stream: adding a tolerance elsewhere leaves this draw alone
    more = dict(table, ball={"diameter_mm_u": 0.001})
    a2, _ = L.parse_lab(more, toml, default_seed=7)
    assert a2.asbuilt["cylinder.radius_mm"] == a.asbuilt["cylinder.radius_mm"]
    # the draws are N(nominal, u): 2000 seeds
    r = np.array([L.parse_lab(table, toml, default_seed=s)[0].asbuilt["cylinder.radius_mm"]
                  for s in range(2000)])
    assert abs(r.mean() - 85.3) < 4 * 0.2 / math.sqrt(2000)
    assert r.std() == pytest.approx(0.2, rel=0.08)
    # through the case: the simulated scenario and the camera get the drawn values
    d = CD.apply_overrides(CD.default_case_dict(), {"lab": table, "render.seed": 7})
    case = C.case_from_dict(d)
    assert case.scenario.cylinder_radius * 1e3 == pytest.approx(a.asbuilt["cylinder.radius_mm"])
    assert case.scene.camera.pixel_size * 1e3 == pytest.approx(
        a.asbuilt["camera.pixel_size_mm"])
    assert case.lab_setup_dict()["cylinder"]["radius_mm"] == 85.3
    # without draw the tolerances are only stated: the truth is the scenario's
    d = CD.apply_overrides(d, {"lab.draw": False})
    assert C.case_from_dict(d).scenario.cylinder_radius == pytest.approx(0.0853)


def test_case_seed_draws_anew_in_every_case_and_the_same_in_the_same_case():
    """lab.seed = "case": a sweep's cases that differ only in lighting get their own as-built
    setups (with the default seed they would share render.seed's one draw)."""
    table = {"draw": True, "seed": "case", "cylinder": {"radius_mm": 85.3, "radius_mm_u": 0.5}}

    def radius(lighting):
        d = CD.apply_overrides(CD.default_case_dict(), {"lab": table, "render.lighting": lighting})
        return C.case_from_dict(d).scenario.cylinder_radius

    assert radius("thesis") == radius("thesis")
    assert radius("thesis") != radius("harsh")
    shared = dict(table, seed=0)
    same = [C.case_from_dict(CD.apply_overrides(CD.default_case_dict(), {
        "lab": shared, "render.lighting": li})).scenario.cylinder_radius
            for li in ("thesis", "harsh")]
    assert same[0] == same[1]
    # the shipped rendered coverage study: every case its own as-built trough radius
    from validation.sweep import load_sweep
    cases = load_sweep("coverage").cases
    radii = {C.case_from_dict(sc.case).scenario.cylinder_radius for sc in cases}
    assert len(cases) >= 200 and len(radii) == len(cases)


@pytest.mark.parametrize("key,value,match", [
    ("lab.colour", 1, "lab.colour"),
    ("lab.cylinder.diameter_mm", 1.0, "lab.cylinder.diameter_mm"),
    ("lab.cylinder.radius_mm", -3.0, "radius_mm"),
    ("lab.center_error_px", [1.0], "center_error_px"),
    ("lab.draw", "yes", "lab.draw"),
    ("lab.ball.diameter_mm", 200.0, "diameter"),
    ("measure.oracle", 1, "oracle"),
])
def test_bad_lab_keys_are_refused(key, value, match):
    with pytest.raises(C.CaseError, match=match):
        C.case_from_dict(CD.apply_overrides(CD.default_case_dict(), {key: value}))


def _whole_trough_case(seconds: float) -> dict:
    """A coarse camera (0.4 mm/px, 320 x 256 px) that sees the trough's whole lower half."""
    d = CD.default_case_dict()
    d["name"] = "blind-small"
    d["scenario"]["motion"].update(theta0_deg=8.0, seconds=seconds)
    d["scenario"]["camera"] = {"pixel_size_mm": 0.4}
    d["render"].update(shadows=False, camera={"width": 320, "height": 256,
                                              "center_px": [160.3, 20.6]})
    return d


def test_blind_case_finds_the_trough_centre_from_the_contour(tmp_path):
    r = e2e.run_case(_whole_trough_case(0.3), recording=tmp_path / "rec.zarr",
                     render_workers=1)
    m = r.metrics
    assert m["mode"] == "blind" and not m["lab_center_measured"]
    assert r.setup.center_px is None and "center_px" not in r.setup_dict["cylinder"]
    assert "contour" in r.track_info.center_source
    # the contour's centre: a fraction of a 0.4 mm pixel off the axis
    assert abs(m["trough_center_err_x_px"]) < 0.2 and abs(m["trough_center_err_y_px"]) < 0.3
    assert m["found_fraction"] == 1.0 and m["center_rms_px"] < 0.1
    assert abs(m["mu_bias_rel"]) < 0.02


def test_camera_roll_is_the_fitted_angle_offset(tmp_path):
    """A camera rolled by 0.5 deg: the trough bottom appears at theta = +0.5 deg; the fit's
    angle offset (on by default: three turning points in 1.2 s) finds it and keeps mu."""
    from rollfric.fit.estimate import fit_mu

    d = CD.small_case_dict(seconds=1.2)
    d["render"]["shadows"] = False
    d["render"]["camera"]["roll_deg"] = 0.5
    r = e2e.run_case(d, recording=tmp_path / "rec.zarr", render_workers=1)
    m = r.metrics
    assert m["camera_roll_deg"] == 0.5 and m["offset_fitted"]
    assert m["center_rms_px"] < 0.1  # the render and its truth agree under roll
    assert m["theta_bias_rad"] == pytest.approx(math.radians(0.5), abs=math.radians(0.01))
    assert m["fit_offset_rad"] == pytest.approx(math.radians(0.5), abs=math.radians(0.01))
    t, th = r.track["t_s"].to_numpy(), r.track["theta_rad"].to_numpy()
    off = fit_mu(t, th, r.setup, offset=False)
    bias_off = off.mu / 0.0079 - 1
    assert abs(m["mu_bias_rel"]) < 0.005
    assert bias_off > abs(m["mu_bias_rel"]) + 0.003, (bias_off, m["mu_bias_rel"])
