"""The ``rollfric`` command: one entry point, one subcommand per stage.

Each stage registers its own subcommands through a ``register(subparsers)`` function in a
light module (argparse only); the heavy imports happen inside the handlers, so ``rollfric fit``
does not load MuJoCo or OpenGL.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from rollfric.errors import InputError

# module that registers subcommands, in the order --help lists them
_SUBCOMMAND_MODULES = [
    "rollfric.cli_fit",
    "rollfric.cli_measure",
    "sim.cli",
    "synth.cli",
    "validation.cli",
    "validation.cli_bench",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rollfric",
        description=(
            "Measure rolling friction of a ball in a cylindrical trough from high-speed camera "
            "recordings, and validate the measurement end to end against simulated and "
            "rendered ground truth. mu is defined by M = mu * r * N throughout."),
    )
    parser.add_argument("--version", action="version", version=_version())
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in _SUBCOMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"rollfric {version('rollfric')}"
    except PackageNotFoundError:
        return "rollfric (not installed)"


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        result = args.func(args)
    except InputError as exc:
        print(f"rollfric {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"rollfric {args.command}: interrupted", file=sys.stderr)
        return 130
    return int(result or 0)


if __name__ == "__main__":
    sys.exit(main())
