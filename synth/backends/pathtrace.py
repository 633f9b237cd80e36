"""The physically based backend: synth's scene path traced by Mitsuba 3 on the CPU.

The same scene description as the pyrender backend (:mod:`synth.backends.raster`), translated once:

- the trough: the same annular-sector mesh (smooth bore, flat end faces), a diffuse surface of
  reflectance ``trough_color``; its front end face faces the camera;
- the paper backdrop: a diffuse rectangle of reflectance ``backdrop_reflectance``;
- each lamp: a small sphere of radius ``lamp_radius`` emitting uniformly, of radiant intensity
  ``intensity`` (W/sr, what pyrender's spot light gives inside its cone: radiance
  I / (pi a^2)); no cone (a sphere lights every direction), soft shadows;
- ambient light: a constant environment of radiance ``ambient`` (a diffuse surface open to it
  reflects ``ambient`` x its reflectance, as pyrender's ambient term);
- the ball: an exact sphere, a rough conductor (GGX, alpha = ``ball_roughness``^2 as in
  pyrender's metallic-roughness model) with iron's optical constants at R, G, B (eta 2.91,
  2.95, 2.58; k 3.09, 2.93, 2.77): a dark curved mirror with Fresnel reflection at grazing
  angles;
- the camera: orthographic or pinhole, mapped so that a pixel centre (u, v) sees exactly the
  point :meth:`synth.camera.CameraModel.project` puts there (roll included); a box pixel
  filter (a pixel is the mean over its square). The camera's rays start just in front of the
  trough, so lamps between the camera and the scene are not seen directly (pyrender's lights
  are invisible too), though the ball reflects them.

Light transport: a path tracer (:class:`synth.backends.rim_path.RimPath`, next-event estimation
with multiple importance sampling, ``mitsuba_max_depth`` vertices) that leaves out light
reaching a diffuse surface by way of the ball (the ball is black seen from the trough or the
backdrop): those caustics of a small lamp in a polished ball are found only by chance and show
up as rare very bright pixels; they land on the trough and backdrop, not on the ball's own
image. Everything else - the ball's reflections of lamps, backdrop and trough, its shadows,
ambient occlusion - is path traced.

Rendered values: linear RGB radiance, clipped to [0, 1], encoded as display values c = L^(1/2.2)
(what pyrender writes) and summed over the three channels in units of 1/UNIT (``scale`` = 3
UNIT is white), rounded to integers: the store's format, read by the same sensor model.

Speed: the ball-free frame is rendered once at ``mitsuba_background_spp`` samples per pixel;
each frame path traces only windows around the ball and its shadows (:meth:`tiles_for`, sized
in steps of WINDOW_STEP px so that Dr.Jit compiles few kernels) at ``mitsuba_spp`` samples per
pixel. Each render is seeded from (seed, frame, sub-frame): same seed, same bytes.
"""

from __future__ import annotations

import math

import numpy as np

from synth.backends.footprint import Footprint
from synth.backends.mitsuba_runtime import VARIANT, load, variant
from synth.backends.scene_model import SceneModel
from synth.camera import CameraModel
from synth.config import SceneConfig, SynthError

IRON_ETA = (2.91, 2.95, 2.58)  # iron's refractive index at R, G, B (~ 650, 550, 450 nm)
IRON_K = (3.09, 2.93, 2.77)  # and its extinction coefficient
UNIT = 4080  # integer levels of display value 1.0 per channel (16 x 255)
WINDOW_STEP = 16  # px: window sizes are rounded up to multiples of this
PASS_SAMPLES = 1 << 24  # samples per Mitsuba call (memory bound of one wavefront)
CORE = 0.4  # the ball's middle (0.6 of its radius) is traced at mitsuba_base_spp
HIGHLIGHT_PX = 6.0  # px about a lamp's highlight on the ball traced at 4 mitsuba_spp
SPP_MAX = 4096
AMBIENT_WEIGHT = 0.05  # next-event estimation's weight of the ambient light (lamps: 1)

def render_seed(seed: int, *key: int) -> int:
    """A 32-bit Mitsuba seed for render ``key`` (e.g. frame, sub-frame) of recording ``seed``.

    Parameters
    ----------
    seed : int
        The recording's seed.
    *key : int
        Which render (the background: no key).

    Returns
    -------
    int
    """
    return int(np.random.SeedSequence(int(seed), spawn_key=tuple(int(k) for k in key))
               .generate_state(1)[0])


def _camera_to_world(cam: CameraModel, window=None) -> np.ndarray:
    """4x4 matrix of Mitsuba's camera frame (looks along its +z; film x along its -x, film y
    along its -y; orthographic: the film spans camera x in [-1, 1]) in the world frame, for a
    film of full-frame pixels ``window`` = (x0, y0, w, h) (default: the whole frame)."""
    W, H, s = cam.width, cam.height, cam.pixel_size
    x0, y0, w, h = window or (0, 0, W, H)
    cx, cy = cam.center_px
    if cam.projection == "orthographic":
        # the film's centre (x0 + (w-1)/2, y0 + (h-1)/2) in the camera's turned world frame
        origin = np.array([(x0 + (w - 1) / 2 - cx) * s, (cy - y0 - (h - 1) / 2) * s,
                           cam.camera_z])
        axes = np.diag([-w * s / 2, w * s / 2, -1.0])
    else:
        origin = np.array([0.0, 0.0, cam.camera_z])
        axes = np.diag([-1.0, 1.0, -1.0])
    c, sn = math.cos(cam.roll), math.sin(cam.roll)
    unturn = np.array([[c, sn, 0.0], [-sn, c, 0.0], [0.0, 0.0, 1.0]])  # R(-roll)
    m = np.eye(4)
    m[:3, :3] = unturn @ axes
    m[:3, 3] = unturn @ origin
    return m


def sensor_dict(cam: CameraModel, near: float, far: float, spp: int,
                window: tuple[int, int, int, int] | None = None) -> dict:
    """Mitsuba sensor of ``cam`` rendering full-frame pixels ``window`` = (x0, y0, w, h).

    Parameters
    ----------
    cam : CameraModel
        The camera (no lens: render its ideal camera).
    near, far : float
        Clip distances from the camera along its axis (m).
    spp : int
        Samples per pixel.
    window : tuple, optional
        The pixels to render (default: the whole frame).

    Returns
    -------
    dict
        For ``mitsuba.load_dict``.
    """
    mi = load()
    W, H = cam.width, cam.height
    x0, y0, w, h = window or (0, 0, W, H)
    # a film of the window's size whose camera sees just those pixels (not a crop of the whole
    # frame: Dr.Jit would compile the crop's offset into the kernel, a new kernel, ~0.6 s of
    # LLVM, for every window position; the camera's transforms are not compiled in)
    film = {"type": "hdrfilm", "width": int(w), "height": int(h), "rfilter": {"type": "box"},
            "pixel_format": "rgb", "component_format": "float32"}
    d = {"to_world": mi.ScalarTransform4f(_camera_to_world(cam, (x0, y0, w, h)).tolist()),
         "near_clip": float(near), "far_clip": float(far), "film": film,
         "sampler": {"type": "ldsampler", "sample_count": int(spp)}}
    if cam.projection == "orthographic":
        d["type"] = "orthographic"
    else:
        cx, cy = cam.center_px
        d |= {"type": "perspective", "fov_axis": "x",
              "fov": math.degrees(2 * math.atan(w / (2 * cam.focal_px))),
              "principal_point_offset_x": -(cx - x0 - (w - 1) / 2) / w,
              "principal_point_offset_y": -(cy - y0 - (h - 1) / 2) / h}
    return d


def to_levels(rgb: np.ndarray) -> np.ndarray:
    """Linear RGB radiance (h, w, 3) -> integer display levels (h, w): the sum over channels
    of round-free UNIT * clip(L, 0, 1)^(1/2.2), rounded once.

    Parameters
    ----------
    rgb : numpy.ndarray
        Linear radiance.

    Returns
    -------
    numpy.ndarray
        int64 levels, 3 UNIT = white.
    """
    c = np.clip(np.asarray(rgb, dtype=np.float64), 0.0, 1.0) ** (1 / 2.2)
    return np.rint(UNIT * c.sum(axis=2)).astype(np.int64)


class MitsubaRenderer:
    """synth's scene in Mitsuba, with the interface of :class:`synth.backends.raster.SceneRenderer`
    that the pipeline uses (scale, render_full, ball_pose, tiles_for, render_tiles, close)."""

    def __init__(self, config: SceneConfig, ball_radius: float, cylinder_radius: float,
                 ovality: float = 0.0, ovality_angle: float = 0.0, seed: int = 0):
        mi = load()
        if config.camera.lens is not None:
            raise SynthError("MitsubaRenderer renders the ideal camera (pass camera.ideal())")
        # the shared scene (an out-of-round bore as its ellipse, sim.section)
        model = SceneModel.of(config, ball_radius, cylinder_radius, ovality, ovality_angle)
        self.model = model
        self.config = config
        self.camera = config.camera
        self.ball_radius = model.ball_radius
        self.cylinder_radius = model.cylinder_radius
        self.section = model.section
        self.footprints = PathTracedFootprint(model)
        self.seed = int(seed)
        self.scale = 3 * UNIT
        self.lamps = config.lighting.lamps
        cam = self.camera
        # camera rays start 1 mm in front of the trough (lamps nearer the camera are unseen)
        self.near = cam.working_distance - config.trough_length / 2 - 1e-3
        self.far = cam.working_distance + config.backdrop_distance + 0.05
        if cam.projection == "perspective":  # clip distances are along the axis
            self.far *= 1.2
        light = config.lighting
        tc = config.trough_color
        scene = {"type": "scene",
                 # the fallback variant (scalar_rgb) cannot run a Python integrator
                 "integrator": {"type": "synth_rim_path" if variant() == VARIANT else "path",
                                "max_depth": int(config.mitsuba_max_depth)},
                 # next-event estimation picks an emitter by weight: the dim ambient light
                 # seldom (its light reaches the surfaces by BSDF sampling as well)
                 "ambient": {"type": "constant", "sampling_weight": AMBIENT_WEIGHT,
                             "radiance": {"type": "rgb", "value": [light.ambient] * 3}}}
        for k, (mesh, smooth) in enumerate(model.trough()):
            m = mi.Mesh(f"trough{k}", len(mesh.vertices), len(mesh.faces),
                        has_vertex_normals=smooth)
            p = mi.traverse(m)
            # the buffers' own types (Dr.Jit arrays; scalar_rgb: dynamic scalar arrays)
            p["vertex_positions"] = type(p["vertex_positions"])(
                np.ravel(mesh.vertices).astype(np.float32))
            p["faces"] = type(p["faces"])(np.ravel(mesh.faces).astype(np.uint32))
            if smooth:
                p["vertex_normals"] = type(p["vertex_normals"])(
                    np.ravel(mesh.vertex_normals).astype(np.float32))
            p.update()
            m.set_bsdf(mi.load_dict({"type": "diffuse",
                                     "reflectance": {"type": "rgb", "value": [tc] * 3}}))
            scene[f"trough{k}"] = m
        size = model.backdrop_half_size
        br = light.backdrop_reflectance
        scene["backdrop"] = {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().translate([0.0, 0.0, model.backdrop_z])
            .scale([size, size, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [br] * 3}}}
        a = config.lamp_radius
        for i, lamp in enumerate(light.lamps):
            radiance = lamp.intensity / (math.pi * a * a)
            scene[f"lamp{i}"] = {"type": "sphere", "center": list(lamp.position), "radius": a,
                                 "emitter": {"type": "area", "radiance": {
                                     "type": "rgb", "value": [radiance] * 3}}}
        self._scene_dict = scene
        self._ball_dict = {
            "type": "sphere", "center": [0.0, 0.0, 0.0], "radius": self.ball_radius,
            "bsdf": {"type": "roughconductor", "distribution": "ggx",
                     "alpha": config.ball_roughness ** 2,
                     "eta": {"type": "rgb", "value": list(IRON_ETA)},
                     "k": {"type": "rgb", "value": list(IRON_K)}}}
        self.background = None  # the ball-free frame's levels (set_background)
        self._static = mi.load_dict(scene)
        self._with_ball = mi.load_dict(scene | {"ball": self._ball_dict})
        self._params = mi.traverse(self._with_ball)

    # -- rendering ---------------------------------------------------------------------------

    def _render(self, scene, window, spp: int, seed: int) -> np.ndarray:
        """Mean linear RGB (h, w, 3) of ``window`` at ``spp`` (a power of 4), in passes of at
        most PASS_SAMPLES samples (each pass seeded from ``seed`` and its number)."""
        mi = load()
        x0, y0, w, h = window
        per = max(1, min(int(spp), PASS_SAMPLES // max(w * h, 1)))
        per = 4 ** int(math.log(per, 4) + 1e-9)  # the sampler takes powers of 4
        n_pass = math.ceil(spp / per)
        acc = np.zeros((h, w, 3))
        done = 0
        for k in range(n_pass):
            n = min(per, spp - done)
            sensor = mi.load_dict(sensor_dict(self.camera, self.near, self.far, n, window))
            s = seed if n_pass == 1 else render_seed(seed, k)
            acc += n * np.asarray(mi.render(scene, sensor=sensor, spp=n, seed=s),
                                  dtype=np.float64)
            done += n
        return acc / spp

    def render_full(self) -> np.ndarray:
        """The ball-free frame at ``mitsuba_background_spp`` samples per pixel.

        Returns
        -------
        numpy.ndarray
            (H, W) int64 levels (``scale`` = white).
        """
        cam = self.camera
        rgb = self._render(self._static, (0, 0, cam.width, cam.height),
                           self.config.mitsuba_background_spp, render_seed(self.seed))
        return to_levels(rgb)

    def render_window_rgb(self, centre, window, spp: int, seed: int) -> np.ndarray:
        """Linear RGB of full-frame pixels ``window`` = (x0, y0, w, h) with the ball at
        ``centre`` (m; None: no ball), at ``spp`` samples per pixel.

        Parameters
        ----------
        centre : array_like or None
            Ball centre in the world frame (m).
        window : tuple
            (x0, y0, w, h) full-frame pixels.
        spp : int
            Samples per pixel.
        seed : int
            Mitsuba's seed.

        Returns
        -------
        numpy.ndarray
            (h, w, 3) float64.
        """
        if centre is None:
            return self._render(self._static, window, spp, seed)
        self.set_ball(centre)
        return self._render(self._with_ball, window, spp, seed)

    def set_ball(self, centre) -> None:
        """Move the ball's centre to ``centre`` (m)."""
        mi = load()
        c = [float(v) for v in np.asarray(centre, float)]
        self._params["ball.to_world"] = mi.ScalarTransform4f().translate(c).scale(
            self.ball_radius)
        self._params.update()

    def ball_pose(self, centre) -> np.ndarray:
        """The ball's centre (m): a uniform sphere needs no orientation."""
        return np.asarray(centre, float)

    def render_tiles(self, poses, tiles, index: int = 0) -> list[np.ndarray]:
        """Render ``tiles`` [(x0, y0, w, h), ...] with the ball at each of ``poses`` (centres,
        one per sub-frame) and return per tile the sum of the sub-frames' levels.

        Each tile is path traced at :meth:`spp_map`'s samples per pixel (``mitsuba_spp`` on
        the ball and in its shadows' penumbra, ``mitsuba_base_spp`` elsewhere; the
        ``scalar_rgb`` fallback: ``mitsuba_spp`` everywhere), seeded from (seed, index,
        sub-frame, tile).

        Returns
        -------
        list of numpy.ndarray
            (h, w) int64 per tile.
        """
        out = []
        for t, (x0, y0, w, h) in enumerate(tiles):
            acc = np.zeros((h, w), dtype=np.int64)
            for k, c in enumerate(poses):
                rgb, plan = self._render_tile(c, (x0, y0, w, h),
                                              render_seed(self.seed, index, k, t))
                levels = to_levels(rgb)
                if plan is not None:  # the pixels the ball leaves unchanged: the ball-free frame's
                    same = plan == 0
                    levels[same] = self.background[y0:y0 + h, x0:x0 + w][same]
                acc += levels
            out.append(acc)
        return out

    def set_background(self, levels) -> None:
        """Use the ball-free frame ``levels`` ((H, W) levels, from :meth:`render_full`) for
        the pixels of a tile that the ball leaves unchanged (:meth:`spp_map` 0) instead of
        path tracing them; None: trace them at ``mitsuba_base_spp``.

        Parameters
        ----------
        levels : numpy.ndarray or None
        """
        self.background = None if levels is None else np.asarray(levels, dtype=np.int64)

    def render_tile_rgb(self, centre, tile, seed: int) -> np.ndarray:
        """Linear RGB of full-frame pixels ``tile`` = (x0, y0, w, h) with the ball at
        ``centre`` (m), each pixel at :meth:`spp_map`'s samples.

        Parameters
        ----------
        centre : array_like
            Ball centre in the world frame (m).
        tile : tuple
            (x0, y0, w, h) full-frame pixels.
        seed : int
            The tile's seed (each group of pixels of one spp gets its own from it).

        Returns
        -------
        numpy.ndarray
            (h, w, 3) float64.
        """
        return self._render_tile(centre, tile, seed)[0]

    def _render_tile(self, centre, tile, seed: int):
        """(rgb of :meth:`render_tile_rgb`, the tile's :meth:`spp_map` when its 0s are to be
        the background's pixels, else None)."""
        x0, y0, w, h = tile
        if variant() != VARIANT:  # Mitsuba's own render of a window, mitsuba_spp everywhere
            win = self._window(x0, y0, w, h)
            rgb = self.render_window_rgb(centre, win, self.config.mitsuba_spp, seed)
            return rgb[y0 - win[1]:y0 - win[1] + h, x0 - win[0]:x0 - win[0] + w], None
        from synth.backends.rim_path import render_pixels  # imports mitsuba

        mi = load()
        self.set_ball(centre)
        tile_plan = self.spp_map(centre, tile)
        plan = tile_plan.ravel().copy()
        sensor = mi.load_dict(sensor_dict(self.camera, self.near, self.far, 4, tile))
        scene = self._with_ball
        base = min(int(self.config.mitsuba_base_spp), int(self.config.mitsuba_spp))
        if self.background is None:
            plan[plan == 0] = base  # nothing to take the unchanged pixels from
        rgb = np.zeros((h * w, 3))
        for spp in np.unique(plan[plan > 0]):
            pix = np.flatnonzero(plan == spp).astype(np.uint32)
            per = 4 ** int(math.log(int(spp), 4) + 1e-9)  # passes of a power of 4 samples
            step = max(1, PASS_SAMPLES // per)
            for j in range(int(spp) // per):
                for k, s0 in enumerate(range(0, len(pix), step)):
                    part = pix[s0:s0 + step]
                    rgb[part] += render_pixels(scene.integrator(), scene, sensor, part, per,
                                               render_seed(seed, int(spp), j, k)) * (per / spp)
        return rgb.reshape(h, w, 3), (tile_plan if self.background is not None else None)

    def spp_map(self, centre, tile) -> np.ndarray:
        """Samples per pixel for tile (x0, y0, w, h) with the ball at ``centre``: more where
        the Monte-Carlo noise is larger, none where the ball changes nothing.

        ``mitsuba_spp`` on the ball's rim (outside the middle 0.6 of its radius: it reflects
        the backdrop at grazing angles) and edge (to 2 px outside it) and in the penumbra of
        its shadows (a lamp partly hidden: with an orthographic camera square to the trough
        the pixels whose point on the backdrop plane sees a lamp partly hidden, 2.5 px of
        margin; with any other camera, which also sees the bore, the shadow boxes whole);
        4 ``mitsuba_spp`` within HIGHLIGHT_PX of each lamp's mirror highlight on the ball;
        0 (the ball-free frame's pixel, :meth:`set_background`) outside the ball's box and
        its shadows' boxes and on the trough's front face (orthographic camera square to the
        trough: the ball can neither hide nor shade it); ``mitsuba_base_spp`` elsewhere (the
        ball's dark middle, the margins, the shadows' umbra). When ``mitsuba_base_spp`` >=
        ``mitsuba_spp``: ``mitsuba_spp`` everywhere.

        Parameters
        ----------
        centre : array_like
            Ball centre (m).
        tile : tuple
            (x0, y0, w, h) full-frame pixels.

        Returns
        -------
        numpy.ndarray
            (h, w) int samples per pixel.
        """
        cfg, cam = self.config, self.camera
        high = int(cfg.mitsuba_spp)
        base = min(int(cfg.mitsuba_base_spp), high)
        x0, y0, w, h = tile
        plan = np.full((h, w), base, dtype=np.int64)
        if base == high:
            return plan
        c = np.asarray(centre, float)
        uu, vv = np.meshgrid(np.arange(x0, x0 + w, dtype=float),
                             np.arange(y0, y0 + h, dtype=float))
        # pixels outside the ball's box and its shadows' boxes (the footprint of tiles_for)
        # are the ball-free frame's
        inside = np.zeros((h, w), dtype=bool)
        boxes = self.shadow_boxes(c[None]) if self.config.shadows else []
        for bx0, by0, bx1, by1 in [self.ball_box(c[None]), *boxes]:
            inside |= (uu >= bx0) & (uu < bx1) & (vv >= by0) & (vv < by1)
        plan[~inside] = 0
        uv, rad = cam.sphere_silhouette(c[None], self.ball_radius)
        stretch = 1.0 if cam.projection == "orthographic" else 1.06  # as ball_box
        d = np.hypot(uu - uv[0, 0], vv - uv[0, 1]) - rad[0] * stretch
        if cam.projection == "orthographic" and not cam.tilted:
            # the trough's front face, which the ball can neither shade nor hide
            face = self._front_face(uu, vv)
            plan[face] = 0
            shade = self._penumbra(c, uu, vv) & ~face & inside
        else:
            shade = inside & (d >= 2.0)  # the shadow boxes whole
        plan[shade] = high
        # the ball's rim (reflections at grazing angles) and edge; its dark middle at base
        plan[(d < 2.0) & (d >= -CORE * rad[0])] = high
        # the lamps' highlights: a small bright reflection, the noisiest pixels of the ball
        view = (cam.position - c if cam.projection == "perspective"
                else cam.pose()[:3, 2])  # towards the camera
        view = view / np.linalg.norm(view)
        for lamp in self.lamps:
            to_lamp = np.asarray(lamp.position, float) - c
            n = to_lamp / np.linalg.norm(to_lamp) + view
            n /= np.linalg.norm(n)
            if n @ view > 0:
                hu, hv = cam.project((c + self.ball_radius * n)[None])[0]
                plan[np.hypot(uu - hu, vv - hv) < HIGHLIGHT_PX] = min(4 * high, SPP_MAX)
        return plan

    def _front_face(self, uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
        """Pixels (uu, vv) that certainly see the trough's front face (orthographic camera
        square to the trough; 2 px inside its edges, as pyrender's footprint's test)."""
        cam = self.camera
        q = np.stack([uu.ravel(), vv.ravel()], axis=1) - np.asarray(cam.center_px)
        rho = np.hypot(q[:, 0], q[:, 1]) * cam.pixel_size
        r_in = self.cylinder_radius + 0.25 * self.section.ovality  # the bore's largest radius
        phi = np.abs(np.arctan2(q[:, 0], q[:, 1]) - cam.roll)  # angle from the bottom
        face = ((rho > r_in + 2 * cam.pixel_size)
                & (rho < self.cylinder_radius + self.config.trough_wall - 2 * cam.pixel_size)
                & (phi < self.config.trough_opening - 0.02))
        return face.reshape(uu.shape)

    def _penumbra(self, c: np.ndarray, uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
        """Pixels (uu, vv) whose point on the backdrop plane sees a lamp partly hidden by the
        ball at ``c`` (orthographic camera square to the trough), with 2.5 px of margin."""
        cam = self.camera
        zb = -self.config.backdrop_distance
        # the plane z = zb maps to pixels affinely: invert that map
        p0 = cam.project(np.array([[0.0, 0.0, zb]]))[0]
        m = np.column_stack([cam.project(np.array([[1e-3, 0.0, zb]]))[0] - p0,
                             cam.project(np.array([[0.0, 1e-3, zb]]))[0] - p0]) / 1e-3
        xy = np.linalg.solve(m, np.stack([uu.ravel() - p0[0], vv.ravel() - p0[1]]))
        X = np.column_stack([xy[0], xy[1], np.full(xy.shape[1], zb)])
        vc = c - X
        dc = np.linalg.norm(vc, axis=1)
        ang_r = np.arcsin(np.clip(self.ball_radius / dc, 0.0, 1.0))
        out = np.zeros(X.shape[0], dtype=bool)
        for lamp in self.lamps:
            vp = np.asarray(lamp.position, float) - X
            dp = np.linalg.norm(vp, axis=1)
            # 2.5 px on the backdrop turn the directions to ball and lamp by at most this much
            margin = 2.5 * cam.pixel_size * (1.0 / dc + 1.0 / dp)
            ang_a = np.arcsin(np.clip(self.config.lamp_radius / dp, 0.0, 1.0))
            sep = np.arccos(np.clip(np.einsum("ij,ij->i", vc, vp) / (dc * dp), -1.0, 1.0))
            out |= np.abs(sep - ang_r) < ang_a + margin
        return out.reshape(uu.shape)

    def _window(self, x0: int, y0: int, w: int, h: int) -> tuple[int, int, int, int]:
        """A window holding tile (x0, y0, w, h), its size rounded up to WINDOW_STEP (fewer
        kernel sizes to compile), kept inside the frame."""
        W, H = self.camera.width, self.camera.height
        ww = min(W, -(-w // WINDOW_STEP) * WINDOW_STEP)
        wh = min(H, -(-h // WINDOW_STEP) * WINDOW_STEP)
        wx = min(max(x0 - (ww - w) // 2, 0), W - ww)
        wy = min(max(y0 - (wh - h) // 2, 0), H - wh)
        return wx, wy, ww, wh

    # -- footprint ---------------------------------------------------------------------------

    def tiles_for(self, centres: np.ndarray) -> list:
        """Tiles (x0, y0, w, h) holding every pixel the ball changes
        (:class:`PathTracedFootprint`)."""
        return self.footprints.tiles_for(centres)

    def tiles_for_many(self, frames) -> list:
        """:meth:`tiles_for` of each frame's centres (K, 3), in order."""
        return [self.footprints.tiles_for(c) for c in frames]

    def ball_box(self, centres: np.ndarray, margin_px: float | None = None):
        """The ball's box (:meth:`PathTracedFootprint.ball_box`)."""
        return self.footprints.ball_box(centres, margin_px)

    def shadow_boxes(self, centres: np.ndarray, margin_px: float = 1.5) -> list:
        """The shadows' boxes (:meth:`PathTracedFootprint.shadow_boxes`)."""
        return self.footprints.shadow_boxes(centres, margin_px)

    def close(self) -> None:
        """Drop the Mitsuba scenes."""
        self._static = self._with_ball = self._params = None



class PathTracedFootprint(Footprint):
    """The pixels the ball changes in a path-traced frame: the rasterised scene's footprint
    (:class:`synth.backends.footprint.Footprint`) widened by the lamps' penumbra and by the
    ball's occlusion of ambient light on the surfaces just around it."""

    def ball_box(self, centres: np.ndarray, margin_px: float | None = None):
        """Pixel box (x0, y0, x1, y1) of the ball's silhouettes at ``centres`` (K, 3) with a
        margin of ``mitsuba_margin`` ball radii (the ball's occlusion of ambient light and
        the penumbra of its shadows on nearby surfaces)."""
        uv, rad = self.camera.sphere_silhouette(centres, self.ball_radius)
        m = self.config.mitsuba_margin * float(rad.max()) + 1.5
        return super().ball_box(centres, m if margin_px is None else margin_px)

    def shadow_boxes(self, centres: np.ndarray, margin_px: float = 1.5) -> list:
        """The rasterised shadow boxes widened by the lamps' penumbra: a s / (D - r) over the
        cosine of the incidence on the backdrop (lamp radius a, lamp to ball D, ball to the
        surface behind it s, at most to the backdrop along the lamp's ray), in px."""
        cam = self.camera
        a, r = self.config.lamp_radius, self.ball_radius
        C = np.atleast_2d(np.asarray(centres, float))
        zb = -self.config.backdrop_distance
        pen = 0.0
        for lamp in self.lamps:
            d = C - np.asarray(lamp.position, float)
            D = np.linalg.norm(d, axis=1)
            cos_inc = np.clip(np.abs(d[:, 2]) / D, 0.3, 1.0)  # the backdrop's normal is z
            s = (C[:, 2] - zb) / cos_inc + r  # the bore's hits are nearer than the backdrop
            pen = max(pen, float((a * s / (D - r) / cos_inc).max()) / cam.pixel_size)
        return super().shadow_boxes(centres, margin_px + pen)
