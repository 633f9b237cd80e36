"""The project's structure: registries that load and have their interface, the CLI's choices
taken from them, readers that are FrameSources."""

import argparse

import numpy as np
import pytest

from rollfric import io
from rollfric.errors import InputError
from rollfric.fit import FitMethod
from rollfric.locate import Locator
from rollfric.registry import FIT_METHODS, LOCATORS, Registry
from sim.engines import ENGINES, Engine


@pytest.mark.parametrize(("registry", "protocol"), [(LOCATORS, Locator),
                                                    (FIT_METHODS, FitMethod),
                                                    (ENGINES, Engine)])
def test_every_registered_name_loads_and_has_the_interface(registry, protocol):
    assert len(registry) >= 3
    for name in registry:
        assert isinstance(registry.load(name), protocol), name


def test_an_unknown_name_is_bad_input_naming_the_known_ones():
    with pytest.raises(InputError, match=r"unknown locator 'hough' \(known: subpixel, "):
        LOCATORS.load("hough")
    assert Registry("thing", {"a": "math:pi"}).load("a") == pytest.approx(3.141592653589793)


def _choices(parser, command, option):
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return next(a.choices for a in sub.choices[command]._actions if option in a.option_strings)


def test_cli_choices_come_from_the_registries():
    from rollfric.cli import build_parser

    parser = build_parser()
    assert list(_choices(parser, "measure", "--method")) == list(LOCATORS)
    assert list(_choices(parser, "measure", "--fit-method")) == list(FIT_METHODS)
    assert list(_choices(parser, "fit", "--method")) == list(FIT_METHODS)
    assert list(_choices(parser, "simulate", "--engine")) == list(ENGINES)
    assert list(_choices(parser, "validate", "--engine")) == list(ENGINES)


def test_readers_are_frame_sources(tmp_path):
    import tifffile

    frames = np.arange(3 * 4 * 5, dtype=np.uint16).reshape(3, 4, 5)
    tifffile.imwrite(tmp_path / "rec.tif", frames)
    src = io.open_recording(tmp_path / "rec.tif")
    assert isinstance(src, io.FrameSource) and isinstance(src, io.RegionSource)
    assert not isinstance(object(), io.FrameSource)
