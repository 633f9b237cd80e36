"""Reading the project's TOML files (setups, scenarios, cases) with one kind of error."""

from __future__ import annotations

import tomllib
from pathlib import Path

from rollfric.errors import InputError


def decode_utf8(data: bytes, path: str | Path, error: type[InputError] = InputError) -> str:
    """The bytes of a text file decoded as UTF-8 (a leading byte-order mark dropped).

    Parameters
    ----------
    data : bytes
        The file's content.
    path : str or pathlib.Path
        The file, for the error message.
    error : type, optional
        The :class:`~rollfric.errors.InputError` subclass raised.

    Returns
    -------
    str
        The text.

    Raises
    ------
    InputError
        ``error``, naming the file, the line and the byte, when it is not UTF-8 (e.g. a comment
        saved as Latin-1).
    """
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise error(f"{path}: not UTF-8 text (byte 0x{data[exc.start]:02x} on line {line}; "
                    "save the file as UTF-8)") from None


def read_text(path: str | Path, what: str, error: type[InputError] = InputError) -> str:
    """The UTF-8 text of a file.

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
    str
        The text.

    Raises
    ------
    InputError
        ``error``, naming ``what`` and the path, when the file is missing, a directory,
        unreadable (permissions) or not UTF-8.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise error(f"{what} file not found: {path}") from None
    except IsADirectoryError:
        raise error(f"{what} file {path} is a directory") from None
    except OSError as exc:
        raise error(f"{what} file {path}: cannot be read ({exc.strerror or exc})") from None
    return decode_utf8(data, path, error)


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
        ``error``, naming ``what`` and the path, when the file is missing, a directory,
        unreadable, not UTF-8 or not valid TOML.
    """
    text = read_text(path, what, error)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {exc}") from None
