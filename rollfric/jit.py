"""numba's ``njit`` with its on-disk cache where it can have one.

``numba.njit(cache=True)`` keeps each compiled kernel beside its module (``__pycache__``) or,
where that is not writable, in the user's cache directory (``NUMBA_CACHE_DIR`` or the
platform's), so that a new process loads the kernels instead of compiling them (compiling the
locator's and the sensor's kernels takes seconds; loading them a fraction of that). Where no
cache directory is writable (a read-only install run by a user without a writable home), numba
refuses the decorator itself with a RuntimeError at import. :func:`njit` then compiles the
kernel without the cache, in every process, and says so once in the ``rollfric.jit`` logger at
debug level: the kernels compute the same either way.
"""

from __future__ import annotations

import logging

import numba

logger = logging.getLogger(__name__)
_warned: list[str] = []  # modules whose kernels were compiled without the cache


def njit(fn=None, **options):
    """``numba.njit(cache=True, **options)``, or without the cache where numba has no writable
    cache directory for ``fn``'s module.

    Parameters
    ----------
    fn : callable, optional
        The function (``@njit``); omitted, a decorator is returned (``@njit(nogil=True)``).
    **options
        numba.njit's options (``nogil``, ``fastmath``, ...); ``cache`` is this function's.

    Returns
    -------
    numba dispatcher or callable
        The compiled function, or the decorator.
    """
    if fn is None:
        return lambda f: njit(f, **options)
    options.pop("cache", None)
    try:
        return numba.njit(cache=True, **options)(fn)
    except RuntimeError as exc:  # "cannot cache function ...: no locator available"
        if "cannot cache" not in str(exc):
            raise
        if fn.__module__ not in _warned:
            _warned.append(fn.__module__)
            logger.debug(f"{fn.__module__}: no writable numba cache directory, its kernels are "
                         "compiled in every process (set NUMBA_CACHE_DIR to a writable folder)")
        return numba.njit(cache=False, **options)(fn)
