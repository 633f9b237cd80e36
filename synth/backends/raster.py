"""The pyrender scene (trough, backdrop, steel ball, spot lamps) and the tile renderer.

The scene is built in metres in the contract's world frame (pyrender's shadow bias is scaled for
metre-sized scenes: in millimetres it shows acne). Rendered colours are 8-bit sRGB-like (pyrender
applies gamma 2.2); a rendered image is returned as the integer SUM over the RGB channels and
the ss x ss supersamples of each output pixel (``scale`` = 3 ss^2 255 is white), so nothing is
lost to rounding and the same scene gives the same integers.

Speed: the static scene (everything but the ball) is rendered once, full frame; each frame then
renders only the pixels the ball and its shadows can change (the footprint, from lamp-to-ball
tangent rays), with the projection shifted so the tile lines up with the full frame pixel for
pixel. Shader programs and mesh buffers persist in the renderer; each frame's shadow maps are
rendered once and reused by every tile of that frame. The mesh shader is pyrender's with its
shadow filter reading the maps by gathers and its light loops bounded by the scene's lamp count
(synth.backends.shaders: the same pixels, less than half the time); ``stock_shaders=True``
renders with pyrender's own, for the benchmark's baseline.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from synth import pyrender_adapter
from synth.backends.footprint import SHADOW_TEX_SZ, Footprint
from synth.backends.gl_calls import read_region
from synth.backends.lean import LeanDraw, unsupported
from synth.backends.scene_model import SceneModel, look_at, view_sphere
from synth.backends.shaders import light_counts, program_cache
from synth.camera import CameraModel
from synth.config import SceneConfig


class SceneRenderer:
    """One pyrender scene and one offscreen renderer (one per process: EGL contexts do not
    survive fork)."""

    def __init__(self, config: SceneConfig, ball_radius: float, cylinder_radius: float,
                 ovality: float = 0.0, ovality_angle: float = 0.0):
        pyrender = pyrender_adapter.load()  # headless EGL unless PYOPENGL_PLATFORM says else

        # the shared scene (an out-of-round bore as its as-built ellipse, sim.section)
        model = SceneModel.of(config, ball_radius, cylinder_radius, ovality, ovality_angle)
        self.model = model
        self.config = config
        self.camera: CameraModel = config.camera
        self.ball_radius = model.ball_radius
        self.cylinder_radius = model.cylinder_radius
        self.section = model.section
        self.footprints = Footprint(model)  # the pixels the ball and its shadows change
        self.ss = config.supersample
        self.scale = 3 * self.ss * self.ss * 255
        self._pyrender = pyrender
        light = config.lighting
        scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 1.0],
                               ambient_light=[light.ambient] * 3)
        scene.add(_trough_mesh(pyrender, model), name="trough")
        self._backdrop_mesh = _backdrop_mesh(pyrender, model)
        scene.add(self._backdrop_mesh, name="backdrop")
        # lamps
        self.lamps = light.lamps
        for i, lamp in enumerate(light.lamps):
            sl = pyrender.SpotLight(color=[1.0, 1.0, 1.0], intensity=lamp.intensity,
                                    innerConeAngle=lamp.inner_cone,
                                    outerConeAngle=lamp.outer_cone)
            scene.add(sl, pose=look_at(lamp.position, lamp.target), name=f"lamp{i}")
        # ball (added/removed per render)
        self._ball_mesh, self.ball_rings = _ball_mesh(pyrender, model)
        self._ball_node = None
        self._bounds_memo = None  # (bounds, [(mesh node, world corners or None: the ball)])
        # camera whose projection we set per tile
        self._cam = _camera_class()(znear=self.camera.znear, zfar=self.camera.zfar)
        scene.add(self._cam, pose=self.camera.pose(), name="camera")
        self.scene = scene
        self.flags = pyrender.RenderFlags.NONE
        if config.shadows:
            self.flags |= pyrender.RenderFlags.SHADOWS_SPOT
        self._offscreen = None
        self._programs: dict = {}  # "stock" or light counts -> pyrender program cache
        self._shadow_cache = None
        self._shadow_prev: dict = {}  # lamp -> texel box the ball covered last
        self._lean = None  # synth.backends.lean.LeanDraw, once pyrender has drawn a tile frame

    def silhouette_mode(self) -> None:
        """Switch to an unlit white ball on black (no trough, no backdrop, no shadows): the
        rendered image is the ball's coverage, for checking the silhouette truth."""
        pr = self._pyrender
        for node in self.scene.mesh_nodes:
            if node.mesh is not self._ball_mesh:
                node.mesh.is_visible = False
        for prim in self._ball_mesh.primitives:
            prim.material = pr.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0])
        self.flags = pr.RenderFlags.FLAT
        self._drop_lean()  # the lean path does not draw the flat mode
        self.config = self.config.replace(shadows=False)
        self.model = dataclasses.replace(self.model, config=self.config)
        self.footprints = Footprint(self.model)

    def layer_coverage(self) -> tuple[np.ndarray, np.ndarray]:
        """The trough's coverage of each pixel, front face and bore apart, from one flat render
        (synth.defocus's layers). The renderer is changed for good (its backdrop and ball
        hidden, the trough drawn flat in two colours): use one of its own, or close it after.

        Returns
        -------
        face, bore : numpy.ndarray
            float32 (H, W) coverage in [0, 1] of the trough's faces and of its bore.
        """
        pr = self._pyrender
        self.set_ball(None)
        trough = None
        for node in self.scene.mesh_nodes:
            if node.name == "trough":
                trough = node
            else:
                node.mesh.is_visible = False
        prims = trough.mesh.primitives  # [bore (smooth), flat parts] (_trough_mesh)
        colours = ([1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0])
        for prim, c in zip(prims, colours, strict=True):
            prim.material = pr.MetallicRoughnessMaterial(baseColorFactor=c)
        self.flags = pr.RenderFlags.FLAT
        self._lean = None
        self._shadow_prev = {}
        cam = self.camera
        r = self._ensure_renderer(cam.width, cam.height)
        self._cam.P = cam.tile_projection(0, 0, cam.width, cam.height)
        color, _ = r.render(self.scene, self.flags)
        s = self.ss
        c = color.astype(np.float32).reshape(cam.height, s, cam.width, s, 3).sum(axis=(1, 3))
        c /= 255.0 * s * s
        return np.clip(c[..., 1], 0, 1), np.clip(c[..., 0], 0, 1)

    # -- low level -------------------------------------------------------------------------

    def _ensure_renderer(self, w: int, h: int, stock_shaders: bool = False):
        """The offscreen renderer at w x h output pixels, compiling pyrender's own shaders
        (``stock_shaders``) or synth's (synth.backends.shaders: built for the scene's light
        counts, so a scene whose lights change gets programs for its new counts)."""
        vw, vh = w * self.ss, h * self.ss
        if self._offscreen is None:
            self._offscreen = self._pyrender.OffscreenRenderer(vw, vh)
            pyrender_adapter.check_internals(self._offscreen)
            self._programs = {"stock": pyrender_adapter.program_cache(self._offscreen)}
            _cache_light_matrices(pyrender_adapter.inner(self._offscreen))
        else:
            self._offscreen.viewport_width = vw
            self._offscreen.viewport_height = vh
        key = "stock" if stock_shaders else light_counts(self.scene)
        if key not in self._programs:
            self._programs[key] = program_cache(key)
        pyrender_adapter.set_program_cache(self._offscreen, self._programs[key])
        return self._offscreen

    def ball_pose(self, centre) -> np.ndarray:
        """Pose of the ball mesh at ``centre`` (m): its +z axis towards the camera."""
        c = np.asarray(centre, float)
        pose = np.eye(4)
        pose[:3, 3] = c
        if self.camera.projection == "perspective":
            pose[:3, :3] = _rotation_z_to(self.camera.position - c)
        elif self.camera.tilted:  # the silhouette ring across the tilted view direction
            pose[:3, :3] = _rotation_z_to(self.camera.rotation.T @ np.array([0.0, 0.0, 1.0]))
        return pose

    def set_ball(self, pose: np.ndarray | None) -> None:
        """Place the ball mesh at ``pose``, or take it out of the scene.

        Parameters
        ----------
        pose : numpy.ndarray or None
            4x4 pose (see :meth:`ball_pose`); None removes the ball (the static background).
        """
        if pose is None:
            if self._ball_node is not None:
                self.scene.remove_node(self._ball_node)
                self._ball_node = None
            return
        if self._ball_node is None:
            self._ball_node = self.scene.add(self._ball_mesh, pose=pose, name="ball")
        else:
            kept = pyrender_adapter.kept_bounds(self.scene)
            self.scene.set_pose(self._ball_node, pose)
            self._renew_bounds(kept)

    def _renew_bounds(self, kept) -> None:
        """The scene's bounds after the ball moved, as pyrender's ``Scene.bounds`` computes
        them (each mesh node's box corners in the world frame, stacked in the scene's order of
        its mesh nodes; their smallest and largest coordinates), with the corners of every
        node but the ball kept from the last time: pyrender computes all of them again
        whenever the ball moves (~0.1 ms a frame; its lamps' shadow cameras ask for the
        bounds every frame). Only while nothing else changed since: ``kept`` (pyrender's
        bounds before the ball moved) must be the bounds set here last, else (a node added,
        removed or moved, the bounds computed by pyrender meanwhile) pyrender's own
        property computes them and the corners are taken again."""
        memo = self._bounds_memo
        scene = self.scene
        if memo is None or kept is None or kept is not memo[0]:
            bounds = scene.bounds
            self._bounds_memo = (bounds, [(n, None if n is self._ball_node else
                                           _world_corners(scene, n)) for n in scene.mesh_nodes])
            return
        ball = _world_corners(scene, self._ball_node)
        corners = np.vstack([ball if c is None else c for _, c in memo[1]])
        bounds = np.array([np.min(corners, axis=0), np.max(corners, axis=0)])
        pyrender_adapter.keep_bounds(scene, bounds)
        self._bounds_memo = (bounds, memo[1])

    def _reduce(self, color: np.ndarray) -> np.ndarray:
        """(h ss, w ss, 3) uint8 -> (h, w) sum over channels and supersamples (uint64, as
        NumPy's sum of uint32 gives)."""
        s = self.ss
        # channel by channel: the same integer sums, ~20x less time than a reduction over the
        # short last axis of the (flipped, strided) read-back view
        c = np.add(color[..., 0], color[..., 1], dtype=np.uint64)
        c += color[..., 2]
        if s > 1:
            h, w = c.shape[0] // s, c.shape[1] // s
            c = c.reshape(h, s, w, s).sum(axis=(1, 3))
        return c

    def render_region(self, x0: int, y0: int, w: int, h: int, *,
                      stock_shaders: bool = False) -> np.ndarray:
        """Plain pyrender render of full-frame pixels [x0, x0+w) x [y0, y0+h); with
        ``stock_shaders`` pyrender's own shaders (the benchmark's baseline)."""
        self._shadow_prev = {}  # pyrender rewrites the whole shadow maps
        if self._lean is not None:
            self._lean.ready = False  # pyrender sets the programs' uniforms its own way
        r = self._ensure_renderer(w, h, stock_shaders)
        self._cam.P = self.camera.tile_projection(x0, y0, w, h)
        color, _ = r.render(self.scene, self.flags)
        return self._reduce(color)

    def render_full(self, *, stock_shaders: bool = False) -> np.ndarray:
        """Plain pyrender render of the whole frame.

        Parameters
        ----------
        stock_shaders : bool, optional
            Use pyrender's own shaders (the benchmark's baseline).

        Returns
        -------
        numpy.ndarray
            As :meth:`render_region` for the full frame.
        """
        return self.render_region(0, 0, self.camera.width, self.camera.height,
                                  stock_shaders=stock_shaders)

    def render_tiles(self, poses, tiles, index: int = 0, *, draw: str = "lean",
                     timings: dict | None = None) -> list[np.ndarray]:
        """Render regions ``tiles`` [(x0, y0, w, h), ...] of the scene with the ball at each of
        ``poses`` (sub-frames) and return, per tile, the sum over the sub-frames. ``index``
        (the frame's number) is not used: a rasteriser draws no random numbers (Mitsuba's
        backend seeds its samples with it).

        The tiles are drawn through the full frame's own viewport and projection with a
        scissor box, and only the box is resolved and read: every tile pixel goes through the
        same arithmetic as in a full-frame render (a shifted projection on a small viewport
        rounds vertex positions differently and flips MSAA samples on the silhouette). Per
        sub-frame the lamps' shadow maps are rendered once (ball over the cached trough) and
        reused by every tile.

        ``draw``: "lean" (default) draws with synth's own list of GL calls
        (:mod:`synth.backends.lean`: the same programs, uniforms and order, less Python) once
        pyrender has drawn a first tile frame, and with pyrender's path when the scene has
        what the lean path does not draw (:func:`synth.backends.lean.unsupported`); "pyrender"
        always draws through pyrender's renderer functions. ``timings``: a dict the lean
        path adds its stages' wall seconds to (:meth:`synth.backends.lean.LeanDraw.render`).
        """
        if draw not in ("lean", "pyrender"):
            raise ValueError(f"draw must be 'lean' or 'pyrender', got {draw!r}")
        if draw == "lean" and self._lean is not None:
            return self._lean.render(poses, tiles, timings)
        out = self._render_tiles_pyrender(poses, tiles)
        if draw == "lean":
            if unsupported(self) is None:
                pyrender_adapter.make_current(self._offscreen)
                try:
                    self._lean = LeanDraw(self)
                finally:
                    pyrender_adapter.make_uncurrent(self._offscreen)
                if self.config.ball_model == "sphere":  # pyrender drew the mesh
                    out = self._lean.render(poses, tiles)
        elif self._lean is not None:
            self._lean.ready = False
        return out

    def _render_tiles_pyrender(self, poses, tiles) -> list[np.ndarray]:
        """:meth:`render_tiles` through pyrender's renderer functions."""
        pr = self._pyrender
        W, H, s = self.camera.width, self.camera.height, self.ss
        r = self._ensure_renderer(W, H)
        self._cam.P = self.camera.tile_projection(0, 0, W, H)
        pyrender_adapter.make_current(r)
        inner = pyrender_adapter.inner(r)
        inner.viewport_width, inner.viewport_height = W * s, H * s
        flags = self.flags | pr.RenderFlags.OFFSCREEN
        out = [None] * len(tiles)
        gl_box = [(x0 * s, (H - y0 - h) * s, w * s, h * s) for x0, y0, w, h in tiles]
        try:
            for pose in poses:
                self.set_ball(pose)
                pyrender_adapter.update_context(inner, self.scene, flags)
                if self.config.shadows:
                    self._ball_shadow_pass(inner, flags)
                for k in range(len(tiles)):
                    c = self._reduce(self._forward_tile(inner, flags, gl_box[k]))
                    out[k] = c if out[k] is None else out[k] + c
        finally:
            pyrender_adapter.make_uncurrent(r)
        return out

    def _forward_tile(self, inner, flags, box) -> np.ndarray:
        """pyrender's forward pass (Renderer._forward_pass) scissored to ``box`` (GL window
        coordinates): the same draws in the same order with the same uniform values, but the
        camera and lamp uniforms are set once per shader program instead of once per
        primitive (they are equal for all)."""
        from OpenGL.GL import (
            GL_COLOR_BUFFER_BIT,
            GL_DEPTH_BUFFER_BIT,
            GL_MULTISAMPLE,
            GL_SCISSOR_TEST,
            glClear,
            glClearColor,
            glDisable,
            glEnable,
            glFlush,
            glScissor,
        )

        pr = self._pyrender
        RF = pr.RenderFlags
        scene = self.scene
        pa = pyrender_adapter
        pa.configure_forward_pass_viewport(inner, flags)
        glEnable(GL_SCISSOR_TEST)
        try:
            glScissor(*box)
            glClearColor(*scene.bg_color)
            glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT)
            glEnable(GL_MULTISAMPLE)
            V, P = pa.camera_matrices(inner, scene)
            cam_pos = scene.get_pose(scene.main_camera_node)[:3, 3]
            lit = not (flags & RF.DEPTH_ONLY or flags & RF.FLAT or flags & RF.SEG)
            # material textures would take texture units after the shadow maps: then the
            # lamps are bound for every primitive, as pyrender does
            textured = any(p.material.tex_flags for n in scene.mesh_nodes
                           for p in n.mesh.primitives)
            ready = set()
            program = None
            for node in pa.sorted_mesh_nodes(inner, scene):
                if not node.mesh.is_visible:
                    continue
                pose = scene.get_pose(node)
                for primitive in node.mesh.primitives:
                    program = pa.primitive_program(inner, primitive, flags,
                                                   pr.constants.ProgramFlags.USE_MATERIAL)
                    pa.bind_program(program)
                    if id(program) not in ready or textured:
                        program.set_uniform("V", V)
                        program.set_uniform("P", P)
                        program.set_uniform("cam_pos", cam_pos)
                        if lit:
                            # shadow maps on texture units 0..: the bindings stay for the
                            # later primitives
                            pa.bind_lighting(inner, scene, program, node, flags)
                        ready.add(id(program))
                    pa.bind_and_draw_primitive(inner, primitive, pose, program, flags)
                    pa.reset_active_textures(inner)
            if program is not None:
                pa.unbind_program(program)
            glFlush()
            glDisable(GL_SCISSOR_TEST)
            return read_region(inner, *box)
        finally:
            glDisable(GL_SCISSOR_TEST)

    def _ball_shadow_pass(self, inner, flags) -> None:
        """Each lamp's shadow map: the cached depth of the static caster (the trough), with the
        ball drawn over it with the depth test, as pyrender would draw both (the backdrop is
        the farthest surface and casts on nothing: it is left out).

        Only the texels the ball covered in the previous sub-frame or covers now change: that
        box is scissored, cleared, restored from the cache and the ball drawn into it; the
        rest of the map already holds the trough.
        """
        from OpenGL.GL import (
            GL_SCISSOR_TEST,
            GL_TEXTURE_2D,
            glCopyImageSubData,
            glDisable,
            glEnable,
            glScissor,
        )

        static = [n.mesh for n in self.scene.mesh_nodes if n.mesh is not self._ball_mesh]
        if self._shadow_cache is None:
            self._shadow_cache = self._make_shadow_cache(inner, flags, static)
        pa = pyrender_adapter
        original = pa.shadow_mapping_viewport(inner)
        visible = [m.is_visible for m in static]
        try:
            for ln in self.scene.light_nodes:
                cache = self._shadow_cache[ln.name]
                now = self._shadow_box(inner, ln, flags)
                prev = self._shadow_prev.get(ln.name)
                if prev is None:  # unknown map content: restore all of it
                    box = (0, 0, SHADOW_TEX_SZ, SHADOW_TEX_SZ)
                else:
                    x0, y0 = min(now[0], prev[0]), min(now[1], prev[1])
                    x1 = max(now[0] + now[2], prev[0] + prev[2])
                    y1 = max(now[1] + now[3], prev[1] + prev[3])
                    box = (x0, y0, x1 - x0, y1 - y0)

                def configure(light, fl, cache=cache, box=box):
                    glEnable(GL_SCISSOR_TEST)
                    glScissor(*box)
                    original(light, fl)  # binds the light's map, clears the box
                    glCopyImageSubData(pa.texture_id(cache), GL_TEXTURE_2D, 0, box[0], box[1], 0,
                                       pa.texture_id(light.shadow_texture), GL_TEXTURE_2D, 0,
                                       box[0], box[1], 0, box[2], box[3], 1)

                pa.set_shadow_mapping_viewport(inner, configure)
                for m in static:
                    m.is_visible = False
                pa.shadow_mapping_pass(inner, self.scene, ln, flags)
                glDisable(GL_SCISSOR_TEST)
                self._shadow_prev[ln.name] = now
        finally:
            glDisable(GL_SCISSOR_TEST)
            pa.set_shadow_mapping_viewport(inner, original)
            for m, v in zip(static, visible, strict=True):
                m.is_visible = v

    def _shadow_box(self, inner, light_node, flags, mats=None, centre=None):
        """Texel box (x, y, w, h) of the lamp's shadow map that the ball covers, with margin
        (``mats``: the lamp's shadow-camera (V, P) and ``centre``: the ball's, when known)."""
        V, P = mats if mats is not None else \
            pyrender_adapter.light_cam_matrices(inner)(self.scene, light_node, flags)
        c = centre if centre is not None else self.scene.get_pose(self._ball_node)[:3, 3]
        cv = V @ np.append(c, 1.0)
        # the corners of a cube of 1.5 ball radii about the centre in the lamp's view (the
        # same sums cv + d as element by element), projected
        pts = np.ones((8, 4))
        np.add(cv[:3], self._cube_offsets(), out=pts[:, :3])
        clip = pts @ P.T
        ndc = clip[:, :2] / clip[:, 3:4]
        t = ((ndc + 1.0) / 2.0 * SHADOW_TEX_SZ).T.tolist()
        x0 = min(max(math.floor(min(t[0])) - 4, 0), SHADOW_TEX_SZ)
        y0 = min(max(math.floor(min(t[1])) - 4, 0), SHADOW_TEX_SZ)
        x1 = min(max(math.ceil(max(t[0])) + 4, 0), SHADOW_TEX_SZ)
        y1 = min(max(math.ceil(max(t[1])) + 4, 0), SHADOW_TEX_SZ)
        return (x0, y0, max(x1 - x0, 1), max(y1 - y0, 1))

    def _cube_offsets(self) -> np.ndarray:
        """(8, 3) offsets (+-r, +-r, +-r), r = 1.5 ball radii, x slowest, z fastest."""
        r = 1.5 * self.ball_radius
        if getattr(self, "_cube", (None,))[0] != r:
            self._cube = (r, np.array([[dx, dy, dz] for dx in (-r, r) for dy in (-r, r)
                                       for dz in (-r, r)]))
        return self._cube[1]

    def _make_shadow_cache(self, inner, flags, static) -> dict:
        """Render each lamp's shadow map of the trough alone, once, and keep a copy."""
        from OpenGL.GL import GL_FLOAT, GL_TEXTURE_2D, glCopyImageSubData

        pr, pa = self._pyrender, pyrender_adapter
        ball_visible = self._ball_mesh.is_visible
        self._ball_mesh.is_visible = False
        self._backdrop_mesh.is_visible = False
        cache = {}
        try:
            for ln in self.scene.light_nodes:
                pa.shadow_mapping_pass(inner, self.scene, ln, flags)
                tex = pr.texture.Texture(width=SHADOW_TEX_SZ, height=SHADOW_TEX_SZ,
                                         source_channels="D", data_format=GL_FLOAT)
                pa.add_to_context(tex)
                glCopyImageSubData(pa.texture_id(ln.light.shadow_texture), GL_TEXTURE_2D, 0,
                                   0, 0, 0, pa.texture_id(tex), GL_TEXTURE_2D, 0, 0, 0, 0,
                                   SHADOW_TEX_SZ, SHADOW_TEX_SZ, 1)
                cache[ln.name] = tex
        finally:
            self._ball_mesh.is_visible = ball_visible
            self._backdrop_mesh.is_visible = True
        return cache

    def close(self) -> None:
        """Free the renderer's OpenGL resources (cached shadow maps, offscreen context)."""
        self._drop_lean()
        if self._offscreen is not None:
            if self._shadow_cache:
                pyrender_adapter.make_current(self._offscreen)
                for tex in self._shadow_cache.values():
                    pyrender_adapter.remove_from_context(tex)
                self._shadow_cache = None
            self._offscreen.delete()
            self._offscreen = None

    def _drop_lean(self) -> None:
        """Forget the lean draw path, freeing its static layer."""
        if self._lean is not None and self._offscreen is not None:
            pyrender_adapter.make_current(self._offscreen)
            try:
                self._lean.close()
            finally:
                pyrender_adapter.make_uncurrent(self._offscreen)
        self._lean = None

    # -- footprint (synth.backends.footprint) ---------------------------------------------

    def ball_box(self, centres: np.ndarray, margin_px: float = 1.5):
        """Pixel box (x0, y0, x1, y1) holding the ball's silhouettes at ``centres`` (K, 3)
        (:meth:`synth.backends.footprint.Footprint.ball_box`)."""
        return self.footprints.ball_box(centres, margin_px)

    def shadow_boxes(self, centres: np.ndarray, margin_px: float = 1.5) -> list:
        """One pixel box per lamp holding every pixel the ball's shadow can change
        (:meth:`synth.backends.footprint.Footprint.shadow_boxes`)."""
        return self.footprints.shadow_boxes(centres, margin_px)

    def shadow_boxes_many(self, frames, margin_px: float = 1.5) -> list:
        """:meth:`shadow_boxes` of several frames' ``centres`` at once."""
        return self.footprints.shadow_boxes_many(frames, margin_px)

    def tiles_for(self, centres: np.ndarray) -> list:
        """Tiles (x0, y0, w, h) inside the frame covering ball and shadows
        (:meth:`synth.backends.footprint.Footprint.tiles_for`)."""
        return self.footprints.tiles_for(centres)

    def tiles_for_many(self, frames) -> list:
        """:meth:`tiles_for` of several frames' ball centres at once (a render process's
        batch), the same tiles."""
        return self.footprints.tiles_for_many(frames)

    def footprint(self, centres):
        """(tiles, ball box, shadow boxes) that :meth:`tiles_for` or :meth:`tiles_for_many`
        found for these ``centres`` (K, 3) among the last frames, or None (the lean path's
        boxes, :meth:`synth.backends.footprint.Footprint.kept`)."""
        return self.footprints.kept(centres)

    def set_background(self, levels) -> None:
        """Nothing: a rasterised tile is drawn whole (the Mitsuba backend takes the pixels the
        ball leaves unchanged from the ball-free frame)."""


def _trough_mesh(pyrender, model: SceneModel):
    """The trough (:meth:`SceneModel.trough`) as a pyrender mesh of two primitives (smooth
    bore, flat faces): each primitive costs a draw call with all its uniforms in every pass."""
    import trimesh

    config = model.config
    tc = config.trough_color
    trough_mat = pyrender.MetallicRoughnessMaterial(
        baseColorFactor=[tc, tc, tc, 1.0], metallicFactor=config.trough_metallic,
        roughnessFactor=config.trough_roughness)
    prims = []
    parts = model.trough()
    flat = trimesh.util.concatenate([m for m, smooth in parts if not smooth])
    for mesh, smooth in [*[(m, True) for m, sm in parts if sm], (flat, False)]:
        prims += pyrender.Mesh.from_trimesh(mesh, material=trough_mat,
                                            smooth=smooth).primitives
    return pyrender.Mesh(primitives=prims)


def _backdrop_mesh(pyrender, model: SceneModel):
    """The paper backdrop as a pyrender mesh (a square; a backlight panel glows on its own:
    an emissive factor only then, so the lit scenes' material and shader stay as they were)."""
    import trimesh

    size = model.backdrop_half_size
    zb = model.backdrop_z
    quad = trimesh.Trimesh(
        np.array([[-size, -size, zb], [size, -size, zb], [size, size, zb],
                  [-size, size, zb]]), np.array([[0, 1, 2], [0, 2, 3]]), process=False)
    light = model.config.lighting
    br = light.backdrop_reflectance
    bl = light.backlight
    paper = pyrender.MetallicRoughnessMaterial(
        baseColorFactor=[br, br, br, 1.0], metallicFactor=0.0, roughnessFactor=1.0,
        **({"emissiveFactor": [bl, bl, bl]} if bl > 0 else {}))
    return pyrender.Mesh.from_trimesh(quad, material=paper, smooth=False)


def _ball_mesh(pyrender, model: SceneModel):
    """(the steel ball as a pyrender mesh (:func:`view_sphere`, its silhouette ring where the
    camera sees the sphere's edge), the polar angles of the mesh's last ring before the
    silhouette and of the silhouette (view_sphere's 16 front rings): the sphere impostor
    continues the mesh's outermost band past the silhouette as the mesh's triangles do)."""
    config, cam, r = model.config, model.camera, model.ball_radius
    if cam.projection == "orthographic":
        sil = math.pi / 2
    else:
        # the ball stays near the ball plane: its distance to the pinhole barely changes
        sil = math.acos(r / cam.working_distance)
    sphere = view_sphere(r, sil, n_silhouette=config.ball_silhouette_segments)
    bc = config.ball_color
    steel = pyrender.MetallicRoughnessMaterial(
        baseColorFactor=[bc, bc, bc, 1.0], metallicFactor=config.ball_metallic,
        roughnessFactor=config.ball_roughness)
    return pyrender.Mesh.from_trimesh(sphere, material=steel, smooth=True), (sil * 15 / 16, sil)


def _cache_light_matrices(inner) -> None:
    """Keep pyrender's shadow-camera matrices of each lamp instead of rebuilding them.

    pyrender builds a new shadow camera and inverts the lamp's pose for every draw that uses a
    lamp (~0.15 ms each, 6-8 times a frame). The matrices depend only on the lamp's pose and the
    scene's bounds (scale, centroid): the cache is emptied when those change. pyrender renews
    its bounds object whenever a node moves, so they are compared only then.
    """
    original = pyrender_adapter.light_cam_matrices(inner)
    state: dict = {"bounds": None, "key": None, "cache": {}}

    def cached(scene, light_node, flags):
        bounds = scene.bounds
        if bounds is not state["bounds"]:
            state["bounds"] = bounds
            key = (bounds.tobytes(),
                   *(scene.get_pose(n).tobytes() for n in scene.light_nodes))
            if key != state["key"]:
                state["key"] = key
                state["cache"] = {}
        cache = state["cache"]
        if light_node not in cache:
            V, P = original(scene, light_node, flags)
            V.setflags(write=False)
            P.setflags(write=False)
            cache[light_node] = (V, P)
        return cache[light_node]

    pyrender_adapter.set_light_cam_matrices(inner, cached)


def _world_corners(scene, node) -> np.ndarray:
    """(8, 3) corners of a mesh node's box in the world frame, as pyrender's
    ``Scene.bounds`` computes them."""
    import trimesh

    pose = scene.get_pose(node)
    corners_local = trimesh.bounds.corners(node.mesh.bounds)
    return pose[:3, :3].dot(corners_local.T).T + pose[:3, 3]


def _camera_class():
    pyrender = pyrender_adapter.load()

    class FixedProjectionCamera(pyrender.camera.Camera):
        """A pyrender camera whose projection matrix is set directly (tile projections)."""

        def __init__(self, znear, zfar):
            super().__init__(znear=znear, zfar=zfar, name="synth-camera")
            self.P = np.eye(4)

        def get_projection_matrix(self, width=None, height=None):
            return self.P

    return FixedProjectionCamera


def _rotation_z_to(direction) -> np.ndarray:
    """Rotation matrix turning +z onto ``direction`` (smallest rotation)."""
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, d)
    c = float(z @ d)
    if np.linalg.norm(v) < 1e-15:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)
