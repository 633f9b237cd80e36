"""validation.case and sweep files: parsing, overrides, ids, bad input (no rendering)."""

from __future__ import annotations

import math

import pytest

from rollfric.cli.main import main
from validation import case as C
from validation import case_dict as CD
from validation import sweep as S


def test_default_case_is_the_thesis_10mm_ball():
    c = C.case_from_dict(CD.default_case_dict())
    assert c.scenario.mu == 0.0079
    assert math.isclose(c.scenario.ball_diameter, 0.010)
    assert (c.scene.camera.width, c.scene.camera.height) == (1280, 1024)
    assert c.sensor.read_noise == 8.0  # the "realistic" preset
    assert len(c.scene.lighting.lamps) == 2
    assert c.locator == "subpixel" and c.fit == "lsq"


def test_case_toml_round_trip_and_stable_id(tmp_path):
    d = CD.small_case_dict()
    d["render"]["sensor"] = {"read_noise": 20.0, "shot_noise": False}
    d["render"]["lamps"] = [{"position_mm": [50, 10, 300], "intensity": 0.1}]
    p = tmp_path / "case.toml"
    p.write_text(C.dumps_case(d))
    back = CD.load_case_dict(p)
    assert back == CD.merge_case(CD.default_case_dict(), d)
    assert CD.case_id(back) == CD.case_id(d)
    c = C.case_from_dict(back)
    assert c.sensor.read_noise == 20.0 and c.sensor.shot_noise is False
    assert c.scene.lighting.lamps[0].position == (0.05, 0.01, 0.3)
    # the id follows the parameters, not the name
    d2 = CD.apply_overrides(d, {"name": "other"})
    assert CD.case_id(d2) == CD.case_id(d)
    d3 = CD.apply_overrides(d, {"render.sensor.read_noise": 21.0})
    assert CD.case_id(d3) != CD.case_id(d)


def test_lamp_knobs_scale_and_move_the_preset_lamps():
    d = CD.apply_overrides(CD.default_case_dict(), {"render.intensity_scale": 2.0,
                                                  "render.lamp_spread": 0.5,
                                                  "render.lamp_dy_mm": 10.0})
    base = C.case_from_dict(CD.default_case_dict()).scene.lighting.lamps
    lamps = C.case_from_dict(d).scene.lighting.lamps
    for a, b in zip(base, lamps, strict=True):
        assert b.intensity == pytest.approx(2 * a.intensity)
        assert b.position[0] == pytest.approx(0.5 * a.position[0])
        assert b.position[1] == pytest.approx(a.position[1] + 0.010)


def test_plain_scenario_file_is_a_case(tmp_path):
    p = tmp_path / "scen.toml"
    p.write_text("[motion]\nmu = 0.01\nseconds = 0.5\n[engine]\nname = \"pybullet\"\n")
    c = C.load_case(p)
    assert c.scenario.mu == 0.01 and c.scenario.engine == "pybullet"
    assert c.sensor.read_noise == 8.0


@pytest.mark.parametrize("key,value,words", [
    ("render.sensor.read_nois", 3.0, "render.sensor.read_nois"),
    ("render.noise", "loud", "loud"),
    ("render.lighting", "disco", "disco"),
    ("render.motion_blur", 0, "motion_blur"),
    ("measure.locator", "magic", "measure.locator"),
    ("render.camera.widht", 100, "widht"),
    ("scenario.motion.mu", -1.0, "mu"),
    ("render.bogus", 1, "render.bogus"),
    ("render.scene.ball_model", "cube", "ball_model"),
])
def test_bad_case_keys_are_named(key, value, words):
    d = CD.apply_overrides(CD.default_case_dict(), {key: value})
    with pytest.raises(C.CaseError, match=words.replace(".", r"\.")):
        C.case_from_dict(d)


def test_validate_cli_bad_case_exits_2(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text("[render]\nnoise = \"loud\"\n")
    assert main(["validate", str(p), "--out", str(tmp_path / "r")]) == 2
    assert "loud" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_sweep_grid_list_and_seeds_expand(tmp_path):
    spec = S.sweep_from_dict({
        "sweep": {"name": "t", "seeds": 2},
        "grid": {"render.sensor.read_noise": [0.0, 8.0], "render": {"lighting": ["thesis",
                                                                                  "dim"]}},
    })
    assert len(spec.cases) == 8
    assert set(spec.swept) == {"render.sensor.read_noise", "render.lighting", "render.seed"}
    assert len({c.case_id for c in spec.cases}) == 8
    c0 = spec.cases[0]
    assert CD.get_dotted(c0.case, "render.sensor.read_noise") == c0.params[
        "render.sensor.read_noise"]
    lst = S.sweep_from_dict({"sweep": {"mode": "list"},
                             "cases": [{"scenario.motion.mu": 0.005},
                                       {"scenario.motion.mu": 0.01}]})
    assert [c.case["scenario"]["motion"]["mu"] for c in lst.cases] == [0.005, 0.01]


@pytest.mark.parametrize("data,words", [
    ({"grid": {"render.sensor.read_nois": [1.0]}}, "read_nois"),
    ({"sweep": {"mode": "cube"}}, "mode"),
    ({"sweep": {"stages": "half"}}, "stages"),
    ({"grid": {"render.seed": 3}}, "non-empty list"),
    ({"sweep": {"mode": "list"}}, "cases"),
    ({"sweep": {"sead": 1}}, "sead"),
])
def test_bad_sweep_files_are_named(data, words):
    with pytest.raises(S.SweepError, match=words):
        S.sweep_from_dict(data)


def test_shipped_sweeps_load(capsys):
    names = [n for n, _, _ in S.shipped_sweeps()]
    for study in ("noise", "lighting", "blur", "ball_size", "engines"):
        assert study in names
    for name in names:
        spec = S.load_sweep(name)
        assert spec.cases and spec.metrics
    assert main(["sweep", "--list"]) == 0
    assert "noise" in capsys.readouterr().out
    assert main(["sweep", "noise", "--dry-run"]) == 0
    assert "16 case(s)" in capsys.readouterr().out


def test_sweep_set_changes_every_case_and_its_id(capsys):
    """rollfric sweep --set KEY=VALUE: the study's [base] with the key set, in every case."""
    from validation import case as C

    plain = S.load_sweep("coverage")
    oracle = S.load_sweep("coverage", {"measure.oracle": True})
    assert len(oracle.cases) == len(plain.cases)
    assert all(c.case["measure"]["oracle"] is True for c in oracle.cases)
    assert all(C.case_from_dict(c.case).mode == "oracle" for c in oracle.cases[:3])
    assert not {c.case_id for c in oracle.cases} & {c.case_id for c in plain.cases}
    assert "# run with --set measure.oracle=True" in oracle.text
    assert main(["sweep", "coverage", "--set", "measure.oracle=true", "--dry-run"]) == 0
    assert "216 case(s)" in capsys.readouterr().out
    assert main(["sweep", "coverage", "--set", "measure.colour=1", "--dry-run"]) == 2
    assert "measure.colour" in capsys.readouterr().err
