"""The one place where synth touches pyrender's internals, and the check of pyrender's version.

synth renders with pyrender (the NumPy-2 fork ``pyrender-maintained``), but its fast tile pass
reaches past pyrender's public API: it draws pyrender's forward pass itself, scissored to
tiles, renders the lamps' shadow maps over a cached copy, swaps in patched shader programs and
reads back only the tiles (see :mod:`synth.backends.raster`). Those are private attributes of
pyrender's ``Renderer``, ``OffscreenRenderer``, ``Texture`` and shader programs, which a new
pyrender release may rename. Every such access is a function here, so that a pyrender upgrade
is checked in one module.

:func:`load` imports pyrender (choosing the headless EGL platform unless ``PYOPENGL_PLATFORM``
is set: PyOpenGL reads it at import) and checks the installed version against
:data:`SUPPORTED`, the range synth was written and tested for (pyproject.toml caps it too).
Outside it, a :class:`PyrenderVersionWarning` says what to do.
"""

from __future__ import annotations

import functools
import importlib.metadata
import os
import warnings

import numpy as np

#: The pyrender-maintained releases synth was written and tested for: [low, high).
SUPPORTED = ((1, 0, 1), (1, 1))
DISTRIBUTION = "pyrender-maintained"


class PyrenderVersionWarning(UserWarning):
    """The installed pyrender is outside the range synth's adapter was written for."""


def _release(text: str) -> tuple[int, ...]:
    out = []
    for part in text.split("."):
        digits = "".join(c for c in part if c.isdigit()) if part[:1].isdigit() else ""
        if not digits:
            break
        out.append(int(digits))
    return tuple(out)


def version_problem(version: str | None) -> str | None:
    """Why ``version`` of pyrender-maintained is not the supported one (None if it is).

    Parameters
    ----------
    version : str or None
        The installed version (None: not installed as pyrender-maintained).

    Returns
    -------
    str or None
        A message saying what to do, or None when the version is supported.
    """
    lo, hi = SUPPORTED
    span = f">={'.'.join(map(str, lo))},<{'.'.join(map(str, hi))}"
    if version is not None and lo <= _release(version) < hi:
        return None
    found = f"{DISTRIBUTION} {version}" if version else f"pyrender without {DISTRIBUTION}"
    return (f"synth was written for {DISTRIBUTION}{span} and found {found}; synth reaches "
            f"into pyrender's renderer internals (synth/pyrender_adapter.py), which another "
            f"release may have changed. Install the supported one: pip install "
            f"\"{DISTRIBUTION}{span}\"; or, to move to this release, check every function of "
            f"synth/pyrender_adapter.py against its source, widen SUPPORTED there and the cap "
            f"in pyproject.toml, and run tests/test_synth_render.py and "
            f"tests/test_synth_shaders.py (renders compared with pyrender's own).")


@functools.cache
def load():
    """pyrender, imported for headless rendering, its version checked (once a process).

    Sets ``PYOPENGL_PLATFORM=egl`` unless it is set already (PyOpenGL reads it when it is
    first imported, so this is called before anything imports pyrender or OpenGL), then
    warns with :class:`PyrenderVersionWarning` when the installed pyrender-maintained is
    outside :data:`SUPPORTED`.

    Returns
    -------
    module
        The ``pyrender`` module.
    """
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    import pyrender

    try:
        version = importlib.metadata.version(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        version = None
    problem = version_problem(version)
    if problem:
        warnings.warn(problem, PyrenderVersionWarning, stacklevel=2)
    return pyrender


# -- pyrender's internals, one function each -------------------------------------------------
#    ``renderer``: a pyrender.OffscreenRenderer; ``inner``: its pyrender.Renderer
#    (:func:`inner`), which does the drawing. Every private attribute of pyrender that synth
#    uses is named below and nowhere else.

#: The private attributes synth uses, by object (checked by :func:`check_internals`).
INTERNALS = {
    "OffscreenRenderer": ("_renderer", "_platform"),
    "Renderer": ("_program_cache", "_update_context", "_configure_forward_pass_viewport",
                 "_get_camera_matrices", "_sorted_mesh_nodes", "_get_primitive_program",
                 "_bind_lighting", "_bind_and_draw_primitive", "_reset_active_textures",
                 "_shadow_mapping_pass", "_configure_shadow_mapping_viewport",
                 "_get_light_cam_matrices", "_main_fb", "_main_fb_ms", "_shadow_fb"),
    "Texture": ("_texid", "_add_to_context", "_remove_from_context"),
    "ShaderProgram": ("_bind", "_unbind", "_program_id"),
    "Primitive": ("_vaid",),
    "ShaderProgramCache": ("_program_cache",),
    "Scene": ("_bounds",),
}


def check_internals(renderer) -> None:
    """Raise RuntimeError, saying what to do, when pyrender lacks an internal synth uses.

    Parameters
    ----------
    renderer : pyrender.OffscreenRenderer
        A renderer that has drawn once or not (its Renderer exists from construction).
    """
    pyrender = load()
    have = {"OffscreenRenderer": renderer, "Renderer": inner(renderer),
            "Texture": pyrender.texture.Texture(width=1, height=1),  # no GL until added
            "ShaderProgram": pyrender.shader_program.ShaderProgram("v", "f"),  # no GL yet
            "Primitive": pyrender.Primitive(positions=np.zeros((3, 3))),  # no GL yet
            "ShaderProgramCache": program_cache(renderer),
            "Scene": pyrender.Scene()}
    missing = [f"{kind}.{name}" for kind, names in INTERNALS.items() for name in names
               if not hasattr(have[kind], name)]
    if missing:
        try:
            version = importlib.metadata.version(DISTRIBUTION)
        except importlib.metadata.PackageNotFoundError:
            version = None
        raise RuntimeError(f"pyrender lacks {', '.join(missing)}: "
                           + (version_problem(version) or "synth/pyrender_adapter.py must be "
                              "brought up to date with the installed pyrender"))


def inner(renderer):
    """The pyrender.Renderer that an OffscreenRenderer draws with."""
    return renderer._renderer


def make_current(renderer) -> None:
    """Make the renderer's GL context current (before drawing past its render())."""
    renderer._platform.make_current()


def make_uncurrent(renderer) -> None:
    """Release the renderer's GL context."""
    renderer._platform.make_uncurrent()


def program_cache(renderer):
    """The shader program cache the renderer compiles and binds programs from."""
    return inner(renderer)._program_cache


def compiled_programs(cache) -> dict:
    """The programs a ShaderProgramCache has compiled so far (empty before a draw)."""
    return cache._program_cache


def set_program_cache(renderer, cache) -> None:
    """Draw with the programs of ``cache`` (a pyrender ShaderProgramCache) from now on."""
    inner(renderer)._program_cache = cache


def update_context(inner_renderer, scene, flags) -> None:
    """Upload the scene's changed meshes, textures and poses (as render() does first)."""
    inner_renderer._update_context(scene, flags)


def configure_forward_pass_viewport(inner_renderer, flags) -> None:
    """Bind the multisampled main framebuffer and set the forward pass's GL state."""
    inner_renderer._configure_forward_pass_viewport(flags)


def camera_matrices(inner_renderer, scene):
    """(V, P): the main camera's view and projection matrices."""
    return inner_renderer._get_camera_matrices(scene)


def sorted_mesh_nodes(inner_renderer, scene):
    """The scene's mesh nodes in pyrender's drawing order."""
    return inner_renderer._sorted_mesh_nodes(scene)


def primitive_program(inner_renderer, primitive, flags, program_flags):
    """The shader program pyrender draws ``primitive`` with."""
    return inner_renderer._get_primitive_program(primitive, flags, program_flags)


def primitive_program_as(inner_renderer, primitive, flags, program_flags, vertex_shader,
                         fragment_shader, programs):
    """A program of shader files ``vertex_shader`` and ``fragment_shader`` from the
    ShaderProgramCache ``programs`` (its shader directory), compiled with the defines pyrender
    gives ``primitive``'s own program (its vertex buffers, lamps, shadows and material)."""
    cache = inner_renderer._program_cache
    seen = {}
    get = cache.get_program

    def record(vertex_shader=None, fragment_shader=None, geometry_shader=None, defines=None):
        seen["defines"] = dict(defines or {})
        return get(vertex_shader, fragment_shader, geometry_shader, defines)

    cache.get_program = record
    try:
        inner_renderer._get_primitive_program(primitive, flags, program_flags)
    finally:
        del cache.get_program  # the class's method again
    program = programs.get_program(vertex_shader, fragment_shader, None, seen["defines"])
    if program._program_id is None:
        program._add_to_context()
    return program


def bind_program(program) -> None:
    """Use ``program`` for the next draws."""
    program._bind()


def unbind_program(program) -> None:
    """Stop using ``program``."""
    program._unbind()


def bind_lighting(inner_renderer, scene, program, node, flags) -> None:
    """Set the lamps' uniforms and bind their shadow maps for ``program``."""
    inner_renderer._bind_lighting(scene, program, node, flags)


def bind_and_draw_primitive(inner_renderer, primitive, pose, program, flags) -> None:
    """Set the primitive's model and material uniforms and draw it."""
    inner_renderer._bind_and_draw_primitive(primitive=primitive, pose=pose, program=program,
                                            flags=flags)


def reset_active_textures(inner_renderer) -> None:
    """Unbind the textures the last draw bound."""
    inner_renderer._reset_active_textures()


def shadow_mapping_pass(inner_renderer, scene, light_node, flags) -> None:
    """Render the shadow map of the lamp ``light_node``."""
    inner_renderer._shadow_mapping_pass(scene, light_node, flags)


def shadow_mapping_viewport(inner_renderer):
    """The function that binds a lamp's shadow map and clears it: (light, flags) -> None."""
    return inner_renderer._configure_shadow_mapping_viewport


def set_shadow_mapping_viewport(inner_renderer, configure) -> None:
    """Bind and clear the shadow maps with ``configure(light, flags)`` from now on (pass
    :func:`shadow_mapping_viewport`'s function to restore pyrender's)."""
    inner_renderer._configure_shadow_mapping_viewport = configure


def light_cam_matrices(inner_renderer):
    """The function giving a lamp's shadow-camera (V, P): (scene, light_node, flags)."""
    return inner_renderer._get_light_cam_matrices


def set_light_cam_matrices(inner_renderer, function) -> None:
    """Give the lamps' shadow-camera matrices with ``function(scene, light_node, flags)``."""
    inner_renderer._get_light_cam_matrices = function


def main_framebuffers(inner_renderer) -> tuple[int, int]:
    """(multisampled, resolved) GL ids of the main framebuffers."""
    return inner_renderer._main_fb_ms, inner_renderer._main_fb


def texture_id(texture) -> int:
    """The GL id of a pyrender Texture (a shadow map, or a copy of one)."""
    return texture._texid


def add_to_context(texture) -> None:
    """Create the texture in the current GL context."""
    texture._add_to_context()


def remove_from_context(texture) -> None:
    """Delete the texture from the current GL context."""
    texture._remove_from_context()


def program_id(program) -> int:
    """The GL id of a compiled pyrender ShaderProgram (synth.backends.lean)."""
    return program._program_id


def vertex_array(primitive) -> int:
    """The GL id of a pyrender Primitive's vertex array (synth.backends.lean)."""
    return primitive._vaid


def kept_bounds(scene):
    """A pyrender Scene's bounds as last computed, or None when a mesh node was added,
    removed or moved since (pyrender computes them again when asked: synth.backends.raster)."""
    return scene._bounds


def keep_bounds(scene, bounds) -> None:
    """Give a pyrender Scene the bounds its ``bounds`` property would compute now
    (synth.backends.raster: the ball moved, the other nodes' corners kept)."""
    scene._bounds = bounds


def shadow_framebuffer(inner_renderer) -> int:
    """The GL id of the framebuffer pyrender renders the shadow maps with (synth.backends.lean)."""
    return inner_renderer._shadow_fb
