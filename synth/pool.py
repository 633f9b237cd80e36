"""synth's render processes: how they start (a fork server that preloads what they import),
how they watch their parent and report a crash, and the pools that run a recording's batches
(started early, restarted when a process dies).

What a render process does with a batch is :mod:`synth.worker`'s; the fork server imports
:data:`PRELOAD` (:func:`preload`, run by importing :mod:`synth.preload`): pyrender (with
trimesh, SciPy, networkx and PyOpenGL on the EGL platform; not its interactive viewer, which
would load pyglet, tkinter and imageio), numcodecs' Zstd and synth's renderer modules, ~1 s of
CPU a process when each process imports them itself. Not numba: a render process applies no
sensor model (synth.sensor's kernels), and importing ``synth`` does not load it (~0.25 s less
for the server); nor zarr: a render process writes its chunk files and reads the background
without it (:func:`synth.chunks.chunk_writer_at`, the main process's ``.npy`` of the
background). The server only imports: it makes no EGL display or context and starts no
llvmpipe thread (those do not survive a fork), so each forked process starts its own, as a
spawned one does.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import faulthandler
import importlib
import multiprocessing as mp
import os
import sys
import threading
import types

from synth import pyrender_adapter

BATCH = 16  # frames per task (progress granularity)
# what the fork server imports (after pyrender_adapter.load(), without pyrender's viewer)
PRELOAD = ("numcodecs.zstd", "synth.backends", "synth.store", "synth.worker", "synth.pipeline")


# -- the fork server ---------------------------------------------------------------------------

def preload() -> None:
    """Import what a render process needs (:data:`PRELOAD`): what the fork server does when it
    starts (it imports :mod:`synth.preload`, which calls this)."""
    _without_viewer()
    pyrender_adapter.load()  # sets PYOPENGL_PLATFORM=egl (unless set) before PyOpenGL's import
    for name in PRELOAD:
        importlib.import_module(name)


def _without_viewer() -> None:
    """Have ``import pyrender`` skip its interactive viewer (``pyrender.viewer``: pyglet,
    tkinter and imageio, ~0.24 s of the server's ~1.3 s of imports) in this process: a
    render process draws offscreen only. ``pyrender.Viewer`` is then a class that says so
    when called. Only here, in the fork server (and the render processes forked from it)."""
    if "pyrender" in sys.modules or "pyrender.viewer" in sys.modules:
        return
    viewer = types.ModuleType("pyrender.viewer", "pyrender's viewer, not loaded in synth's "
                              "render processes (synth.pool)")

    class Viewer:
        def __init__(self, *args, **kwargs):
            raise RuntimeError("pyrender's viewer is not loaded in synth's render processes "
                               "(synth.pool)")

    Viewer.__module__, Viewer.__qualname__ = viewer.__name__, "Viewer"
    viewer.Viewer = Viewer
    sys.modules[viewer.__name__] = viewer


# -- render processes -------------------------------------------------------------------------

def crash_report() -> bool:
    """Have this process write the Python stacks of all its threads to stderr if it crashes
    (a segfault, an abort: :mod:`faulthandler`), as render processes do. A render process dies
    now and then in libc's malloc (a 4-byte zero written at +8 of a freed block, which glibc
    trips over later; the writer not found, see tools/heapprobe): the lost batches are rendered
    again, and the stacks say where the process was when glibc tripped (not who wrote).

    Returns
    -------
    bool
        Whether it is on (not where stderr has no file descriptor).
    """
    try:
        faulthandler.enable(all_threads=True)
    except (AttributeError, OSError, RuntimeError, ValueError):  # no usable stderr
        return False
    return True


def exit_with_parent() -> bool:
    """Have this render process exit when the process that started it has gone.

    A pool's worker waits for its next task on a queue whose pipe it holds both ends of, so it
    never sees its parent die; forked from the fork server, it also keeps the server alive. A
    main process killed by SIGKILL (or by a SIGTERM it does not handle) left its render
    processes (~370 MB each), the fork server and their semaphores behind for good. A daemon
    thread waits on the parent's sentinel
    (:func:`multiprocessing.parent_process`) and ends the process when it fires.

    Returns
    -------
    bool
        Whether this process has a parent to watch (False in a main process).
    """
    parent = mp.parent_process()
    if parent is None:
        return False

    def watch():
        parent.join()
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()
    return True


def _pool_worker(initializer, *args) -> None:
    """A render pool's initializer: :func:`exit_with_parent`, then ``initializer(*args)``."""
    exit_with_parent()
    initializer(*args)


def _ready() -> int:
    """A no-op task: submitting one per process makes the pool start them all now."""
    return os.getpid()


MAX_POOL_RESTARTS = 3


def pool_context():
    """The multiprocessing context render processes start in: forked from a fork server that
    has imported what they need once (:mod:`synth.preload`; the server makes no EGL context,
    which would not survive a fork) on Linux, spawned elsewhere (macOS's system frameworks,
    which pyglet may load, do not survive a fork either; Windows has no fork server).

    Each process then makes its own EGL context, as a spawned one does, and draws the same
    bytes; a recording's start-up loses the imports of every process but the server's (~2 s
    of CPU each), and a later recording of the same process reuses the server.

    Returns
    -------
    multiprocessing.context.BaseContext
    """
    if not sys.platform.startswith("linux") or "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["synth.preload"])  # used when the server starts
    return ctx


def start_fork_server() -> bool:
    """Start the fork server render processes are forked from (:func:`pool_context`), if that
    is how they start here and it is not running yet: its imports (:mod:`synth.preload`,
    ~1 s of CPU) then run while the caller goes on. :func:`render` calls it as soon as it knows
    it will start render processes (before its own imports and preparations, ~0.2 s); a caller
    may call it earlier (before a simulation).

    Returns
    -------
    bool
        Whether render processes start from a fork server here (Linux).
    """
    if pool_context().get_start_method() != "forkserver":
        return False
    from multiprocessing import forkserver

    forkserver.ensure_running()
    return True


def _start_processes(pool, workers, first=(), out=None) -> None:
    """Submit the tasks ``first`` (their futures appended to the list ``out``), then a no-op
    task per process (the pool forks one per task while none is idle); a pool that broke
    meanwhile is reported by the batches' own submission (and ``out`` is then short)."""
    try:
        for task in first:
            out.append(pool.submit(task))
        for _ in range(workers):
            pool.submit(_ready)
    except RuntimeError:  # BrokenProcessPool is one
        pass


@contextlib.contextmanager
def early_pool(workers, initializer, init, first=()):
    """``workers`` render processes (:func:`pool_context`) started now, each running
    ``initializer(*init)`` (:func:`synth.worker.start`: imports, EGL, the renderer) while the
    caller goes on, and the
    tasks ``first`` (callables) submitted first, in order, for the processes as they are ready:
    (pool, a function that returns the futures of ``first``, once submitted, raising
    BrokenProcessPool if the pool broke before), (None, None) for 0 workers. Shut down on
    leaving (already done unless the render failed before using it)."""
    if not workers:
        yield None, None
        return
    pool = cf.ProcessPoolExecutor(workers, mp_context=pool_context(),
                                  initializer=_pool_worker, initargs=(initializer, *init))
    # a process is spawned per task while none is idle; from a thread, as the first process
    # of a fork server waits for the server's imports (~1 s), the caller's own work meanwhile
    futures: list = []
    first = list(first)
    starter = threading.Thread(target=_start_processes, args=(pool, workers, first, futures),
                               daemon=True)
    starter.start()

    def submitted() -> list:
        starter.join()
        if len(futures) < len(first):
            raise cf.process.BrokenProcessPool("a render process died while starting")
        return futures

    try:
        yield pool, submitted
    finally:
        starter.join()
        pool.shutdown(cancel_futures=True)


def render_parallel(batches, centres, workers, init, bar, *, initializer, batch_fn, pool=None,
                    schedule=None) -> None:
    """Render batches in ``workers`` processes (:func:`pool_context`: forked from a fork server
    that made no EGL context, or spawned; EGL contexts do not survive fork).

    A batch writes only its own frames' chunks, so a batch whose process died (llvmpipe has
    crashed a worker once in a 4000-frame run on this machine) is simply rendered again in a
    fresh pool, at most MAX_POOL_RESTARTS times. ``initializer(*init)`` prepares each process
    and ``batch_fn(indices, centres)`` renders a batch (:mod:`synth.worker`'s); ``pool``: a
    pool already started with that initializer (:func:`early_pool`), used first.
    A batch function may return (frames, info) instead of frames: each info is appended to the
    list ``schedule`` (if given).
    """
    ctx = pool_context()
    pending = list(range(len(batches)))
    for attempt in range(MAX_POOL_RESTARTS + 1):
        failed = []
        if pool is None:
            pool = cf.ProcessPoolExecutor(workers, mp_context=ctx, initializer=_pool_worker,
                                          initargs=(initializer, *init))
        with pool:
            futs = {}
            try:
                for k in pending:
                    futs[pool.submit(batch_fn, batches[k], centres[batches[k]])] = k
            except cf.process.BrokenProcessPool:  # it broke before (an early pool's process)
                failed = pending[len(futs):]
            for f in cf.as_completed(futs):
                try:
                    done = f.result()
                except cf.process.BrokenProcessPool:
                    failed.append(futs[f])
                    continue
                if isinstance(done, tuple):
                    done, info = done
                    if schedule is not None:
                        schedule.append(info)
                bar.update(done)
        pool = None
        if not failed:
            return
        if attempt == MAX_POOL_RESTARTS:
            raise RuntimeError(f"render processes kept dying: {len(failed)} batches of "
                               f"{BATCH} frames not rendered after {attempt} restarts")
        # on stderr (tqdm writes to stdout unless told): stdout may be a result, e.g.
        # `rollfric validate --json`'s
        bar.write(f"a render process died; rendering {len(failed)} batches again (its threads' "
                  "Python stacks, if it crashed, are above on stderr; to catch a write into "
                  "freed memory where it happens, run under synth's heap probe: "
                  "LD_PRELOAD=$(python tools/heapprobe/heapprobe.py))", file=sys.stderr)
        pending = sorted(failed)
