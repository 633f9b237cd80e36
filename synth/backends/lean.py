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

import os

import numpy as np

from synth import pyrender_adapter as pa
from synth.backends import footprint, gl_calls, triangles
from synth.backends.shaders import (
    SPHERE_FRAG,
    SPHERE_VERT,
    light_counts,
    program_cache,
    shader_dir,
    specialised_mesh_shader,
    specialised_values_names,
)

STATIC_BLOCK = 32  # px: the static layer is drawn where tiles first need it, in such blocks


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
                    "material": gl_calls.material_uniforms(pid, prim.material),
                    "cull": not prim.material.doubleSided,
                    "boxes": None if node is self.ball else self._triangle_boxes(node, prim),
                    "far": None if node is self.ball else self._triangle_far(node, prim),
                    "prim": prim,
                    **gl_calls.drawing(prim)})
        for d in self.draws:
            d["raw_material"] = [gl_calls.raw(u) for u in d["material"]]
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
                                   **gl_calls.drawing(prim)})
        self.ready = False

    def _sphere_draw(self, mesh_draw) -> dict:
        """The ball drawn as an exact sphere (``SceneConfig.ball_model = "sphere"``): one
        triangle over the viewport, scissored to the ball's box, whose fragment shader
        (:func:`synth.backends.shaders.sphere_shader`) intersects each pixel's ray with the
        sphere and shades the hit with the mesh shader's own code; the ball mesh's material."""
        from OpenGL import GL

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
        material = gl_calls.material_uniforms(pid, prim.material)
        return {**mesh_draw, "program": prog, "pid": pid, "M": -1,
                "material": material, "raw_material": [gl_calls.raw(u) for u in material],
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
            u = gl_calls.uniform(pid, name, value)
            if u is not None:
                u[0](*u[1])
        loc = GL.glGetUniformLocation(pid, "sphere_samples")
        GL.glUniform2fv(loc, 4, samples.astype(np.float32).ravel())

    def _triangle_boxes(self, node, prim):
        """:func:`synth.backends.triangles.triangle_boxes` of a static primitive."""
        return triangles.triangle_boxes(self.sr.camera, self.sr.scene.get_pose(node), prim)

    def _lamp_positions(self) -> np.ndarray:
        return np.array([self.sr.scene.get_pose(ln)[:3, 3] for ln in self.lamps]).reshape(-1, 3)

    def _triangle_far(self, node, prim):
        """:func:`synth.backends.triangles.triangle_far` of a static primitive from the lamps
        where they are now (kept: what :meth:`_reach` measures from)."""
        if prim.mode != 4 or not self.lamps:
            return None
        self._far_lamps = self._lamp_positions()
        return triangles.triangle_far(self.sr.scene.get_pose(node), prim, self._far_lamps)

    def _reach(self, centres) -> np.ndarray:
        """:func:`synth.backends.triangles.reach` of the ball at ``centres`` (K, 3)."""
        return triangles.reach(centres, self._far_lamps, self.sr.ball_radius)

    def _runs(self, d, tile, reach=None) -> list:
        """:func:`synth.backends.triangles.runs` of draw ``d`` in ``tile``."""
        return triangles.runs(d, tile, reach)

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
            d["M_ptr"] = gl_calls.matrix(scene.get_pose(d["node"]))
            d["M_key"] = d["M_ptr"][1].tobytes()
        for d in self.draws + self.ball_draws:
            d["material_keys"] = [gl_calls.values_key(u) for u in d["material"]]
        # the model matrix and material values each program holds, set by this path since
        # the uniforms were set (pyrender's draws set them their own way: then ready is
        # False and this runs again)
        self._held = {}
        self._light_ptrs = [(gl_calls.matrix(V_l), gl_calls.matrix(P_l))
                            for V_l, P_l in self._light_mats or ()]
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
        material = gl_calls.material_uniforms(pid, d["prim"].material)
        return {**d, "program": prog, "pid": pid, "M": GL.glGetUniformLocation(pid, "M"),
                "material": material, "raw_material": [gl_calls.raw(u) for u in material]}

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
        pieces = footprint.disjoint_boxes(shadow_boxes) if self.disjoint else shadow_boxes
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
                        part = footprint.meet(tile, box)
                        if part is not None:  # the static surfaces the shadows fall on
                            self._forward(M, self._gl_box(part), part, self.static_draws,
                                          self.units, clear=False, redraw=True, reach=reach)
                    t0 = lap("draw: shadowed surfaces", t0)
                    part = footprint.meet(tile, ball_box)
                    if part is not None:
                        self._forward(M, self._gl_box(part), part, self.ball_draws,
                                      self.units, clear=False)
                    t0 = lap("draw: ball", t0)
                    c = sr._reduce(gl_calls.read_region(inner, *gl_box[k]))
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
        M_ptr = gl_calls.matrix(M)
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
                    gl_calls.draw(d)
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
            ball_ptr = None if M is None else gl_calls.matrix(M)
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
                    gl_calls.draw(d, None)
                else:
                    runs = self._runs(d, tile, reach)
                    if runs:
                        gl_calls.draw(d, runs)
            GL.glBindVertexArray(0)
            GL.glFlush()
        finally:
            GL.glDisable(GL.GL_SCISSOR_TEST)
