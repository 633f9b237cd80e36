"""The rendered fault study (validation.studies.rendered_faults): its frames, faults and tables."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

pytest.importorskip("pyrender")  # synth renders the recordings

from validation.studies import rendered_faults as rf  # noqa: E402


def test_draw_case_cycles_and_is_seeded():
    a = [rf.draw_case("lighting", i, seed=3) for i in range(7)]
    assert [c.lighting for c in a] == ["thesis", "dim", "harsh", "uneven", "flat", "backlit",
                                       "thesis"]
    assert a[2] == rf.draw_case("lighting", 2, seed=3)
    assert a[2].mu != rf.draw_case("lighting", 2, seed=4).mu
    for c in a:
        assert rf.MU_RANGE[0] <= c.mu <= rf.MU_RANGE[1]
        assert rf.THETA0_RANGE[0] <= c.theta0 <= rf.THETA0_RANGE[1]
    wide = rf.draw_case("mu, angle", 0)
    assert 0.002 <= wide.mu <= 0.03 and 0.08 <= wide.theta0 <= 0.4
    assert [rf.draw_case("ball", i).ball for i in range(3)] == ["1.58mm", "3mm", "10mm"]


def test_frame_geometry_holds_the_path_with_its_margin():
    d, theta0, R, m = 10e-3, 0.25, 85.3e-3, rf.MARGIN_PX
    w, h, (cx, cy) = rf.frame_geometry(d, theta0, R)
    r = d / 2 / rf.PIXEL_SIZE
    L = (R - d / 2) / rf.PIXEL_SIZE
    # the ball's outline at the release angle and at the bottom, m px from the frame's edges
    x_release = cx + L * math.sin(theta0)
    assert w - 1 - (x_release + r) == pytest.approx(m - 1, abs=1.0)
    assert cy + L * math.cos(theta0) - r == pytest.approx(m)
    assert h - (cy + L + r) == pytest.approx(m, abs=1.0)


def _row(family, err_U, reasons=(), findings=()):
    return {"family": family, "fault": "clean", "magnitude": 0.0,
            "verdict": "suspect" if reasons else "ok", "err_U": err_U,
            "err_rel": None if err_U is None else 1e-4 * err_U,
            "reasons": list(reasons), "findings": list(findings)}


def test_rest_from_finds_the_ball_at_rest():
    th = np.concatenate([np.cos(np.arange(50) / 5.0), np.full(30, math.cos(49 / 5.0))])
    assert rf.rest_from(th) == 49
    assert rf.rest_from(np.cos(np.arange(80) / 5.0)) is None


def test_reason_and_error_tables_count_cases():
    rows = [_row("a", 0.5, ["ball_radius"]), _row("a", -2.0, ["ball_radius", "timing"]),
            _row("b", 0.1, [], ["still:rest"]), _row("b", None), _row("b", -0.3, ["timing"]),
            {**_row("b", 0.2, [], ["still:rest"]), "truth_rest_from": 900}]
    t = rf.reason_table(rows)
    assert t == {"ball_radius": {"a": 2, "all": 2}, "still:rest": {"b": 1, "all": 1},
                 "timing": {"a": 1, "b": 1, "all": 2}}
    e = rf.error_table(rows)
    assert e["a"] == {"n": 2, "median": -0.75, "max_abs": 2.0, "off_by_U": 1}
    assert e["b"]["n"] == 3 and e["b"]["median"] == pytest.approx(0.1)
    assert e["all"]["n"] == 5 and e["all"]["off_by_U"] == 1
    study = {"clean": {"a": {"n": 2}, "b": {"n": 3}, "all": {"n": 5}}, "reasons": t,
             "errors": e}
    md = rf.format_reasons(study).splitlines()
    assert md[0].startswith("| reason") and "a (n 2)" in md[0] and "b (n 3)" in md[0]
    assert "| timing | 1 | 1 | 2 |" in md


@pytest.fixture(scope="module")
def base():
    # no sensor noise: a frame's picture is the same bytes whatever its frame number
    case = dataclasses.replace(rf.draw_case("ball", 2), noise="none", seconds=0.5)
    with rf.rendered(case) as b:
        yield b


def test_rendered_base_is_its_truth(base):
    n = len(base.frames)
    assert n == 501 and base.theta[0] == pytest.approx(base.case.theta0)
    h, w = base.frames[0].shape
    x, y = base.centers.T
    assert (x - base.r_px >= 0).all() and (x + base.r_px <= w - 1).all()
    assert (y - base.r_px >= 0).all() and (y + base.r_px <= h - 1).all()
    # the ball is dark on the bright backdrop: the darkest spot of the difference at its centre
    i = 250
    diff = base.frames[i].astype(int) - base.background.astype(int)
    yy, xx = np.mgrid[:h, :w]
    inside = np.hypot(xx - x[i], yy - y[i]) < 0.7 * base.r_px
    assert np.abs(diff[inside]).mean() > 5 * np.abs(diff[~inside]).mean()
    assert np.array_equal(base.frame_like(i, i), base.frames[i])


def test_held_and_rest_repeat_the_release_and_the_turning_frame(base):
    n = len(base.frames)
    held = rf.rendered_fault(base, "held", 40)
    assert len(held.source) == n + 39 and held.truth["release_frame"] == 39
    for j in range(40):
        assert np.array_equal(held.source[j], base.frames[0])
    assert np.array_equal(held.source[40], base.frames[1])
    rest = rf.rendered_fault(base, "rest", 0.5)
    k = rest.truth["rest_from"]
    # a turning point: the angle's extreme among its neighbours
    th = base.theta
    assert (th[k] - th[k - 1]) * (th[k + 1] - th[k]) <= 0
    for j in (k, k + 1, n - 1):
        assert np.array_equal(rest.source[j], base.frames[k])
    assert np.array_equal(rest.source[k - 1], base.frames[k - 1])
    assert rf.rendered_fault(base, "rest", 0.5, median_background=True).background is None


def test_setup_and_timestamp_faults(base):
    r = rf.rendered_fault(base, "radius", 1.1)
    assert r.setup.cylinder_radius == pytest.approx(1.1 * base.setup.cylinder_radius)
    assert r.source[3].tobytes() == base.frames[3].tobytes()
    t = rf.rendered_fault(base, "timestamps_ms", 3.0)
    assert t.source.timestamps[:2] == pytest.approx([3000.0, 3001.0])
    b = rf.rendered_fault(base, "bump", 3.0)
    assert b.centers[-1, 0] - base.centers[-1, 0] == pytest.approx(3.0)
    with pytest.raises(ValueError):
        rf.rendered_fault(base, "yaw", 4.0)


def test_study_smoke_tables_match_rows(tmp_path):
    rc = rf.main(["--out", str(tmp_path), "--cases", "1", "--fault-bases", "1",
                  "--families", "ball", "--faults", "timestamps_us", "--seconds", "0.6"])
    assert rc == 0
    study = json.loads((tmp_path / "rendered_faults.json").read_text())
    (row,) = study["clean_rows"]
    (frow,) = study["fault_rows"]
    assert row["family"] == "ball" and frow["fault"] == "timestamps_us"
    assert study["clean"]["ball"]["n"] == 1
    for c in row["reasons"] + row["findings"]:
        assert study["reasons"][c] == {"ball": 1, "all": 1}
    assert len(study["reasons"]) == len(set(row["reasons"] + row["findings"]))
    if row["err_U"] is not None:
        assert study["errors"]["ball"]["median"] == pytest.approx(row["err_U"])
        assert row["err_U"] == pytest.approx((row["mu"] - row["mu_true"]) / row["U_mu"])
    s = study["faults"]["timestamps_us 3"]
    assert s["n"] == 1 and s["named"] == int(bool(frow["named"]))
    # refuses to overwrite without --overwrite
    assert rf.main(["--out", str(tmp_path), "--cases", "0"]) == 2


def test_a_turned_camera_compresses_the_ball_path_by_the_cosine_of_its_angle(base):
    # the base rendered again by a camera yawed 8 deg (pitched 8 deg): the truth's centres
    # span cos 8 deg of the square camera's across (along) the path, about the same axis
    # point; the setup is the renderer's, its center_px unchanged (the lab does not know)
    for fault, axis in (("yaw", 0), ("pitch", 1)):
        rec = rf.turned(base.case, fault, 8.0)
        assert rec.fault == fault and rec.magnitude == 8.0
        assert rec.setup.center_px == base.setup.center_px
        c0 = base.setup.center_px
        seen = np.asarray(rec.centers, float)[:, axis] - c0[axis]
        square = base.centers[:, axis] - c0[axis]
        ratio = np.ptp(seen) / np.ptp(square)
        assert ratio == pytest.approx(math.cos(math.radians(8.0)), abs=2e-3)
