"""Where a command writes: nothing of the user's is deleted or mixed with new results.

Every command checks its destinations before it does any work (exit status 2 and nothing
written when one is refused):

- a destination that exists is refused unless the user said ``--overwrite``;
- a file is never written where a folder is, nor a folder where a file is, even with
  ``--overwrite``; a destination under a regular file, or in a folder that cannot be written, is
  refused with a message naming it;
- an output *folder* (``measure --out DIR``, ``validate``, ``bench``, ``render --export``) may
  hold other files: ``--overwrite`` replaces the command's own outputs (a known list of names)
  and removes those of its own outputs it did not write this time (an old ``fit.png`` does not
  stay beside a new ``track.csv``), and leaves every other file alone;
- the outputs go to a hidden temporary folder first, which becomes the output folder in one
  step when all are written (a run killed at any moment leaves the old folder or the new one);
  temporary paths of killed runs are removed by the next run (:mod:`rollfric.output.atomic`);
- while a run writes a folder it holds it (:mod:`rollfric.output.swap`): a second run into it is
  refused.
"""

from __future__ import annotations

import contextlib
import errno
import os
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

from rollfric.errors import InputError
from rollfric.output.atomic import (
    install,
    is_leftover,
    remove_leftovers,
    remove_path,
    temp_path,
)
from rollfric.output.swap import claim, exchange

FILE = "file"
FOLDER = "folder"


class OutputError(InputError):
    """A destination that the command will not write (exists, wrong kind, not writable)."""


def _existing_ancestor(path: Path, what: str) -> Path:
    """The nearest existing ancestor of ``path``; OutputError if it is not a writable folder."""
    anc = path.parent
    while not anc.exists() and anc != anc.parent:
        if anc.is_symlink():  # a dangling link: mkdir would fail
            raise OutputError(f"{what} {path}: {anc} is a broken link")
        anc = anc.parent
    if not anc.is_dir():
        raise OutputError(f"{what} {path}: {anc} is a file, not a folder")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: cannot write in {anc} (permission denied)")
    return anc


def named(path: str | Path, what: str = "--out") -> Path:
    """An output path that has a name to write beside: ``.``, ``..`` and ``""`` (the folder
    the command runs in, its parent) made absolute.

    Parameters
    ----------
    path : str or pathlib.Path
        The output as given.
    what : str, optional
        How the message names the output.

    Returns
    -------
    pathlib.Path
        ``path``, absolute when its last part is ``.`` or ``..``.

    Raises
    ------
    OutputError
        The path is the file system's root, beside which nothing can be staged.
    """
    p = Path(path)
    if p.name in ("", ".", ".."):
        p = Path(os.path.abspath(p))
        if not p.name:
            raise OutputError(f"{what} {path}: the root folder cannot be an output")
    return p


def check_file(path: str | Path, *, overwrite: bool, what: str = "--out") -> Path:
    """Check, before any work, that a command may write the file ``path``.

    Parameters
    ----------
    path : str or pathlib.Path
        The output file.
    overwrite : bool
        Whether the user said ``--overwrite``.
    what : str, optional
        How the message names the output.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputError
        A folder is there; it exists and ``overwrite`` is false; its folder cannot be made
        (a regular file on the way) or written.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{what} {path} is a folder (this output is a file; a folder is "
                          "never replaced by a file)")
    if path.exists() or path.is_symlink():
        if not overwrite:
            raise OutputError(f"{what} {path} exists (--overwrite replaces it)")
        if not os.access(path.parent, os.W_OK | os.X_OK):
            raise OutputError(f"{what} {path}: cannot write in {path.parent} "
                              "(permission denied)")
        return path
    _existing_ancestor(path, what)
    return path


def _entries(folder: Path) -> list[Path]:
    """The folder's entries, without the temporary paths of killed runs."""
    return [p for p in folder.iterdir() if not (p.name.startswith(".") and is_leftover(p))]


def check_folder(path: str | Path, own: Mapping[str, str], *, overwrite: bool,
                 what: str = "--out", command: str = "the command") -> Path:
    """Check, before any work, that a command may write its output folder ``path``.

    An existing empty folder (temporary paths of killed runs aside) is used as it is.

    Parameters
    ----------
    path : str or pathlib.Path
        The output folder.
    own : mapping of str to str
        The command's own output names in it, each ``FILE`` or ``FOLDER``.
    overwrite : bool
        Whether the user said ``--overwrite``.
    what, command : str, optional
        How the message names the output and the command.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputError
        It is a file; it holds anything and ``overwrite`` is false; one of the ``own`` names is
        there as the other kind; it cannot be made or written.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{what} {path} is a file (this output is a folder; a file is never "
                          "replaced by a folder)")
    if not path.exists():
        _existing_ancestor(path, what)
        return path
    try:
        entries = _entries(path)
    except PermissionError:
        raise OutputError(f"{what} {path}: cannot read the folder (permission denied)") from None
    if entries and not overwrite:
        raise OutputError(f"{what} {path} exists and is not empty (--overwrite replaces "
                          f"{command}'s own files in it and leaves the others alone)")
    for name, kind in own.items():
        p = path / name
        if kind == FILE and p.is_dir():
            raise OutputError(f"{what}: {p} is a folder where {command} writes a file: "
                              "not replaced")
        if kind == FOLDER and p.exists() and not p.is_dir():
            raise OutputError(f"{what}: {p} is a file where {command} writes a folder: "
                              "not replaced")
    if not os.access(path, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: cannot write in the folder (permission denied)")
    return path


def check_distinct(paths: Iterable[str | Path], what: str = "outputs") -> None:
    """Check that the outputs of a command do not collide.

    Parameters
    ----------
    paths : iterable of str or pathlib.Path
        The paths a command writes.
    what : str, optional
        How the message names them.

    Raises
    ------
    OutputError
        Two of them are the same path.
    """
    seen: dict[Path, Path] = {}
    for p in paths:
        key = Path(os.path.abspath(p))
        if key in seen:
            raise OutputError(f"{what}: {seen[key]} and {p} are the same path")
        seen[key] = Path(p)


def check_not_input(out: str | Path, inputs: Iterable[str | Path | None],
                    what: str = "--out") -> None:
    """Check that an output is not one of the command's inputs.

    Parameters
    ----------
    out : str or pathlib.Path
        The output.
    inputs : iterable of str, pathlib.Path or None
        The inputs (None entries are skipped).
    what : str, optional
        How the message names the output.

    Raises
    ------
    OutputError
        ``out`` is the same path or the same file as an input.
    """
    o = Path(os.path.abspath(out))
    for i in inputs:
        if i is None:
            continue
        same = Path(os.path.abspath(i)) == o
        if not same:
            with contextlib.suppress(OSError):
                same = o.exists() and os.path.samefile(o, i)
        if same:
            raise OutputError(f"{what} {out} is an input of the command ({i})")


def remove_stale(folder: str | Path, names: Iterable[str]) -> list[Path]:
    """Remove a command's own outputs that it did not write this time.

    Parameters
    ----------
    folder : str or pathlib.Path
        Where they are.
    names : iterable of str
        Their names.

    Returns
    -------
    list of pathlib.Path
        What was removed.
    """
    removed = []
    for name in names:
        p = Path(folder) / name
        if p.exists() or p.is_symlink():
            remove_path(p)
            removed.append(p)
    return removed


# the signals (SIGINT, SIGTERM) that reached the running command, noted by rollfric.cli.main: a
# signal whose exception was swallowed where it landed (numba's compiler calls back through
# ctypes, which prints such an exception and drops it) still keeps the outputs out of place
signals_received: list[int] = []


class Interrupted(BaseException):
    """The command was interrupted while it ran (a signal in :data:`signals_received`): its
    outputs are not put in place. A BaseException, as KeyboardInterrupt is."""


@contextlib.contextmanager
def staged_folder(out: str | Path, own: Mapping[str, str], *, overwrite: bool,
                  what: str = "--out", command: str = "the command") -> Iterator[Path]:
    """Write a command's outputs into a folder all at once, its other files left alone.

    Parameters
    ----------
    out : str or pathlib.Path
        The output folder (created if needed; checked with :func:`check_folder`).
    own : mapping of str to str
        The command's own output names, each ``FILE`` or ``FOLDER``; every name written must
        be one of them.
    overwrite : bool
        Whether the user said ``--overwrite``.
    what, command : str, optional
        How messages name the output and the command.

    Yields
    ------
    pathlib.Path
        An empty hidden folder beside ``out`` to write the outputs in. When the block succeeds
        it becomes ``out`` in one step (renamed, or swapped with an existing ``out`` after
        the user's other files there are hard-linked into it): the ``own`` names written
        replace the old ones, those not written this time are gone, the user's files stay;
        on an error nothing in ``out`` changes. While the block runs ``out`` is claimed
        (:func:`rollfric.output.swap.claim`): another run into it is refused.

    Raises
    ------
    OutputError
        As :func:`check_folder`; or another run is writing ``out``, or wrote it meanwhile.
    """
    out = Path(out)
    check_folder(out, own, overwrite=overwrite, what=what, command=command)
    out.parent.mkdir(parents=True, exist_ok=True)
    with claim(out, what):
        # again, now that no other run of ours can: one may have written it meanwhile
        check_folder(out, own, overwrite=overwrite, what=what, command=command)
        remove_leftovers(out.parent)
        tmp = temp_path(out)
        remove_path(tmp)
        tmp.mkdir()
        try:
            yield tmp
            written = sorted(p.name for p in tmp.iterdir())
            unknown = [n for n in written if n not in own]
            if unknown:
                raise RuntimeError(f"{command} wrote {unknown}, not among its own output names")
            # again: the folder may have changed while the command ran
            check_folder(out, own, overwrite=overwrite, what=what, command=command)
            if signals_received:
                raise Interrupted(signals_received[-1])
            _put_in_place(tmp, out, own, written, what)
        finally:
            remove_path(tmp)


def _put_in_place(tmp: Path, out: Path, own: Mapping[str, str], written: list[str],
                  what: str) -> None:
    """Make the finished folder ``tmp`` the outputs of ``out`` in one step where it can be.

    ``out`` absent: ``tmp`` renamed to it. ``out`` a folder whose other entries are files:
    they are hard-linked into ``tmp``, which then swaps places with ``out`` at once
    (:func:`rollfric.output.swap.exchange`). Otherwise (``out`` the folder this process runs in, a
    link, holding folders of the user's, or no atomic swap here) the outputs are moved in one
    at a time as before.
    """
    if not os.path.lexists(out):
        try:
            os.rename(tmp, out)
        except OSError as exc:  # made, and filled, by someone else since the check
            if exc.errno in (errno.EEXIST, errno.ENOTEMPTY, errno.EISDIR, errno.ENOTDIR):
                raise OutputError(f"{what} {out} was written by another process while this "
                                  "run worked: not replaced") from None
            raise
        return
    if _swappable(out) and _link_others(tmp, out, own):
        os.chmod(tmp, os.stat(out).st_mode & 0o7777)
        if exchange(tmp, out):
            # tmp now holds the old folder: anything there that is no output of ours and was
            # not linked across (written by someone during the swap) is moved over, then the
            # old folder goes
            for e in os.scandir(tmp):
                if e.name not in own and not os.path.lexists(out / e.name) \
                        and not (e.name.startswith(".") and is_leftover(e.path)):
                    os.rename(e.path, out / e.name)
            return
        for e in os.scandir(tmp):  # no swap here: the links go again
            if e.name not in written:
                remove_path(Path(e.path))
    out.mkdir(exist_ok=True)
    remove_leftovers(out)
    for name in written:
        install(tmp / name, out / name, folder_ok=True)
    remove_stale(out, [n for n in own if n not in written])


def _swappable(out: Path) -> bool:
    """Whether ``out`` may swap places with a new folder: a real folder, not the one this
    process runs in (its working directory would stay with the old one)."""
    if out.is_symlink() or not out.is_dir():
        return False
    with contextlib.suppress(OSError):
        if os.path.samefile(out, os.getcwd()):
            return False
    return True


def _link_others(tmp: Path, out: Path, own: Mapping[str, str]) -> bool:
    """Hard-link ``out``'s entries that are not the command's into ``tmp``; False (and none
    linked) when one is a folder or cannot be linked."""
    others = [e for e in os.scandir(out) if e.name not in own
              and not (e.name.startswith(".") and is_leftover(e.path))]
    if any(e.is_dir(follow_symlinks=False) for e in others):
        return False
    done = []
    try:
        for e in others:
            os.link(e.path, tmp / e.name, follow_symlinks=False)
            done.append(tmp / e.name)
    except OSError:
        for p in done:
            remove_path(p)
        return False
    return True
