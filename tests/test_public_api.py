"""rollfric's declared public API: every name in __all__ is there, is what its module defines,
and `import rollfric` imports none of the heavy libraries until a name is used."""

import subprocess
import sys

import pytest

import rollfric


@pytest.mark.parametrize("name", rollfric.__all__)
def test_every_public_name_resolves_to_its_definition(name):
    obj = getattr(rollfric, name)
    assert obj.__module__.startswith("rollfric.")
    assert getattr(sys.modules[obj.__module__], name) is obj
    assert name in dir(rollfric)
    assert obj.__doc__, f"rollfric.{name} has no docstring"


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nonesuch'"):
        rollfric.nonesuch  # noqa: B018


def test_version_and_docstring():
    assert rollfric.__doc__ and "mu" in rollfric.__doc__
    assert rollfric.__version__ and rollfric.__version__[0].isdigit()


def test_import_rollfric_is_light():
    code = ("import sys, rollfric; heavy = {'numpy', 'scipy', 'numba', 'pandas', 'cv2', "
            "'matplotlib'} & set(sys.modules); print(sorted(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
