"""Reading the project's TOML files (setups, scenarios, cases) with one kind of error."""

from __future__ import annotations

import tomllib
from pathlib import Path

from rollfric.errors import InputError


def read_toml(path: str | Path, what: str, error: type[InputError] = InputError) -> dict:
    """The table in the TOML file at ``path``.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    what : str
        What the file is ("setup", "scenario", ...), for the error message.
    error : type, optional
        The :class:`~rollfric.errors.InputError` subclass raised.

    Returns
    -------
    dict
        The parsed table.

    Raises
    ------
    InputError
        ``error``, naming ``what`` and the path, when the file is missing, a directory, or not
        valid TOML.
    """
    path = Path(path)
    try:
        with path.open("rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise error(f"{what} file not found: {path}") from None
    except IsADirectoryError:
        raise error(f"{what} file {path} is a directory") from None
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {exc}") from None
