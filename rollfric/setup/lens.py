"""The lab camera's lens calibration: OpenCV's camera matrix and distortion coefficients.

A setup file may carry the calibration exactly as ``cv2.calibrateCamera`` returns it::

    [camera]
    matrix = [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]   # px
    distortion = [k1, k2, p1, p2, k3]
    matrix_u = [[u_fx, 0.0, u_cx], [0.0, u_fy, u_cy], [0.0, 0.0, 0.0]]   # optional
    distortion_u = [u_k1, u_k2, u_p1, u_p2, u_k3]                       # optional

(``matrix_u`` and ``distortion_u``: the standard uncertainties ``rollfric calibrate`` writes
from ``cv2.calibrateCameraExtended``; the uncertainty budget propagates them.)

Located ball centres and the trough's contour points are then undistorted
(``cv2.undistortPoints``, iterated to convergence) before the trough centre and the angles are
computed; ``pixel_size_mm`` is the scale of the undistorted image at the ball.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rollfric.errors import InputError


class CalibrationError(InputError):
    """A camera matrix or distortion vector that OpenCV's model cannot take."""


# the entries of the camera matrix a calibration fits: name -> (row, column)
MATRIX_ENTRIES = {"fx": (0, 0), "fy": (1, 1), "cx": (0, 2), "cy": (1, 2)}
# OpenCV's names of the distortion coefficients, in their order
DISTORTION_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4",
                    "tx", "ty")


@dataclasses.dataclass(frozen=True)
class Calibration:
    """OpenCV camera matrix (3 x 3, px) and distortion coefficients [k1, k2, p1, p2, k3]
    (4, 5, 8, 12 or 14 coefficients, as OpenCV accepts), optionally with their standard
    uncertainties: ``matrix_u`` (3 x 3, px; only fx, fy, cx, cy may be > 0) and
    ``distortion_u`` (one per coefficient), as ``cv2.calibrateCameraExtended``'s
    stdDeviationsIntrinsics give them (None: exact). ``image_size`` is (width, height) px of
    the images it was made from (None: not stated): a calibration holds only for that size and
    crop, and a recording of another size is refused (:func:`check_image_size`).

    Parameters
    ----------
    matrix : tuple
        ((fx, 0, cx), (0, fy, cy), (0, 0, 1)), px.
    distortion : tuple of float
        OpenCV's coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, tx, ty]]]]).
    matrix_u, distortion_u : tuple or None, optional
        Their standard uncertainties (None: exact).
    image_size : tuple of int or None, optional
        (width, height) px of the calibration's images.

    Raises
    ------
    CalibrationError
        A matrix that is not [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, a
        distortion of another length or not finite, a bad uncertainty or image size.

    Examples
    --------
    A barrel distortion (k1 = -0.1) on a 1000 px focal length: the point imaged 500 px right
    of the principal point lies 513.5 px out in the undistorted image.

    >>> from rollfric import Calibration
    >>> lens = Calibration(matrix=((1000.0, 0.0, 640.0), (0.0, 1000.0, 512.0), (0.0, 0.0, 1.0)),
    ...                    distortion=(-0.1, 0.0, 0.0, 0.0, 0.0))
    >>> lens.undistort([[640.0, 512.0], [1140.0, 512.0]]).round(2)
    array([[ 640.  ,  512.  ],
           [1153.54,  512.  ]])
    >>> lens.distort(lens.undistort([[1140.0, 512.0]])).round(6)
    array([[1140.,  512.]])
    """

    matrix: tuple
    distortion: tuple
    matrix_u: tuple | None = None
    distortion_u: tuple | None = None
    image_size: tuple | None = None

    def __post_init__(self) -> None:
        try:
            k = np.asarray(self.matrix, dtype=float)
            d = np.asarray(self.distortion, dtype=float).ravel()
        except (TypeError, ValueError):
            raise CalibrationError("camera.matrix must be 3 rows of 3 numbers and "
                                   "camera.distortion a list of numbers") from None
        if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0 \
                or k[1, 0] != 0 or k[2, 0] != 0 or k[2, 1] != 0 or k[2, 2] != 1:
            raise CalibrationError(
                "camera.matrix must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (px) with "
                f"fx, fy > 0, got {self.matrix!r}")
        if d.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
            raise CalibrationError("camera.distortion must be [k1, k2, p1, p2, k3] (or the "
                                   f"4, 8, 12, 14 coefficients OpenCV takes), got "
                                   f"{self.distortion!r}")
        object.__setattr__(self, "matrix", tuple(tuple(float(v) for v in r) for r in k))
        object.__setattr__(self, "distortion", tuple(float(v) for v in d))
        if self.matrix_u is not None:
            try:
                ku = np.asarray(self.matrix_u, dtype=float)
            except (TypeError, ValueError):
                ku = np.full(1, np.nan)
            free = np.zeros((3, 3), bool)
            for r, c in MATRIX_ENTRIES.values():
                free[r, c] = True
            if ku.shape != (3, 3) or not np.all(np.isfinite(ku)) or np.any(ku < 0) \
                    or np.any(ku[~free] != 0):
                raise CalibrationError(
                    "camera.matrix_u must be [[u_fx, 0, u_cx], [0, u_fy, u_cy], [0, 0, 0]] "
                    f"(px, finite, >= 0), got {self.matrix_u!r}")
            object.__setattr__(self, "matrix_u", tuple(tuple(float(v) for v in r) for r in ku))
        if self.distortion_u is not None:
            try:
                du = np.asarray(self.distortion_u, dtype=float).ravel()
            except (TypeError, ValueError):
                du = np.full(1, np.nan)
            if du.size != d.size or not np.all(np.isfinite(du)) or np.any(du < 0):
                raise CalibrationError(
                    f"camera.distortion_u must be {d.size} standard uncertainties (finite, >= "
                    f"0), one per distortion coefficient, got {self.distortion_u!r}")
            object.__setattr__(self, "distortion_u", tuple(float(v) for v in du))
        if self.image_size is not None:
            size = self.image_size
            if (not isinstance(size, (list, tuple)) or len(size) != 2
                    or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                               and math.isfinite(v) and v == int(v) and v > 0 for v in size)):
                raise CalibrationError("camera.image_size_px must be [width, height], two "
                                       f"positive whole numbers of pixels, got {size!r}")
            object.__setattr__(self, "image_size", (int(size[0]), int(size[1])))

    def parameters(self) -> list:
        """The calibration's fitted parameters with their standard uncertainties: [(name,
        value, u)], names ``matrix[fx]``, ``matrix[fy]``, ``matrix[cx]``, ``matrix[cy]`` and
        ``distortion[k1]`` ...; u 0 where not given.

        Returns
        -------
        list of tuple
            (name, value, standard uncertainty).
        """
        mu = self.matrix_u or ((0.0,) * 3,) * 3
        du = self.distortion_u or (0.0,) * len(self.distortion)
        out = [(f"matrix[{name}]", self.matrix[r][c], mu[r][c])
               for name, (r, c) in MATRIX_ENTRIES.items()]
        out += [(f"distortion[{DISTORTION_NAMES[i]}]", v, du[i])
                for i, v in enumerate(self.distortion)]
        return out

    def moved(self, name: str, delta: float) -> Calibration:
        """A copy with one parameter moved by ``delta``.

        Parameters
        ----------
        name : str
            A name of :meth:`parameters`: ``matrix[fx]``, ..., ``distortion[k1]``, ...
        delta : float
            The change (px for the matrix, 1 for the distortion).

        Returns
        -------
        Calibration
            The moved calibration (without uncertainties).
        """
        kind, entry = name[:-1].split("[")
        m = [list(r) for r in self.matrix]
        d = list(self.distortion)
        if kind == "matrix":
            r, c = MATRIX_ENTRIES[entry]
            m[r][c] += delta
        else:
            d[DISTORTION_NAMES.index(entry)] += delta
        return Calibration(matrix=m, distortion=d, image_size=self.image_size)

    @property
    def K(self) -> np.ndarray:
        """The camera matrix as a (3, 3) array."""
        return np.asarray(self.matrix, dtype=float)

    @property
    def D(self) -> np.ndarray:
        """The distortion coefficients as an array."""
        return np.asarray(self.distortion, dtype=float)

    def undistort(self, xy) -> np.ndarray:
        """Image pixels (..., 2) -> their positions in the undistorted image (same camera
        matrix), iterated until they move less than 1e-10 px.

        Parameters
        ----------
        xy : array_like
            Pixel positions (x, y), shape (..., 2), px.

        Returns
        -------
        numpy.ndarray
            Undistorted positions, same shape, px.
        """
        import cv2

        xy = np.asarray(xy, dtype=float)
        if xy.size == 0:
            return xy.copy()
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)
        out = cv2.undistortPoints(xy.reshape(-1, 1, 2), self.K, self.D, None, None, self.K, crit)
        return out.reshape(xy.shape)

    def distort(self, xy) -> np.ndarray:
        """Undistorted pixels (..., 2) -> where the lens puts them (``cv2.projectPoints``).

        Parameters
        ----------
        xy : array_like
            Undistorted pixel positions (x, y), shape (..., 2), px.

        Returns
        -------
        numpy.ndarray
            Distorted (image) positions, same shape, px.
        """
        import cv2

        xy = np.asarray(xy, dtype=float)
        if xy.size == 0:
            return xy.copy()
        p = xy.reshape(-1, 2)
        K = self.K
        y = (p[:, 1] - K[1, 2]) / K[1, 1]
        x = (p[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
        obj = np.column_stack([x, y, np.ones_like(x)])
        out, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), K, self.D)
        return out.reshape(xy.shape)

    def undistort_ball(self, xy, radius_px: float, n: int = 16, iterations: int = 2
                       ) -> np.ndarray:
        """Centres of circles fitted to balls' outlines in the recorded image (..., 2) -> the
        balls' centres in the undistorted image.

        The lens bends a ball's round outline (radius ``radius_px`` in the undistorted image)
        into one that is not quite round, and the circle fitted to it is not centred on the
        recorded image of the ball's centre: the difference is second order in the lens
        (its curvature over the ball; k1 = -0.18 at fx = 2400 px: up to 0.06 px at the
        thesis's ball path). It is computed here for each ball (the least-squares circle
        through ``n`` points of its bent outline, against the bent centre) and taken off
        before the centre is undistorted; ``iterations`` repeats it from the corrected
        centre.

        Parameters
        ----------
        xy : array_like
            Fitted circle centres in the recorded image (x, y), shape (..., 2), px.
        radius_px : float
            The ball's radius in the undistorted image (px).
        n : int
            Points of each outline.
        iterations : int
            Passes (the difference changes by about 1e-4 px per px of centre; two leave
            1e-9 px).

        Returns
        -------
        numpy.ndarray
            The balls' centres in the undistorted image, same shape, px.
        """
        xy = np.asarray(xy, dtype=float)
        if xy.size == 0:
            return xy.copy()
        p = xy.reshape(-1, 2)
        phi = np.linspace(0.0, 2.0 * np.pi, int(n), endpoint=False)
        ring = float(radius_px) * np.column_stack([np.cos(phi), np.sin(phi)])
        c = self.undistort(p)
        for _ in range(max(1, int(iterations))):
            bent = self.distort(c[:, None, :] + ring[None, :, :])  # (N, n, 2)
            offset = _circle_centres(bent) - self.distort(c)
            c = self.undistort(p - offset)
        return c.reshape(xy.shape)

    def shift_px(self, xy) -> np.ndarray:
        """How far (px) the lens moves undistorted points ``xy`` (..., 2).

        Parameters
        ----------
        xy : array_like
            Undistorted pixel positions (x, y), shape (..., 2), px.

        Returns
        -------
        numpy.ndarray
            Distance between each point and its distorted position, shape (...), px.
        """
        xy = np.asarray(xy, dtype=float)
        return np.hypot(*(self.distort(xy) - xy).reshape(-1, 2).T).reshape(xy.shape[:-1])

    def to_toml_dict(self) -> dict:
        """The setup file's [camera] keys (``matrix_u``, ``distortion_u``, ``image_size_px``
        when known)."""
        out = {"matrix": [list(r) for r in self.matrix], "distortion": list(self.distortion)}
        if self.image_size is not None:
            out["image_size_px"] = list(self.image_size)
        if self.matrix_u is not None:
            out["matrix_u"] = [list(r) for r in self.matrix_u]
        if self.distortion_u is not None:
            out["distortion_u"] = list(self.distortion_u)
        return out


def check_image_size(calibration: Calibration | None, width: int, height: int) -> None:
    """Refuse frames of another size than the lens calibration's images.

    A camera matrix and distortion hold for the sensor window they were fitted on: on a
    cropped or binned recording the optical centre and the distortion fall on other pixels,
    and the undistorted centres (so mu) would be wrong without any other sign.

    Parameters
    ----------
    calibration : Calibration or None
        The setup's calibration; None, or one without ``image_size``, is not checked.
    width, height : int
        The frames' size, px.

    Raises
    ------
    CalibrationError
        If the sizes differ.
    """
    if calibration is None or calibration.image_size is None:
        return
    cw, ch = calibration.image_size
    if (cw, ch) != (width, height):
        raise CalibrationError(
            f"the lens calibration (camera.matrix, camera.distortion) was made on {cw}x{ch} px "
            f"images (camera.image_size_px) but the frames are {width}x{height} px: a "
            "calibration holds only for the sensor window it was made at; calibrate again at "
            "this size (rollfric calibrate), or fix camera.image_size_px if it is wrong")


def _circle_centres(pts: np.ndarray) -> np.ndarray:
    """Least-squares (Kasa) circle centres of point sets (N, n, 2) -> (N, 2), each set taken
    about its mean (the fit is then well conditioned)."""
    m = pts.mean(axis=1, keepdims=True)
    q = pts - m
    x, y = q[..., 0], q[..., 1]
    b = x * x + y * y
    a = np.stack([x, y, np.ones_like(x)], axis=-1)  # (N, n, 3)
    ata = np.einsum("kni,knj->kij", a, a)
    atb = np.einsum("kni,kn->ki", a, b)
    sol = np.linalg.solve(ata, atb[..., None])[..., 0]
    return m[:, 0, :] + 0.5 * sol[:, :2]


def calibration_from_dict(camera: dict, source: str = "setup") -> Calibration | None:
    """The [camera] table's calibration (None when it has neither matrix nor distortion).

    Parameters
    ----------
    camera : dict
        The setup file's [camera] table (keys ``matrix``, px, and ``distortion``, optionally
        their standard uncertainties ``matrix_u`` and ``distortion_u`` and the calibration
        images' size ``image_size_px``).
    source : str
        Name of the file or table, for messages.

    Returns
    -------
    Calibration or None
        The calibration, or None when the table has neither key.

    Raises
    ------
    CalibrationError
        If only one of the two keys is given, they are not lists of numbers, or OpenCV's
        model cannot take them.
    """
    has_m, has_d = "matrix" in camera, "distortion" in camera
    if not has_m and not has_d:
        if "image_size_px" in camera:
            raise CalibrationError(f"{source}: camera.image_size_px is the size of the lens "
                                   "calibration's images: it goes with camera.matrix and "
                                   "camera.distortion")
        return None
    if has_m != has_d:
        raise CalibrationError(f"{source}: camera.matrix and camera.distortion go together "
                               "(as cv2.calibrateCamera returns them)")
    m, d = camera["matrix"], camera["distortion"]
    if not isinstance(m, list) or not all(isinstance(r, list) for r in m) \
            or not isinstance(d, list) \
            or any(isinstance(v, bool) or not isinstance(v, (int, float))
                   for v in [*(x for r in m for x in r), *d]):
        raise CalibrationError(f"{source}: camera.matrix must be 3 rows of 3 numbers and "
                               "camera.distortion a list of numbers")
    for key, base in (("matrix_u", "matrix"), ("distortion_u", "distortion")):
        v = camera.get(key)
        if v is not None and (not isinstance(v, list) or any(
                isinstance(x, bool) or not isinstance(x, (int, float))
                for x in (y for r in v for y in (r if isinstance(r, list) else [r])))):
            raise CalibrationError(f"{source}: camera.{key} must be a list of numbers shaped "
                                   f"like camera.{base}")
    try:
        return Calibration(matrix=m, distortion=d, matrix_u=camera.get("matrix_u"),
                           distortion_u=camera.get("distortion_u"),
                           image_size=camera.get("image_size_px"))
    except CalibrationError as exc:
        raise CalibrationError(f"{source}: {exc}") from None
