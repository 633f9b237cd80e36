"""The ``rollfric`` command: one entry point, one subcommand per stage.

The measurement's own subcommands (``fit``, ``measure``) are registered here. Every other
subcommand comes from an installed entry point of the group ``rollfric.commands``: a
``register(subparsers)`` function in a light module (argparse only; the heavy imports happen
inside the handlers). The validation suite registers its commands that way, so ``rollfric``
imports nothing of it. An entry point that names extras (``module:register [suite]``) is loaded
only when the requirements of those extras are installed; otherwise its commands answer with
exit status 2 and the ``pip install`` line that brings them.
"""

from __future__ import annotations

import _thread
import argparse
import atexit
import functools
import gc
import importlib.metadata
import signal
import sys

from rollfric.cli import calibrate as cli_calibrate
from rollfric.cli import combine as cli_combine
from rollfric.cli import fit as cli_fit
from rollfric.cli import info as cli_info
from rollfric.cli import measure as cli_measure
from rollfric.cli import sample as cli_sample
from rollfric.cli import track as cli_track
from rollfric.cli.helpformat import HelpFormatter, example
from rollfric.errors import InputError

COMMAND_GROUP = "rollfric.commands"

# The validation suite's commands, known here only as text: `rollfric --help` lists them, and
# running one without the suite says how to install it. Their parsers come from the suite.
SUITE_COMMANDS = {
    "simulate": "ground-truth trajectory from an engine",
    "render": "render a trajectory as a synthetic camera recording with exact ground truth",
    "validate": "the main job: one case end to end against the truth, with a report",
    "sweep": "many validation cases on Dask, one table row per case, with plots",
    "bench": "speed and accuracy of every stage beside its baseline",
}
SUITE_INSTALL = 'pip install "rollfric[suite]"'


def build_parser() -> argparse.ArgumentParser:
    """The ``rollfric`` argument parser with every available subcommand.

    Returns
    -------
    argparse.ArgumentParser
        Subcommands in the order ``--help`` lists them: ``fit``, ``measure``, then those of
        the ``rollfric.commands`` entry points sorted by entry point name; the suite's commands
        are listed even when the suite is not installed (running one then exits with 2).
    """
    parser = argparse.ArgumentParser(
        prog="rollfric",
        description=(
            "Measure rolling friction of a ball in a cylindrical trough from high-speed camera "
            "recordings, and validate the measurement end to end against simulated and "
            "rendered ground truth. mu is defined by M = mu * r * N throughout."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric sample demo",
                       "rollfric measure demo/frames.tif --setup demo/setup.toml "
                       "--out demo/result --plot",
                       "rollfric COMMAND --help", docs="docs/guide/measure.md"),
    )
    parser.add_argument("--version", action="version", version=_version())
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    cli_fit.register(sub)
    cli_measure.register(sub)
    cli_track.register(sub)
    cli_calibrate.register(sub)
    cli_info.register(sub)
    cli_combine.register(sub)
    cli_sample.register(sub)
    reasons = []
    for ep in command_entry_points():
        missing = missing_requirements(ep)
        if missing:
            reasons.append(f"missing: {', '.join(missing)}")
            continue
        try:
            register = ep.load()
        except ImportError as exc:
            reasons.append(f"entry point {ep.name} ({ep.value}) cannot be loaded: {exc}")
            continue
        register(sub)
    for name, summary in SUITE_COMMANDS.items():
        if name not in sub.choices:
            _add_unavailable(sub, name, summary, "; ".join(dict.fromkeys(reasons)))
    return parser


def command_entry_points() -> list[importlib.metadata.EntryPoint]:
    """The installed entry points of the group ``rollfric.commands``, sorted by name.

    Returns
    -------
    list of importlib.metadata.EntryPoint
        One per distinct name (the first found wins, as in ``importlib.metadata``).
    """
    eps = importlib.metadata.entry_points(group=COMMAND_GROUP)
    return sorted(eps, key=lambda ep: ep.name)


def missing_requirements(ep: importlib.metadata.EntryPoint) -> list[str]:
    """The distributions that the extras named by an entry point need and that are absent.

    Parameters
    ----------
    ep : importlib.metadata.EntryPoint
        An entry point such as ``name = "package.module:register [suite]"``.

    Returns
    -------
    list of str
        Names of the requirements of the entry point's extras (in its distribution's metadata)
        that are not installed, in the metadata's order; empty when the entry point names no
        extras or all are installed.
    """
    if not ep.extras or ep.dist is None:
        return []
    from packaging.requirements import Requirement

    missing = []
    for text in ep.dist.requires or []:
        req = Requirement(text)
        if req.marker is None or req.marker.evaluate({"extra": ""}):
            continue  # a requirement of the base install, not of an extra
        if not any(req.marker.evaluate({"extra": extra}) for extra in ep.extras):
            continue
        try:
            importlib.metadata.distribution(req.name)
        except importlib.metadata.PackageNotFoundError:
            missing.append(req.name)
    return missing


def _add_unavailable(sub, name: str, summary: str, reason: str) -> None:
    p = sub.add_parser(name, add_help=False, help=f"{summary} (needs: {SUITE_INSTALL})",
                       description=f"{summary}. Needs the validation suite: {SUITE_INSTALL}",
                       formatter_class=HelpFormatter)
    p.set_defaults(func=functools.partial(_suite_missing, reason=reason), accepts_any=True)


def _suite_missing(args: argparse.Namespace, reason: str) -> int:
    why = f" ({reason})" if reason else ""
    raise InputError(f"this command belongs to the validation suite, which is not "
                     f"installed{why}: {SUITE_INSTALL} "
                     f'(in a source checkout: pip install -e ".[suite]")')


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"rollfric {version('rollfric')}"
    except PackageNotFoundError:
        return "rollfric (not installed)"


def _os_error_text(exc: OSError) -> str:
    """An OSError as 'PATH: problem' (the file first, as the other messages name it)."""
    what = exc.strerror or str(exc)
    if exc.filename is not None:
        names = f"{exc.filename}" + (f" -> {exc.filename2}" if exc.filename2 else "")
        return f"{names}: {what}"
    return str(exc)


class _Terminated(BaseException):
    """SIGTERM, raised in the main thread so that every ``finally`` runs (temporary outputs
    removed, render processes shut down) as after Ctrl-C; without it Python ends at once."""


_running: list[str] = []  # the commands main() runs (nested when one calls another)


def _on_signal(signum, frame):
    """SIGINT and SIGTERM while a command runs: noted (so that main() reports the signal
    whatever exception it ends up as), then raised in the main thread."""
    from rollfric.output.folder import signals_received  # noted where the outputs can see it

    signals_received.append(signum)
    if signum == signal.SIGTERM:
        raise _Terminated
    raise KeyboardInterrupt


_pending: list[int] = []  # signals caught in a finalizer, to be raised again (_redeliver)


def _redeliver(previous):
    """An unraisable-exception hook: a signal's exception raised where Python cannot raise it
    (an object's finalizer, e.g. llvmlite's as numba frees a function) is raised again a
    millisecond later from SIGALRM's handler (:func:`_on_alarm`), in the command's own code,
    instead of being printed and lost; any other goes to ``previous``. (Raising it from the
    hook itself would land in the hook, where Python cannot raise either.) Once a signal has
    reached the command, any other error of a finalizer is not printed: a signal raised inside
    an object's constructor leaves it half built, and its finalizer then fails (llvmlite's
    ``OutputString`` without ``_owned`` when SIGTERM lands as numba compiles a kernel)."""
    from rollfric.output.folder import signals_received

    def hook(unraisable):
        exc = unraisable.exc_value
        if not isinstance(exc, (KeyboardInterrupt, _Terminated)):
            if not signals_received:  # else the signal's echo: the command is ending on it
                previous(unraisable)
            return
        _pending.append(signal.SIGTERM if isinstance(exc, _Terminated) else signal.SIGINT)
        if hasattr(signal, "setitimer"):
            signal.setitimer(signal.ITIMER_REAL, 1e-3)
        else:  # no timer signal (Windows): the main thread's next check
            _thread.interrupt_main(_pending[-1])
    return hook


def _on_alarm(signum, frame):
    """SIGALRM after :func:`_redeliver`: the signal caught in a finalizer, raised again."""
    if _pending:
        _on_signal(_pending.pop(), frame)


def _interruption(exc: BaseException, received: list[int]) -> int | None:
    """The signal that ended a command with ``exc``: SIGINT for a KeyboardInterrupt, SIGTERM
    for _Terminated, anywhere in the exception's chain, else the last signal ``received``
    while it ran; None when no signal did."""
    seen = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, KeyboardInterrupt):
            return signal.SIGINT
        if isinstance(e, _Terminated):
            return signal.SIGTERM
        e = e.__cause__ or e.__context__
    return received[-1] if received else None


_freeze_registered: list[bool] = []  # gc.freeze registered with atexit (once a process)


def _freeze_at_exit() -> None:
    """Have the interpreter's exit skip the collector's passes over what the command left.

    At exit Python collects reference cycles among every object still alive (after ``rollfric
    validate``: numba's, SciPy's, pandas's and matplotlib's, millions of them), which took
    0.6-0.8 s after a validate had printed its summary. :func:`gc.freeze`, run by atexit
    before that clean-up, moves them all into the collector's permanent generation, which its
    passes skip: the memory goes back to the system with the process as before (the atexit
    handlers, ``finally`` blocks and the report's files are done by then). Registered once a
    process; in a process that goes on (tests calling :func:`main`) it runs only when that
    process ends (about half a second of a validate's exit: docs/history.md).
    """
    if not _freeze_registered:
        atexit.register(gc.freeze)
        _freeze_registered.append(True)


def main(argv: list[str] | None = None) -> int:
    """Run the ``rollfric`` command line.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after ``rollfric`` (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status: 0 good result, 2 bad input (or a command whose package is not
        installed), 3 a measurement that cannot be trusted, 130 interrupted (Ctrl-C),
        143 terminated (SIGTERM).
    """
    _freeze_at_exit()
    previous = {}
    try:
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, _on_signal)
        if hasattr(signal, "SIGALRM"):
            previous[signal.SIGALRM] = signal.signal(signal.SIGALRM, _on_alarm)
    except ValueError:  # not the main thread: signals are the main thread's
        pass
    unraisable = sys.unraisablehook
    if previous:
        sys.unraisablehook = _redeliver(unraisable)
    from rollfric.output.folder import signals_received

    if not _running:  # a new command, not one that another runs: no signal has reached it
        signals_received.clear()
        _pending.clear()
    mark, depth = len(signals_received), len(_running)
    command = "command"
    try:
        try:
            return _main(argv)
        finally:
            if _pending and not depth and hasattr(signal, "setitimer"):  # before the alarm
                signal.setitimer(signal.ITIMER_REAL, 0.0)
            for signum, handler in previous.items():
                signal.signal(signum, handler)
            sys.unraisablehook = unraisable
            command = _running[-1] if len(_running) > depth else command
            del _running[depth:]
            if _pending and not depth:  # caught in a finalizer as the command ended
                _on_signal(_pending.pop(), None)
    except BaseException as exc:
        # a signal raises where it lands: inside a numba kernel its exception comes back as
        # numba's SystemError ("returned a result with an exception set"), in a clean-up as
        # whatever that clean-up raised; the signal received is what ended the command
        signum = _interruption(exc, signals_received[mark:])
        if signum is None:
            raise
        if signum == signal.SIGINT:
            print(f"rollfric {command}: interrupted", file=sys.stderr)
            return 130
        print(f"rollfric {command}: terminated", file=sys.stderr)
        return 143


def _name_outputs(args) -> None:
    """``--out .`` (or ``..``, ``--export .``) as the folder it names: a path without a name
    ends in pathlib's ValueError where a command stages its output beside it."""
    from pathlib import Path

    from rollfric.output.folder import named

    for key in ("out", "export"):
        value = getattr(args, key, None)
        if isinstance(value, str) and value and Path(value).name in ("", ".", ".."):
            setattr(args, key, str(named(value, f"--{key}")))


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    _running.append(args.command)
    if unknown and not getattr(args, "accepts_any", False):
        parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    try:
        _name_outputs(args)
        result = args.func(args)
    except InputError as exc:
        print(f"rollfric {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file that cannot be read or written (permissions, disk full)
        print(f"rollfric {args.command}: error: {_os_error_text(exc)}", file=sys.stderr)
        return 2
    except MemoryError:
        print(f"rollfric {args.command}: error: not enough memory for this input",
              file=sys.stderr)
        return 2
    return int(result or 0)


if __name__ == "__main__":
    sys.exit(main())
