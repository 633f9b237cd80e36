"""The scene both renderer backends draw, as plain data: the trough's meshes, the paper
backdrop, the ball's sphere, the lamps and the camera, in metres in the contract's world frame.

:class:`SceneModel` holds the sizes and the as-built bore (:class:`sim.section.Section`) of one
recording's scene; the functions build the meshes (trimesh, imported when a mesh is built: a
process that renders nothing, such as the pipeline's main process, does not load it). Each
backend translates them into its own scene (:mod:`synth.backends.raster`: pyrender;
:mod:`synth.backends.pathtrace`: Mitsuba).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from sim.section import Section
from synth.camera import CameraModel
from synth.config import Lamp, SceneConfig


@dataclasses.dataclass(frozen=True)
class SceneModel:
    """One recording's scene: its description, the ball's and bore's sizes and the bore as
    built (an out-of-round trough is drawn as its ellipse).

    Parameters
    ----------
    config : SceneConfig
        The scene (its camera ideal, lens-free: a backend renders the ideal image).
    ball_radius, cylinder_radius : float
        Sizes (m).
    section : sim.section.Section
        The bore's section (mean radius ``cylinder_radius``).
    """

    config: SceneConfig
    ball_radius: float
    cylinder_radius: float
    section: Section

    @classmethod
    def of(cls, config: SceneConfig, ball_radius: float, cylinder_radius: float,
           ovality: float = 0.0, ovality_angle: float = 0.0) -> SceneModel:
        """The model of ``config`` with these sizes and the bore's (ovality, angle).

        Parameters
        ----------
        config : SceneConfig
            The scene.
        ball_radius, cylinder_radius : float
            Sizes (m).
        ovality, ovality_angle : float, optional
            The bore's out-of-roundness (sim.section; 0: round).

        Returns
        -------
        SceneModel
        """
        R = float(cylinder_radius)
        return cls(config, float(ball_radius), R, Section(R, float(ovality),
                                                          float(ovality_angle)))

    @property
    def camera(self) -> CameraModel:
        """The camera."""
        return self.config.camera

    @property
    def lamps(self) -> tuple[Lamp, ...]:
        """The lamps of the scene's lighting."""
        return self.config.lighting.lamps

    @property
    def backdrop_half_size(self) -> float:
        """Half the side of the square paper backdrop (m), centred on the trough's axis."""
        return 4.0 * self.cylinder_radius + 0.4

    @property
    def backdrop_z(self) -> float:
        """The backdrop's plane z (m; behind the trough)."""
        return -self.config.backdrop_distance

    def trough(self) -> list:
        """The trough's parts, as :func:`trough_meshes` builds them for this scene."""
        cfg = self.config
        return trough_meshes(self.cylinder_radius, cfg.trough_wall, cfg.trough_length,
                             cfg.trough_opening, section=self.section)


def look_at(position, target) -> np.ndarray:
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


def trough_meshes(R: float, wall: float, length: float, half_open: float, n: int = 720,
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


def stitch(a: np.ndarray, ta: np.ndarray, b: np.ndarray, tb: np.ndarray) -> list:
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
        faces += [f for f in stitch(a, ta, b, tb) if len(set(f)) == 3]
    faces = np.array(faces)[:, ::-1]  # counter-clockwise seen from outside
    unit = np.array(verts)
    return trimesh.Trimesh(unit * radius, faces, vertex_normals=unit, process=False)
