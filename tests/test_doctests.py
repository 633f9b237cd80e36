"""The Examples of the public API run as doctests: every module that defines a name of
``rollfric.__all__`` (and ``rollfric`` itself, and the help formatter), with their real
outputs; and every public name has an Examples section of its own."""

import doctest
import importlib
import inspect

import pytest

import rollfric

MODULES = sorted({"rollfric", "rollfric.cli.helpformat", *rollfric._WHERE.values()})


@pytest.mark.parametrize("name", MODULES)
def test_the_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # an example that writes leaves nothing in the checkout
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE, report=True)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0, f"{result.failed} example(s) of {name} failed (output above)"


@pytest.mark.parametrize("name", rollfric.__all__)
def test_every_public_name_has_runnable_examples(name):
    obj = getattr(rollfric, name)
    doc = inspect.getdoc(obj)
    assert "\nExamples\n--------\n" in doc, f"rollfric.{name}: no Examples section"
    assert doctest.DocTestParser().get_examples(obj.__doc__), f"rollfric.{name}: no >>>"
    if callable(obj) and not inspect.isclass(obj):
        assert "\nParameters\n----------\n" in doc and "\nReturns\n-------\n" in doc, name
