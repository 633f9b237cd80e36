"""rollfric combine: releases combined, against hand-made fit.json files with known rows."""

import json
import math

import numpy as np
import pytest
from scipy.stats import chi2

from rollfric.cli.main import main
from rollfric.errors import InputError
from rollfric.uncertainty.combine import birge_range, combine_files

SETUP = {"cylinder": {"radius_mm": 85.3, "radius_mm_u": 0.5},
         "ball": {"diameter_mm": 10.0, "mass_g": 4.07612},
         "camera": {"fps": 1000.0, "fps_u": 0.05, "pixel_size_mm": 0.1343}}


def fit_json(path, mu, u_stat, *, radius=(5e-5, 1.0), fps=(3e-5, -1.0), center=None,
             setup=SETUP, quality="ok", extra=()):
    """A fit.json with a statistical row u_stat and shared rows (u_mu, sign of sensitivity)."""
    rows = [{"source": "statistical", "value": None, "u": u_stat, "sensitivity": 1.0,
             "u_mu": u_stat},
            {"source": "cylinder.radius_mm", "value": 85.3, "u": 0.5,
             "sensitivity": radius[1] * radius[0] / 0.5, "u_mu": radius[0]},
            {"source": "camera.fps", "value": 1000.0, "u": 0.05,
             "sensitivity": fps[1] * fps[0] / 0.05, "u_mu": fps[0]}]
    if center is not None:  # (u_mu, sign, value)
        rows.append({"source": "cylinder.center_px[x]", "value": center[2], "u": 0.3,
                     "sensitivity": center[1] * center[0] / 0.3, "u_mu": center[0]})
    rows += list(extra)
    u = math.sqrt(sum(r["u_mu"] ** 2 for r in rows))
    data = {"mu": mu, "mu_stderr": u_stat, "method": "lsq", "n_samples": 4000, "u_mu": u,
            "U_mu": 2 * u, "coverage_factor": 2.0, "uncertainty_budget": rows,
            "quality": quality, "quality_reasons": [] if quality == "ok" else
            [{"code": "residual", "message": "the residual is not white"}]}
    if setup is not None:
        data["setup"] = setup
    path.write_text(json.dumps(data))
    return str(path)


def three(tmp_path, **kw):
    mus, us = (0.010000, 0.010010, 0.009995), (1e-5, 2e-5, 1e-5)
    return [fit_json(tmp_path / f"fit{i}.json", m, u, **kw)
            for i, (m, u) in enumerate(zip(mus, us, strict=True))]


def test_weighted_mean_and_its_parts_exactly(tmp_path):
    c, warnings = combine_files(three(tmp_path))
    # weights 1/u^2: 4/9, 1/9, 4/9
    assert [r["weight"] for r in c.runs] == pytest.approx([4 / 9, 1 / 9, 4 / 9], rel=1e-12)
    assert c.mu == pytest.approx((4 * 0.010000 + 0.010010 + 4 * 0.009995) / 9, rel=1e-13)
    assert c.u_independent == pytest.approx(1 / 150_000, rel=1e-12)  # (1e10 + 2.5e9 + 1e10)^-1/2
    assert c.u_shared == pytest.approx(math.hypot(5e-5, 3e-5), rel=1e-12)
    assert c.mu_u == pytest.approx(math.sqrt((1 / 150_000) ** 2 + 5e-5**2 + 3e-5**2), rel=1e-12)
    assert c.U_mu == pytest.approx(2 * c.mu_u, rel=1e-15)
    chi = sum((m - c.mu) ** 2 / u**2 for m, u in zip((0.010000, 0.010010, 0.009995),
                                                     (1e-5, 2e-5, 1e-5), strict=True))
    assert c.chi2 == pytest.approx(chi, rel=1e-9)
    assert c.birge_ratio == pytest.approx(math.sqrt(chi / 2), rel=1e-9)
    assert c.scale == 1.0 and c.quality == "ok" and not warnings


def test_birge_range_from_chi2_quantiles():
    lo, hi = birge_range(3)
    assert lo == pytest.approx(math.sqrt(-2 * math.log(1 - 0.025) / 2), rel=1e-9)  # chi2(2) cdf
    assert hi == pytest.approx(math.sqrt(-2 * math.log(0.025) / 2), rel=1e-9)
    lo, hi = birge_range(11)
    assert (lo, hi) == pytest.approx((math.sqrt(chi2.ppf(0.025, 10) / 10),
                                      math.sqrt(chi2.ppf(0.975, 10) / 10)), rel=1e-12)


@pytest.mark.parametrize("n", [2, 10])
def test_shared_part_does_not_average_down(tmp_path, n):
    paths = [fit_json(tmp_path / f"f{i}.json", 0.01, 1e-5) for i in range(n)]
    c, _ = combine_files(paths)
    assert c.u_independent == pytest.approx(1e-5 / math.sqrt(n), rel=1e-12)
    assert c.u_shared == pytest.approx(math.hypot(5e-5, 3e-5), rel=1e-12)  # as one run's
    assert c.mu_u == pytest.approx(math.sqrt(1e-10 / n + 5e-5**2 + 3e-5**2), rel=1e-12)


def test_common_input_with_opposite_sensitivities_cancels(tmp_path):
    # releases to the left and to the right: a common centre error moves them oppositely
    a = fit_json(tmp_path / "a.json", 0.01, 1e-5, center=(4e-5, 1.0, 640.0))
    b = fit_json(tmp_path / "b.json", 0.01, 1e-5, center=(4e-5, -1.0, 640.0))
    c, _ = combine_files([a, b])
    row = next(r for r in c.shared_rows if r["source"] == "cylinder.center_px[x]")
    assert row["u_mu"] == pytest.approx(0.0, abs=1e-18)
    # the centre found anew in each recording (values differ): not below independent errors
    a = fit_json(tmp_path / "c.json", 0.01, 1e-5, center=(4e-5, 1.0, 640.0))
    b = fit_json(tmp_path / "d.json", 0.01, 1e-5, center=(4e-5, -1.0, 640.4))
    c, _ = combine_files([a, b])
    row = next(r for r in c.shared_rows if r["source"] == "cylinder.center_px[x]")
    assert row["u_mu"] == pytest.approx(math.sqrt(2) * 0.5 * 4e-5, rel=1e-12)


def test_scattered_releases_widen_the_independent_part(tmp_path):
    mus = (0.0100, 0.0101, 0.0099, 0.01005)
    paths = [fit_json(tmp_path / f"s{i}.json", m, 1e-5) for i, m in enumerate(mus)]
    c, _ = combine_files(paths)
    mean = np.mean(mus)
    rb = math.sqrt(sum((m - mean) ** 2 for m in mus) / 1e-10 / 3)
    assert c.birge_ratio == pytest.approx(rb, rel=1e-9)
    assert rb > c.birge_range[1]
    assert c.u_independent == pytest.approx(rb * 1e-5 / 2, rel=1e-9)
    assert c.mu_u == pytest.approx(math.sqrt((rb * 5e-6) ** 2 + 5e-5**2 + 3e-5**2), rel=1e-9)
    assert [r["code"] for r in c.quality_reasons] == ["birge_ratio"]


def test_cli_writes_combined_json_and_exit_codes(tmp_path, capsys):
    out = tmp_path / "combined.json"
    assert main(["combine", *three(tmp_path), "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    for key in ("mu", "mu_u", "U_mu", "u_shared", "u_independent", "n", "runs", "birge_ratio",
                "birge_range", "quality_reasons", "shared_budget"):
        assert key in data
    assert data["n"] == 3 and data["quality"] == "ok"
    assert "combined 3 releases" in capsys.readouterr().out
    # an existing --out without --overwrite: refused, left alone
    before = out.read_text()
    assert main(["combine", *three(tmp_path), "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err and out.read_text() == before
    # scattered: written, exit 3, the reason on stderr
    paths = [fit_json(tmp_path / f"s{i}.json", m, 1e-5)
             for i, m in enumerate((0.0100, 0.0101, 0.0099))]
    assert main(["combine", *paths, "--out", str(out), "--overwrite"]) == 3
    assert "[birge_ratio]" in capsys.readouterr().err
    assert json.loads(out.read_text())["quality"] == "suspect"


def test_refusals_name_the_file(tmp_path, capsys):
    good = three(tmp_path)
    other = fit_json(tmp_path / "other.json", 0.01, 1e-5,
                     setup={**SETUP, "ball": {"diameter_mm": 12.69, "mass_g": 8.35}})
    notfit = tmp_path / "track.json"
    notfit.write_text(json.dumps({"n_frames": 10, "n_found": 9}))
    notjson = tmp_path / "x.json"
    notjson.write_text("mu = 0.01\n")
    out = tmp_path / "combined.json"
    cases = [([*good[:2], other], ["other.json", "different setups", "ball.diameter_mm"]),
             ([good[0], str(notfit)], ["track.json", "not a rollfric fit.json"]),
             ([good[0], str(notjson)], ["x.json", "not JSON"]),
             ([good[0]], ["at least two runs"]),
             ([good[0], good[0]], ["named twice"]),
             ([good[0], str(tmp_path / "missing.json")], ["missing.json", "not found"]),
             ([good[0], good[1], "--out", good[1], "--overwrite"], ["is an input"])]
    for argv, words in cases:
        if "--out" not in argv:
            argv = [*argv, "--out", str(out)]
        assert main(["combine", *argv]) == 2, argv
        err = capsys.readouterr().err
        assert all(w in err for w in words), err
        assert "Traceback" not in err
        assert not out.exists()


def test_suspect_runs_left_out_or_kept(tmp_path, capsys):
    paths = three(tmp_path)
    bad = fit_json(tmp_path / "bad.json", 0.0105, 1e-5, quality="suspect")
    c, warnings = combine_files([*paths, bad])
    assert c.n == 3 and c.left_out[0]["path"] == bad and "bad.json" in warnings[0]
    c_all, _ = combine_files([*paths, bad], include_suspect=True)
    assert c_all.n == 4 and "suspect_runs" in [r["code"] for r in c_all.quality_reasons]
    # the suspect run left out leaves one run: refused, saying why
    assert main(["combine", paths[0], bad]) == 2
    err = capsys.readouterr().err
    assert "bad.json: left out" in err and "--include-suspect" in err


def test_fit_json_without_a_setup_record_compared_through_its_budget(tmp_path):
    a = fit_json(tmp_path / "a.json", 0.01, 1e-5, setup=None)
    b = fit_json(tmp_path / "b.json", 0.01, 1e-5, setup=None)
    _, warnings = combine_files([a, b])
    assert "no setup recorded" in warnings[0]
    data = json.loads((tmp_path / "b.json").read_text())
    data["uncertainty_budget"][1]["value"] = 85.0  # another trough
    (tmp_path / "b.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match="different setups.*cylinder.radius_mm"):
        combine_files([a, b])


def test_fit_records_its_setup_and_two_fits_combine(tmp_path, capsys):
    from rollfric.fit import eom
    from rollfric.setup.model import load_setup, save_setup, thesis_setup

    setup = thesis_setup("10mm", uncertainty=(("cylinder_radius", 0.5e-3), ("fps", 0.05)))
    save_setup(setup, tmp_path / "setup.toml")
    t = np.arange(2000) / 1000.0
    outs = []
    for i, theta0 in enumerate((15.0, -20.0)):  # released to the right, then to the left
        th, _, _ = eom.solve_reference(math.radians(theta0), 0.0, 0.008, t,
                                       track_radius=setup.track_radius)
        th = th + np.random.default_rng(i).normal(0.0, 2e-4, t.size)
        lines = ["t_s,theta_rad"] + [f"{a:.17g},{b:.17g}" for a, b in zip(t, th, strict=True)]
        (tmp_path / f"track{i}.csv").write_text("\n".join(lines) + "\n")
        outs.append(str(tmp_path / f"fit{i}.json"))
        assert main(["fit", str(tmp_path / f"track{i}.csv"), "--setup",
                     str(tmp_path / "setup.toml"), "--out", outs[-1]]) == 0
    data = [json.loads(open(p).read()) for p in outs]
    assert load_setup(tmp_path / "setup.toml").to_toml_dict() == data[0]["setup"]
    c, warnings = combine_files(outs)
    assert not warnings
    # a common radius error moves both the same way: its part of the mean is their weighted sum
    radius = [next(r for r in d["uncertainty_budget"] if r["source"] == "cylinder.radius_mm")
              for d in data]
    assert radius[0]["sensitivity"] * radius[1]["sensitivity"] > 0
    row = next(r for r in c.shared_rows if r["source"] == "cylinder.radius_mm")
    w = [r["weight"] for r in c.runs]
    assert row["u_mu"] == pytest.approx(w[0] * radius[0]["u_mu"] + w[1] * radius[1]["u_mu"],
                                        rel=1e-12)
    assert abs(c.mu - 0.008) < c.U_mu


def test_a_common_error_acting_differently_is_expected_scatter(tmp_path):
    # two releases either side of a centre known to +-u: its error moves them apart by c1 - c2,
    # so chi2 = (mu1 - mu2)^2 / (u1^2 + u2^2 + (c1 - c2)^2) (N = 2: one residual)
    a = fit_json(tmp_path / "a.json", 0.0100, 1e-5, center=(4e-5, 1.0, 640.0))
    b = fit_json(tmp_path / "b.json", 0.0101, 1e-5, center=(4e-5, -1.0, 640.0))
    c, _ = combine_files([a, b])
    assert c.chi2 == pytest.approx(1e-8 / (2e-10 + (8e-5) ** 2), rel=1e-9)
    assert c.birge_ratio_independent == pytest.approx(math.sqrt(1e-8 / 2e-10), rel=1e-9)
    assert c.birge_ratio < c.birge_range[1] and c.quality == "ok"
    # R_B > 1 (within its range) scales the independent part (PDG); the centre's row cancels
    assert c.scale == pytest.approx(c.birge_ratio, rel=1e-15) and c.scale > 1
    assert c.mu_u == pytest.approx(math.sqrt(c.scale**2 * 0.5e-10 + 5e-5**2 + 3e-5**2),
                                   rel=1e-12)


def test_second_order_row_full_in_the_mean_independent_in_the_birge_ratio(tmp_path):
    # the inputs' interactions (radius x centre) move releases to either side oppositely
    row = {"source": "second order", "value": None, "u": 3e-5, "sensitivity": 1.0,
           "u_mu": 3e-5}
    a = fit_json(tmp_path / "a.json", 0.0100, 1e-5, extra=[row])
    b = fit_json(tmp_path / "b.json", 0.0101, 1e-5, extra=[row])
    c, _ = combine_files([a, b])
    assert c.chi2 == pytest.approx(1e-8 / (2e-10 + 2 * (3e-5) ** 2), rel=1e-9)
    assert c.u_shared == pytest.approx(math.sqrt(5e-5**2 + 3e-5**2 + 3e-5**2), rel=1e-12)


@pytest.mark.parametrize("u_mu", [1e308, -1e-5])
def test_a_row_that_is_no_uncertainty_is_refused(tmp_path, capsys, u_mu):
    a = fit_json(tmp_path / "a.json", 0.01, 1e-5)
    data = json.loads((tmp_path / "a.json").read_text())
    data["uncertainty_budget"][1]["u_mu"] = u_mu
    (tmp_path / "b.json").write_text(json.dumps(data))
    assert main(["combine", a, str(tmp_path / "b.json")]) == 2
    err = capsys.readouterr().err
    assert "b.json" in err and "cylinder.radius_mm" in err and "Traceback" not in err


def _law(mu1, u_stat, u_air, selected="coulomb"):
    return {"selected": selected, "mu1": mu1, "mu1_u_statistical": u_stat,
            "mu1_u_inputs": u_air, "mu1_u": math.hypot(u_stat, u_air),
            "inputs": [{"source": "air drag law", "u_mu1": u_air}]}


def test_the_friction_law_tested_on_the_releases_together(tmp_path):
    # mu1 weighted by the statistical parts; the drag law's part is common: it does not
    # average down, so the z of four releases is not twice one release's
    mu1s, u_stat, u_air = (4e-6, 6e-6, 5e-6, 5e-6), 3e-6, 2e-6
    paths = []
    for i, m in enumerate(mu1s):
        p = fit_json(tmp_path / f"f{i}.json", 0.01, 1e-5)
        data = json.loads(open(p).read())
        data["friction_law"] = _law(m, u_stat, u_air)
        open(p, "w").write(json.dumps(data))
        paths.append(p)
    c, _ = combine_files(paths)
    law = c.to_json()["friction_law"]
    mean = sum(mu1s) / 4
    chi = sum((m - mean) ** 2 for m in mu1s) / u_stat**2
    u = math.hypot(max(1.0, math.sqrt(chi / 3)) * u_stat / 2, u_air)
    assert law["mu1"] == pytest.approx(mean, rel=1e-12)
    assert law["mu1_u"] == pytest.approx(u, rel=1e-12)
    assert law["z"] == pytest.approx(mean / u, rel=1e-12)
    assert law["selected"] == "speed" and law["n"] == 4  # z 2.0 > 1.645
    assert "friction_law" in [r["code"] for r in c.quality_reasons]
    # each alone says coulomb (z = 5e-6 / 3.6e-6 = 1.4): together they reject it


def test_runs_suspect_only_for_their_law_are_kept_and_models_must_agree(tmp_path):
    a = fit_json(tmp_path / "a.json", 0.01, 1e-5)
    b = fit_json(tmp_path / "b.json", 0.01, 1e-5, quality="suspect")
    data = json.loads(open(b).read())
    data["quality_reasons"] = [{"code": "friction_law", "message": "speed"}]
    open(b, "w").write(json.dumps(data))
    c, _ = combine_files([a, b])
    assert c.n == 2 and not c.left_out
    assert c.to_json()["friction_law"]["selected"] is None  # no law test in these files
    data["model"] = "speed"
    open(b, "w").write(json.dumps(data))
    with pytest.raises(InputError, match="different friction models"):
        combine_files([a, b])
