"""synth's lean draw path: a tile frame drawn with a fixed list of OpenGL calls instead of
pyrender's per-draw Python.

pyrender sets every uniform of every primitive on every draw, looking each location up by name,
rebuilds the lamps' uniforms for each program and re-sorts the scene's nodes each pass: ~5 ms of
Python a tile frame against ~9 ms of drawing (llvmpipe, one thread; cProfile with CPU time).
Everything but the ball's pose is the same in every frame of a recording, so here:

- pyrender itself draws the first tile frame (it compiles the programs, uploads the meshes,
  renders and caches the trough's shadow maps:
  :meth:`synth.backends.raster.SceneRenderer.render_tiles`);
- the camera's and lamps' uniforms are then set once per program by pyrender's own functions
  (the same values: a GL program keeps its uniforms), again whenever pyrender drew in between
  (a full-frame render sets other projections) or the lamps' shadow cameras change;
- the scene without the ball (the static layer: its multisampled colour and depth, shaded with
  the cached trough-only shadow maps) is drawn once, into a framebuffer of its own, in 32 px
  blocks the first time a tile needs them, and drawn again only when the static scene
  changes (camera, lamps, static meshes' poses or materials: a fingerprint taken whenever the
  uniforms are set);
- each frame then makes only the calls that draw: per lamp, the ball's depth into the
  scissored box of its shadow map over the cached trough; per tile, the static layer's samples
  copied in (a multisample blit), the static surfaces drawn again only in the boxes of the
  ball's shadows (:meth:`synth.backends.raster.SceneRenderer.shadow_boxes`: outside them the ball
  changes no shadow lookup; once in their union, :func:`disjoint_boxes`) and the ball in its
  own box, with the model matrix and material
  uniforms at locations looked up once, in the GL state pyrender's draw sets; the tile
  resolved and read.

The same programs (but for the ball's, whose fragment shader holds the lamps' and camera's
uniform values as constants: :func:`synth.backends.shaders.specialised_mesh_shader`, 0 DN), buffers,
uniform values and GL state as pyrender's path; the static
surfaces are drawn before the ball instead of in pyrender's order by distance, which changes
nothing with the depth test and opaque surfaces (no two of them at the same depth), so the
same pixels (tests/test_synth_render.py compares the two bit for bit and both with stock
pyrender). What this path does not draw (textured materials, point or directional lamps, the
flat silhouette mode) is drawn by pyrender's path: :func:`unsupported` says why.
"""

from __future__ import annotations

import ctypes
import os

import numpy as np

from synth import pyrender_adapter as pa

STATIC_BLOCK = 32  # px: the static layer is drawn where tiles first need it, in such blocks
RUN_GAP = 64  # triangles: runs of a draw's triangles closer than this are drawn as one


def unsupported(sr) -> str | None:
    """Why the lean path cannot draw SceneRenderer ``sr``'s scene (None if it can).

    Parameters
    ----------
    sr : synth.backends.raster.SceneRenderer
        The renderer.

    Returns
    -------
    str or None
        The reason, or None.
    """
    pr = sr._pyrender
    RF = pr.RenderFlags
    scene = sr.scene
    if sr.flags & ~(RF.SHADOWS_SPOT | RF.OFFSCREEN):
        return "render flags other than spot shadows (the silhouette mode)"
    if scene.point_light_nodes or scene.directional_light_nodes:
        return "point or directional lights"
    for node in scene.mesh_nodes:
        for p in node.mesh.primitives:
            m = p.material
            if m.tex_flags or not isinstance(m, pr.MetallicRoughnessMaterial):
                return "a textured or specular-glossiness material"
            if m.alphaMode == "BLEND" or m.wireframe or p.mode == 0 or p.poses is not None:
                return "a transparent, wireframe, point or instanced primitive"
    return None


def _material_uniforms(program_id: int, m) -> list:
    """The (function, args) pairs setting a pyrender material's four factors in a program
    (those the program has), as pyrender's primitive draw sets them."""
    material = [_uniform(program_id, "material.emissive_factor", m.emissiveFactor),
                _uniform(program_id, "material.base_color_factor", m.baseColorFactor),
                _uniform(program_id, "material.metallic_factor", m.metallicFactor),
                _uniform(program_id, "material.roughness_factor", m.roughnessFactor)]
    return [u for u in material if u is not None]


def _uniform(program_id: int, name: str, value):
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


def _raw(call):
    """A (function, args) pair of :func:`_uniform` as PyOpenGL's raw function with a pointer
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


def _values_key(call) -> bytes:
    """The GL function and arguments of a :func:`_uniform` call as bytes: equal keys set
    equal values at the same location."""
    fn, args = call
    return repr((fn.__name__, [np.asarray(a).tolist() for a in args])).encode()


def _matrix(M) -> tuple:
    """(pointer, kept array) of a 4 x 4 matrix as the float32 values glUniformMatrix4fv gets
    from PyOpenGL's conversion of ``M`` (row-major: set with transpose GL_TRUE)."""
    kept = np.ascontiguousarray(M, dtype=np.float32)
    return kept.ctypes.data_as(ctypes.POINTER(ctypes.c_float)), kept


def _drawing(prim) -> dict:
    """What drawing a pyrender Primitive takes: its vertex array, mode and count."""
    indexed = prim.indices is not None
    return {"vao": pa.vertex_array(prim), "mode": prim.mode, "indexed": indexed,
            "count": prim.indices.size if indexed else len(prim.positions)}


def _draw(d, runs=None) -> None:
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


class LeanDraw:
    """The lean tile draw of one SceneRenderer (built after pyrender drew a tile frame).

    Parameters
    ----------
    sr : synth.backends.raster.SceneRenderer
        The renderer; its scene must be drawable (:func:`unsupported` is None) and pyrender
        must have drawn one tile frame with it (programs, buffers and shadow cache exist).
    """

    def __init__(self, sr):
        pr = sr._pyrender
        self.sr = sr
        inner = pa.inner(sr._offscreen)
        self.inner = inner
        scene = sr.scene
        self.flags = sr.flags | pr.RenderFlags.OFFSCREEN
        self.shadows = bool(sr.config.shadows)
        self.ball = sr._ball_node
        self.lamps = list(scene.light_nodes)
        self.units: list = []  # (texture unit, GL texture) of each lamp's shadow map
        self._light_mats = None
        self.ready = False
        self._static = None  # (framebuffer, renderbuffers) of the static layer
        self._valid = None  # (rows, cols) of STATIC_BLOCK px blocks drawn into it
        self._static_key = None
        self._sphere_vao = None
        self._far_lamps = None
        # "mesh" or "sphere" (SceneConfig.ball_model); set it and ``ready = False`` to switch
        self.ball_model = sr.config.ball_model
        # the ball's mesh drawn by a fragment shader with the lamps' and camera's uniforms held
        # as constants (synth.backends.shaders.specialised_mesh_shader); set it and
        # ``ready = False`` to switch
        self.specialise = True
        # the static surfaces drawn again once in the union of the shadows' boxes (cut into
        # boxes that do not overlap: disjoint_boxes) rather than once per box, twice where two
        # lamps' boxes overlap (the same pixels either way); set it to switch
        self.disjoint = True
        # a program's model matrix and material set only when they differ from what this path
        # set in it last (the same values: the same state); set it to switch
        self.keep_uniforms = True
        self._held: dict = {}
        self._build(self._order())

    def close(self) -> None:
        """Free the static layer's framebuffer (the renderer's context current)."""
        from OpenGL import GL

        if self._static is not None:
            fb, rbs, _ = self._static
            GL.glDeleteFramebuffers(1, [fb])
            GL.glDeleteRenderbuffers(len(rbs), rbs)
            self._static = None

    def _order(self) -> list:
        return [n for n in pa.sorted_mesh_nodes(self.inner, self.sr.scene) if n.mesh.is_visible]

    def _build(self, order) -> None:
        """The forward draws in pyrender's order (by distance of the node origins from the
        camera: rebuilt if a ball's move ever changes it) and the ball's depth draws."""
        from OpenGL import GL

        pr, inner = self.sr._pyrender, self.inner
        self.order = order
        self.draws = []
        for node in order:
            for prim in node.mesh.primitives:
                prog = pa.primitive_program(inner, prim, self.flags,
                                            pr.constants.ProgramFlags.USE_MATERIAL)
                pid = pa.program_id(prog)
                self.draws.append({
                    "node": node, "program": prog, "pid": pid,
                    "M": GL.glGetUniformLocation(pid, "M"),
                    "material": _material_uniforms(pid, prim.material),
                    "cull": not prim.material.doubleSided,
                    "boxes": None if node is self.ball else self._triangle_boxes(node, prim),
                    "far": None if node is self.ball else self._triangle_far(node, prim),
                    "prim": prim,
                    **_drawing(prim)})
        for d in self.draws:
            d["raw_material"] = [_raw(u) for u in d["material"]]
        self.static_draws = [d for d in self.draws if d["node"] is not self.ball]
        self.ball_draws = [d for d in self.draws if d["node"] is self.ball]
        if self.ball_model == "sphere":
            self.ball_draws = [self._sphere_draw(self.ball_draws[0])]
            self.draws = self.static_draws + self.ball_draws
        self.depth = []
        if self.shadows:
            for prim in self.ball.mesh.primitives:
                prog = pa.primitive_program(inner, prim, self.flags,
                                            pr.constants.ProgramFlags.NONE)
                pid = pa.program_id(prog)
                self.depth.append({"program": prog, "pid": pid,
                                   "M": GL.glGetUniformLocation(pid, "M"),
                                   "V": GL.glGetUniformLocation(pid, "V"),
                                   "P": GL.glGetUniformLocation(pid, "P"),
                                   **_drawing(prim)})
        self.ready = False

    def _sphere_draw(self, mesh_draw) -> dict:
        """The ball drawn as an exact sphere (``SceneConfig.ball_model = "sphere"``): one
        triangle over the viewport, scissored to the ball's box, whose fragment shader
        (:func:`synth.backends.shaders.sphere_shader`) intersects each pixel's ray with the
        sphere and shades the hit with the mesh shader's own code; the ball mesh's material."""
        from OpenGL import GL

        from synth.backends.shaders import SPHERE_FRAG, SPHERE_VERT, light_counts, program_cache

        sr = self.sr
        pr = sr._pyrender
        prim = self.ball.mesh.primitives[0]
        counts = light_counts(sr.scene)
        if counts not in sr._programs:
            sr._programs[counts] = program_cache(counts)
        prog = pa.primitive_program_as(self.inner, prim, self.flags,
                                       pr.constants.ProgramFlags.USE_MATERIAL, SPHERE_VERT,
                                       SPHERE_FRAG, sr._programs[counts])
        pid = pa.program_id(prog)
        if self._sphere_vao is None:
            self._sphere_vao = int(np.asarray(GL.glGenVertexArrays(1)).ravel()[0])
        material = _material_uniforms(pid, prim.material)
        return {**mesh_draw, "program": prog, "pid": pid, "M": -1,
                "material": material, "raw_material": [_raw(u) for u in material],
                "cull": False,
                "boxes": None, "sphere": True, "vao": self._sphere_vao, "mode": 4,
                "indexed": False, "count": 3,
                "centre": GL.glGetUniformLocation(pid, "sphere_centre")}

    def _sphere_uniforms(self, prog, V, P) -> None:
        """The sphere program's camera, viewport, sample positions and radius."""
        from OpenGL import GL

        inner = self.inner
        vp = np.asarray(P, float) @ np.asarray(V, float)
        fb_ms, _ = pa.main_framebuffers(inner)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, fb_ms)
        samples = np.array([np.asarray(GL.glGetMultisamplefv(GL.GL_SAMPLE_POSITION, k),
                                       float).ravel()[:2] for k in range(4)])
        pid = pa.program_id(prog)
        for name, value in (("sphere_vp", vp), ("sphere_inv_vp", np.linalg.inv(vp)),
                            ("sphere_viewport", np.array([0.0, 0.0, inner.viewport_width,
                                                          inner.viewport_height])),
                            ("sphere_radius", float(self.sr.ball_radius)),
                            ("sphere_band", np.array([f(a) for a in self.sr.ball_rings
                                                      for f in (np.sin, np.cos)]))):
            u = _uniform(pid, name, value)
            if u is not None:
                u[0](*u[1])
        loc = GL.glGetUniformLocation(pid, "sphere_samples")
        GL.glUniform2fv(loc, 4, samples.astype(np.float32).ravel())

    def _triangle_boxes(self, node, prim):
        """(n, 4) pixel boxes [x0, y0, x1, y1] of a static primitive's triangles in the frame
        (exact projections, 2 px wider), or None when it is not a triangle list or a vertex is
        not in front of the camera (then it is always drawn whole)."""
        if prim.mode != 4:  # GL_TRIANGLES
            return None
        cam = self.sr.camera
        pose = self.sr.scene.get_pose(node)
        v = np.asarray(prim.positions, float) @ pose[:3, :3].T + pose[:3, 3]
        if cam.projection == "perspective" and np.any(v[:, 2] > cam.camera_z - cam.znear):
            return None
        if prim.indices is not None:
            tri = np.asarray(prim.indices, dtype=np.int64).reshape(-1, 3)
        else:
            tri = np.arange(len(v)).reshape(-1, 3)
        q = cam.project(v)[tri]  # (n, 3, 2)
        return np.concatenate([q.min(axis=1) - 2.0, q.max(axis=1) + 2.0], axis=1)

    def _lamp_positions(self) -> np.ndarray:
        return np.array([self.sr.scene.get_pose(ln)[:3, 3] for ln in self.lamps]).reshape(-1, 3)

    def _triangle_far(self, node, prim):
        """(n, lamps) the largest distance of each triangle's vertices from each lamp (a
        triangle's farthest point from a lamp is a vertex), or None when it is not a triangle
        list: what :meth:`_reach` is compared with."""
        if prim.mode != 4 or not self.lamps:
            return None
        pose = self.sr.scene.get_pose(node)
        v = np.asarray(prim.positions, float) @ pose[:3, :3].T + pose[:3, 3]
        if prim.indices is not None:
            tri = np.asarray(prim.indices, dtype=np.int64).reshape(-1, 3)
        else:
            tri = np.arange(len(v)).reshape(-1, 3)
        lamps = self._lamp_positions()
        self._far_lamps = lamps
        dist = np.linalg.norm(v[:, None, :] - lamps[None, :, :], axis=2)  # (vertices, lamps)
        return dist[tri].max(axis=1)

    def _reach(self, centres) -> np.ndarray:
        """Per lamp, the distance of the ball's nearest point at ``centres`` (K, 3) (a
        little less): a point nearer a lamp than that has the ball behind it, not between it
        and the lamp, so the ball cannot shadow a triangle whose vertices are all nearer."""
        lamps = self._far_lamps
        near = np.linalg.norm(centres[:, None, :] - lamps[None, :, :], axis=2).min(axis=0)
        return near - self.sr.ball_radius * (1 + 1e-6) - 1e-9

    def _runs(self, d, tile, reach=None) -> list:
        """(first triangle, count) runs of draw ``d``'s triangles that can touch ``tile``
        (x0, y0, w, h): the others have no pixel in the scissor box, so leaving them out
        changes no pixel (the drawn ones keep their order); with ``reach`` (:meth:`_reach`)
        only those the ball can shadow. Runs closer than RUN_GAP triangles are drawn as one."""
        boxes = d["boxes"]
        n = d["count"] // 3
        if boxes is None:
            return [(0, n)]
        if n <= RUN_GAP:  # a few triangles (the backdrop's two): drawn whole, no pixel
            return [(0, n)]  # changes (see above), and NumPy's per-call cost is saved
        x0, y0, w, h = tile
        if "box_columns" not in d:  # x0, y0, x1, y1 each contiguous
            d["box_columns"] = [np.ascontiguousarray(boxes[:, k]) for k in range(4)]
        bx0, by0, bx1, by1 = d["box_columns"]
        m = bx0 <= x0 + w
        m &= bx1 >= x0
        m &= by0 <= y0 + h
        m &= by1 >= y0
        hit = np.flatnonzero(m)
        if reach is not None and d.get("far") is not None and hit.size:
            hit = hit[(d["far"][hit] >= reach[None, :]).any(axis=1)]
        if hit.size == 0:
            return []
        if hit.size > 16:
            cut = np.flatnonzero(np.diff(hit) > RUN_GAP)
            starts = np.concatenate([[hit[0]], hit[cut + 1]])
            ends = np.concatenate([hit[cut], [hit[-1]]]) + 1
            return list(zip(starts.tolist(), (ends - starts).tolist(), strict=True))
        runs = []  # a few triangles: the same runs without NumPy's per-call cost
        start = prev = None
        for i in hit.tolist():
            if start is None:
                start = i
            elif i - prev > RUN_GAP:
                runs.append((start, prev + 1 - start))
                start = i
            prev = i
        runs.append((start, prev + 1 - start))
        return runs

    # -- uniforms that stay ----------------------------------------------------------------

    def _set_static(self) -> None:
        """Camera and lamp uniforms of every program, by pyrender's own functions (once, and
        again after pyrender drew with the programs or the lamps' shadow cameras changed)."""
        inner, scene, flags = self.inner, self.sr.scene, self.flags
        V, P = pa.camera_matrices(inner, scene)
        cam_pos = scene.get_pose(scene.main_camera_node)[:3, 3]
        done = set()
        for d in self.draws:
            prog = d["program"]
            if id(prog) in done:
                continue
            done.add(id(prog))
            pa.bind_program(prog)
            prog.set_uniform("V", V)
            prog.set_uniform("P", P)
            prog.set_uniform("cam_pos", cam_pos)
            pa.bind_lighting(inner, scene, prog, d["node"], flags)  # units 0.. in lamp order
            if d.get("sphere"):
                self._sphere_uniforms(prog, V, P)
            pa.reset_active_textures(inner)
        if self.shadows:
            self.units = [(k, pa.texture_id(ln.light.shadow_texture))
                          for k, ln in enumerate(self.lamps)]
            self.static_units = [(k, pa.texture_id(self.sr._shadow_cache[ln.name]))
                                 for k, ln in enumerate(self.lamps)]
        else:
            self.units = self.static_units = []
        if self.specialise and not any(d.get("sphere") for d in self.ball_draws):
            self.ball_draws = [self._specialised(d) for d in self.draws
                               if d["node"] is self.ball]
        for d in self.static_draws:  # the static meshes' model matrices, as uploaded
            d["M_ptr"] = _matrix(scene.get_pose(d["node"]))
            d["M_key"] = d["M_ptr"][1].tobytes()
        for d in self.draws + self.ball_draws:
            d["material_keys"] = [_values_key(u) for u in d["material"]]
        # the model matrix and material values each program holds, set by this path since
        # the uniforms were set (pyrender's draws set them their own way: then ready is
        # False and this runs again)
        self._held = {}
        self._light_ptrs = [(_matrix(V_l), _matrix(P_l)) for V_l, P_l in self._light_mats or ()]
        key = self._static_fingerprint(V, P, cam_pos)
        if key != self._static_key:  # the static scene changed: draw its layer again
            self._static_key = key
            self._valid = None
        self.ready = True

    def _specialised(self, d) -> dict:
        """Draw ``d`` (the ball's mesh) by a program whose fragment shader holds the lamps',
        ambient light's and camera's uniforms as constants, their values read back from
        ``d``'s program just after pyrender's functions set them (:meth:`_set_static`); the
        same vertex shader and defines, the shadow maps' samplers, camera matrices and material
        set as for ``d``. A program is compiled once per process and text. ``d`` itself when
        its program lacks one of those uniforms (a scene without shadows)."""
        import hashlib

        from OpenGL import GL

        from synth.backends.shaders import (
            light_counts,
            program_cache,
            shader_dir,
            specialised_mesh_shader,
            specialised_values_names,
        )

        sr, inner = self.sr, self.inner
        counts = light_counts(sr.scene)
        values = {}
        for name, n in specialised_values_names(counts[1]):
            loc = GL.glGetUniformLocation(d["pid"], name)
            if loc < 0:  # not in this program (no shadows: no shadow-camera matrices)
                return d
            buf = np.zeros(16, dtype=np.float32)
            GL.glGetUniformfv(d["pid"], loc, buf)
            values[name] = buf[:n]
        folder = shader_dir(*counts)
        with open(os.path.join(folder, "mesh.frag")) as f:
            text = specialised_mesh_shader(f.read(), values, counts[1])
        name = f"mesh-{hashlib.sha1(text.encode()).hexdigest()[:16]}.frag"
        path = os.path.join(folder, name)
        if not os.path.exists(path):
            with open(path, "w") as f:
                f.write(text)
        if counts not in sr._programs:
            sr._programs[counts] = program_cache(counts)
        pr = sr._pyrender
        prog = pa.primitive_program_as(inner, d["prim"], self.flags,
                                       pr.constants.ProgramFlags.USE_MATERIAL, "mesh.vert", name,
                                       sr._programs[counts])
        pid = pa.program_id(prog)
        V, P = pa.camera_matrices(inner, sr.scene)
        pa.bind_program(prog)
        prog.set_uniform("V", V)
        prog.set_uniform("P", P)
        pa.bind_lighting(inner, sr.scene, prog, d["node"], self.flags)  # the samplers' units
        pa.reset_active_textures(inner)
        material = _material_uniforms(pid, d["prim"].material)
        return {**d, "program": prog, "pid": pid, "M": GL.glGetUniformLocation(pid, "M"),
                "material": material, "raw_material": [_raw(u) for u in material]}

    def _static_fingerprint(self, V, P, cam_pos) -> bytes:
        """Everything the static layer's pixels depend on besides the programs: camera, frame
        size, lamps (poses, light, shadow cameras), background, the static meshes' poses,
        materials and buffers, the cached shadow maps."""
        sr, scene = self.sr, self.sr.scene
        parts = [np.asarray(V, float).tobytes(), np.asarray(P, float).tobytes(),
                 np.asarray(cam_pos, float).tobytes(),
                 repr((sr.camera.width, sr.camera.height, sr.ss, self.flags,
                       np.asarray(scene.ambient_light, float).tolist(),
                       np.asarray(scene.bg_color, float).tolist())).encode()]
        for ln in self.lamps:
            lt = ln.light
            parts.append(scene.get_pose(ln).tobytes())
            parts.append(repr((np.asarray(lt.color, float).tolist(), lt.intensity,
                               getattr(lt, "innerConeAngle", None),
                               getattr(lt, "outerConeAngle", None))).encode())
        for V_l, P_l in self._light_mats or ():
            parts += [np.asarray(V_l).tobytes(), np.asarray(P_l).tobytes()]
        for d in self.draws:
            if d["node"] is self.ball:
                continue
            parts.append(scene.get_pose(d["node"]).tobytes())
            parts.append(repr((d["pid"], d["vao"], d["count"], d["cull"],
                               [(getattr(fn, "__name__", repr(fn)),
                                 [np.asarray(a).tolist() for a in args])
                                for fn, args in d["material"]])).encode())
        parts.append(repr(self.static_units).encode())
        return b"|".join(parts)

    # -- a frame -----------------------------------------------------------------------------

    def render(self, poses, tiles, timings: dict | None = None) -> list[np.ndarray]:
        """Tiles [(x0, y0, w, h), ...] of the frame with the ball at each of ``poses``, summed
        over the poses (as :meth:`synth.backends.raster.SceneRenderer.render_tiles`).

        ``timings`` (the benchmark's): a dict to which the wall seconds of each stage are
        added ("set-up", "shadow maps", "static layer", "draw: shadowed surfaces",
        "draw: ball", "read back"), the GL work finished
        (glFinish) at the end of each, which costs a little more than not waiting.
        """
        import time

        from OpenGL import GL

        def lap(stage, t0):
            if timings is None:
                return t0
            GL.glFinish()
            t1 = time.perf_counter()
            timings[stage] = timings.get(stage, 0.0) + t1 - t0
            return t1

        sr = self.sr
        W, H, s = sr.camera.width, sr.camera.height, sr.ss
        inner = self.inner
        gl_box = [self._gl_box(t) for t in tiles]
        out = [None] * len(tiles)
        ball_box, shadow_boxes = self._footprint(poses)
        # a sample drawn again gets the colour it got the first time: once is enough
        pieces = disjoint_boxes(shadow_boxes) if self.disjoint else shadow_boxes
        pa.make_current(sr._offscreen)
        try:
            inner.viewport_width, inner.viewport_height = W * s, H * s
            for pose in poses:
                t0 = time.perf_counter()
                sr.set_ball(pose)
                if not self.ready or sr._ball_node is not self.ball:
                    # pyrender drew meanwhile (it may have dropped and re-uploaded meshes) or
                    # the ball was taken out and put back: upload, look everything up again
                    pa.update_context(inner, sr.scene, self.flags)
                    self.ball = sr._ball_node
                    self._build(self._order())
                mats = [pa.light_cam_matrices(inner)(sr.scene, ln, self.flags)
                        for ln in self.lamps] if self.shadows else []
                same = self._light_mats is not None and all(
                    a[0] is b[0] and a[1] is b[1]
                    for a, b in zip(mats, self._light_mats, strict=True))
                if not (self.ready and same):
                    # the lamps' shadow cameras are new whenever a lamp or the scene's bounds
                    # moved (the ball's set_pose renews the bounds, and their cache compares
                    # the lamps' poses): only then can pyrender's order of the static meshes
                    # (the ball's place in it does not matter here: it is drawn last) or the
                    # lamps' distances to the triangles have changed
                    order = self._order()
                    if order != self.order or self._far_lamps is not None and not \
                            np.array_equal(self._far_lamps, self._lamp_positions()):
                        self._build(order)
                    self._light_mats = mats
                    self._set_static()
                M = np.asarray(pose, dtype=float)
                reach = None if self._far_lamps is None else self._reach(M[None, :3, 3])
                t0 = lap("set-up", t0)
                if self.shadows:
                    self._shadow_pass(M, mats)
                    t0 = lap("shadow maps", t0)
                for k, tile in enumerate(tiles):
                    self._restore(tile)
                    t0 = lap("static layer", t0)
                    for box in pieces:
                        part = _meet(tile, box)
                        if part is not None:  # the static surfaces the shadows fall on
                            self._forward(M, self._gl_box(part), part, self.static_draws,
                                          self.units, clear=False, redraw=True, reach=reach)
                    t0 = lap("draw: shadowed surfaces", t0)
                    part = _meet(tile, ball_box)
                    if part is not None:
                        self._forward(M, self._gl_box(part), part, self.ball_draws,
                                      self.units, clear=False)
                    t0 = lap("draw: ball", t0)
                    c = sr._reduce(read_region(inner, *gl_box[k]))
                    t0 = lap("read back", t0)
                    out[k] = c if out[k] is None else out[k] + c
            GL.glUseProgram(0)
        finally:
            pa.make_uncurrent(sr._offscreen)
        return out

    def _gl_box(self, tile) -> tuple:
        """Frame pixels (x0, y0, w, h) -> GL window box of the supersampled viewport."""
        x0, y0, w, h = tile
        s, H = self.sr.ss, self.sr.camera.height
        return (x0 * s, (H - y0 - h) * s, w * s, h * s)

    def _footprint(self, poses) -> tuple:
        """The ball's box and the shadows' boxes (x0, y0, x1, y1) over all ``poses``: those
        :meth:`synth.backends.raster.SceneRenderer.tiles_for` found for the same centres, or found
        again."""
        sr = self.sr
        centres = np.array([np.asarray(p, float)[:3, 3] for p in poses])
        known = sr.footprint(centres)
        if known is not None:
            return known[1], known[2]
        shadows = sr.shadow_boxes(centres) if self.shadows else []
        return sr.ball_box(centres), shadows

    def _static_layer(self):
        """The static layer's multisampled framebuffer (made on first use, the main
        framebuffer's formats and size): the scene without the ball, shaded with the cached
        trough-only shadow maps, drawn block by block where tiles need it."""
        from OpenGL import GL

        inner = self.inner
        W, H = inner.viewport_width, inner.viewport_height
        if self._static is not None and self._static[2] != (W, H):
            self.close()
        if self._static is None:
            cb, db = GL.glGenRenderbuffers(2)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, cb)
            GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, 4, GL.GL_RGBA, W, H)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, db)
            GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, 4, GL.GL_DEPTH_COMPONENT24,
                                                W, H)
            fb = GL.glGenFramebuffers(1)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, fb)
            GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0,
                                         GL.GL_RENDERBUFFER, cb)
            GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT,
                                         GL.GL_RENDERBUFFER, db)
            self._static = (fb, [cb, db], (W, H))
            self._valid = None
        if self._valid is None:
            self._valid = np.zeros((-(-self.sr.camera.height // STATIC_BLOCK),
                                    -(-self.sr.camera.width // STATIC_BLOCK)), dtype=bool)
        return self._static[0]

    def _restore(self, tile) -> None:
        """Copy the static layer's samples (colour and depth) of ``tile`` into the main
        multisampled framebuffer, drawing first the blocks of the layer not drawn yet."""
        from OpenGL import GL

        fb = self._static_layer()
        x0, y0, w, h = tile
        b = STATIC_BLOCK
        r0, r1, c0, c1 = y0 // b, (y0 + h - 1) // b + 1, x0 // b, (x0 + w - 1) // b + 1
        missing = ~self._valid[r0:r1, c0:c1]
        if missing.any():
            rows = np.flatnonzero(missing.any(axis=1)) + r0
            cols = np.flatnonzero(missing.any(axis=0)) + c0
            W, H = self.sr.camera.width, self.sr.camera.height
            bx0, by0 = cols[0] * b, rows[0] * b
            bx1, by1 = min((cols[-1] + 1) * b, W), min((rows[-1] + 1) * b, H)
            box = (bx0, by0, bx1 - bx0, by1 - by0)
            self._forward(None, self._gl_box(box), box, self.static_draws, self.static_units,
                          clear=True, fb=fb)
            self._valid[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1] = True
        fb_ms, _ = pa.main_framebuffers(self.inner)
        x, y, w, h = self._gl_box(tile)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, fb)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, fb_ms)
        GL.glBlitFramebuffer(x, y, x + w, y + h, x, y, x + w, y + h,
                             GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT, GL.GL_NEAREST)

    def _shadow_pass(self, M, mats) -> None:
        """Each lamp's shadow map: its box the ball covered last or covers now restored from
        the cached trough depth, the ball's depth drawn into it (pyrender's shadow pass with the
        static meshes hidden, see SceneRenderer._ball_shadow_pass)."""
        from OpenGL import GL
        from OpenGL.raw.GL.VERSION import GL_2_0

        sr, inner = self.sr, self.inner
        size = sr._pyrender.constants.SHADOW_TEX_SZ
        if sr._shadow_cache is None:
            raise RuntimeError("the trough's shadow maps are not cached yet")
        fb = pa.shadow_framebuffer(inner)
        M_ptr = _matrix(M)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        try:
            for ln, (V, P), (V_ptr, P_ptr) in zip(self.lamps, mats, self._light_ptrs,
                                                  strict=True):
                cache = sr._shadow_cache[ln.name]
                now = sr._shadow_box(inner, ln, self.flags, (V, P), M[:3, 3])
                prev = sr._shadow_prev.get(ln.name)
                if prev is None:
                    box = (0, 0, size, size)
                else:
                    x0, y0 = min(now[0], prev[0]), min(now[1], prev[1])
                    x1 = max(now[0] + now[2], prev[0] + prev[2])
                    y1 = max(now[1] + now[3], prev[1] + prev[3])
                    box = (x0, y0, x1 - x0, y1 - y0)
                tex = pa.texture_id(ln.light.shadow_texture)
                # pyrender's _configure_shadow_mapping_viewport, scissored
                GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fb)
                GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
                GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT,
                                          GL.GL_TEXTURE_2D, tex, 0)
                GL.glActiveTexture(GL.GL_TEXTURE0)
                GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
                GL.glDrawBuffer(GL.GL_NONE)
                GL.glReadBuffer(GL.GL_NONE)
                GL.glScissor(*box)
                # the box's depth is the cache's (copied over the whole box: no clear first,
                # which cost llvmpipe a queued clear and a wait before the copy)
                GL.glCopyImageSubData(pa.texture_id(cache), GL.GL_TEXTURE_2D, 0, box[0], box[1],
                                      0, tex, GL.GL_TEXTURE_2D, 0, box[0], box[1], 0, box[2],
                                      box[3], 1)
                GL.glViewport(0, 0, size, size)
                GL.glEnable(GL.GL_DEPTH_TEST)
                GL.glDepthMask(GL.GL_TRUE)
                GL.glDepthFunc(GL.GL_LESS)
                GL.glDepthRange(0.0, 1.0)
                # pyrender's DEPTH_ONLY draw state
                GL.glEnable(GL.GL_CULL_FACE)
                GL.glEnable(GL.GL_BLEND)
                GL.glCullFace(GL.GL_BACK)
                GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
                GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
                GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
                for d in self.depth:
                    GL.glUseProgram(d["pid"])
                    GL_2_0.glUniformMatrix4fv(d["V"], 1, GL.GL_TRUE, V_ptr[0])
                    GL_2_0.glUniformMatrix4fv(d["P"], 1, GL.GL_TRUE, P_ptr[0])
                    GL_2_0.glUniformMatrix4fv(d["M"], 1, GL.GL_TRUE, M_ptr[0])
                    _draw(d)
                GL.glBindVertexArray(0)
                sr._shadow_prev[ln.name] = now
        finally:
            GL.glDisable(GL.GL_SCISSOR_TEST)

    def _forward(self, M, box, tile, draws, units, *, clear: bool, fb=None,
                 redraw: bool = False, reach=None) -> None:
        """``draws`` (the ball's at pose ``M``, the static ones at their poses) scissored to
        ``box`` (GL window coordinates) of ``tile`` (frame pixels), with the shadow maps
        ``units`` [(texture unit, GL texture)], into the main multisampled framebuffer (or
        ``fb``), the box cleared first with ``clear``; :func:`read_region` reads it.

        ``redraw`` (with ``clear=False``): the static surfaces drawn again over the static
        layer's samples (not cleared) where the ball's shadows fall, with the depth test
        passing equal depths, and with ``reach`` (:meth:`_reach`) only the triangles the
        ball can shadow. A surface
        drawn again has the very depth the layer holds for it (the same program, vertices
        and rasterisation), so its samples are shaded again and every other sample (a surface
        in front of it, one the ball cannot shadow) keeps the layer's colour, which is what
        drawing it would give: the ball is not between it and any lamp, and the ball's depth
        in the shadow maps lies behind it."""
        from OpenGL import GL
        from OpenGL.raw.GL.VERSION import GL_2_0

        inner, scene = self.inner, self.sr.scene
        if fb is None:
            fb, _ = pa.main_framebuffers(inner)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, fb)
        GL.glViewport(0, 0, inner.viewport_width, inner.viewport_height)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LEQUAL if redraw else GL.GL_LESS)
        GL.glDepthRange(0.0, 1.0)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        try:
            GL.glScissor(*box)
            if clear:
                GL.glClearColor(*scene.bg_color)
                GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
            GL.glEnable(GL.GL_MULTISAMPLE)
            for unit, tex in units:
                GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
                GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
            GL.glEnable(GL.GL_BLEND)
            GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
            GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
            GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
            current = None
            ball_ptr = None if M is None else _matrix(M)
            for d in draws:
                if d["pid"] != current:
                    GL.glUseProgram(d["pid"])
                    current = d["pid"]
                held = self._held
                if d.get("sphere"):
                    GL.glUniform3f(d["centre"], *(float(v) for v in M[:3, 3]))
                elif d["node"] is self.ball:
                    GL_2_0.glUniformMatrix4fv(d["M"], 1, GL.GL_TRUE, ball_ptr[0])
                    held.pop((d["pid"], "M"), None)
                elif not self.keep_uniforms or held.get((d["pid"], "M")) != d["M_key"]:
                    GL_2_0.glUniformMatrix4fv(d["M"], 1, GL.GL_TRUE, d["M_ptr"][0])
                    held[(d["pid"], "M")] = d["M_key"]
                for (fn, args, _), key in zip(d["raw_material"], d["material_keys"],
                                              strict=True):
                    if not self.keep_uniforms or held.get((d["pid"], args[0])) != key:
                        fn(*args)  # args[0]: the uniform's location
                        held[(d["pid"], args[0])] = key
                if d["cull"]:
                    GL.glEnable(GL.GL_CULL_FACE)
                    GL.glCullFace(GL.GL_BACK)
                else:
                    GL.glDisable(GL.GL_CULL_FACE)
                if d.get("sphere") or d["mode"] != 4:
                    _draw(d, None)
                else:
                    runs = self._runs(d, tile, reach)
                    if runs:
                        _draw(d, runs)
            GL.glBindVertexArray(0)
            GL.glFlush()
        finally:
            GL.glDisable(GL.GL_SCISSOR_TEST)


def _meet(tile, box):
    """The part (x0, y0, w, h) of ``tile`` (x0, y0, w, h) inside ``box`` (x0, y0, x1, y1),
    or None."""
    x0, y0 = max(tile[0], box[0]), max(tile[1], box[1])
    x1, y1 = min(tile[0] + tile[2], box[2]), min(tile[1] + tile[3], box[3])
    return (x0, y0, x1 - x0, y1 - y0) if x1 > x0 and y1 > y0 else None


def disjoint_boxes(boxes) -> list:
    """Boxes covering the union of ``boxes`` with no two overlapping: each box less the
    ones before it, cut into at most four boxes each time.

    Parameters
    ----------
    boxes : list of tuple
        Boxes (x0, y0, x1, y1), px (x1, y1 exclusive).

    Returns
    -------
    list of tuple
        Boxes (x0, y0, x1, y1) whose union is that of ``boxes``, pairwise without a common
        pixel; ``boxes`` themselves when none overlap.
    """
    out: list = []
    for box in boxes:
        parts = [tuple(box)]
        for other in out:
            parts = [q for p in parts for q in _less(p, other)]
        out += parts
    return out


def _less(a, b) -> list:
    """Box ``a`` less box ``b`` (both (x0, y0, x1, y1)) as at most four boxes."""
    x0, y0, x1, y1 = max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3])
    if x0 >= x1 or y0 >= y1:
        return [a]
    parts = [(a[0], a[1], a[2], y0), (a[0], y1, a[2], a[3]),  # below and above b
             (a[0], y0, x0, y1), (x1, y0, a[2], y1)]  # left and right of b, beside it
    return [p for p in parts if p[2] > p[0] and p[3] > p[1]]
