"""The raw OpenGL calls synth's lean draw path (:mod:`synth.backends.lean`) makes instead of
pyrender's: uniforms set at locations looked up once (as pyrender's ShaderProgram.set_uniform
sets them, by PyOpenGL's raw functions with pointers to the converted values), a primitive's
draw (as pyrender's), and the read-back of a box of the multisampled framebuffer. PyOpenGL is
imported when a call is made (a process that draws nothing does not load it).
"""

from __future__ import annotations

import ctypes

import numpy as np

from synth import pyrender_adapter as pa


def material_uniforms(program_id: int, m) -> list:
    """The (function, args) pairs setting a pyrender material's four factors in a program
    (those the program has), as pyrender's primitive draw sets them."""
    material = [uniform(program_id, "material.emissive_factor", m.emissiveFactor),
                uniform(program_id, "material.base_color_factor", m.baseColorFactor),
                uniform(program_id, "material.metallic_factor", m.metallicFactor),
                uniform(program_id, "material.roughness_factor", m.roughnessFactor)]
    return [u for u in material if u is not None]


def uniform(program_id: int, name: str, value):
    """(function, args) setting uniform ``name`` to ``value`` as pyrender's
    ShaderProgram.set_uniform does (the same GL function and converted value), or None when the
    program has no such uniform (pyrender then sets nothing)."""
    from OpenGL import GL

    loc = GL.glGetUniformLocation(program_id, name)
    if loc == -1:
        return None
    if isinstance(value, np.ndarray):
        if value.ndim == 1:
            if np.issubdtype(value.dtype, np.unsignedinteger):
                v, kind = value.astype(np.uint32), "ui"
            elif np.issubdtype(value.dtype, np.integer):
                v, kind = value.astype(np.int32), "i"
            else:
                v, kind = value.astype(np.float32), "f"
            return getattr(GL, f"glUniform{v.shape[0]}{kind}v"), (loc, 1, v)
        fn = GL.glUniformMatrix4fv if value.shape == (4, 4) else \
            getattr(GL, f"glUniformMatrix{value.shape[0]}x{value.shape[1]}fv")
        return fn, (loc, 1, GL.GL_TRUE, np.asarray(value))
    if isinstance(value, float):
        return GL.glUniform1f, (loc, value)
    if isinstance(value, (bool, int)):
        return GL.glUniform1i, (loc, int(value))
    raise ValueError(f"uniform {name}: unsupported value {value!r}")


def raw(call):
    """A (function, args) pair of :func:`uniform` as PyOpenGL's raw function with a pointer
    to the converted values (the same GL function and values): PyOpenGL's wrapped array
    functions convert their arguments on every call (~15 us against ~2.5 us; a frame makes
    ~25 such calls). Scalar calls are returned as they are. The values are kept with the
    pointer."""
    from OpenGL.raw.GL.VERSION import GL_2_0, GL_2_1, GL_3_0

    fn, args = call
    name = fn.__name__
    if not name.endswith("v"):
        return fn, args, None
    raw = getattr(GL_2_0, name, None) or getattr(GL_2_1, name, None) or getattr(GL_3_0, name)
    value = args[-1]
    if name.startswith("glUniformMatrix"):
        kept = np.ascontiguousarray(value, dtype=np.float32)
        return raw, (*args[:-1], kept.ctypes.data_as(ctypes.POINTER(ctypes.c_float))), kept
    kind = {np.dtype(np.float32): ctypes.c_float, np.dtype(np.int32): ctypes.c_int,
            np.dtype(np.uint32): ctypes.c_uint}[value.dtype]
    kept = np.ascontiguousarray(value)
    return raw, (*args[:-1], kept.ctypes.data_as(ctypes.POINTER(kind))), kept


def values_key(call) -> bytes:
    """The GL function and arguments of a :func:`uniform` call as bytes: equal keys set
    equal values at the same location."""
    fn, args = call
    return repr((fn.__name__, [np.asarray(a).tolist() for a in args])).encode()


def matrix(M) -> tuple:
    """(pointer, kept array) of a 4 x 4 matrix as the float32 values glUniformMatrix4fv gets
    from PyOpenGL's conversion of ``M`` (row-major: set with transpose GL_TRUE)."""
    kept = np.ascontiguousarray(M, dtype=np.float32)
    return kept.ctypes.data_as(ctypes.POINTER(ctypes.c_float)), kept


def drawing(prim) -> dict:
    """What drawing a pyrender Primitive takes: its vertex array, mode and count."""
    indexed = prim.indices is not None
    return {"vao": pa.vertex_array(prim), "mode": prim.mode, "indexed": indexed,
            "count": prim.indices.size if indexed else len(prim.positions)}


def draw(d, runs=None) -> None:
    """Draw a primitive as pyrender's _bind_and_draw_primitive does (one instance), or only
    its triangles in ``runs`` [(first, count), ...]."""
    from OpenGL import GL
    from OpenGL.raw.GL.VERSION import GL_3_1

    GL.glBindVertexArray(d["vao"])
    if runs is None:
        runs = [(0, d["count"] // 3)] if d["mode"] == 4 else None
    if runs is None:
        first_counts = [(0, d["count"])]
    else:
        first_counts = [(3 * a, 3 * n) for a, n in runs]
    for first, count in first_counts:
        if d["indexed"]:
            GL_3_1.glDrawElementsInstanced(d["mode"], count, GL.GL_UNSIGNED_INT,
                                           ctypes.c_void_p(4 * first), 1)
        else:
            GL_3_1.glDrawArraysInstanced(d["mode"], first, count, 1)


def read_region(inner, x: int, y: int, w: int, h: int) -> np.ndarray:
    """Resolve a box of the multisampled main framebuffer and read it.

    Parameters
    ----------
    inner : pyrender.Renderer
        The renderer whose main framebuffers hold the drawing (its context current).
    x, y, w, h : int
        The box in GL window coordinates (origin bottom left).

    Returns
    -------
    numpy.ndarray
        (h, w, 3) uint8 RGB, top row first.
    """
    from OpenGL.GL import (
        GL_COLOR_BUFFER_BIT,
        GL_DRAW_FRAMEBUFFER,
        GL_NEAREST,
        GL_READ_FRAMEBUFFER,
        GL_RGBA,
        GL_UNSIGNED_BYTE,
        glBindFramebuffer,
        glBlitFramebuffer,
        glReadPixels,
    )

    fb_ms, fb = pa.main_framebuffers(inner)
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fb_ms)
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fb)
    glBlitFramebuffer(x, y, x + w, y + h, x, y, x + w, y + h, GL_COLOR_BUFFER_BIT, GL_NEAREST)
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fb)
    buf = glReadPixels(x, y, w, h, GL_RGBA, GL_UNSIGNED_BYTE)
    return np.frombuffer(buf, dtype=np.uint8).reshape(h, w, 4)[::-1, :, :3]
