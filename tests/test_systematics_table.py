"""validation.studies.systematics: the error-budget table from a small fixture of the study's rows,
and
the track-level sweep's plumbing (no rendering)."""

import json

import pandas as pd
import pytest

from validation.studies import error_sources as es
from validation.studies import systematics as st
from validation.sweep import sweep_from_dict


def _row(source, mag, bias, corrected=None, unit="mm", rel=0.001, stages="track"):
    return {"case_id": f"{source[:3]}{mag}{corrected}", "source": source, "magnitude": mag,
            "unit": unit, "corrected": corrected, "stages": stages, "mu_bias_rel": bias,
            "fit_relative_error": rel, "theta_rms_rad": 1e-5}


RADIUS = "trough radius as built - nominal"
ROLL = "camera roll"
PERSP = "pinhole camera at working distance"


def test_crossing_interpolates_from_the_origin():
    # bias 0.01 per mm: 0.1 % at 0.1 mm, 1 % at 1 mm (between the swept 0.5 and 2 mm)
    pts = [(-0.5, -0.005), (0.5, 0.005), (2.0, 0.02)]
    assert st.crossing(pts, 0.001, True) == ("at", pytest.approx(0.1))
    assert st.crossing(pts, 0.01, True) == ("at", pytest.approx(1.0))
    # never reached within the range; reached before the first point without an origin
    assert st.crossing([(1.0, 1e-4), (2.0, 2e-4)], 0.001, True) == ("above", 2.0)
    assert st.crossing([(1.0, 0.02), (2.0, 0.04)], 0.01, False) == ("below", 1.0)
    assert st.crossing([(1.0, 0.04), (2.0, 0.02)], 0.01, False) == ("everywhere", 2.0)
    assert st.crossing([(1.0, 0.004), (2.0, 0.002)], 0.01, False) == ("nowhere", 1.0)
    # a bias that falls as the magnitude grows (a working distance): where it drops to the level
    kind, v = st.crossing([(0.2, 0.03), (0.5, 0.012), (1.0, 0.004)], 0.01, False)
    assert kind == "decreasing" and v == pytest.approx(0.5 + 0.5 * 0.002 / 0.008)


def test_budget_table_and_markdown_from_a_fixture_json(tmp_path):
    rows = [_row("none", None, 5e-5, stages="track"),
            _row(RADIUS, -1.0, 0.0098), _row(RADIUS, -0.2, 0.002), _row(RADIUS, 0.3, -0.003),
            _row(ROLL, 0.2, 0.0026, corrected=False, unit="deg", rel=0.02),
            _row(ROLL, 1.0, 0.0137, corrected=False, unit="deg", rel=0.09),
            _row(ROLL, 0.5, -0.0001, corrected=True, unit="deg"),
            _row(ROLL, 2.0, 0.0002, corrected=True, unit="deg"),
            _row(PERSP, 0.3, 0.004, unit="m"), _row(PERSP, 1.0, 0.0004, unit="m")]
    path = tmp_path / "systematics.json"
    failed = [{"params": {"render.camera.working_distance": 0.3}, "stages": "track",
               "error": "ContourError: hidden"}]
    path.write_text(json.dumps({"meta": {"date": "2026-11-23", "n_cases": len(rows),
                                         "note": "fixture", "failed": failed}, "rows": rows}))
    data = json.loads(path.read_text())
    table = st.budget_table(data["rows"])
    assert [(t["source"], t["corrected"]) for t in table] == [
        (RADIUS, None), (ROLL, False), (ROLL, True), (PERSP, None)]
    radius = table[0]
    # |bias| 0.01 per mm from the origin to 0.2 mm: 0.1 % at 0.1 mm; 1 % not within 1 mm
    assert radius["levels"]["0.001"] == ("at", pytest.approx(0.1))
    assert radius["levels"]["0.01"] == ("above", 1.0)
    roll_off = table[1]
    assert roll_off["levels"]["0.001"][1] == pytest.approx(0.2 * 0.001 / 0.0026)
    assert roll_off["levels"]["0.01"][1] == pytest.approx(0.2 + 0.8 * (0.01 - 0.0026) / 0.0111)
    assert table[2]["levels"]["0.001"] == ("above", 2.0)
    assert table[3]["levels"]["0.001"] == ("decreasing", pytest.approx(0.3 + 0.7 * 3 / 3.6))
    md = st.render_markdown(data)
    lines = [ln for ln in md.splitlines() if ln.startswith("| ")]
    assert len(lines) == 1 + len(table)  # header + one line per source and correction
    assert "| camera roll | off | 0.077 deg | 0.73 deg |" in md
    assert "| camera roll | on | not reached (> 2 deg) |" in md
    assert "| below 0.88 m | not reached (down to 0.3 m) |" in md
    assert "mu bias +0.0050 %" in md
    assert ("Refused by rollfric (track): render.camera.working_distance = 0.3: "
            "ContourError: hidden") in md


def test_classify_names_the_source_and_the_correction():
    swept = ["lab.center_error_px", "measure.offset", "render.camera.roll_deg",
             "trough.ellipse"]
    assert es.classify({"lab.center_error_px": "[2.0, 0.0]", "measure.offset": False},
                       swept)[1:] == (2.0, "px", False)
    name, mag, _, corr = es.classify({"lab.center_error_px": "[0.0, 5.0]"}, swept)
    assert (name, mag, corr) == ("trough centre measured by the lab, y error", 5.0, None)
    assert es.classify({"lab_err_cylinder_radius_mm": -0.5, "lab_cylinder_radius_mm": 85.3},
                       swept)[:2] == (RADIUS, 0.5)
    assert es.classify({"lab_err_camera_fps": -1.0, "lab_camera_fps": 1000.0},
                       swept)[1] == pytest.approx(1000.0)
    # a source this module does not know: named after its key, the first number its magnitude
    assert es.classify({"trough.ellipse": "[0.2, 0.0]"}, swept) == (
        "trough.ellipse", 0.2, "", None)
    assert es.classify({"render.seed": 0}, ["render.seed"])[0] == "none"


def test_study_rows_from_a_sweep_table():
    df = pd.DataFrame([
        {"case_id": "a", "status": "ok", "stages": "track", "render.camera.roll_deg": 0.5,
         "measure.offset": False, "mu_bias_rel": 0.0067, "fit_relative_error": 0.046,
         "theta_rms_rad": 8.7e-3, "mu_stderr": 1e-5, "mu_true": 0.0079},
        {"case_id": "b", "status": "failed", "stages": "full"}])
    rows = st.study_rows(df, ["render.camera.roll_deg", "measure.offset"])
    assert len(rows) == 1
    assert rows[0]["source"] == ROLL and rows[0]["corrected"] is False
    assert rows[0]["mu_bias_rel"] == 0.0067 and rows[0]["stages"] == "track"


def test_a_case_may_name_its_own_stages():
    spec = sweep_from_dict({"sweep": {"mode": "list", "stages": "track"},
                            "cases": [{"render": {"seed": 0}},
                                      {"render": {"seed": 0}, "stages": "full"}]})
    assert [c.stages for c in spec.cases] == ["track", "full"]
    assert spec.cases[0].case_id != spec.cases[1].case_id  # same case, measured otherwise
    assert "stages" not in spec.swept
    # a key the track level does not represent (the ball's image, its timing): rendered
    spec = sweep_from_dict({"sweep": {"mode": "list", "stages": "track"},
                            "cases": [{"render": {"motion_blur": 4}},
                                      {"render": {"camera": {"roll_deg": 0.5}}}]})
    assert [c.stages for c in spec.cases] == ["full", "track"]
    with pytest.raises(Exception, match="stages"):
        sweep_from_dict({"sweep": {"mode": "list"},
                         "cases": [{"render": {"seed": 0}, "stages": "quick"}]})
