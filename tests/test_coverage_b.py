"""The second rendered coverage study (``coverage_b``): the first study's grid with fresh draws,
and the report of several studies with their miss counts' binomial tails."""

import functools
import math
import tomllib

import pandas as pd
import pytest
from scipy.stats import binom

from validation import sweep as S
from validation.case import _case_seeded_lab
from validation.lab import standard_normal


@functools.cache
def _cases(name):
    return S.load_sweep(name).cases


def _lab_seeds(name):
    return [_case_seeded_lab(sc.case)["seed"] for sc in _cases(name)]


def test_coverage_b_is_the_first_studys_grid_with_other_render_seeds():
    first = tomllib.loads(S._find_sweep("coverage").read_text())
    second = tomllib.loads(S._find_sweep("coverage_b").read_text())
    assert second["base"] == first["base"]
    assert set(second["grid"]) == set(first["grid"])
    for key, values in first["grid"].items():
        if key != "render.seed":
            assert second["grid"][key] == values, key
    assert set(first["grid"]["render.seed"]).isdisjoint(second["grid"]["render.seed"])
    assert len(_cases("coverage_b")) == len(_cases("coverage")) >= 200


def test_coverage_b_draws_are_not_the_first_studys():
    """lab.seed = "case" hashes the whole case, render.seed included: the 432 cases of both
    studies have 432 different seeds, hence their own as-built trough radius and lab centre."""
    seeds = _lab_seeds("coverage") + _lab_seeds("coverage_b")
    assert len(set(seeds)) == len(seeds) == 432
    for key in ("cylinder.radius_mm", "cylinder.center_px.x"):
        draws = [standard_normal(s, key) for s in seeds]
        assert len(set(draws)) == len(draws)
    # and the same case gives the same seed (same bytes)
    assert _lab_seeds("coverage_b") == _lab_seeds("coverage_b")


def test_misses_and_their_binomial_tails():
    from validation.studies.coverage import MISS_PROBABILITY, misses

    assert MISS_PROBABILITY[2.0] == pytest.approx(0.0455003, abs=1e-7)
    assert MISS_PROBABILITY[1.0] == pytest.approx(0.3173105, abs=1e-7)
    z = [0.5, -1.5, 2.5, 0.1, -0.2, float("nan"), -3.0, 1.2]
    m = misses(z, "blind")
    assert m["blind_misses_U"] == 2 and m["blind_misses_u"] == 4
    p = MISS_PROBABILITY[2.0]
    # P(X >= 2) for 7 cases, by hand
    assert m["blind_misses_U_p_at_least"] == pytest.approx(
        1 - (1 - p) ** 7 - 7 * p * (1 - p) ** 6, rel=1e-9)
    assert m["blind_misses_U_p_at_most"] == pytest.approx(binom.cdf(2, 7, p), rel=1e-12)
    assert m["blind_misses_U_expected"] == pytest.approx(7 * p)


def _results(seed, z):
    return pd.DataFrame([{"case_id": f"s{seed}c{i}", "status": "ok", "mu_recovered": 0.008,
                          "U_mu": 1e-4, "z_budget": v, "t_budget_s": 0.1, "render.seed": seed,
                          "scenario.motion.theta0_deg": 8.0 + i,
                          "z_stat": 2 * v, "mu_true": 0.008, "mu_stderr": 1e-4}
                         for i, v in enumerate(z)])


def test_two_studies_reported_together(tmp_path):
    """``--from-sweep A B --out DIR``: the cases of both, split by study, each matched with
    its own oracle run; the combined fractions' binomial standard error."""
    import json

    from validation.studies.coverage import main

    za, zb = [0.5, -2.5, 0.1, 1.5], [0.2, 0.3, -0.4, 3.0, 0.9]
    for name, seed, z in (("a", 0, za), ("b", 3, zb)):
        for sub, zz in ((name, z), (f"{name}_oracle", [v / 2 for v in z])):
            (tmp_path / sub).mkdir()
            _results(seed, zz).to_parquet(tmp_path / sub / "results.parquet")
    out = tmp_path / "both"
    assert main(["--from-sweep", str(tmp_path / "a"), str(tmp_path / "b"),
                 "--oracle-sweep", str(tmp_path / "a_oracle"), str(tmp_path / "b_oracle"),
                 "--out", str(out)]) == 0
    s = json.loads((out / "coverage.json").read_text())
    assert s["cases"] == 9 and s["blind_misses_U"] == 2
    assert s["blind_within_U"] == pytest.approx(7 / 9)
    assert s["blind_within_U_se"] == pytest.approx(math.sqrt(7 / 9 * 2 / 9 / 9))
    assert s["cases[study=a]"] == 4 and s["within_U[study=b]"] == pytest.approx(0.8)
    # the oracle's z_stat is twice its z_budget (z / 2): matched within each study
    assert s["oracle_within_2u_stat"] == pytest.approx(7 / 9)
    assert s["oracle_within_2u_budget"] == 1.0
    assert (out / "coverage.png").is_file()
    with pytest.raises(SystemExit):  # several studies need --out
        main(["--from-sweep", str(tmp_path / "a"), str(tmp_path / "b")])


def test_blind_error_split_into_the_setups_part_and_the_rest_on_the_same_recording():
    """from_sweep with an oracle run: (blind mu - oracle mu) / u_mu is the setup's part of the
    blind error, (oracle mu - truth) / u_mu the rest; the summary compares the setup's part
    with the budget's own linear prediction (z_linear), case by case."""
    from validation.studies.coverage import from_sweep, summarize

    n = 6
    seeds = list(range(n))
    mu_true = [0.005] * n
    mu_o = [0.005 + 1e-6 * k for k in range(n)]  # the oracle's: truth + a small rest
    setup = [2e-4, -1e-4, 0.5e-4, 3e-4, -2.5e-4, 1e-4]  # the setup's part of the error
    u = [1e-4, 2e-4, 1e-4, 1.5e-4, 1e-4, 2e-4]
    mu_b = [o + d for o, d in zip(mu_o, setup, strict=True)]
    lin = [d / uu + 0.1 * (-1) ** k for k, (d, uu) in enumerate(zip(setup, u, strict=True))]
    blind = pd.DataFrame({"case_id": [f"b{k}" for k in seeds], "status": "ok",
                          "render.seed": seeds, "mu_recovered": mu_b, "mu_true": mu_true,
                          "u_mu": u, "U_mu": [2 * v for v in u],
                          "z_budget": [(b - t) / uu
                                       for b, t, uu in zip(mu_b, mu_true, u, strict=True)],
                          "z_linear": lin, "t_budget_s": 0.1, "t_measure_s": 1.0})
    oracle = pd.DataFrame({"case_id": [f"o{k}" for k in seeds], "status": "ok",
                           "render.seed": seeds[::-1], "mu_recovered": mu_o[::-1],
                           "mu_true": mu_true, "z_stat": 0.0, "z_budget": 0.0,
                           "mu_stderr": 1e-5})
    df = from_sweep(blind, oracle)
    for k in seeds:  # matched on the swept key, not on the row order
        assert df["z_setup"][k] == pytest.approx(setup[k] / u[k])
        assert df["z_rest"][k] == pytest.approx(1e-6 * k / u[k])
    s = summarize(df)
    d = [setup[k] / u[k] - lin[k] for k in seeds]
    assert s["setup_minus_linear_mean"] == pytest.approx(sum(d) / n)
    assert s["setup_minus_linear_sd"] == pytest.approx(pd.Series(d).std())
    assert s["rest_part_rms"] == pytest.approx(
        math.sqrt(sum((1e-6 * k / u[k]) ** 2 for k in seeds) / n))
    assert 0.9 < s["setup_vs_linear_corr"] < 1.0
