"""What a render process imports, loaded once in the fork server its processes are forked from.

:func:`synth.pipeline.pool_context` starts render processes from a fork server that has
imported this module: pyrender (with trimesh, SciPy, networkx, pyglet and PyOpenGL on the EGL
platform), numcodecs' Zstd and synth's renderer modules, ~1 s of CPU a process when each
process imports them itself. Not numba: a render process applies no sensor model
(synth.sensor's kernels), and importing ``synth`` does not load it (~0.25 s less for the
server); nor zarr: a render process writes its chunk files and reads the background without
it (:func:`synth.store.chunk_writer_at`, the main process's ``.npy`` of the background). The
server only imports: it makes no EGL display or context and starts no llvmpipe thread (those
do not survive a fork), so each forked process starts its own, as a spawned one does.
"""

from __future__ import annotations

from synth import pyrender_adapter

pyrender_adapter.load()  # sets PYOPENGL_PLATFORM=egl (unless set) before PyOpenGL's import

from numcodecs import Zstd  # noqa: E402, F401  (the chunk writer's codec; no zarr)

import synth.leandraw  # noqa: E402, F401
import synth.pipeline  # noqa: E402, F401
import synth.scene  # noqa: E402, F401
import synth.shaders  # noqa: E402, F401
import synth.store  # noqa: E402, F401
