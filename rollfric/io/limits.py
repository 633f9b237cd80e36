"""Sizes checked before anything is allocated: stated limits, and the machine's memory.

A number typed by mistake (``simulate --fps 1e9``, a sweep with ``seeds = 100000000``, a TIFF
whose header claims a 2^31-pixel page) must be refused with a message, not allocated until the
kernel kills the process. Every stage checks the size it is about to allocate against these
limits (generous for any real measurement) and against the memory this machine has free.
"""

from __future__ import annotations

from rollfric.errors import InputError

MAX_SAMPLES = 10_000_000
"""Samples of one trajectory or track (seconds x fps): 2.8 hours at 1000 Hz."""

MAX_FRAME_PIXELS = 100_000_000
"""Pixels of one frame (width x height): a 10 000 x 10 000 sensor."""

MAX_CASES = 100_000
"""Cases of one sweep (grid combinations x seeds)."""


def available_memory() -> int:
    """Bytes of memory this machine can give now (psutil's ``available``)."""
    import psutil

    return int(psutil.virtual_memory().available)


def _size(nbytes: float) -> str:
    for unit, f in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if nbytes >= f:
            return f"{nbytes / f:.3g} {unit}"
    return f"{nbytes:.0f} B"


def check_memory(nbytes: float, what: str) -> None:
    """Refuse (InputError) to allocate ``nbytes`` for ``what`` when the machine has less free.

    Parameters
    ----------
    nbytes : float
        Bytes about to be allocated.
    what : str
        What they are for, named in the message (e.g. ``"the median background of 41 frames"``).
    """
    free = available_memory()
    if nbytes > free:
        raise InputError(f"{what} needs {_size(nbytes)} of memory; this machine has "
                         f"{_size(free)} free")


def check_count(n: float, limit: int, what: str, hint: str = "") -> int:
    """``n`` as an int if it is a finite count within ``limit``; InputError otherwise.

    Parameters
    ----------
    n : float
        The count (may be a float product such as seconds x fps, or inf).
    limit : int
        The largest count accepted.
    what : str
        What is counted, named in the message.
    hint : str
        Appended to the message (what to change).
    """
    if not n == n or n > limit:  # NaN or too many
        raise InputError(f"{what}: {n:.4g} is more than the limit of {limit:,}"
                         + (f" ({hint})" if hint else ""))
    return int(n)
