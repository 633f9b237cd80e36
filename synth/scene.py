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
(synth.shaders: the same pixels, less than half the time); ``stock_shaders=True`` renders with
pyrender's own, for the benchmark's baseline.
"""

from __future__ import annotations

import math

import numpy as np

from synth import pyrender_adapter
from synth.camera import CameraModel
from synth.config import SceneConfig
from synth.leandraw import read_region

SHADOW_TEX_SZ = 2048  # pyrender.constants.SHADOW_TEX_SZ
# two tiles are drawn as one when that shades at most this many extra pixels (a forward pass
# has a fixed cost of a few thousand pixels' shading on llvmpipe)
MERGE_PX = 4000
FOOTPRINTS = 64  # frames whose footprint (tiles_for) a renderer keeps for the lean path


def _look_at(position, target) -> np.ndarray:
    """Pose whose -z axis points from position to target (OpenGL camera/light convention)."""
    p = np.asarray(position, float)
    fwd = np.asarray(target, float) - p
    fwd /= np.linalg.norm(fwd)
    up = np.array([0.0, 1.0, 0.0])
    if abs(fwd @ up) > 0.99:
        up = np.array([1.0, 0.0, 0.0])
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    pose = np.eye(4)
    pose[:3, 0] = right
    pose[:3, 1] = true_up
    pose[:3, 2] = -fwd
    pose[:3, 3] = p
    return pose


def _trough_meshes(R: float, wall: float, length: float, half_open: float, n: int = 720,
                   section=None):
    """Trimesh parts of the trough: inner bore (smooth), outer surface, end faces, caps.

    ``section``: an out-of-round bore (:class:`sim.section.Section`, an ellipse of mean radius
    R): the bore and the inner edges of the end faces follow it, with the ellipse's normals;
    the outer surface stays round."""
    import trimesh

    full = half_open >= math.pi - 1e-9
    phi = np.linspace(-half_open, half_open, n + 1)
    if full:
        phi = phi[:-1]
    oval = section is not None and not section.round
    # angle from the bottom, positive to the right (like theta)
    def ring(rad, z):
        if oval and rad == R:
            xy = section.outline(phi)
            return np.column_stack([xy[:, 0], xy[:, 1], np.full(len(phi), z)])
        return np.column_stack([rad * np.sin(phi), -rad * np.cos(phi), np.full(len(phi), z)])

    z0, z1 = -length / 2, length / 2
    m = len(phi)
    seg = [(i, (i + 1) % m) for i in range(m if full else m - 1)]

    def strip(a, b, flip):
        verts = np.vstack([a, b])
        faces = []
        for i, j in seg:
            f1 = [i, j, m + j]
            f2 = [i, m + j, m + i]
            faces += [f1[::-1], f2[::-1]] if flip else [f1, f2]
        return verts, np.array(faces)

    parts = []
    # inner bore, normals towards the axis
    v, f = strip(ring(R, z0), ring(R, z1), flip=False)
    if oval:  # the ellipse's inward normal: -(x / a^2, y / b^2) in its own frame
        a, b = section.semi_axes
        ca, sa = math.cos(section.angle), math.sin(section.angle)
        lx, ly = ca * v[:, 0] + sa * v[:, 1], -sa * v[:, 0] + ca * v[:, 1]
        gx, gy = lx / (a * a), ly / (b * b)
        nrm = -np.column_stack([ca * gx - sa * gy, sa * gx + ca * gy, np.zeros(len(v))])
    else:
        nrm = -np.column_stack([v[:, 0], v[:, 1], np.zeros(len(v))])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    inner = trimesh.Trimesh(v, f, vertex_normals=nrm, process=False)
    if np.mean(np.einsum("ij,ij->i", inner.face_normals, nrm[f[:, 0]])) < 0:
        inner = trimesh.Trimesh(v, f[:, ::-1], vertex_normals=nrm, process=False)
    parts.append((inner, True))
    v, f = strip(ring(R + wall, z0), ring(R + wall, z1), flip=True)
    outer = trimesh.Trimesh(v, f, process=False)
    parts.append((outer, False))
    for z, flip in ((z1, False), (z0, True)):  # front face (towards the camera) and back face
        v, f = strip(ring(R, z), ring(R + wall, z), flip=flip)
        face = trimesh.Trimesh(v, f, process=False)
        want = 1.0 if z > 0 else -1.0
        if np.mean(face.face_normals[:, 2]) * want < 0:
            face = trimesh.Trimesh(v, f[:, ::-1], process=False)
        parts.append((face, False))
    if not full:
        for k in (0, m - 1):
            a, b = ring(R, z0)[k], ring(R + wall, z0)[k]
            c, d = ring(R + wall, z1)[k], ring(R, z1)[k]
            cap = trimesh.Trimesh(np.array([a, b, c, d]), np.array([[0, 1, 2], [0, 2, 3],
                                                                     [0, 2, 1], [0, 3, 2]]),
                                  process=False)
            parts.append((cap, False))
    return parts


def _stitch(a: np.ndarray, ta: np.ndarray, b: np.ndarray, tb: np.ndarray) -> list:
    """Triangles joining closed ring a (vertex ids, angles ta in [0, 1)) to ring b."""
    na, nb = len(a), len(b)
    faces = []
    i = j = 0
    while i < na or j < nb:
        next_a = ta[i + 1] if i + 1 < na else 1.0 + ta[0]
        next_b = tb[j + 1] if j + 1 < nb else 1.0 + tb[0]
        if (i < na and next_a <= next_b) or j >= nb:
            faces.append([a[i % na], a[(i + 1) % na], b[j % nb]])
            i += 1
        else:
            faces.append([a[i % na], b[(j + 1) % nb], b[j % nb]])
            j += 1
    return faces


def view_sphere(radius: float, silhouette_angle: float = math.pi / 2, n_silhouette: int = 512,
                n_segments: int = 64, n_front: int = 16, n_back: int = 8):
    """A sphere mesh for a camera on its +z axis: few triangles, an exact silhouette.

    Rings of constant polar angle phi about +z; the ring at ``silhouette_angle`` (pi/2 for an
    orthographic camera, acos(r/d) for a pinhole at distance d) is the silhouette and gets
    ``n_silhouette`` vertices (its polygon's area is short of the circle's by 2.5e-5, i.e.
    0.001 px in radius for a 37 px ball); the other rings ``n_segments`` sin(phi). Vertex
    normals are the exact sphere normals. A uniform ball looks the same in any orientation,
    so the renderer turns this mesh's +z towards the camera instead of applying the ball's spin.
    """
    import trimesh

    phis = np.concatenate([np.linspace(0, silhouette_angle, n_front + 1)[1:],
                           np.linspace(silhouette_angle, math.pi, n_back + 1)[1:-1]])
    verts = [np.array([0.0, 0.0, 1.0])]
    rings = [(np.array([0]), np.array([0.0]))]
    for phi in phis:
        if abs(phi - silhouette_angle) < 1e-12:
            n = n_silhouette
        else:
            n = max(6, int(math.ceil(n_segments * math.sin(phi))))
        t = (np.arange(n) + (0.5 if len(rings) % 2 else 0.0)) / n
        t = t % 1.0
        order = np.argsort(t)
        t = t[order]
        ang = 2 * math.pi * t
        pts = np.column_stack([math.sin(phi) * np.cos(ang), math.sin(phi) * np.sin(ang),
                               np.full(n, math.cos(phi))])
        ids = np.arange(len(verts), len(verts) + n)
        verts.extend(pts)
        rings.append((ids, t))
    verts.append(np.array([0.0, 0.0, -1.0]))
    rings.append((np.array([len(verts) - 1]), np.array([0.0])))
    faces = []
    for (a, ta), (b, tb) in zip(rings[:-1], rings[1:], strict=True):
        faces += [f for f in _stitch(a, ta, b, tb) if len(set(f)) == 3]
    faces = np.array(faces)[:, ::-1]  # counter-clockwise seen from outside
    unit = np.array(verts)
    return trimesh.Trimesh(unit * radius, faces, vertex_normals=unit, process=False)


class SceneRenderer:
    """One pyrender scene and one offscreen renderer (one per process: EGL contexts do not
    survive fork)."""

    def __init__(self, config: SceneConfig, ball_radius: float, cylinder_radius: float,
                 ovality: float = 0.0, ovality_angle: float = 0.0):
        import trimesh

        from sim.section import Section

        pyrender = pyrender_adapter.load()  # headless EGL unless PYOPENGL_PLATFORM says else

        self.config = config
        self.camera: CameraModel = config.camera
        self.ball_radius = float(ball_radius)
        self.cylinder_radius = float(cylinder_radius)
        # an out-of-round bore (sim.section): the trough's as-built ellipse
        self.section = Section(self.cylinder_radius, float(ovality), float(ovality_angle))
        self.ss = config.supersample
        self.scale = 3 * self.ss * self.ss * 255
        self._pyrender = pyrender
        light = config.lighting
        scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 1.0],
                               ambient_light=[light.ambient] * 3)
        # trough
        tc = config.trough_color
        trough_mat = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=[tc, tc, tc, 1.0], metallicFactor=config.trough_metallic,
            roughnessFactor=config.trough_roughness)
        prims = []
        parts = _trough_meshes(cylinder_radius, config.trough_wall, config.trough_length,
                               config.trough_opening, section=self.section)
        # two primitives (smooth bore, flat faces): each primitive costs a draw call with
        # all its uniforms in every pass
        flat = trimesh.util.concatenate([m for m, smooth in parts if not smooth])
        for mesh, smooth in [*[(m, True) for m, sm in parts if sm], (flat, False)]:
            prims += pyrender.Mesh.from_trimesh(mesh, material=trough_mat,
                                                smooth=smooth).primitives
        scene.add(pyrender.Mesh(primitives=prims), name="trough")
        # paper backdrop
        size = 4.0 * cylinder_radius + 0.4
        zb = -config.backdrop_distance
        quad = trimesh.Trimesh(
            np.array([[-size, -size, zb], [size, -size, zb], [size, size, zb],
                      [-size, size, zb]]), np.array([[0, 1, 2], [0, 2, 3]]), process=False)
        br = light.backdrop_reflectance
        # a backlight panel glows on its own (an emissive factor only then: the lit scenes'
        # material and shader stay as they were)
        bl = light.backlight
        paper = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=[br, br, br, 1.0], metallicFactor=0.0, roughnessFactor=1.0,
            **({"emissiveFactor": [bl, bl, bl]} if bl > 0 else {}))
        self._backdrop_mesh = pyrender.Mesh.from_trimesh(quad, material=paper, smooth=False)
        scene.add(self._backdrop_mesh, name="backdrop")
        # lamps
        self.lamps = light.lamps
        for i, lamp in enumerate(light.lamps):
            sl = pyrender.SpotLight(color=[1.0, 1.0, 1.0], intensity=lamp.intensity,
                                    innerConeAngle=lamp.inner_cone,
                                    outerConeAngle=lamp.outer_cone)
            scene.add(sl, pose=_look_at(lamp.position, lamp.target), name=f"lamp{i}")
        # ball (added/removed per render)
        cam = self.camera
        if cam.projection == "orthographic":
            sil = math.pi / 2
        else:
            # the ball stays near the ball plane: its distance to the pinhole barely changes
            sil = math.acos(self.ball_radius / cam.working_distance)
        sphere = view_sphere(self.ball_radius, sil, n_silhouette=config.ball_silhouette_segments)
        # the polar angles of the mesh's last ring before the silhouette and of the silhouette
        # (view_sphere's 16 front rings): the sphere impostor continues the mesh's outermost
        # band past the silhouette as the mesh's triangles do
        self.ball_rings = (sil * 15 / 16, sil)
        bc = config.ball_color
        steel = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=[bc, bc, bc, 1.0], metallicFactor=config.ball_metallic,
            roughnessFactor=config.ball_roughness)
        self._ball_mesh = pyrender.Mesh.from_trimesh(sphere, material=steel, smooth=True)
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
        self._lean = None  # synth.leandraw.LeanDraw, once pyrender has drawn a tile frame
        # centres' bytes -> (tiles, ball box, shadow boxes) of the last FOOTPRINTS tiles_for
        self._footprints: dict = {}

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

    # -- low level -------------------------------------------------------------------------

    def _ensure_renderer(self, w: int, h: int, stock_shaders: bool = False):
        """The offscreen renderer at w x h output pixels, compiling pyrender's own shaders
        (``stock_shaders``) or synth's (synth.shaders: built for the scene's light counts, so
        a scene whose lights change gets programs for its new counts)."""
        from synth.shaders import light_counts, program_cache

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
        (:mod:`synth.leandraw`: the same programs, uniforms and order, less Python) once
        pyrender has drawn a first tile frame, and with pyrender's path when the scene has
        what the lean path does not draw (:func:`synth.leandraw.unsupported`); "pyrender"
        always draws through pyrender's renderer functions. ``timings``: a dict the lean
        path adds its stages' wall seconds to (:meth:`synth.leandraw.LeanDraw.render`).
        """
        if draw not in ("lean", "pyrender"):
            raise ValueError(f"draw must be 'lean' or 'pyrender', got {draw!r}")
        if draw == "lean" and self._lean is not None:
            return self._lean.render(poses, tiles, timings)
        out = self._render_tiles_pyrender(poses, tiles)
        if draw == "lean":
            from synth.leandraw import LeanDraw, unsupported

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

    # -- footprint -------------------------------------------------------------------------

    def ball_box(self, centres: np.ndarray, margin_px: float = 1.5):
        """Pixel box (x0, y0, x1, y1) holding the ball's silhouettes at ``centres`` (K, 3)."""
        uv, rad = self.camera.sphere_silhouette(centres, self.ball_radius)
        # a pixel is touched when its centre is within r + 0.71 px; in perspective the
        # silhouette ellipse's semi-major axis exceeds sqrt(ab) by < 3 % for off-axis angles
        # up to 20 deg: 6 % is kept
        stretch = 1.0 if self.camera.projection == "orthographic" else 1.06
        e = rad[:, None] * stretch + margin_px
        return _box(np.vstack([uv - e, uv + e]))

    def shadow_boxes(self, centres: np.ndarray, margin_px: float = 1.5) -> list:
        """One pixel box per lamp holding every pixel the ball's shadow can change.

        Rays from the lamp through the ball (its tangent cone, boundary and interior) are
        followed to the first surface behind the ball: the trough bore (visible in perspective)
        or the backdrop plane. The box holds the projections of all hits, widened by the
        shadow filter's reach (2.5 shadow-map texels at the hit distance).
        """
        return SceneRenderer.shadow_boxes_many(self, [centres], margin_px)[0]

    def shadow_boxes_many(self, frames, margin_px: float = 1.5) -> list:
        """:meth:`shadow_boxes` of several frames' ``centres`` (each (K, 3)) at once: the same
        arithmetic ray by ray (NumPy's per-call overhead, most of a frame's footprint, is paid
        once for all of them), the same boxes.

        Parameters
        ----------
        frames : sequence of numpy.ndarray
            Each frame's ball centres (K, 3), m.
        margin_px : float
            Added around each box, px.

        Returns
        -------
        list of list
            Per frame, the boxes (x0, y0, x1, y1) of :meth:`shadow_boxes`.
        """
        cam = self.camera
        r = self.ball_radius
        R = self.cylinder_radius
        zb = -self.config.backdrop_distance
        zlo, zhi = -self.config.trough_length / 2, self.config.trough_length / 2
        rings, cos_a, sin_a = _SHADOW_RAYS
        n_lamps = len(self.lamps)
        # the ray circles of every frame, lamp and centre (items, in that order), the same
        # arithmetic as one at a time: NumPy's elementwise operations over all items, the
        # norms (NumPy's dot of each 3-vector) and the rings' radii item by item
        items = [(np.atleast_2d(centres), np.asarray(lamp.position, dtype=float),
                  f * n_lamps + k)
                 for f, centres in enumerate(frames) for k, lamp in enumerate(self.lamps)]
        out: list = [[] for _ in frames]
        if not items or not sum(len(c) for c, _, _ in items):
            return out
        C = np.concatenate([c for c, _, _ in items])
        lamp_pos = np.concatenate([np.broadcast_to(p, c.shape) for c, p, _ in items])
        group = np.repeat(np.concatenate([np.full(len(c), g) for c, _, g in items]), rings.size)
        d_vec = C - lamp_pos
        d = np.array([np.linalg.norm(v) for v in d_vec])
        u = d_vec / d[:, None]
        off = C - u * (r * r / d)[:, None]
        rho = np.array([r * math.sqrt(1 - (r / di) ** 2) for di in d])
        # u x (0, 0, 1), or u x (1, 0, 0) where u is near the z axis
        near_z = np.abs(u[:, 2]) >= 0.9
        e = np.where(near_z[:, None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
        a = _cross_rows(u, e)
        a = a / np.array([np.linalg.norm(v) for v in a])[:, None]
        b = _cross_rows(u, a)
        circs = off[:, None, :] + (rho[:, None] * rings[None, :])[:, :, None] * (
            cos_a[None, :, None] * a[:, None, :] + sin_a[None, :, None] * b[:, None, :])
        P = np.repeat(lamp_pos, rings.size, axis=0)
        dirs = circs.reshape(-1, 3) - P
        # backdrop hit
        t_hit = (zb - P[:, 2]) / dirs[:, 2]
        # bore hit: leaving the cylinder of radius R beyond the tangent circle
        A = dirs[:, 0] ** 2 + dirs[:, 1] ** 2
        B = 2 * (P[:, 0] * dirs[:, 0] + P[:, 1] * dirs[:, 1])
        Cq = P[:, 0] ** 2 + P[:, 1] ** 2 - R * R
        disc = B * B - 4 * A * Cq
        with np.errstate(invalid="ignore", divide="ignore"):
            t_cyl = (-B + np.sqrt(np.maximum(disc, 0))) / (2 * A)
        zc = P[:, 2] + t_cyl * dirs[:, 2]
        on_bore = (disc > 0) & (t_cyl > 1.0) & (t_cyl < t_hit) & (zc >= zlo) & (zc <= zhi)
        t_hit = np.where(on_bore, t_cyl, t_hit)
        hits = P + t_hit[:, None] * dirs
        # an orthographic camera sees the bore edge-on (no pixels); a pinhole sees the part of
        # the bore behind the front edge
        bore_seen = on_bore & (cam.projection == "perspective" or cam.tilted)
        keep = bore_seen | (~on_bore & ~self._behind_trough(hits))
        if not keep.any():
            return out
        dirs, hits, P, on_bore, group = (x[keep] for x in (dirs, hits, P, on_bore, group))
        # texel footprint grows as 1 / cos(incidence) on the receiving surface
        d = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
        normal = np.where(on_bore[:, None],
                          -np.column_stack([hits[:, 0], hits[:, 1], 0 * hits[:, 2]]) / R,
                          np.array([0.0, 0.0, 1.0]))
        cos_inc = np.clip(np.abs(np.einsum("ij,ij->i", d, normal)), 0.3, 1.0)
        reach = np.linalg.norm(hits - P, axis=1) / cos_inc
        q_all = cam.project(hits)
        # the kept rays of group g (frame g // lamps, lamp g % lamps) are q_all[ends[g]:ends[g+1]]
        ends = np.searchsorted(group, np.arange(len(frames) * n_lamps + 1))
        for f in range(len(frames)):
            for k, lamp in enumerate(self.lamps):
                a, b = ends[f * n_lamps + k], ends[f * n_lamps + k + 1]
                if a == b:
                    continue  # this lamp's shadow falls only where the trough hides the backdrop
                q = q_all[a:b]
                fov = min(2 * lamp.outer_cone + np.pi / 16, np.pi)
                texel = reach[a:b].max() * 2 * math.tan(fov / 2) / SHADOW_TEX_SZ
                # the 3x3 PCF of bilinear lookups reaches 2.5 texels from the shadow's edge
                pm = 2.5 * texel / cam.pixel_size + margin_px
                # an out-of-round bore is within ovality / 4 of the round one the rays hit
                pm += 0.25 * self.section.ovality / cam.pixel_size
                out[f].append(_box(np.vstack([q.min(0) - pm, q.max(0) + pm])))
        return out

    def _behind_trough(self, points: np.ndarray) -> np.ndarray:
        """True for backdrop points the trough's wall certainly hides from the camera."""
        cam = self.camera
        R, wall = self.cylinder_radius, self.config.trough_wall
        R = R + 0.25 * self.section.ovality  # the bore's largest radius (sim.section)
        half = self.config.trough_length / 2
        q = cam.project(points) - np.asarray(cam.center_px)
        rho = np.hypot(q[:, 0], q[:, 1])
        if cam.projection == "orthographic":
            lo, hi = R / cam.pixel_size, (R + wall) / cam.pixel_size
            if cam.tilted:  # the faces shift by (L/2) sin(tilt): widen the margins by it
                shift = half * math.sin(math.hypot(cam.yaw, cam.pitch)) / cam.pixel_size
                lo, hi = lo + shift, hi - shift
        else:
            f, D = cam.focal_px, cam.camera_z
            lo, hi = R * f / (D - half), (R + wall) * f / (D + half)
            # a pinhole off the axis sees the trough's edges about other centres: widen
            # the margins by how far they move (synth.camera)
            shift = math.hypot(*cam.pinhole_offset) / cam.pixel_size * half / (D - half)
            lo, hi = lo + shift, hi - shift
        # angle from the bottom (image y down; the bottom appears at +roll)
        phi = np.abs(np.arctan2(q[:, 0], q[:, 1]) - cam.roll)
        # 3 px and 1 degree inside the wall's silhouette, to stay clear of its edges
        return (rho > lo + 3) & (rho < hi - 3) & (phi < self.config.trough_opening - 0.02)

    def tiles_for(self, centres: np.ndarray) -> list:
        """Tiles (x0, y0, w, h) inside the frame covering ball and shadows; boxes whose union
        adds at most MERGE_PX pixels are merged."""
        centres = np.array(centres, dtype=float, copy=True).reshape(-1, 3)
        shadows = self.shadow_boxes(centres) if self.config.shadows else []
        return SceneRenderer._tiles(self, centres, self.ball_box(centres), shadows)

    def tiles_for_many(self, frames) -> list:
        """:meth:`tiles_for` of several frames' ball centres at once (a render process's batch:
        the shadows' rays of all of them followed together, :meth:`shadow_boxes_many`), the
        same tiles; the lean path finds each frame's boxes again by its centres.

        Parameters
        ----------
        frames : sequence of numpy.ndarray
            Each frame's ball centres (K, 3), m (K motion-blur sub-frames).

        Returns
        -------
        list of list
            Per frame, its tiles (x0, y0, w, h).
        """
        frames = [np.array(c, dtype=float, copy=True).reshape(-1, 3) for c in frames]
        shadows = self.shadow_boxes_many(frames) if self.config.shadows else \
            [[] for _ in frames]
        return [self._tiles(c, self.ball_box(c), s)
                for c, s in zip(frames, shadows, strict=True)]

    def _tiles(self, centres, ball, shadows) -> list:
        """The tiles of the ball's box and the shadows' boxes (clipped to the frame, merged),
        kept with the boxes for the lean path (:meth:`footprint`)."""
        W, H = self.camera.width, self.camera.height
        clipped = []
        for x0, y0, x1, y1 in [ball, *shadows]:
            x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
            if x1 > x0 and y1 > y0:
                clipped.append((x0, y0, x1, y1))
        clipped = merge_boxes(clipped, lambda a, b, u: _area(u) - (_area(a) + _area(b))
                              <= MERGE_PX)
        tiles = [(x0, y0, x1 - x0, y1 - y0) for x0, y0, x1, y1 in clipped]
        # what the lean path redraws inside these tiles (synth.leandraw: the ball in its box,
        # the static surfaces in the shadows' boxes; the rest is the static layer)
        kept = getattr(self, "_footprints", None)
        if kept is None:
            kept = self._footprints = {}
        key = centres.tobytes()
        kept.pop(key, None)
        kept[key] = (tuple(tiles), ball, tuple(shadows))
        while len(kept) > FOOTPRINTS:
            del kept[next(iter(kept))]
        return tiles

    def footprint(self, centres):
        """(tiles, ball box, shadow boxes) that :meth:`tiles_for` or :meth:`tiles_for_many`
        found for these ``centres`` (K, 3) among its last FOOTPRINTS frames, or None."""
        c = np.ascontiguousarray(np.asarray(centres, dtype=float).reshape(-1, 3))
        return self._footprints.get(c.tobytes())


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


def _shadow_rays():
    """(rings, cos, sin) of the rays shadow_boxes follows through the ball: 64 angles on each
    of three rings (1.03, 0.7 and 0.35 of the tangent circle's radius), each ring turned a
    little."""
    ang = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    rings = np.concatenate([np.full(64, 1.03), np.full(64, 0.7), np.full(64, 0.35)])
    angs = np.concatenate([ang, ang + 0.05, ang + 0.1])
    return rings, np.cos(angs), np.sin(angs)


_SHADOW_RAYS = _shadow_rays()


def _cross(a, b) -> np.ndarray:
    """Cross product of two 3-vectors, as numpy.cross computes it (the same products and
    differences) without its array overhead."""
    a0, a1, a2 = (float(x) for x in a)
    b0, b1, b2 = (float(x) for x in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of (n, 3) arrays with the products and differences of
    :func:`_cross` (NumPy's elementwise arithmetic: the same numbers)."""
    return np.column_stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]])


def _world_corners(scene, node) -> np.ndarray:
    """(8, 3) corners of a mesh node's box in the world frame, as pyrender's
    ``Scene.bounds`` computes them."""
    import trimesh

    pose = scene.get_pose(node)
    corners_local = trimesh.bounds.corners(node.mesh.bounds)
    return pose[:3, :3].dot(corners_local.T).T + pose[:3, 3]


def _box(pts: np.ndarray):
    return (math.floor(pts[:, 0].min()), math.floor(pts[:, 1].min()),
            math.ceil(pts[:, 0].max()) + 1, math.ceil(pts[:, 1].max()) + 1)


def _area(b) -> int:
    return max(b[2] - b[0], 0) * max(b[3] - b[1], 0)


def merge_boxes(boxes: list, joinable) -> list:
    """Merge boxes (x0, y0, x1, y1) pairwise into their union while ``joinable(a, b, union)``
    holds for some pair, until no pair is left to merge.

    Parameters
    ----------
    boxes : list of tuple
        Boxes (x0, y0, x1, y1), px.
    joinable : callable
        ``joinable(a, b, union) -> bool``.

    Returns
    -------
    list of tuple
        The merged boxes (a new list).
    """
    boxes = list(boxes)
    merged = True
    while merged and len(boxes) > 1:
        merged = False
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                a, b = boxes[i], boxes[j]
                u = (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
                if joinable(a, b, u):
                    boxes[i] = u
                    del boxes[j]
                    merged = True
                    break
            if merged:
                break
    return boxes


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
