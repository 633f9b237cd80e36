"""A finished output folder put in place in one step, and a destination claimed by one run.

:func:`claim` holds an exclusive lock (``fcntl.flock``) on a hidden file beside an output
folder, ``.NAME.claim-rollfric``, while a command writes it: a second run into the same folder
is refused instead of both writing it. The lock dies with its process, so a killed run never
blocks the next one (its claim file is reused and removed by that run).

:func:`exchange` swaps two paths atomically (Linux's ``renameat2(RENAME_EXCHANGE)``): a new
folder takes an existing folder's place at once, so a reader (or a run killed at any moment)
sees the old folder or the new one, never a mixture.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
from collections.abc import Iterator
from pathlib import Path

from rollfric.errors import InputError

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
_held: dict[str, list] = {}  # claim file -> [fd, depth]: claims this process holds


def claim_path(out: str | Path) -> Path:
    """The claim file of output folder ``out``: ``.NAME.claim-rollfric`` beside it."""
    out = Path(out)
    return out.with_name(f".{out.name}.claim-rollfric")


@contextlib.contextmanager
def claim(out: str | Path, what: str = "--out") -> Iterator[Path]:
    """Hold output folder ``out`` for this run while the block runs.

    Parameters
    ----------
    out : str or pathlib.Path
        The output folder (its parent must exist).
    what : str, optional
        How the message names the output.

    Yields
    ------
    pathlib.Path
        The claim file. Re-entrant within a process; where ``fcntl`` is missing (Windows) the
        block runs unclaimed.

    Raises
    ------
    InputError
        Another process holds the claim (writes the same folder now).
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not a POSIX system
        yield claim_path(out)
        return
    path = claim_path(out)
    key = os.path.abspath(path)
    if key in _held:
        _held[key][1] += 1
        try:
            yield path
        finally:
            _held[key][1] -= 1
        return
    while True:
        fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise InputError(f"{what} {out} is being written by another run now (it holds "
                             f"{path.name}); run one at a time, or write elsewhere") from None
        try:  # the file may have been removed by its last holder while we opened it
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    _held[key] = [fd, 1]
    try:
        yield path
    finally:
        del _held[key]
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)  # still locked: no other run holds this file now
        os.close(fd)


def exchange(a: str | Path, b: str | Path) -> bool:
    """Swap paths ``a`` and ``b`` in one step.

    Parameters
    ----------
    a, b : str or pathlib.Path
        Two existing paths on one file system.

    Returns
    -------
    bool
        True when swapped; False where the system or file system cannot swap atomically
        (nothing changed then).
    """
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = (ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                          ctypes.c_uint)
    renameat2.restype = ctypes.c_int
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV):
        return False
    raise OSError(err, os.strerror(err), str(a), None, str(b))
