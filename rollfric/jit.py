"""numba's ``njit`` with its on-disk cache where it can have one.

``numba.njit(cache=True)`` keeps each compiled kernel beside its module (``__pycache__``) or,
where that is not writable, in the user's cache directory (``NUMBA_CACHE_DIR`` or the
platform's), so that a new process loads the kernels instead of compiling them (compiling the
locator's and the sensor's kernels takes seconds; loading them a fraction of that). Where no
cache directory is writable (a read-only install run by a user without a writable home), numba
refuses the decorator itself with a RuntimeError at import. :func:`njit` then compiles the
kernel without the cache, in every process, and says so once in the ``rollfric.jit`` logger at
debug level: the kernels compute the same either way.

A kernel is compiled on its first call when neither this process nor the on-disk cache has it
(a fresh install, an update, a new ``NUMBA_CACHE_DIR``): :func:`cold` tells which,
:func:`announce` says so before the work that compiles them starts, and :class:`CompileClock`
(numba's compile events) lets a progress bar restart its clock once a compilation is over, so
that its rate and ETA are those of the work, not of the compiler.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from pathlib import Path

import numba
from numba.core import event

logger = logging.getLogger(__name__)
_warned: list[str] = []  # modules whose kernels were compiled without the cache
_kernels: list = []  # every dispatcher njit made, in the order made


def njit(fn=None, **options):
    """``numba.njit(cache=True, **options)``, or without the cache where numba has no writable
    cache directory for ``fn``'s module.

    Parameters
    ----------
    fn : callable, optional
        The function (``@njit``); omitted, a decorator is returned (``@njit(nogil=True)``).
    **options
        numba.njit's options (``nogil``, ``fastmath``, ...); ``cache`` is this function's. A
        function inlined into its callers (``inline="always"``) is not one of
        :func:`kernels`: numba compiles it only as part of them.

    Returns
    -------
    numba dispatcher or callable
        The compiled function, or the decorator.
    """
    if fn is None:
        return lambda f: njit(f, **options)
    options.pop("cache", None)
    try:
        disp = numba.njit(cache=True, **options)(fn)
    except RuntimeError as exc:  # "cannot cache function ...: no locator available"
        if "cannot cache" not in str(exc):
            raise
        if fn.__module__ not in _warned:
            _warned.append(fn.__module__)
            logger.debug(f"{fn.__module__}: no writable numba cache directory, its kernels are "
                         "compiled in every process (set NUMBA_CACHE_DIR to a writable folder)")
        disp = numba.njit(cache=False, **options)(fn)
    if options.get("inline") != "always":  # else compiled into its callers only, never alone
        _kernels.append(disp)
    return disp


def kernels(*modules: str) -> list:
    """The kernels :func:`njit` made in ``modules`` (all of them without an argument).

    Parameters
    ----------
    *modules : str
        Module or package names, e.g. ``"rollfric.locate.kernels"`` (a package: the kernels
        of its modules).

    Returns
    -------
    list of numba dispatchers
    """
    return [k for k in _kernels if not modules or any(
        k.py_func.__module__ == m or k.py_func.__module__.startswith(m + ".") for m in modules)]


def share_source_stamp(package: str) -> None:
    """Renew the disk cache of every kernel of ``package`` when any of its modules changes.

    numba renews a kernel's cache when its own module's file changes (its time or size) and
    not when a kernel it calls from another module does, although that one is compiled into
    it. Every kernel :func:`njit` made in the package's modules gets the stamp of all of them
    (the newest time, the summed size), which an edit to any one changes. Call it once the
    package's modules are imported, before a kernel runs.

    Parameters
    ----------
    package : str
        An imported package's name, e.g. ``"rollfric.locate.kernels"``.
    """
    stats = [p.stat() for p in sorted(Path(sys.modules[package].__file__).parent.glob("*.py"))]
    stamp = (max(st.st_mtime for st in stats), sum(st.st_size for st in stats))
    for k in kernels(package):
        cache_file = getattr(getattr(k, "_cache", None), "_cache_file", None)  # NullCache: none
        if cache_file is not None:
            cache_file._source_stamp = stamp


def cold(dispatchers=None) -> list:
    """The kernels whose next call compiles: no machine code for them in this process, none
    in numba's on-disk cache (no index, or one of another numba or of an older source).

    Parameters
    ----------
    dispatchers : list, optional
        numba dispatchers (default: every kernel :func:`njit` made).

    Returns
    -------
    list of numba dispatchers
    """
    out = []
    for k in _kernels if dispatchers is None else dispatchers:
        if k.overloads:
            continue
        index = getattr(getattr(k, "_cache", None), "_cache_file", None)  # NullCache: none
        try:
            if index is not None and index._load_index():
                continue
        except Exception:  # an unreadable index: numba compiles again
            pass
        out.append(k)
    return out


def announce(modules, what: str, seconds: str, log: logging.Logger | None = None) -> bool:
    """Say, before they are compiled, that the kernels of ``modules`` are not yet compiled.

    Parameters
    ----------
    modules : str or sequence of str
        Module names whose kernels the coming work calls.
    what : str
        What they are, for the message ("the locator's kernels").
    seconds : str
        The expected compile time, for the message ("about 1-2 minutes").
    log : logging.Logger, optional
        Where the message goes (info level; default this module's logger).

    Returns
    -------
    bool
        Whether any kernel is to be compiled (and the message was logged).
    """
    names = (modules,) if isinstance(modules, str) else tuple(modules)
    todo = cold(kernels(*names))
    if todo and any(getattr(getattr(k, "_cache", None), "_cache_file", None) is None
                    for k in todo):  # numba's NullCache: no writable cache directory
        (log or logger).info(
            f"compiling {what} ({len(todo)} numba kernels): {seconds}, in every run, as no "
            "cache directory is writable (set NUMBA_CACHE_DIR to a writable folder)")
    elif todo:
        (log or logger).info(
            f"compiling {what} ({len(todo)} numba kernels) on this first run: {seconds}; "
            "they are cached and load in about a second from the next run on")
    return bool(todo)


class CompileClock(event.Listener):
    """Counts numba's compilations (``with CompileClock() as clock``) while it is installed.

    ``clock.compiled`` is the number of top-level compilations ended so far (a kernel's own
    callees compiled inside it are part of it), ``clock.seconds`` their time.
    """

    def __init__(self) -> None:
        self.compiled = 0
        self.seconds = 0.0
        self._depth = 0
        self._t0 = 0.0
        self._lock = threading.Lock()
        self._seen = 0
        self._ctx = None

    def on_start(self, ev) -> None:
        with self._lock:
            if self._depth == 0:
                self._t0 = time.perf_counter()
            self._depth += 1

    def on_end(self, ev) -> None:
        with self._lock:
            self._depth = max(0, self._depth - 1)
            if self._depth == 0:
                self.compiled += 1
                self.seconds += time.perf_counter() - self._t0

    def __enter__(self) -> CompileClock:
        self._ctx = event.install_listener("numba:compile", self)
        self._ctx.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self._ctx.__exit__(*exc)

    def restart(self, bar) -> bool:
        """Restart ``bar``'s (a tqdm) clock, its count kept, when a compilation ended since
        the last call: its elapsed time, rate and ETA then leave the compiler out.

        Returns
        -------
        bool
            Whether the clock was restarted.
        """
        from tqdm.std import EMA

        with self._lock:
            if self.compiled == self._seen:
                return False
            self._seen = self.compiled
        if not bar.disable:
            # tqdm.reset's clock without its count set to 0 (nor a line drawn at 0): the rate
            # counts the frames from now (n - initial) over the time from now
            bar.start_t = bar.last_print_t = bar._time()
            bar.initial = bar.last_print_n = bar.n
            bar._ema_dn, bar._ema_dt = EMA(bar.smoothing), EMA(bar.smoothing)
            bar._ema_miniters = EMA(bar.smoothing)
        return True
