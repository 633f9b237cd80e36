"""The trough's centre step of a measurement (rollfric.geometry.trough_center): the setup's
center_px as given, else the drawn contour's known centre; a contour of another radius refused."""

import dataclasses
import logging
import math

import numpy as np
import pytest
from test_cylinder import XC, YC, R, draw_trough

from rollfric.geometry import trough_center as trough_center_mod
from rollfric.geometry.trough import find_cylinder_center
from rollfric.geometry.trough_center import trough_center
from rollfric.setup.model import SetupError, thesis_setup

SHAPE = (100, 1024, 1280)


def _setup(**changes):
    s = thesis_setup("10mm")
    return s.replace(**{"cylinder_radius": R * s.pixel_size, "center_px": None, **changes})


def test_the_setup_s_centre_is_taken_as_given():
    axis = trough_center(draw_trough(), _setup(center_px=(600.0, 300.0)), SHAPE)
    assert axis.center == (600.0, 300.0) and axis.center_u is None
    assert axis.source == "setup center_px" and axis.ellipse is None and axis.notes == ()


def test_the_drawn_contour_s_centre_is_found():
    axis = trough_center(draw_trough(blur=1.0), _setup(), SHAPE)
    assert math.hypot(axis.center[0] - XC, axis.center[1] - YC) < 0.01
    assert axis.center_u is not None and max(axis.center_u) < 0.05
    assert axis.source.startswith("contour in the background (")
    assert f"radius {R:.1f} px" in axis.source and axis.notes == ()


def test_a_contour_of_another_radius_than_the_setup_s_is_refused(monkeypatch):
    """A contour 20 % larger than cylinder.radius_mm / camera.pixel_size_mm says (the contour
    finder's answer scaled: a real one that far off is refused by the finder itself)."""
    found = find_cylinder_center(draw_trough(), radius_px=R)
    monkeypatch.setattr(trough_center_mod, "find_cylinder_center",
                        lambda *a, **k: dataclasses.replace(found, radius=1.2 * found.radius))
    with pytest.raises(SetupError, match=r"the trough contour in the background has a radius "
                                         rf"of {1.2 * found.radius:.1f} px, the setup says "
                                         rf"{R:.1f} px"):
        trough_center(draw_trough(), _setup(), SHAPE)


def test_a_saturated_contour_is_a_note_for_the_caller_to_log(caplog):
    """The backdrop clipped (as in test_cylinder): the note is returned, not yet logged (the
    measurement logs it after checking the setup with the centre)."""
    img = draw_trough(gradient=(0.3, -0.5))
    img = np.clip(img.astype(float) * 1.8, 0, 255).astype(np.uint8)  # the backdrop clips
    with caplog.at_level(logging.WARNING, logger="rollfric"):
        axis = trough_center(img, _setup(), SHAPE)
    assert len(axis.notes) == 1 and axis.notes[0].startswith("the trough contour is saturated")
    assert not caplog.records
