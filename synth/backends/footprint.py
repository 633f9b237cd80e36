"""The ball's footprint: which pixels of a frame the ball and its shadows can change.

Both renderer backends render only these pixels of each frame (the rest is the ball-free
frame): the ball's box from its silhouette, and per lamp the box of the ball's shadow, from
rays of the lamp through the ball followed to the bore or the backdrop, widened by the shadow
filter's reach. Plain arithmetic on the :class:`~synth.backends.scene_model.SceneModel`; a
backend whose shadows reach further (Mitsuba's lamps are spheres: a penumbra) widens the boxes
in a subclass.
"""

from __future__ import annotations

import math

import numpy as np

from synth.backends.scene_model import SceneModel

SHADOW_TEX_SZ = 2048  # pyrender.constants.SHADOW_TEX_SZ: the shadow maps' texels a side
# two tiles are drawn as one when that shades at most this many extra pixels (a forward pass
# has a fixed cost of a few thousand pixels' shading on llvmpipe)
MERGE_PX = 4000
FOOTPRINTS = 64  # frames whose footprint (tiles_for) is kept for the lean path


class Footprint:
    """The pixels the ball and its shadows can change, for the scene ``model``; the last
    FOOTPRINTS frames' tiles and boxes are kept (:meth:`kept`).

    Parameters
    ----------
    model : SceneModel
        The scene.
    """

    def __init__(self, model: SceneModel):
        self.model = model
        self.config = model.config
        self.camera = model.camera
        self.ball_radius = model.ball_radius
        self.cylinder_radius = model.cylinder_radius
        self.section = model.section
        self.lamps = model.lamps
        # centres' bytes -> (tiles, ball box, shadow boxes) of the last FOOTPRINTS tiles_for
        self._kept: dict = {}

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
        return self.shadow_boxes_many([centres], margin_px)[0]

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
        keep = bore_seen | (~on_bore & ~self.behind_trough(hits))
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

    def behind_trough(self, points: np.ndarray) -> np.ndarray:
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
        return self._tiles(centres, self.ball_box(centres), shadows)

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
        kept with the boxes for the lean path (:meth:`kept`)."""
        W, H = self.camera.width, self.camera.height
        clipped = []
        for x0, y0, x1, y1 in [ball, *shadows]:
            x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
            if x1 > x0 and y1 > y0:
                clipped.append((x0, y0, x1, y1))
        clipped = merge_boxes(clipped, lambda a, b, u: _area(u) - (_area(a) + _area(b))
                              <= MERGE_PX)
        tiles = [(x0, y0, x1 - x0, y1 - y0) for x0, y0, x1, y1 in clipped]
        # what the lean path redraws inside these tiles (synth.backends.lean: the ball in its box,
        # the static surfaces in the shadows' boxes; the rest is the static layer)
        kept = self._kept
        key = centres.tobytes()
        kept.pop(key, None)
        kept[key] = (tuple(tiles), ball, tuple(shadows))
        while len(kept) > FOOTPRINTS:
            del kept[next(iter(kept))]
        return tiles

    def kept(self, centres):
        """(tiles, ball box, shadow boxes) that :meth:`tiles_for` or :meth:`tiles_for_many`
        found for these ``centres`` (K, 3) among its last FOOTPRINTS frames, or None."""
        c = np.ascontiguousarray(np.asarray(centres, dtype=float).reshape(-1, 3))
        return self._kept.get(c.tobytes())


def _shadow_rays():
    """(rings, cos, sin) of the rays shadow_boxes follows through the ball: 64 angles on each
    of three rings (1.03, 0.7 and 0.35 of the tangent circle's radius), each ring turned a
    little."""
    ang = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    rings = np.concatenate([np.full(64, 1.03), np.full(64, 0.7), np.full(64, 0.35)])
    angs = np.concatenate([ang, ang + 0.05, ang + 0.1])
    return rings, np.cos(angs), np.sin(angs)


_SHADOW_RAYS = _shadow_rays()


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of (n, 3) arrays (the products and differences of
    numpy.cross, by NumPy's elementwise arithmetic: the same numbers)."""
    return np.column_stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]])


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


def meet(tile, box):
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
