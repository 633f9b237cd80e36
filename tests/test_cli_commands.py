"""The command line's two installs: rollfric alone, and rollfric with the validation suite.

rollfric imports nothing of sim, synth or validation; their commands come from the
``rollfric.commands`` entry points, loaded only when the ``suite`` extra is installed.
"""

from __future__ import annotations

import ast
import importlib.metadata
import importlib.util
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import rollfric
from rollfric.cli import main as cli

SUITE_PACKAGES = ("sim", "synth", "validation")
ROLLFRIC_DIR = Path(rollfric.__file__).parent
REPO = ROLLFRIC_DIR.parent


def _run(code: str, tmp_path: Path, block_suite: bool = False) -> subprocess.CompletedProcess:
    code = (textwrap.dedent(BLOCK_SUITE) if block_suite else "") + textwrap.dedent(code)
    return subprocess.run([sys.executable, "-c", code], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})


# A meta path finder that makes the suite's packages unimportable, as in an install without them.
BLOCK_SUITE = """
    import sys
    class Block:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in ("sim", "synth", "validation"):
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    sys.meta_path.insert(0, Block())
"""


@pytest.mark.parametrize("path", sorted(ROLLFRIC_DIR.rglob("*.py")), ids=lambda p: p.name)
def test_rollfric_sources_neither_import_nor_name_the_suite(path):
    text = path.read_text()
    for node in ast.walk(ast.parse(text, filename=str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        else:
            continue
        for name in names:
            assert name.split(".")[0] not in SUITE_PACKAGES, (path.name, node.lineno, name)
    # nor as text (importlib.import_module("sim.cli"), an entry point's value, a comment)
    assert not re.findall(r"\b(?:sim|synth|validation)\.\w*", text), path.name


def test_without_the_suite_every_rollfric_module_imports_and_suite_commands_exit_2(tmp_path):
    proc = _run("""
        import contextlib, io, pkgutil, importlib
        import rollfric
        for mod in pkgutil.walk_packages(rollfric.__path__, "rollfric."):
            importlib.import_module(mod.name)
        from rollfric.cli.main import build_parser, main
        print("HELP", build_parser().format_help())
        for argv in (["validate"], ["validate", "--help"], ["sweep", "x.toml", "--out", "d"],
                     ["simulate", "--mu", "0.01"], ["render", "t.csv"], ["bench"]):
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                print("STATUS", argv[0], main(argv))
            print("ERR", err.getvalue().strip())
        assert not [m for m in sys.modules if m.split(".")[0] in ("sim", "synth", "validation")]
    """, tmp_path, block_suite=True)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    for name in cli.SUITE_COMMANDS:
        assert f"    {name} " in out.split("STATUS")[0], name   # listed in --help
        assert f"STATUS {name} 2" in out
    errors = [line for line in out.splitlines() if line.startswith("ERR")]
    assert len(errors) == 6
    for line in errors:
        assert line.startswith("ERR rollfric ") and 'pip install "rollfric[suite]"' in line, line
    assert not list(tmp_path.iterdir())   # nothing written


def test_without_the_suite_measurement_commands_still_parse(tmp_path):
    proc = _run("""
        from rollfric.cli.main import build_parser
        parser = build_parser()
        args = parser.parse_args(["fit", "track.csv", "--setup", "s.toml", "--out", "f.json"])
        print(args.command, args.func.__module__)
        for argv in (["fit", "--help"], ["measure", "--help"], ["info", "--help"],
                     ["track", "--help"]):
            try:
                parser.parse_args(argv)
            except SystemExit as exc:
                print("EXIT", exc.code)
    """, tmp_path, block_suite=True)
    assert proc.returncode == 0, proc.stderr
    assert "fit rollfric.cli.fit" in proc.stdout
    assert proc.stdout.count("EXIT 0") == 4


def test_building_the_parser_loads_nothing_of_the_suites_stack(tmp_path):
    proc = _run("""
        import sys
        from rollfric.cli.main import build_parser
        build_parser()
        # SciPy and numba too: --help should not wait for them (0.65 s against 0.27 s)
        heavy = ("mujoco", "pybullet", "pyrender", "OpenGL", "trimesh", "dask", "distributed",
                 "pyarrow", "skimage", "scipy", "numba", "pandas", "matplotlib")
        print(sorted(m for m in sys.modules if m.split(".")[0] in heavy))
    """, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


def test_the_suites_commands_come_from_entry_points_that_need_the_suite_extra():
    eps = cli.command_entry_points()
    if not eps:
        pytest.fail("no rollfric.commands entry points: install the project "
                    '(pip install -e ".[suite,test]") so that its metadata is there')
    suite_installed = importlib.util.find_spec("mujoco") is not None
    registered = set()
    for ep in eps:
        assert ep.extras == ["suite"] and ep.value.split(".")[0] in SUITE_PACKAGES, ep
        missing = cli.missing_requirements(ep)
        assert (missing == []) == suite_installed, missing
        assert suite_installed or "mujoco" in missing
        sub = cli.argparse.ArgumentParser().add_subparsers()
        ep.load()(sub)   # light modules: they load without the suite's packages
        registered |= set(sub.choices)
    assert registered == set(cli.SUITE_COMMANDS)
    # the suite's own parsers when it is installed (validate has --seed), stand-ins otherwise
    choices = cli.build_parser()._subparsers._group_actions[0].choices
    assert ("--seed" in choices["validate"].format_help()) == suite_installed


def test_a_missing_requirement_of_the_suite_makes_its_commands_exit_2(monkeypatch, tmp_path,
                                                                      capsys):
    if not cli.command_entry_points():
        pytest.fail("no rollfric.commands entry points: install the project first")
    real = importlib.metadata.distribution

    def without_mujoco(name):
        if name == "mujoco":
            raise importlib.metadata.PackageNotFoundError(name)
        return real(name)

    monkeypatch.setattr(importlib.metadata, "distribution", without_mujoco)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["validate"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rollfric validate: error: ") and "mujoco" in err
    assert 'pip install "rollfric[suite]"' in err
    parser = cli.build_parser()
    assert parser.parse_args(["fit", "t.csv", "--setup", "s.toml", "--out", "f.json"]).func
    assert not list(tmp_path.iterdir())


def _fake_distribution(root: Path, requires: list[str]) -> Path:
    info = root / "fakeplug-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fakeplug\nVersion: 1.0\n"
                                   "Provides-Extra: heavy\n"
                                   + "".join(f"Requires-Dist: {r}\n" for r in requires))
    (info / "entry_points.txt").write_text(
        "[rollfric.commands]\nfakeplug = fakeplug_cli:register [heavy]\nplain = x:register\n")
    return root


@pytest.mark.parametrize(("requires", "missing"), [
    (['numpy', 'surely-not-installed-xyz; extra == "heavy"', 'numpy; extra == "heavy"'],
     ["surely-not-installed-xyz"]),
    (['surely-not-installed-xyz', 'numpy; extra == "heavy"',
      'also-absent-abc; extra == "other"'], []),
    (['a-absent-one; extra == "heavy" and python_version >= "3"',
      'numpy; python_version >= "3"', 'b-absent-two ; extra == "heavy"'],
     ["a-absent-one", "b-absent-two"]),
])
def test_missing_requirements_reads_the_extras_of_the_entry_points_distribution(
        tmp_path, requires, missing):
    root = _fake_distribution(tmp_path, requires)
    (dist,) = importlib.metadata.distributions(path=[str(root)])
    eps = {ep.name: ep for ep in dist.entry_points}
    assert eps["fakeplug"].extras == ["heavy"]
    assert cli.missing_requirements(eps["fakeplug"]) == missing
    assert cli.missing_requirements(eps["plain"]) == []   # names no extra: nothing needed


def test_sigterm_runs_the_cleanup_and_exits_143(monkeypatch, capsys):
    # SIGTERM (a job scheduler's stop, `kill`) ends a command as Ctrl-C does: every `finally`
    # runs (temporary outputs removed, render processes shut down), exit 143; the previous
    # handler is back afterwards
    import argparse
    import os
    import signal

    from rollfric.cli import main as cli

    cleaned = []

    def work(args):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(1000):  # the handler runs at the next bytecode
                pass
            return 0
        finally:
            cleaned.append(True)

    def parser():
        p = argparse.ArgumentParser(prog="rollfric")
        sub = p.add_subparsers(dest="command")
        sub.add_parser("slow").set_defaults(func=work)
        return p

    monkeypatch.setattr(cli, "build_parser", parser)
    before = signal.getsignal(signal.SIGTERM)
    assert cli.main(["slow"]) == 143
    assert cleaned == [True]
    assert "rollfric slow: terminated" in capsys.readouterr().err
    assert signal.getsignal(signal.SIGTERM) is before


def test_the_exit_freezes_what_the_command_left_for_the_collector(tmp_path):
    # gc.freeze runs at the interpreter's exit (atexit, registered once by main), not when
    # main returns: a process that goes on (these tests) keeps its collector as it was
    code = textwrap.dedent("""
        import atexit, gc, sys
        atexit.register(lambda: print("frozen at exit", gc.get_freeze_count() > 0))
        from rollfric.cli import main as cli
        for name in ("a", "b"):  # twice; a command of rollfric's own (bad input: exit 2), as
            # the measurement-only install runs this file too (`simulate` is the suite's)
            assert cli.main(["fit", sys.argv[1] + name + ".csv", "--setup",
                             sys.argv[1] + "none.toml", "--out", sys.argv[1] + name]) == 2
        print("frozen after main", gc.get_freeze_count())
        print("registered", cli._freeze_registered)
    """)
    r = subprocess.run([sys.executable, "-c", code, f"{tmp_path}/"],
                       capture_output=True, text=True, timeout=120,
                       env={**__import__("os").environ,
                            "PYTHONPATH": __import__("os").pathsep.join(sys.path)})
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[-3:] == ["frozen after main 0", "registered [True]",
                                          "frozen at exit True"]
