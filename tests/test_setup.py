import math

import pytest

from rollfric.setup.model import (
    Setup,
    SetupError,
    dumps_setup,
    load_setup,
    setup_from_dict,
    thesis_setup,
)

GOOD = """
[cylinder]
radius_mm = 85.3
center_px = [640.0, 380.0]
[ball]
diameter_mm = 10.0
mass_g = 4.07612
[camera]
fps = 1000
pixel_size_mm = 0.1343
"""


def write(tmp_path, text):
    p = tmp_path / "setup.toml"
    p.write_text(text)
    return p


def test_load_converts_to_si(tmp_path):
    s = load_setup(write(tmp_path, GOOD))
    assert s.cylinder_radius == pytest.approx(0.0853)
    assert s.ball_diameter == pytest.approx(0.010)
    assert s.ball_mass == pytest.approx(4.07612e-3)
    assert s.pixel_size == pytest.approx(0.1343e-3)
    assert s.fps == 1000
    assert s.center_px == (640.0, 380.0)
    assert s.track_radius == pytest.approx(0.0853 - 0.005)


def test_round_trip(tmp_path):
    s = load_setup(write(tmp_path, GOOD))
    again = load_setup(write(tmp_path, dumps_setup(s)))
    assert again == s
    no_centre = thesis_setup("1.58mm")
    assert load_setup(write(tmp_path, dumps_setup(no_centre))) == no_centre


@pytest.mark.parametrize("edit, key", [
    (("radius_mm = 85.3", ""), "cylinder.radius_mm"),
    (("mass_g = 4.07612", ""), "ball.mass_g"),
    (("fps = 1000", "fps = 0"), "camera.fps"),
    (("diameter_mm = 10.0", "diameter_mm = -1"), "ball.diameter_mm"),
    (("pixel_size_mm = 0.1343", "pixel_size_mm = 0.1343\nshutter = 2"), "camera.shutter"),
    (("diameter_mm = 10.0", "diameter_mm = 171"), "ball.diameter_mm"),
    (("center_px = [640.0, 380.0]", "center_px = [640.0]"), "cylinder.center_px"),
    (("mass_g = 4.07612", 'mass_g = "heavy"'), "ball.mass_g"),
    (("[camera]", "[lens]\nf=1\n[camera]"), "[lens]"),
])
def test_bad_values_name_the_key(tmp_path, edit, key):
    text = GOOD.replace(*edit)
    with pytest.raises(SetupError, match=key.replace("[", r"\[").replace("]", r"\]")):
        load_setup(write(tmp_path, text))


def test_missing_section_and_bad_toml(tmp_path):
    with pytest.raises(SetupError, match=r"\[camera\]"):
        setup_from_dict({"cylinder": {"radius_mm": 85.3},
                         "ball": {"diameter_mm": 10, "mass_g": 4}})
    with pytest.raises(SetupError, match="not valid TOML"):
        load_setup(write(tmp_path, "[cylinder\n"))
    with pytest.raises(SetupError, match="not found"):
        load_setup(tmp_path / "nope.toml")


def test_direct_construction_is_checked():
    with pytest.raises(SetupError, match="ball_diameter"):
        Setup(cylinder_radius=0.01, ball_diameter=0.02, ball_mass=1e-3, fps=1000,
              pixel_size=1e-4)
    with pytest.raises(SetupError, match="fps"):
        Setup(cylinder_radius=0.1, ball_diameter=0.02, ball_mass=1e-3, fps=math.nan,
              pixel_size=1e-4)
