"""synth's lean draw path: a tile frame drawn with a fixed list of OpenGL calls instead of
pyrender's per-draw Python.

pyrender sets every uniform of every primitive on every draw, looking each location up by name,
rebuilds the lamps' uniforms for each program and re-sorts the scene's nodes each pass: ~5 ms of
Python a tile frame against ~9 ms of drawing (llvmpipe, one thread; cProfile with CPU time).
Everything but the ball's pose is the same in every frame of a recording, so here:

- pyrender itself draws the first tile frame (it compiles the programs, uploads the meshes,
  renders and caches the trough's shadow maps: :meth:`synth.scene.SceneRenderer.render_tiles`);
- the camera's and lamps' uniforms are then set once per program by pyrender's own functions
  (the same values: a GL program keeps its uniforms), again whenever pyrender drew in between
  (a full-frame render sets other projections) or the lamps' shadow cameras change;
- each frame then makes only the calls that draw: per lamp, the ball's depth into the
  scissored box of its shadow map over the cached trough; the forward pass scissored to each
  tile, the primitives in pyrender's order with the model matrix and material uniforms at
  locations looked up once, in the GL state pyrender's draw sets; the box resolved and read.

The same programs, buffers, uniform values, draw order and GL state as pyrender's path, so the
same pixels (tests/test_synth_render.py compares the two bit for bit and both with stock
pyrender). What this path does not draw (textured materials, point or directional lamps, the
flat silhouette mode) is drawn by pyrender's path: :func:`unsupported` says why.
"""

from __future__ import annotations

import ctypes

import numpy as np

from synth import pyrender_adapter as pa


def unsupported(sr) -> str | None:
    """Why the lean path cannot draw SceneRenderer ``sr``'s scene (None if it can).

    Parameters
    ----------
    sr : synth.scene.SceneRenderer
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


def _drawing(prim) -> dict:
    """What drawing a pyrender Primitive takes: its vertex array, mode and count."""
    indexed = prim.indices is not None
    return {"vao": pa.vertex_array(prim), "mode": prim.mode, "indexed": indexed,
            "count": prim.indices.size if indexed else len(prim.positions)}


def _draw(d, runs=None) -> None:
    """Draw a primitive as pyrender's _bind_and_draw_primitive does (one instance), or only
    its triangles in ``runs`` [(first, count), ...]."""
    from OpenGL import GL

    GL.glBindVertexArray(d["vao"])
    if runs is None:
        runs = [(0, d["count"] // 3)] if d["mode"] == 4 else None
    if runs is None:
        first_counts = [(0, d["count"])]
    else:
        first_counts = [(3 * a, 3 * n) for a, n in runs]
    for first, count in first_counts:
        if d["indexed"]:
            GL.glDrawElementsInstanced(d["mode"], count, GL.GL_UNSIGNED_INT,
                                       ctypes.c_void_p(4 * first), 1)
        else:
            GL.glDrawArraysInstanced(d["mode"], first, count, 1)


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
    sr : synth.scene.SceneRenderer
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
        self._build(self._order())

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
                m = prim.material
                material = [_uniform(pid, "material.emissive_factor", m.emissiveFactor),
                            _uniform(pid, "material.base_color_factor", m.baseColorFactor),
                            _uniform(pid, "material.metallic_factor", m.metallicFactor),
                            _uniform(pid, "material.roughness_factor", m.roughnessFactor)]
                self.draws.append({
                    "node": node, "program": prog, "pid": pid,
                    "M": GL.glGetUniformLocation(pid, "M"),
                    "material": [u for u in material if u is not None],
                    "cull": not m.doubleSided,
                    "boxes": None if node is self.ball else self._triangle_boxes(node, prim),
                    **_drawing(prim)})
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

    def _runs(self, d, tile) -> list:
        """(first triangle, count) runs of draw ``d``'s triangles that can touch ``tile``
        (x0, y0, w, h): the others have no pixel in the scissor box, so leaving them out
        changes no pixel (the drawn ones keep their order). Runs closer than 64 triangles
        are drawn as one."""
        boxes = d["boxes"]
        n = d["count"] // 3
        if boxes is None:
            return [(0, n)]
        x0, y0, w, h = tile
        hit = np.flatnonzero((boxes[:, 0] <= x0 + w) & (boxes[:, 2] >= x0)
                             & (boxes[:, 1] <= y0 + h) & (boxes[:, 3] >= y0))
        if hit.size == 0:
            return []
        cut = np.flatnonzero(np.diff(hit) > 64)
        starts = np.concatenate([[hit[0]], hit[cut + 1]])
        ends = np.concatenate([hit[cut], [hit[-1]]]) + 1
        return list(zip(starts.tolist(), (ends - starts).tolist(), strict=True))

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
            pa.reset_active_textures(inner)
        if self.shadows:
            self.units = [(k, pa.texture_id(ln.light.shadow_texture))
                          for k, ln in enumerate(self.lamps)]
        self.ready = True

    # -- a frame -----------------------------------------------------------------------------

    def render(self, poses, tiles, timings: dict | None = None) -> list[np.ndarray]:
        """Tiles [(x0, y0, w, h), ...] of the frame with the ball at each of ``poses``, summed
        over the poses (as :meth:`synth.scene.SceneRenderer.render_tiles`).

        ``timings`` (the benchmark's): a dict to which the wall seconds of each stage are
        added ("set-up", "shadow maps", "draw", "read back"), the GL work finished
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
        gl_box = [(x0 * s, (H - y0 - h) * s, w * s, h * s) for x0, y0, w, h in tiles]
        out = [None] * len(tiles)
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
                order = self._order()
                if order != self.order:
                    self._build(order)
                mats = [pa.light_cam_matrices(inner)(sr.scene, ln, self.flags)
                        for ln in self.lamps] if self.shadows else []
                same = self._light_mats is not None and all(
                    a[0] is b[0] and a[1] is b[1]
                    for a, b in zip(mats, self._light_mats, strict=True))
                if not (self.ready and same):
                    self._set_static()
                    self._light_mats = mats
                M = np.asarray(pose, dtype=float)
                t0 = lap("set-up", t0)
                if self.shadows:
                    self._shadow_pass(M, mats)
                    t0 = lap("shadow maps", t0)
                for k in range(len(tiles)):
                    self._forward(M, gl_box[k], tiles[k])
                    t0 = lap("draw", t0)
                    c = sr._reduce(read_region(inner, *gl_box[k]))
                    t0 = lap("read back", t0)
                    out[k] = c if out[k] is None else out[k] + c
            GL.glUseProgram(0)
        finally:
            pa.make_uncurrent(sr._offscreen)
        return out

    def _shadow_pass(self, M, mats) -> None:
        """Each lamp's shadow map: its box the ball covered last or covers now restored from
        the cached trough depth, the ball's depth drawn into it (pyrender's shadow pass with the
        static meshes hidden, see SceneRenderer._ball_shadow_pass)."""
        from OpenGL import GL

        sr, inner = self.sr, self.inner
        size = sr._pyrender.constants.SHADOW_TEX_SZ
        if sr._shadow_cache is None:
            raise RuntimeError("the trough's shadow maps are not cached yet")
        fb = pa.shadow_framebuffer(inner)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        try:
            for ln, (V, P) in zip(self.lamps, mats, strict=True):
                cache = sr._shadow_cache[ln.name]
                now = sr._shadow_box(inner, ln, self.flags)
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
                GL.glClear(GL.GL_DEPTH_BUFFER_BIT)
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
                    GL.glUniformMatrix4fv(d["V"], 1, GL.GL_TRUE, V)
                    GL.glUniformMatrix4fv(d["P"], 1, GL.GL_TRUE, P)
                    GL.glUniformMatrix4fv(d["M"], 1, GL.GL_TRUE, M)
                    _draw(d)
                GL.glBindVertexArray(0)
                sr._shadow_prev[ln.name] = now
        finally:
            GL.glDisable(GL.GL_SCISSOR_TEST)

    def _forward(self, M, box, tile) -> None:
        """The forward pass scissored to ``box`` (GL window coordinates) of ``tile`` (frame
        pixels), into the multisampled framebuffer (:func:`read_region` reads it)."""
        from OpenGL import GL

        inner, scene = self.inner, self.sr.scene
        fb_ms, _ = pa.main_framebuffers(inner)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, fb_ms)
        GL.glViewport(0, 0, inner.viewport_width, inner.viewport_height)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthRange(0.0, 1.0)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        try:
            GL.glScissor(*box)
            GL.glClearColor(*scene.bg_color)
            GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
            GL.glEnable(GL.GL_MULTISAMPLE)
            for unit, tex in self.units:
                GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
                GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
            GL.glEnable(GL.GL_BLEND)
            GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
            GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
            GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
            current = None
            for d in self.draws:
                if d["pid"] != current:
                    GL.glUseProgram(d["pid"])
                    current = d["pid"]
                pose = M if d["node"] is self.ball else scene.get_pose(d["node"])
                GL.glUniformMatrix4fv(d["M"], 1, GL.GL_TRUE, pose)
                for fn, args in d["material"]:
                    fn(*args)
                if d["cull"]:
                    GL.glEnable(GL.GL_CULL_FACE)
                    GL.glCullFace(GL.GL_BACK)
                else:
                    GL.glDisable(GL.GL_CULL_FACE)
                _draw(d, self._runs(d, tile) if d["mode"] == 4 else None)
            GL.glBindVertexArray(0)
            GL.glFlush()
        finally:
            GL.glDisable(GL.GL_SCISSOR_TEST)
