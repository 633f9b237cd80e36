"""Every command's --help: each option has a line of help, a default is shown once and only
when it says something, no path to a source file, an example command line, and the deprecated
--first-order hidden but still accepted."""

import argparse
import re
from pathlib import Path

import pytest

from rollfric.cli.helpformat import HelpFormatter
from rollfric.cli.main import build_parser


def _commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, sub.choices


PARSER, COMMANDS = _commands()
# the suite's commands are placeholders (no options) when the suite is not installed
REAL = {name: p for name, p in COMMANDS.items() if p.add_help}


def _option_help(parser, action):
    formatter = parser._get_formatter()
    return formatter._expand_help(action) if action.help else ""


@pytest.mark.parametrize("name", ["rollfric", *COMMANDS])
def test_help_names_no_source_file_and_no_none_default(name):
    parser = PARSER if name == "rollfric" else COMMANDS[name]
    text = parser.format_help()
    assert not re.search(r"[\w/]+\.py\b", text), name
    assert "(default: None)" not in text and "(default: False)" not in text
    assert "(default: [])" not in text
    assert parser.formatter_class is HelpFormatter


@pytest.mark.parametrize("name", ["rollfric", *REAL])
def test_every_command_shows_an_example(name):
    parser = PARSER if name == "rollfric" else REAL[name]
    assert parser.description
    text = parser.format_help()
    prog = "rollfric" if name == "rollfric" else f"rollfric {name}"
    assert "\nexample:\n  " in text, text[-400:]
    examples = text.split("\nexample:\n", 1)[1]
    assert re.search(rf"^  {re.escape(prog)} ", examples, re.M), examples


@pytest.mark.parametrize("name", list(REAL))
def test_every_option_has_help_and_one_default(name):
    parser = REAL[name]
    for action in parser._actions:
        if action.help is argparse.SUPPRESS:
            continue
        assert action.help and action.help.strip(), f"rollfric {name} {action.dest}: no help"
        text = _option_help(parser, action)
        assert text.lower().count("default") <= 1, f"rollfric {name} {action.dest}: {text}"


def test_the_formatter_shows_defaults_that_say_something():
    p = argparse.ArgumentParser(prog="demo", formatter_class=HelpFormatter)
    p.add_argument("--frames", type=int, default=41, help="frames in the median")
    p.add_argument("--spp", type=int, default=None, help="samples (default 256)")
    p.add_argument("--lighting", default="thesis", help="lighting (default: the case's)")
    p.add_argument("--set", action="append", default=[], help="a key")
    p.add_argument("--plot", action="store_true", help="plots")
    p.add_argument("--name", default="", help="a name")
    helps = {a.dest: _option_help(p, a) for a in p._actions}
    assert helps["frames"] == "frames in the median (default: 41)"
    assert helps["spp"] == "samples (default 256)"
    assert helps["lighting"] == "lighting (default: the case's)"
    assert helps["set"] == "a key" and helps["name"] == "a name" and helps["plot"] == "plots"


def test_the_formatter_keeps_indented_lines_and_whole_paths():
    p = argparse.ArgumentParser(prog="demo", formatter_class=HelpFormatter,
                                description="one two\nthree see docs/lab-validation.md " * 4,
                                epilog="example:\n  demo --a 1 --b 2\n\nmore: docs/x.md")
    text = p.format_help()
    assert "docs/lab-validation.md" in text
    assert "example:\n  demo --a 1 --b 2\n\nmore: docs/x.md" in text


def test_first_order_is_hidden_and_still_accepted():
    for name in ("fit", "measure"):
        assert "--first-order" not in COMMANDS[name].format_help()
    args = PARSER.parse_args(["fit", "t.csv", "--setup", "s.toml", "--out", "f.json",
                              "--first-order"])
    assert args.first_order is True


@pytest.mark.parametrize("name", ["rollfric", *REAL])
def test_the_docs_pages_named_in_help_exist(name):
    root = Path(__file__).resolve().parents[1]
    parser = PARSER if name == "rollfric" else REAL[name]
    pages = re.findall(r"docs/[\w/.-]+?\.md\b", parser.format_help())
    for page in pages:
        assert (root / page).is_file(), f"rollfric {name} --help names {page}, which is absent"
