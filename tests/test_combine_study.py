"""validation.studies.combine: its draws and its summary."""

import numpy as np
import pandas as pd
import pytest

from validation.studies.combine import draw_setup, summarize


def test_releases_share_the_setup_and_differ_in_angle():
    a, b = draw_setup(3, 4), draw_setup(3, 6)
    # the setup's draws come first, so its releases' number does not change them
    for key in ("mu", "true_radius_mm", "true_center_px", "true_fps", "noise_px"):
        assert a[key] == b[key]
    assert len(a["theta0_deg"]) == 4 and len(set(a["theta0_deg"])) == 4
    assert all(6.0 <= abs(t) <= 30.0 for t in a["theta0_deg"])
    assert draw_setup(4, 4)["true_radius_mm"] != a["true_radius_mm"]


def test_summary_fractions_and_birge_tail():
    # 20 setups of N = 4: z known, Birge ratios at chosen chi2(3) quantiles
    z = np.array([0.5] * 15 + [1.5] * 3 + [2.5] * 2)
    rb = np.array([0.3] * 18 + [3.0] * 2)
    df = pd.DataFrame({"z": z, "birge_ratio": rb, "n": 4, "n_suspect": 0,
                       "birge_low": 0.27, "birge_high": 1.77, "u": 1.0, "u_shared": 0.9,
                       "U": 2.0, "mu": 100.0})
    s = summarize(df)
    assert s["within_U"] == pytest.approx(18 / 20)
    assert s["within_u"] == pytest.approx(15 / 20)
    assert s["combined_misses_U"] == 2
    assert s["birge_above_range"] == pytest.approx(2 / 20)
    assert s["birge_below_range"] == 0.0
    assert s["median_shared_fraction"] == pytest.approx(0.9)


@pytest.mark.slow
def test_rendered_releases_combine():
    # two releases rendered by synth and measured by rollfric.measure, combined: the
    # renderer's exact setup leaves the independent part alone
    from validation.studies.combine import run_study

    df, s = run_study(1, 2, rendered=True)
    row = df.iloc[0]
    assert "error" not in row or not isinstance(row["error"], str), row.get("error")
    assert row["n"] == 2 and row["ball"] == "1.58mm"
    assert row["u_shared"] == 0.0 and abs(row["z"]) < 4
