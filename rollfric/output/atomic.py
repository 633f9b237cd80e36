"""Writing files and directories all at once: a reader never sees half of one.

Everything the project writes goes to a temporary path beside its destination and is moved
into place (``os.replace``, atomic on one file system) only when complete; on an error the
temporary path is removed and the destination is left as it was.

Temporary paths are hidden and name the process that writes them:
``.NAME.part-PID-START.SUFFIX`` (START: the process's start time, so a reused PID is told
apart). A run that is killed cannot remove its temporary path; :func:`remove_leftovers` removes
those whose process is gone (or whose PID now belongs to another process), and every command
calls it for the folders it writes in.

A file never replaces a directory and a directory never replaces a file: :func:`replacing`
raises :class:`~rollfric.errors.InputError` instead (a directory replaces a directory only
when the caller says so, ``folder_ok=True``).
"""

from __future__ import annotations

import contextlib
import functools
import os
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

from rollfric.errors import InputError

# .NAME.part-PID[-START][.SUFFIX] (temporary output) and .NAME.old-PID[-START][.SUFFIX] (a
# directory moved aside while being replaced); names without START come from older versions
_TEMP_RE = re.compile(r"^\.(?P<stem>.*)\.(?P<kind>part|old)-(?P<pid>\d+)(?:-(?P<start>\d+))?"
                      r"(?P<suffix>\.[^.]*)?$")


@functools.cache
def _own_start() -> int:
    return _start_time(os.getpid()) or 0


def _start_time(pid: int) -> int | None:
    """The start time of process ``pid`` (1/100 s since the epoch), None when no such process
    exists; 0 when it exists but its start time cannot be read."""
    try:
        import psutil
    except ImportError:  # pragma: no cover - psutil is a dependency
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None
        except PermissionError:
            return 0
        return 0
    try:
        return int(round(psutil.Process(pid).create_time() * 100))
    except psutil.NoSuchProcess:
        return None
    except psutil.AccessDenied:
        return 0


def temp_path(path: str | Path, kind: str = "part") -> Path:
    """The hidden temporary path of this process beside ``path``.

    Parameters
    ----------
    path : str or pathlib.Path
        The destination.
    kind : str, optional
        ``"part"`` (an output being written) or ``"old"`` (a folder moved aside).

    Returns
    -------
    pathlib.Path
        ``.NAME.KIND-PID-START.SUFFIX`` beside ``path`` (the same suffix, so writers that go by
        the suffix pick the same format).
    """
    path = Path(path)
    return path.with_name(f".{path.stem}.{kind}-{os.getpid()}-{_own_start()}{path.suffix}")


def is_leftover(path: str | Path) -> bool:
    """Whether ``path`` is a temporary path left by a process that no longer runs.

    Parameters
    ----------
    path : str or pathlib.Path
        Any path; only names of the :func:`temp_path` form can be leftovers.

    Returns
    -------
    bool
        True when its PID is gone, or now belongs to a process started at another time.
    """
    m = _TEMP_RE.match(Path(path).name)
    if m is None:
        return False
    pid = int(m["pid"])
    start = None if m["start"] is None else int(m["start"])
    if pid == os.getpid():
        return start != _own_start()  # ours only if it carries this process's start time
    now = _start_time(pid)
    if now is None:
        return True
    return start is not None and now != 0 and now != start


def remove_leftovers(folder: str | Path, prefix: str = ".") -> list[Path]:
    """Remove the temporary paths left by killed runs in a folder (not its subfolders).

    Parameters
    ----------
    folder : str or pathlib.Path
        The folder; a missing or unreadable one removes nothing.
    prefix : str, optional
        Only names that start with it (in a shared folder such as /tmp: only this
        program's own kind of temporary path).

    Returns
    -------
    list of pathlib.Path
        What was removed.
    """
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        if e.name.startswith(".") and e.name.startswith(prefix) and is_leftover(e.path):
            remove_path(Path(e.path))
            removed.append(Path(e.path))
    return removed


def remove_path(path: Path) -> None:
    """Remove a file, a link or a folder with its contents; one that is gone already, or that
    cannot be removed, is left alone.

    Parameters
    ----------
    path : pathlib.Path
    """
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError, IsADirectoryError, PermissionError):
            path.unlink()


def install(tmp: Path, path: Path, *, folder_ok: bool = False) -> None:
    """Move a finished temporary file or folder to its destination.

    Parameters
    ----------
    tmp : pathlib.Path
        The finished output.
    path : pathlib.Path
        Its destination.
    folder_ok : bool, optional
        Whether a folder may replace an existing folder (the old one is moved aside first and
        removed once the new one is in place).

    Raises
    ------
    InputError
        A file would replace a folder or a folder a file, or a folder a folder without
        ``folder_ok``.
    """
    new_is_dir = tmp.is_dir() and not tmp.is_symlink()
    old_is_dir = path.is_dir() and not path.is_symlink()
    if old_is_dir and not new_is_dir:
        raise InputError(f"{path} is a folder: a file is not written in its place")
    if path.exists() and not old_is_dir and new_is_dir:
        raise InputError(f"{path} is a file: a folder is not written in its place")
    if not old_is_dir:
        os.replace(tmp, path)
        return
    if not folder_ok:
        raise InputError(f"{path} is an existing folder: not replaced")
    aside = temp_path(path, "old")
    remove_path(aside)
    os.replace(path, aside)
    try:
        os.replace(tmp, path)
    except BaseException:
        os.replace(aside, path)
        raise
    remove_path(aside)


@contextlib.contextmanager
def replacing(path: str | Path, *, folder_ok: bool = False) -> Iterator[Path]:
    """Write ``path`` all at once: a temporary path to write, moved into place at the end.

    Parameters
    ----------
    path : str or pathlib.Path
        The destination (its folder is created).
    folder_ok : bool, optional
        Whether the output (a folder) may replace an existing folder (see :func:`install`).

    Yields
    ------
    pathlib.Path
        The temporary path beside ``path``, with the same suffix. When the block succeeds it
        replaces ``path``; on an error it is removed and ``path`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_path(path)
    remove_path(tmp)
    try:
        yield tmp
        install(tmp, path, folder_ok=folder_ok)
    except BaseException:
        remove_path(tmp)
        raise


def write_text(path: str | Path, text: str) -> Path:
    """Write text to a file atomically.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    text : str
        Written as UTF-8, newlines as given.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    with replacing(path) as tmp:
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            f.write(text)
    return Path(path)
