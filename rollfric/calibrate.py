"""The lens calibration from chessboard images (OpenCV), for the setup file's [camera] keys.

``calibrate_chessboard(images, board=(9, 6), square=0.005)`` finds the inner corners of a
chessboard in each image (``cv2.findChessboardCorners``, refined with ``cv2.cornerSubPix``) and
fits OpenCV's camera model to them (``cv2.calibrateCameraExtended``): the camera matrix and
the distortion [k1, k2, p1, p2, k3] that rollfric's setup file takes (:mod:`rollfric.lens`),
with their standard uncertainties (its stdDeviationsIntrinsics: from the reprojection
residuals and the Jacobian of the fit, parameters taken one at a time, their correlations not
given).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rollfric.errors import InputError
from rollfric.lens import Calibration

MIN_VIEWS = 3
# The rms reprojection error above which a calibration is written but called suspect (exit 3):
# sub-pixel chessboard corners fit OpenCV's model to ~0.1-0.5 px, and more than 1 px means the
# corners or the model do not fit (motion blur, a board that is not flat, a lens the model
# cannot take) - OpenCV's tutorials take an error "as close to zero as possible", under 1 px.
MAX_RMS_PX = 1.0
SQUARE_RANGE = (1e-6, 1.0)  # m: the side of a chessboard square, 1 um .. 1 m


@dataclasses.dataclass(frozen=True)
class ChessboardCalibration:
    """The fitted calibration, its rms reprojection error (px) and which images had a board."""

    calibration: Calibration
    rms_px: float
    used: tuple  # names of the images whose board was found
    skipped: tuple  # names of the images without a board
    image_size: tuple  # (width, height) px


def _gray8(img: np.ndarray) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim == 3:
        a = a[..., :3].mean(axis=2)
    if a.dtype != np.uint8:
        a = a.astype(float)
        lo, hi = float(a.min()), float(a.max())
        a = np.zeros_like(a) if hi <= lo else (a - lo) * (255.0 / (hi - lo))
    return np.clip(np.rint(a), 0, 255).astype(np.uint8)


def calibrate_chessboard(images, board: tuple[int, int], square: float,
                         names=None, free_k3: bool = False) -> ChessboardCalibration:
    """OpenCV's camera model fitted to chessboard views.

    Parameters
    ----------
    images : sequence of numpy.ndarray
        The views (grey or colour, any integer or float type), all of one size.
    board : tuple of int
        Inner corners per row and per column, e.g. (9, 6) for a 10 x 7 squares board.
    square : float
        The side of one square (m).
    names : sequence of str, optional
        A name per image for the report (default: its index).
    free_k3 : bool, optional
        Fit k3 too; by default it is held at 0 (OpenCV's advice for lenses that are not wide
        angle: with k1, k2 and k3 free the views rarely pin the corners down).

    Returns
    -------
    ChessboardCalibration

    Raises
    ------
    InputError
        Images of different sizes, fewer than MIN_VIEWS views with a board found, or a
        square size outside SQUARE_RANGE.
    """
    import cv2

    cols, rows = (int(v) for v in board)
    if cols < 2 or rows < 2:
        raise InputError(f"the board needs at least 2 x 2 inner corners, got {cols} x {rows}")
    if not square > 0:
        raise InputError(f"the square size must be positive, got {square!r}")
    if not SQUARE_RANGE[0] <= square <= SQUARE_RANGE[1]:  # inf, or beyond float32's corners
        raise InputError(f"the square size {square * 1e3:g} mm is outside the plausible range "
                         f"{SQUARE_RANGE[0] * 1e3:g}..{SQUARE_RANGE[1] * 1e3:g} mm")
    names = [str(i) for i in range(len(images))] if names is None else [str(n) for n in names]
    obj = np.zeros((rows * cols, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    obj_pts, img_pts, used, skipped, size = [], [], [], [], None
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    for name, img in zip(names, images, strict=True):
        g = _gray8(img)
        if size is None:
            size = (g.shape[1], g.shape[0])
        elif (g.shape[1], g.shape[0]) != size:
            raise InputError(f"image {name} is {g.shape[1]} x {g.shape[0]} px, the first "
                             f"{size[0]} x {size[1]}: one camera, one size")
        ok, corners = cv2.findChessboardCorners(
            g, (cols, rows), flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not ok:
            skipped.append(name)
            continue
        corners = cv2.cornerSubPix(g, corners, (5, 5), (-1, -1), crit)
        obj_pts.append(obj)
        img_pts.append(corners)
        used.append(name)
    if len(used) < MIN_VIEWS:
        raise InputError(f"a {cols} x {rows} chessboard was found in {len(used)} of "
                         f"{len(names)} image(s); at least {MIN_VIEWS} views are needed")
    flags = 0 if free_k3 else cv2.CALIB_FIX_K3
    rms, K, D, _, _, std, _, _ = cv2.calibrateCameraExtended(obj_pts, img_pts, size, None, None,
                                                             flags=flags)
    # stdDeviationsIntrinsics: fx, fy, cx, cy, k1, k2, p1, p2, k3, ... (0 for a fixed one)
    std = np.nan_to_num(np.asarray(std, dtype=float).ravel(), nan=0.0)
    matrix_u = [[std[0], 0.0, std[2]], [0.0, std[1], std[3]], [0.0, 0.0, 0.0]]
    return ChessboardCalibration(
        calibration=Calibration(matrix=K.tolist(), distortion=D.ravel()[:5].tolist(),
                                matrix_u=matrix_u, distortion_u=std[4:9].tolist(),
                                image_size=tuple(int(v) for v in size)),
        rms_px=float(rms), used=tuple(used), skipped=tuple(skipped), image_size=size)
