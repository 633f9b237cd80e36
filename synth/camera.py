"""Camera models: exact projection of world points, sphere silhouettes and tile projections.

World frame (team contract): origin on the cylinder axis in the plane of the ball centre, x right,
y up, z along the axis towards the camera. The camera sits on the cylinder axis and looks along
-z, so the cylinder axis projects to ``center_px`` in both models.

Pixels: x right, y down, origin at the centre of the top-left pixel (OpenCV).

- orthographic: u = cx + x / s, v = cy - y / s (s = pixel size at the ball plane, m/px);
- perspective (pinhole at distance ``working_distance`` from the ball plane z = 0):
  u = cx + f x / (D - z), v = cy - f y / (D - z) with f = D / s (pixels), so that one pixel is
  exactly s at the ball plane.

A pinhole need not sit on the cylinder axis: ``principal_px`` (perspective only; default
``center_px``) is where its optical axis, still parallel to the cylinder axis, meets the image.
The pinhole then sits at (X0, Y0) = ((pu - cx) s, (cy - pv) s) across the axis and
u = pu + f (x - X0) / (D - z), v = pv - f (y - Y0) / (D - z): the axis still projects to
``center_px`` in the ball plane, but at depth z to pp + (center_px - pp) D / (D - z), so the
trough's front and back edges (z = +-L/2) are seen about centres displaced by
(center_px - pp) (+-L/2) / D from the ball plane's axis (4 px for 131.5 px at L/2 = 15 mm,
D = 0.5 m).

The camera may be rolled about its optical axis by ``roll`` (rad): world points are turned by
``roll`` about the cylinder axis before they are projected, so the trough's bottom (the
direction of gravity) appears at theta = +roll in rollfric's convention (right of the image
vertical through the axis), a camera turned clockwise as seen from behind it.

The camera may also be tilted against the cylinder axis, swung about the axis point in the
ball plane (it stays aimed at it): ``yaw`` (rad) swings it towards +x (image right, about the
world's y axis), ``pitch`` towards +y (up, about x). World points are turned by
Rz(roll) Ry(yaw) Rx(pitch) (the camera's view of them); the ball plane's axis point still
projects to ``center_px``, but the trough's front face (z = +L/2, nearer the camera) shifts by
(L/2) sin(angle) / s left (yaw) or down (pitch) and its back face the other way: 1.95 px a
degree for the thesis's 15 mm half-length at 0.1343 mm/px; circles become ellipses (axes
ratio cos(angle)).

A lens (``lens_distortion`` = OpenCV's [k1, k2, p1, p2, k3] with ``lens_matrix``, default
fx = fy = focal_px at the frame centre) bends the ideal image (:mod:`synth.distortion`); the
projections here are the ideal ones, :meth:`CameraModel.recorded` maps them through the lens.

A thin lens (``f_number``, ``focus_distance``, ``focal_length``) keeps these projections (the
chief ray through the lens's centre is the pinhole's ray) and blurs each point by its circle
of confusion (:mod:`synth.defocus`): the truth stays the ball centre's projection.

All functions are plain numpy and exact (no rendering): they are the ground truth.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rollfric.errors import InputError
from synth.distortion import Lens, cached_window, lens_of


@dataclasses.dataclass(frozen=True)
class CameraModel:
    """Where the camera is and how it projects (SI units, pixels)."""

    width: int = 1280
    height: int = 1024
    pixel_size: float = 0.1343e-3  # m per pixel in the ball plane z = 0
    center_px: tuple[float, float] = (640.0, 380.0)  # cylinder axis in the image
    projection: str = "orthographic"  # "orthographic" | "perspective"
    working_distance: float = 0.5  # m, pinhole to ball plane (perspective only)
    znear: float = 0.05  # m, clip planes as distances from the camera
    zfar: float = 2.0
    roll: float = 0.0  # rad about the optical axis: the trough bottom appears at theta = +roll
    yaw: float = 0.0  # rad: the camera swung towards +x about the ball plane's axis point
    pitch: float = 0.0  # rad: swung towards +y
    lens_matrix: tuple | None = None  # OpenCV 3x3 camera matrix (px) of the lens model
    lens_distortion: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)  # OpenCV k1, k2, p1, p2, k3
    principal_px: tuple | None = None  # perspective: the optical axis in the image (px);
    # None: center_px (the pinhole on the cylinder axis)
    f_number: float | None = None  # a thin lens at this f-number (synth.defocus); None: pinhole
    focus_distance: float | None = None  # m from the lens to the plane in focus; None: the
    # working distance (the ball's plane)
    focal_length: float = 0.05  # m, the thin lens's (its aperture diameter is f / N)

    def __post_init__(self) -> None:
        if self.projection not in ("orthographic", "perspective"):
            raise InputError(f"camera projection must be 'orthographic' or 'perspective', "
                             f"got {self.projection!r}")
        for name in ("width", "height"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 8 or v > 8192:
                raise InputError(f"camera {name} must be an integer 8..8192 px, got {v!r}")
        for name in ("pixel_size", "working_distance", "znear", "zfar"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise InputError(f"camera {name} must be positive, got {v!r}")
        if self.znear >= self.zfar:
            raise InputError("camera znear must be smaller than zfar")
        c = tuple(float(v) for v in self.center_px)
        if len(c) != 2 or not all(math.isfinite(v) for v in c):
            raise InputError(f"camera center_px must be two finite numbers, got "
                             f"{self.center_px!r}")
        object.__setattr__(self, "center_px", c)
        if self.principal_px is not None:
            pp = tuple(float(v) for v in self.principal_px)
            if len(pp) != 2 or not all(math.isfinite(v) for v in pp):
                raise InputError(f"camera principal_px must be two finite numbers, got "
                                 f"{self.principal_px!r}")
            if self.projection != "perspective":
                raise InputError("camera principal_px is a pinhole's: it needs projection = "
                                 "'perspective'")
            object.__setattr__(self, "principal_px", pp)
        if not math.isfinite(self.roll) or abs(self.roll) > math.pi / 4:
            raise InputError(f"camera roll must be within +-45 deg, got {self.roll!r} rad")
        for name in ("yaw", "pitch"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or abs(v) > math.pi / 12:
                raise InputError(f"camera {name} must be within +-15 deg, got {v!r} rad")
        d = tuple(float(v) for v in self.lens_distortion)
        if len(d) != 5 or not all(math.isfinite(v) for v in d):
            raise InputError(f"camera lens_distortion must be [k1, k2, p1, p2, k3], got "
                             f"{self.lens_distortion!r}")
        object.__setattr__(self, "lens_distortion", d)
        self._check_thin_lens()
        if self.lens_matrix is not None:
            object.__setattr__(self, "lens_matrix", Lens(self.lens_matrix, d).matrix)

    def _check_thin_lens(self) -> None:
        f = self.focal_length
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f) \
                or not 0.001 <= f <= 1.0:
            raise InputError(f"camera focal_length must be 1..1000 mm, got {f!r} m")
        n = self.f_number
        if n is None:
            if self.focus_distance is not None:
                raise InputError("camera focus_distance needs an f_number (a thin lens)")
            return
        if isinstance(n, bool) or not isinstance(n, (int, float)) or not math.isfinite(n) \
                or not 0.5 <= n <= 128:
            raise InputError(f"camera f_number must be 0.5..128, got {n!r}")
        if self.working_distance <= f:
            raise InputError(f"camera working_distance {self.working_distance * 1e3:g} mm must "
                             f"exceed the focal length {f * 1e3:g} mm (a thin lens)")
        s = self.focus_distance
        if s is not None and (isinstance(s, bool) or not isinstance(s, (int, float))
                              or not math.isfinite(s) or s <= f):
            raise InputError(f"camera focus_distance must exceed the focal length "
                             f"{f * 1e3:g} mm, got {s!r} m")

    @property
    def thin_lens(self) -> bool:
        """True when the camera has a finite aperture (``f_number``): synth.defocus blurs."""
        return self.f_number is not None

    @property
    def lens(self):
        """The :class:`synth.distortion.Lens` (None without distortion)."""
        return lens_of(self)

    def recorded(self, uv) -> np.ndarray:
        """Ideal pixel coordinates (..., 2) -> where the lens puts them in the recording."""
        lens = self.lens
        return np.asarray(uv, dtype=float) if lens is None else lens.distort(uv)

    def ideal(self) -> CameraModel:
        """The camera without its lens whose frame covers everything the lens shows, at
        :data:`synth.distortion.FACTOR` x FACTOR pixels per frame pixel: the render that
        :mod:`synth.distortion` bends into this camera's frames (self when no lens)."""
        lens = self.lens
        if lens is None:
            return self
        win = cached_window(lens, self.width, self.height)
        pp = None if self.principal_px is None else tuple(win.to_render(self.principal_px))
        return dataclasses.replace(
            self, width=win.width, height=win.height, lens_matrix=None,
            lens_distortion=(0.0,) * 5, pixel_size=self.pixel_size / win.factor,
            center_px=tuple(float(c) for c in win.to_render(self.center_px)),
            principal_px=None if pp is None else tuple(float(c) for c in pp))

    @property
    def rotation(self) -> np.ndarray:
        """World -> camera axes (3 x 3): Rz(roll) Ry(yaw) Rx(pitch)."""
        cr, sr = math.cos(self.roll), math.sin(self.roll)
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        rz = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
        # the camera swung towards +x: its right axis is (cos, 0, -sin) in the world, its
        # view axis (towards it) (sin, 0, cos); towards +y likewise in y
        ry = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]])
        rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
        return rz @ ry @ rx

    @property
    def tilted(self) -> bool:
        """True when the optical axis is not along the cylinder axis (yaw or pitch)."""
        return bool(self.yaw or self.pitch)

    def _turned(self, p: np.ndarray) -> np.ndarray:
        """World points in the camera's axes (turned by roll, yaw, pitch: what it sees)."""
        if not self.roll and not self.tilted:
            return p
        if not self.tilted:  # the roll alone: exactly as before (x, y only)
            c, s = math.cos(self.roll), math.sin(self.roll)
            out = p.copy()
            out[..., 0] = c * p[..., 0] - s * p[..., 1]
            out[..., 1] = s * p[..., 0] + c * p[..., 1]
            return out
        return p @ self.rotation.T

    @property
    def principal(self) -> tuple[float, float]:
        """Where the optical axis meets the image (px): ``principal_px``, else ``center_px``."""
        return self.center_px if self.principal_px is None else self.principal_px

    @property
    def pinhole_offset(self) -> tuple[float, float]:
        """(X0, Y0), m: the pinhole across the cylinder axis, in the camera's (rolled) x right,
        y up; (0, 0) on the axis and for the orthographic camera."""
        if self.principal_px is None:
            return 0.0, 0.0
        (pu, pv), (cx, cy) = self.principal_px, self.center_px
        return (pu - cx) * self.pixel_size, (cy - pv) * self.pixel_size

    @property
    def position(self) -> np.ndarray:
        """The camera's (pinhole's) position in the world frame (m)."""
        return self.pose()[:3, 3].copy()

    @property
    def focal_px(self) -> float:
        """Focal length in pixels (perspective): working distance / pixel size."""
        return self.working_distance / self.pixel_size

    @property
    def camera_z(self) -> float:
        """z of the camera (the pinhole, or the orthographic eye) in the world frame."""
        return self.working_distance

    def pose(self) -> np.ndarray:
        """4x4 camera-to-world pose (OpenGL camera: looks along its -z)."""
        pose = np.eye(4)
        if self.tilted:
            pose[:3, :3] = self.rotation.T  # camera-to-world
        elif self.roll:
            # camera-to-world: the inverse of the roll that turns world points for the camera
            c, s = math.cos(self.roll), math.sin(self.roll)
            pose[:2, :2] = [[c, s], [-s, c]]
        x0, y0 = self.pinhole_offset
        pose[:3, 3] = pose[:3, :3] @ np.array([x0, y0, self.camera_z])
        return pose

    # -- exact projections -------------------------------------------------------------------

    def project(self, points) -> np.ndarray:
        """Exact projection of world points to pixel coordinates.

        Parameters
        ----------
        points : array_like
            (..., 3) world points (m; x right, y up, z towards the camera).

        Returns
        -------
        numpy.ndarray
            (..., 2) pixel coordinates (u right, v down, origin at the centre of the top-left
            pixel).

        Raises
        ------
        InputError
            A point lies behind the perspective camera.
        """
        p = self._turned(np.asarray(points, dtype=float))
        cx, cy = self.center_px
        if self.projection == "orthographic":
            u = cx + p[..., 0] / self.pixel_size
            v = cy - p[..., 1] / self.pixel_size
        else:
            depth = self.camera_z - p[..., 2]
            if np.any(depth <= 0):
                raise InputError("point behind the perspective camera")
            (pu, pv), (x0, y0) = self.principal, self.pinhole_offset
            u = pu + self.focal_px * (p[..., 0] - x0) / depth
            v = pv - self.focal_px * (p[..., 1] - y0) / depth
        return np.stack([u, v], axis=-1)

    def sphere_silhouette(self, centres, radius: float):
        """Silhouette of spheres of ``radius`` at world ``centres``.

        Orthographic: the projected centre and r / s. Perspective: the tangent cone from the pinhole
        cut by the image plane is an ellipse whose centre lies outward of the projected sphere
        centre.

        Parameters
        ----------
        centres : array_like
            (N, 3) sphere centres (m).
        radius : float
            Sphere radius (m).

        Returns
        -------
        centre_uv : numpy.ndarray
            (N, 2) centres of the silhouette ellipses (px).
        radius_px : numpy.ndarray
            (N,) area-equivalent radii sqrt(a b) (px).

        Raises
        ------
        InputError
            The perspective camera is inside a ball.
        """
        c = np.atleast_2d(np.asarray(centres, dtype=float))
        if self.projection == "orthographic":
            return self.project(c), np.full(len(c), radius / self.pixel_size)
        c = self._turned(c)
        # camera coordinates with y down, z = depth (standard pinhole)
        x0, y0 = self.pinhole_offset
        X = c[:, 0] - x0
        Y = -(c[:, 1] - y0)
        Z = self.camera_z - c[:, 2]
        k = X * X + Y * Y + Z * Z - radius * radius
        if np.any(k <= 0):
            raise InputError("the perspective camera is inside the ball")
        # conic q^T (C C^T - k I) q = 0 for q = (a, b, 1) in normalised image coordinates
        A = X * X - k
        B = X * Y
        E = Y * Y - k
        D = X * Z
        F = Y * Z
        G = Z * Z - k
        det = A * E - B * B
        a0 = -(E * D - B * F) / det
        b0 = -(-B * D + A * F) / det
        # semi-axes: value of the form at the centre, then eigenvalues of the 2x2 part
        g = D * a0 + F * b0 + G  # conic value at the centre (q^T M q with centre substituted)
        tr = A + E
        disc = np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0))
        l1 = 0.5 * tr + disc
        l2 = 0.5 * tr - disc
        semi_prod = np.sqrt((g / l1) * (g / l2))  # a * b in normalised units
        f = self.focal_px
        cx, cy = self.principal
        uv = np.stack([cx + f * a0, cy + f * b0], axis=-1)
        return uv, f * np.sqrt(semi_prod)

    # -- OpenGL projection for a pixel-aligned tile ------------------------------------------

    def tile_projection(self, x0: int, y0: int, w: int, h: int) -> np.ndarray:
        """4x4 OpenGL projection that renders the full-frame pixels [x0, x0+w) x [y0, y0+h).

        Pixel (i, j) of the tile is full-frame pixel (x0 + i, y0 + j), exactly: the tile lines up
        with the full frame pixel for pixel (supersampling renders more pixels over the same region,
        which keeps this mapping).

        Parameters
        ----------
        x0, y0 : int
            Full-frame pixel of the tile's top-left corner.
        w, h : int
            Tile size (px).

        Returns
        -------
        numpy.ndarray
            The 4x4 projection matrix.
        """
        cx, cy = self.center_px if self.projection == "orthographic" else self.principal
        a = 2.0 * (cx - x0 + 0.5) / w - 1.0
        b = 1.0 - 2.0 * (cy - y0 + 0.5) / h
        n, fa = self.znear, self.zfar
        P = np.zeros((4, 4))
        if self.projection == "orthographic":
            s = self.pixel_size
            P[0, 0] = 2.0 / (s * w)
            P[0, 3] = a
            P[1, 1] = 2.0 / (s * h)
            P[1, 3] = b
            P[2, 2] = -2.0 / (fa - n)
            P[2, 3] = -(fa + n) / (fa - n)
            P[3, 3] = 1.0
        else:
            f = self.focal_px
            P[0, 0] = 2.0 * f / w
            P[0, 2] = -a
            P[1, 1] = 2.0 * f / h
            P[1, 2] = -b
            P[2, 2] = -(fa + n) / (fa - n)
            P[2, 3] = -2.0 * fa * n / (fa - n)
            P[3, 2] = -1.0
        return P

    def to_dict(self) -> dict:
        """The camera as plain data, the form stored in a recording's attributes.

        Returns
        -------
        dict
        """
        d = dataclasses.asdict(self) | {"center_px": list(self.center_px),
                                        "lens_distortion": list(self.lens_distortion)}
        if self.f_number is None:  # a pinhole: stored as before the thin lens
            for k in ("f_number", "focus_distance", "focal_length"):
                d.pop(k)
        if self.principal_px is None:
            d.pop("principal_px")
        else:
            d["principal_px"] = list(self.principal_px)
        if self.lens_matrix is not None:
            d["lens_matrix"] = [list(r) for r in self.lens_matrix]
        return d
