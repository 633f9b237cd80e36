"""Independent computations on the CPUs that are free, with the results of a plain loop.

Every thread rollfric starts is started here. The tracker's segments
(:func:`rollfric.track.tracker.track_recording`) and the fits that do not depend on one another
(the least-squares fit's coarse starts, :mod:`rollfric.fit.lsq`; the refits of the dropped-frame
search at turning points; the uncertainty budget's refits,
:class:`rollfric.uncertainty.sensitivity.Refitter`) run on threads when CPUs are free: their
numerical kernels (the locator's, the equation of motion's RK4, LAPACK) release the GIL. Each
computation is the same function call with the same inputs as in a loop, so the results are the
same; only the order in which they finish differs, and :func:`map_ordered` hands them back in
the order of the inputs. On a busy machine (no CPU free at the start) everything runs one after
another in the calling thread: a second thread would only wait for the GIL while the
first is descheduled.
"""

from __future__ import annotations

import concurrent.futures
import os
import time


def cpus() -> int:
    """The CPUs this process may run on.

    Returns
    -------
    int
        ``len(os.sched_getaffinity(0))``, else ``os.cpu_count()`` (at least 1).
    """
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def free_cpus(samples: int = 1, interval: float = 0.002) -> int:
    """The CPUs this thread and the ones it may start have now: this process's CPUs less the
    threads running elsewhere (Linux's /proc/loadavg; all of them where it cannot be read). On
    a busy machine a second thread only waits for the GIL while the first is descheduled, and
    the tracking is then slower on two threads than on one.

    The count of running threads is an instant's: a process that runs for a millisecond (a
    render process exiting, a kernel worker) could cost a long computation its second thread.
    A caller whose work is long (the tracking: seconds) reads it ``samples`` times,
    ``interval`` seconds apart, and takes the fewest running count (5 readings: about 10 ms
    on a busy machine); a short one (a fit's starts, nested in other threads) reads it once,
    as the wait would cost more than the thread could win.

    Parameters
    ----------
    samples : int
        Readings of /proc/loadavg (at least 1); it stops at one that sees nothing else run.
    interval : float
        Seconds between readings.

    Returns
    -------
    int
        At least 1.
    """
    running = None
    for i in range(max(1, int(samples))):
        if i:
            time.sleep(interval)
        try:
            with open("/proc/loadavg") as f:
                now = int(f.read().split()[3].split("/")[0])  # this thread included
        except (OSError, ValueError, IndexError):
            return cpus()
        running = now if running is None else min(running, now)
        if running <= 1:
            break  # nothing else runs: it cannot get freer
    return max(1, cpus() - max(0, running - 1))


def map_ordered(fn, items, *, workers: int | None = None, name: str = "rollfric") -> list:
    """``[fn(x) for x in items]``, on up to ``workers`` threads.

    Parameters
    ----------
    fn : callable
        The computation; it must not depend on the others' results or order.
    items : iterable
        Its inputs.
    workers : int or None
        Threads at most; None: :func:`free_cpus` now. 1 (or one item): the plain loop in the
        calling thread.
    name : str
        Prefix of the threads' names.

    Returns
    -------
    list
        The results in the order of ``items``. The first exception (in that order) is raised
        once every computation started has ended; none is left running.
    """
    items = list(items)
    n = min(len(items), free_cpus() if workers is None else int(workers))
    if n <= 1:
        return [fn(x) for x in items]
    with concurrent.futures.ThreadPoolExecutor(max_workers=n, thread_name_prefix=name) as pool:
        futures = [pool.submit(fn, x) for x in items]
        concurrent.futures.wait(futures)
    return [f.result() for f in futures]


def first_ordered(fn, items, accept, *, workers: int | None = None, name: str = "rollfric"):
    """The first ``(x, fn(x))`` in the order of ``items`` whose result ``accept`` takes, as a
    loop that stops there would find it; None when none is taken.

    Up to ``workers`` of the computations run at once on threads, started in the order of
    ``items``; once one is taken, those not started yet are cancelled and the results of those
    after it are not looked at (the loop would not have made them), so neither is an error
    they raise.

    Parameters
    ----------
    fn : callable
        The computation, independent of the others.
    items : iterable
        Its inputs, in the order they are tried.
    accept : callable
        ``accept(x, result) -> bool``, called in the calling thread, in order.
    workers : int or None
        Threads at most; None: :func:`free_cpus` now; 1: the plain loop.
    name : str
        Prefix of the threads' names.

    Returns
    -------
    tuple or None
        ``(x, fn(x))`` of the first accepted, else None.
    """
    items = list(items)
    n = min(len(items), free_cpus() if workers is None else int(workers))
    if n <= 1:
        for x in items:
            r = fn(x)
            if accept(x, r):
                return x, r
        return None
    with concurrent.futures.ThreadPoolExecutor(max_workers=n, thread_name_prefix=name) as pool:
        futures = [pool.submit(fn, x) for x in items]
        try:
            for x, f in zip(items, futures, strict=True):
                if accept(x, f.result()):
                    return x, f.result()
            return None
        finally:
            for f in futures:
                f.cancel()  # those not started yet
