"""validation.studies.redraw: fresh lab draws on located centres (the coverage of the budget
without the
luck of one draw per case), checked against the known as-built setup and the measurement's
own path at the track level (no rendering)."""

import math

import numpy as np
import pytest

from validation.case import case_from_dict
from validation.case_dict import apply_overrides, small_case_dict
from validation.studies.redraw import redraw_case, redrawn_lab, redrawn_setup, refit, summarize


def _case(seed=7, **over):
    d = small_case_dict(seconds=1.0)
    d["scenario"]["environment"] = {"air_density_kg_m3": 0.0}  # airless, as the study was made
    d["lab"] = {"draw": True, "seed": seed, "center_px_u": [2.0, 2.0],
                "cylinder": {"radius_mm": 85.3, "radius_mm_u": 0.5},
                "ball": {"diameter_mm_u": 0.005},
                "camera": {"fps_u": 0.05, "pixel_size_mm_u": 0.0003}}
    return case_from_dict(apply_overrides(d, over))


def test_draw_zero_is_the_studys_lab_and_fresh_draws_are_seeded():
    case = _case()
    assert redrawn_lab(case, 0) is case.lab
    a, b = redrawn_lab(case, 3), redrawn_lab(_case(), 3)
    assert a == b  # same case, same draw: same lab
    assert a.nominal != redrawn_lab(case, 4).nominal
    assert a.asbuilt == case.lab.asbuilt  # the recording's truth is not redrawn
    # a key without a stated u keeps the as-built value (the lab knows it exactly)
    assert a.nominal["ball.mass_g"] == case.lab.asbuilt["ball.mass_g"]


def test_fresh_draws_scatter_around_the_asbuilt_values_with_the_stated_u():
    case = _case(seed=11)
    n = 600
    labs = [redrawn_lab(case, k) for k in range(1, n + 1)]
    for key, u in (("cylinder.radius_mm", 0.5), ("camera.fps", 0.05),
                   ("ball.diameter_mm", 0.005)):
        e = np.array([lab.nominal[key] - lab.asbuilt[key] for lab in labs]) / u
        assert abs(e.mean()) < 4.0 / math.sqrt(n), key
        assert e.std() == pytest.approx(1.0, abs=4.0 / math.sqrt(2 * n)), key
    for i in (0, 1):
        e = np.array([lab.center_error_px[i] for lab in labs]) / 2.0
        assert abs(e.mean()) < 4.0 / math.sqrt(n)
        assert e.std() == pytest.approx(1.0, abs=4.0 / math.sqrt(2 * n))
    # the setup rollfric gets: the true centre (the camera's) + the drawn error, with its u
    s = redrawn_setup(case, 5)
    cx, cy = case.scene.camera.center_px
    assert s.center_px == pytest.approx((cx + labs[4].center_error_px[0],
                                         cy + labs[4].center_error_px[1]))
    assert s.cylinder_radius == pytest.approx(labs[4].nominal["cylinder.radius_mm"] * 1e-3)
    assert s.u("cylinder_radius") == pytest.approx(0.5e-3)


def test_draw_zero_reproduces_the_measurement_and_fresh_draws_move_mu_as_the_budget_says():
    case = _case(seed=3)
    rows = redraw_case(case, None, 2)
    assert [r["draw"] for r in rows] == [0, 1, 2]
    # draw 0 re-done from the located centres is the study's own fit (same path)
    assert rows[0]["mu"] == pytest.approx(rows[0]["mu_study"], rel=1e-9)
    for r in rows:
        assert r["z"] == pytest.approx((r["mu"] - r["mu_true"]) / r["u_mu"])
        assert r["within_U"] == float(abs(r["z"]) <= 2.0)
    # a fresh draw is a new lab: a new centre error, a new mu
    assert rows[1]["e_center_x"] != rows[0]["e_center_x"]
    assert rows[1]["mu"] != rows[0]["mu"]


def test_refit_with_the_asbuilt_setup_recovers_mu_and_a_radius_error_acts_by_its_row():
    from types import SimpleNamespace

    from rollfric.uncertainty.budget import budget
    from rollfric.uncertainty.measured import measurement_from_track
    from validation.track_level import measure_track, oracle_setup

    case = _case(seed=5)
    tc = measure_track(case, sigma_px=0.0)  # the exact projection, no locator noise
    info = SimpleNamespace(center_px=tc.center_px, undistorted=False, setup=tc.setup,
                           angle="atan2", times="frame / camera.fps")
    true = oracle_setup(case)
    fit, _ = refit(tc.track, info, true, False)
    assert fit.mu == pytest.approx(case.scenario.mu, rel=2e-4)
    # the lab's setup with only the radius off by +0.4 mm: mu moves by the radius row's
    # sensitivity x 0.4 mm (first order; the budget's own coefficient)
    off = true.replace(cylinder_radius=true.cylinder_radius + 0.4e-3,
                       uncertainty=(("cylinder_radius", 0.5e-3),))
    fit_off, b = refit(tc.track, info, off, False)
    c = next(r.sensitivity for r in b.rows if r.source == "cylinder.radius_mm")
    assert fit_off.mu - fit.mu == pytest.approx(c * 0.4, rel=0.05)
    # and refit is the budget's own re-evaluation: the same fit as measurement_from_track's
    m = measurement_from_track(tc.track, SimpleNamespace(**{**vars(info), "setup": off}))
    assert budget(m, fit_off).u_mu == pytest.approx(b.u_mu, rel=1e-9)


def test_summary_counts_the_misses_of_the_studys_and_the_fresh_draws():
    import pandas as pd

    df = pd.DataFrame({"draw": [0, 0, 1, 1, 2, 2], "z": [0.5, 2.5, -1.5, 0.2, -3.0, 0.9]})
    s = summarize(df)
    assert s["draw 0"]["n"] == 2 and s["draw 0"]["outside_U"] == 1
    assert s["fresh"]["n"] == 4 and s["fresh"]["outside_U"] == 1
    assert s["fresh"]["outside_u"] == 2 and s["all"]["outside_U"] == 2
    assert s["all"]["within_U"] == pytest.approx(4 / 6)
    assert s["fresh"]["outside_U_expected"] == pytest.approx(4 * 0.0455003, rel=1e-5)


def test_cli_bad_input_and_report_of_earlier_runs(tmp_path, capsys):
    import pandas as pd

    from validation.studies.redraw import main

    assert main(["--out", str(tmp_path / "a")]) == 2  # neither runs nor a report
    assert not (tmp_path / "a").exists()
    assert main(["--report", str(tmp_path), "--out", str(tmp_path / "b")]) == 2  # no csv
    run = tmp_path / "run"
    run.mkdir()
    pd.DataFrame({"study": ["s1"] * 4 + ["s2"] * 2, "draw": [0, 1, 0, 1, 0, 1],
                  "z": [0.1, 2.2, -0.5, 0.3, 1.5, -0.2]}).to_csv(run / "redraw.csv",
                                                                 index=False)
    assert main(["--report", str(run), "--out", str(run)]) == 2  # --out exists
    assert main(["--report", str(run), "--out", str(tmp_path / "rep")]) == 0
    import json

    s = json.loads((tmp_path / "rep" / "redraw.json").read_text())
    assert s["recordings"] == 3 and s["draws"] == 1
    assert s["all studies"]["fresh"]["outside_U"] == 1
    assert s["s2"]["draw 0"]["outside_u"] == 1
    assert "## s1" in (tmp_path / "rep" / "summary.md").read_text()
