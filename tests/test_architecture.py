"""The project's structure: registries that load and have their interface, the CLI's choices
taken from them, readers that are FrameSources."""

import argparse

import numpy as np
import pytest

from rollfric.errors import InputError
from rollfric.fit.estimate import FitMethod
from rollfric.io import readers as io
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
    from rollfric.cli.main import build_parser

    parser = build_parser()
    assert list(_choices(parser, "measure", "--method")) == list(LOCATORS)
    assert list(_choices(parser, "measure", "--fit-method")) == list(FIT_METHODS)
    assert list(_choices(parser, "track", "--method")) == list(LOCATORS)
    assert list(_choices(parser, "fit", "--method")) == list(FIT_METHODS)
    assert list(_choices(parser, "simulate", "--engine")) == list(ENGINES)
    assert list(_choices(parser, "validate", "--engine")) == list(ENGINES)


def test_readers_are_frame_sources(tmp_path):
    import tifffile

    frames = np.arange(3 * 4 * 5, dtype=np.uint16).reshape(3, 4, 5)
    tifffile.imwrite(tmp_path / "rec.tif", frames, photometric="minisblack")
    src = io.open_recording(tmp_path / "rec.tif")
    assert isinstance(src, io.FrameSource) and isinstance(src, io.RegionSource)
    assert not isinstance(object(), io.FrameSource)


# -- the import graph: every import statement of the project's modules, also those inside
#    functions (a lazy import is still a dependency)

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
PACKAGES = ("rollfric", "sim", "synth", "validation")


def _import_graph() -> dict[str, set[str]]:
    import ast

    paths = {}
    for pkg in PACKAGES:
        for p in (ROOT / pkg).rglob("*.py"):
            parts = list(p.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            paths[".".join(parts)] = p

    def resolve(name):
        while name and name not in paths:
            name = name.rpartition(".")[0]
        return name

    graph = {}
    for mod, p in paths.items():
        here = mod.split(".") if p.name == "__init__.py" else mod.split(".")[:-1]
        deps = set()
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(here[:len(here) - node.level + 1] + ([base] if base else []))
                names = [f"{base}.{a.name}" if f"{base}.{a.name}" in paths else base
                         for a in node.names]
            else:
                continue
            deps.update(r for r in map(resolve, names) if r and r != mod)
        graph[mod] = deps
    return graph


def _a_cycle(graph):
    """One import cycle as a list of modules, or None."""
    state, stack = {}, []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                return stack[stack.index(d):] + [d]
            if d not in state:
                found = visit(d)
                if found:
                    return found
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state:
            found = visit(m)
            if found:
                return found
    return None


def test_no_import_cycles():
    graph = _import_graph()
    assert {"rollfric.fit.estimate", "rollfric.fit.thesis", "sim.scenario",
            "sim.engines.mujoco_engine", "validation.e2e", "validation.report"} <= set(graph)
    assert ("rollfric.fit.thesis" in graph["rollfric.fit.start"]
            or "rollfric.fit.start" in graph["rollfric.fit.thesis"])
    cycle = _a_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)
    assert _a_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]


def test_rollfric_imports_nothing_from_the_validation_suite():
    graph = _import_graph()
    bad = {m: sorted(d for d in deps if d.split(".")[0] != "rollfric")
           for m, deps in graph.items() if m.split(".")[0] == "rollfric"}
    assert not {m: d for m, d in bad.items() if d}


def test_pyrender_versions_outside_the_supported_range_say_what_to_do():
    from synth.pyrender_adapter import SUPPORTED, version_problem

    assert SUPPORTED == ((1, 0, 1), (1, 1))
    assert version_problem("1.0.1") is None and version_problem("1.0.7.post1") is None
    for bad in ("1.1.0", "1.0.0", "0.1.45", "2.0", None):
        msg = version_problem(bad)
        assert 'pip install "pyrender-maintained>=1.0.1,<1.1"' in msg
        assert "synth/pyrender_adapter.py" in msg


def test_only_the_adapter_touches_pyrenders_private_attributes():
    import ast

    from synth import pyrender_adapter

    private = {name for names in pyrender_adapter.INTERNALS.values() for name in names}
    for p in (ROOT / "synth").rglob("*.py"):
        if p.name == "pyrender_adapter.py":
            continue
        used = {n.attr for n in ast.walk(ast.parse(p.read_text(encoding="utf-8")))
                if isinstance(n, ast.Attribute) and n.attr in private}
        assert not used, f"{p.name} uses pyrender's {sorted(used)}: go through the adapter"


def test_a_command_prints_the_librarys_messages_and_stops_after(capsys):
    import logging

    from rollfric.cli.messages import to_stderr

    log = logging.getLogger("rollfric.track.tracker")
    with to_stderr("measure"):
        log.info("no background given")
        log.warning("the recording says 30 frames/s")
        logging.getLogger("sim").warning("not rollfric's")
    log.info("after the command")
    err = capsys.readouterr().err.splitlines()
    assert err[:2] == ["rollfric measure: no background given",
                       "rollfric measure: warning: the recording says 30 frames/s"]
    assert not any("after the command" in line or line.startswith("rollfric measure: not")
                   for line in err)
