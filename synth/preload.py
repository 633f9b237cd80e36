"""What a render process imports, loaded once in the fork server its processes are forked from.

:func:`synth.pipeline.pool_context` starts render processes from a fork server that has
imported this module: pyrender (with trimesh, SciPy, networkx and PyOpenGL on the EGL
platform; not its interactive viewer, which would load pyglet, tkinter and imageio),
numcodecs' Zstd and synth's renderer modules, ~1 s of CPU a process when each
process imports them itself. Not numba: a render process applies no sensor model
(synth.sensor's kernels), and importing ``synth`` does not load it (~0.25 s less for the
server); nor zarr: a render process writes its chunk files and reads the background without
it (:func:`synth.store.chunk_writer_at`, the main process's ``.npy`` of the background). The
server only imports: it makes no EGL display or context and starts no llvmpipe thread (those
do not survive a fork), so each forked process starts its own, as a spawned one does.
"""

from __future__ import annotations

import sys
import types

from synth import pyrender_adapter


def _without_viewer() -> None:
    """Have ``import pyrender`` skip its interactive viewer (``pyrender.viewer``: pyglet,
    tkinter and imageio, ~0.24 s of the server's ~1.3 s of imports) in this process: a
    render process draws offscreen only. ``pyrender.Viewer`` is then a class that says so
    when called. Only here, in the fork server (and the render processes forked from it)."""
    if "pyrender" in sys.modules or "pyrender.viewer" in sys.modules:
        return
    viewer = types.ModuleType("pyrender.viewer", "pyrender's viewer, not loaded in synth's "
                              "render processes (synth.preload)")

    class Viewer:
        def __init__(self, *args, **kwargs):
            raise RuntimeError("pyrender's viewer is not loaded in synth's render processes "
                               "(synth.preload)")

    Viewer.__module__, Viewer.__qualname__ = viewer.__name__, "Viewer"
    viewer.Viewer = Viewer
    sys.modules[viewer.__name__] = viewer


_without_viewer()
pyrender_adapter.load()  # sets PYOPENGL_PLATFORM=egl (unless set) before PyOpenGL's import

from numcodecs import Zstd  # noqa: E402, F401  (the chunk writer's codec; no zarr)

import synth.leandraw  # noqa: E402, F401
import synth.pipeline  # noqa: E402, F401
import synth.scene  # noqa: E402, F401
import synth.shaders  # noqa: E402, F401
import synth.store  # noqa: E402, F401
