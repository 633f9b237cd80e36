"""The help formatter of every ``rollfric`` command (argparse only: ``--help`` stays light).

Descriptions and epilogs are wrapped paragraph by paragraph (a blank line separates two), and a
paragraph with an indented line (an example command, a file layout) is kept as written. An
option's default is shown only when it says something: not None, False or empty, and not when
the option's help already speaks of its default.
"""

from __future__ import annotations

import argparse
import textwrap

__all__ = ["HelpFormatter", "example"]


def _says_something(default) -> bool:
    if default is None or default is False or default is argparse.SUPPRESS:
        return False
    return not (isinstance(default, (str, list, tuple, dict, set)) and len(default) == 0)


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """argparse's formatter with paragraphs and the defaults that say something.

    Use it as ``formatter_class`` of a command's parser.

    Examples
    --------
    >>> import argparse
    >>> p = argparse.ArgumentParser(prog="demo", formatter_class=HelpFormatter)
    >>> _ = p.add_argument("--frames", type=int, default=41, help="frames in the median")
    >>> _ = p.add_argument("--spp", type=int, default=None, help="samples (default 256)")
    >>> _ = p.add_argument("--plot", action="store_true", help="also write plots")
    >>> text = p.format_help()
    >>> "frames in the median (default: 41)" in text, "(default: None)" in text
    (True, False)
    """

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if ("%(default)" in text or "default" in text.lower()
                or not _says_something(action.default)):
            return text
        if action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE):
            return text + " (default: %(default)s)"
        return text

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        paragraphs = textwrap.dedent(text).strip("\n").split("\n\n")
        out = []
        for para in paragraphs:
            lines = para.splitlines()
            if any(line[:1].isspace() for line in lines):
                out.append("\n".join(indent + line for line in lines))
            else:
                out.append(textwrap.fill(" ".join(line.strip() for line in lines), width,
                                         initial_indent=indent, subsequent_indent=indent,
                                         break_on_hyphens=False))
        return "\n\n".join(out)

    def _split_lines(self, text: str, width: int) -> list[str]:
        # option names, paths and locator names stay whole (no break after a hyphen)
        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False)


def example(*commands: str, docs: str | None = None) -> str:
    """An epilog: example command lines, and the documentation page that says more.

    Parameters
    ----------
    *commands : str
        Command lines, shown one a line, indented (kept as written by :class:`HelpFormatter`).
    docs : str, optional
        The documentation page (a path under ``docs/``) that describes the command.

    Returns
    -------
    str
        The epilog text.

    Examples
    --------
    >>> print(example("rollfric info frames.tif", docs="docs/formats/recordings.md"))
    example:
      rollfric info frames.tif
    <BLANKLINE>
    more: docs/formats/recordings.md
    """
    text = "example:\n" + "\n".join("  " + c for c in commands)
    if docs:
        text += f"\n\nmore: {docs}"
    return text
