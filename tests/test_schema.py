"""The declarative schema of the TOML files (rollfric.setup.schema) and the readers built on it:
conversions, the checker's rules, and each file's messages word for word."""

import copy
import math

import pytest

import sim
from rollfric.errors import InputError
from rollfric.setup.model import LAB_KEYS, SetupError, setup_from_dict, thesis_setup
from rollfric.setup.schema import (
    BENCH_MM,
    DEG,
    MM,
    Key,
    Messages,
    Schema,
    check_file,
    check_section,
)
from sim.errors import ScenarioError
from validation.case import CaseError, case_from_dict
from validation.case_dict import small_case_dict
from validation.sweep import SweepError, sweep_from_dict


class TableError(InputError):
    pass


TOY = Schema(
    sections={
        "a": (Key("length_mm", field="length", unit=MM, required=True, sign=">0",
                  uncertain=True),
              Key("angle_deg", field="angle", unit=DEG, default=0.0),
              Key("name", "str", choices=("x", "y")),
              Key("n", "int", bounds=(1, 3), hint="must be 1, 2 or 3")),
        "b": (Key("seconds", sign=">=0", plausible="fps"),),
    },
    error=TableError, required=("a",), uncertain_note=" (+ _u)")


def fault(data) -> str:
    with pytest.raises(TableError) as exc:
        check_file(TOY, data, "f")
    return str(exc.value)


def test_units_convert_as_declared():
    assert MM.to_si(85.3) == 85.3 * 1e-3
    assert BENCH_MM.to_si(85.3) == 0.0853  # exact for a typed decimal
    assert DEG.to_si(180) == math.pi
    got = check_file(TOY, {"a": {"length_mm": 2, "angle_deg": 90, "name": "y", "n": 3}}, "f")
    assert got == {"length": 2e-3, "angle": math.pi / 2, "name": "y", "n": 3}
    assert check_file(TOY, {"a": {"length_mm": 1.5}}, "f") == {"length": 1.5e-3, "angle": 0.0}


def test_the_checker_words_each_fault():
    good = {"a": {"length_mm": 1.0}}
    assert fault({**good, "c": {}}) == "f: unknown section [c] (known: a, b)"
    assert fault({"b": {}}) == "f: missing section [a]"
    assert fault({**good, "b": 3}) == "f: [b] must be a table"
    assert fault({"a": {"length_mm": 1, "z": 1}}) == \
        "f: unknown key a.z (known: length_mm, angle_deg, name, n (+ _u))"
    assert fault({"a": {}}) == "f: missing key a.length_mm"
    assert fault({"a": {"length_mm": True}}) == "f: a.length_mm must be a number, got True"
    assert fault({"a": {"length_mm": math.inf}}) == "f: a.length_mm must be finite, got inf"
    assert fault({"a": {"length_mm": 0}}) == "f: a.length_mm must be positive, got 0"
    assert fault({"a": {"length_mm": 1, "name": "z"}}) == \
        "f: a.name must be one of x, y, got 'z'"
    assert fault({"a": {"length_mm": 1, "n": 4}}) == "f: a.n must be 1, 2 or 3, got 4"
    assert fault({"a": {"length_mm": 1, "n": True}}) == "f: a.n must be 1, 2 or 3, got True"
    assert fault({**good, "b": {"seconds": 1e9}}) == \
        "f: b.seconds = 1e+09 Hz is outside the plausible range 0.001..1e+08 Hz"
    assert fault({"a": {"length_mm_u": 1}}) == \
        "f: a.length_mm_u (a standard uncertainty) is given without a.length_mm"
    assert fault({"a": {"length_mm": 1, "angle_deg_u": 1, "angle_deg": 1}}) == \
        "f: a.angle_deg_u: no standard uncertainty is taken for a.angle_deg (only for " \
        "a.length_mm)"


def test_a_file_may_word_its_faults_its_own_way():
    worded = Schema(sections={"t": (Key("k", "float"),)}, error=TableError,
                    messages=Messages(unknown_key="unknown key {source}: {section}.{key}",
                                      not_table="{source}: {section} is {value!r}",
                                      kind_names=()))
    with pytest.raises(TableError, match="^unknown key f: t.z$"):
        check_section(worded, "t", {"z": 1}, "f")
    with pytest.raises(TableError, match="^f: t is 5$"):
        check_section(worded, "t", 5, "f")
    with pytest.raises(TableError, match="^f: t.k must be float, got 'x'$"):
        check_section(worded, "t", {"k": "x"}, "f")
    assert check_section(worded, "t", {"k": 2}, "f") == {"k": 2.0}


def test_the_setup_keys_with_an_uncertainty_are_read_from_the_schema():
    assert LAB_KEYS == {
        "cylinder_radius": ("cylinder", "radius_mm", 1e3),
        "center_px": ("cylinder", "center_px", 1.0),
        "ball_diameter": ("ball", "diameter_mm", 1e3),
        "ball_mass": ("ball", "mass_g", 1e3),
        "fps": ("camera", "fps", 1.0),
        "pixel_size": ("camera", "pixel_size_mm", 1e3),
        "gravity": ("environment", "gravity_m_s2", 1.0),
        "air_density": ("environment", "air_density_kg_m3", 1.0),
        "air_viscosity": ("environment", "air_viscosity_pa_s", 1.0),
        "air_cd": ("environment", "air_cd", 1.0),
        # the trough and camera as built (rollfric.uncertainty.asbuilt): deg and mm
        "cylinder_tilt": ("cylinder", "tilt_deg", pytest.approx(180.0 / math.pi)),
        "cylinder_ovality": ("cylinder", "ovality_mm", 1e3),
        "camera_yaw": ("camera", "yaw_deg", pytest.approx(180.0 / math.pi)),
        "camera_pitch": ("camera", "pitch_deg", pytest.approx(180.0 / math.pi)),
    }


def _setup(edit):
    d = thesis_setup().to_toml_dict()
    edit(d)
    return setup_from_dict(d, "S")


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["cylinder"].update(z=1), "S: unknown key cylinder.z (known: radius_mm, "
     "center_px, contour_depth_mm, tilt_deg, ovality_mm, each with an optional _u: its "
     "standard uncertainty)"),
    (lambda d: d["cylinder"].update(tilt_deg=12.0), "S: cylinder.tilt_deg must be the axis's "
     "tilt along its length in degrees, -10..10, got 12.0"),
    (lambda d: d["cylinder"].update(tilt_deg_u=0.05), "S: cylinder.tilt_deg_u (a standard "
     "uncertainty) is given without cylinder.tilt_deg"),
    (lambda d: d["camera"].update(yaw_deg="x"), "S: camera.yaw_deg must be the camera's yaw "
     "against the trough's axis in degrees, -10..10, got 'x'"),
    (lambda d: d["cylinder"].update(ovality_mm=-0.1), "S: cylinder.ovality_mm must be the "
     "bore's D_max - D_min in mm, >= 0, got -0.1"),
    (lambda d: d.pop("camera"), "S: missing section [camera]"),
    (lambda d: d["ball"].update(mass_g="x"), "S: ball.mass_g must be a number, got 'x'"),
    (lambda d: d["ball"].update(mass_g=0), "S: ball.mass_g must be positive, got 0"),
    (lambda d: d["ball"].update(mass_g=1e300),
     "S: ball.mass_g = 1e+300 g is outside the plausible range 1e-09..1e+09 g"),
    (lambda d: d["cylinder"].update(center_px=[1]),
     "S: cylinder.center_px must be [x, y] in pixels, got [1]"),
    (lambda d: d["ball"].update(mass_g_u=-1),
     "S: ball.mass_g_u (a standard uncertainty) must be finite and >= 0, got -1"),
    (lambda d: d["camera"].update(bit_depth=17), "S: camera.bit_depth must be the camera's "
     "effective bit depth, a whole number of bits 1..16 (12 for a 12-bit camera), got 17"),
    (lambda d: d["camera"].update(matrix_u=5),
     "S: camera.matrix_u (its standard uncertainties) is given without camera.matrix"),
])
def test_setup_messages_word_for_word(edit, message):
    with pytest.raises(SetupError) as exc:
        _setup(edit)
    assert str(exc.value) == message


def test_setup_values_in_si_with_their_uncertainties():
    s = _setup(lambda d: d["cylinder"].update(radius_mm=85.3, radius_mm_u=0.05,
                                              center_px_u=2.0, center_px=[640, 380]))
    assert s.cylinder_radius == 85.3 * 1e-3 and s.center_px == (640.0, 380.0)
    assert dict(s.uncertainty) == {"cylinder_radius": 0.05 / 1e3, "center_px": (2.0, 2.0)}


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["motion"].update(z=1), "SC: unknown key motion.z (known: mu, theta0_deg, "
     "theta_dot0_deg_s, seconds, mu_speed_s_m)"),
    (lambda d: d["motion"].update(mu="x"), "SC: motion.mu must be a number, got 'x'"),
    (lambda d: d["environment"].update(air_drag=5),
     "SC: environment.air_drag must be a string, got 5"),
    (lambda d: d["engine"].update(z=5),
     "SC: unknown key engine.z (known: name, surface, seed, options)"),
    (lambda d: d["motion"].update(seconds=-1), "SC: duration must be a positive number, "
     "got -1.0"),
    (lambda d: d["engine"].update(seed=-1), "SC: seed must be a non-negative integer, got -1"),
    (lambda d: d["environment"].update(air_drag="x"),
     "SC: air_drag must be one of constant, law, got 'x'"),
])
def test_scenario_messages_word_for_word(edit, message):
    d = sim.Scenario().to_toml_dict()
    edit(d)
    with pytest.raises(ScenarioError) as exc:
        sim.scenario_from_dict(d, "SC")
    assert str(exc.value) == message


def test_scenario_toml_converts_bench_units_exactly():
    d = sim.Scenario().to_toml_dict()
    d["cylinder"]["radius_mm"] = 85.3
    d["motion"]["theta0_deg"] = 20
    s = sim.scenario_from_dict(d)
    assert s.cylinder_radius == 0.0853 and s.theta0 == math.radians(20)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["render"].update(intensity_scale="x"),
     "C: render.intensity_scale must be float, got 'x'"),
    (lambda d: d["render"].update(intensity_scale=math.inf),
     "C: render.intensity_scale must be finite, got inf"),
    (lambda d: d["measure"].update(locator="x"),
     "C: measure.locator must be one of subpixel, thesis-large, thesis-small, got 'x'"),
    (lambda d: d.update(render=3), "C: render must be a table, got 3"),
    (lambda d: d["render"].update(timing={"jitter_us": "x"}),
     "C: render.timing.jitter_us must be float, got 'x'"),
    (lambda d: d["lab"].update(draw=5), "C: lab.draw must be true or false, got 5"),
    (lambda d: d["lab"].update(cylinder={"radius_mm_u": -1}),
     "C: lab.cylinder.radius_mm_u must be >= 0, got -1"),
    (lambda d: d["lab"].update(cylinder={"z": 1}),
     "C: unknown key lab.cylinder.z (known: radius_mm, radius_mm_u, contour_depth_mm)"),
])
def test_case_and_lab_messages_word_for_word(edit, message):
    d = copy.deepcopy(small_case_dict())
    edit(d)
    with pytest.raises(CaseError) as exc:
        case_from_dict(d, "C")
    assert str(exc.value) == message


@pytest.mark.parametrize("head, message", [
    ({"mode": "x"}, "SW: sweep.mode must be 'grid' or 'list', got 'x'"),
    ({"seeds": 0}, "SW: sweep.seeds must be a positive integer, got 0"),
    ({"stages": 1}, "SW: sweep.stages must be one of ('full', 'sim', 'track'), got 1"),
])
def test_sweep_messages_word_for_word(head, message):
    with pytest.raises(SweepError) as exc:
        sweep_from_dict({"sweep": head}, "SW")
    assert str(exc.value) == message
