"""The lens calibration from chessboard images (OpenCV), for the setup file's [camera] keys.

``calibrate_chessboard(images, board=(9, 6), square=0.005)`` finds the inner corners of a
chessboard in each image (``cv2.findChessboardCorners``, refined with ``cv2.cornerSubPix``) and
fits OpenCV's camera model to them (``cv2.calibrateCameraExtended``): the camera matrix and
the distortion [k1, k2, p1, p2, k3] that rollfric's setup file takes (:mod:`rollfric.setup.lens`),
with their standard uncertainties (its stdDeviationsIntrinsics: from the reprojection
residuals and the Jacobian of the fit, parameters taken one at a time, their correlations not
given).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rollfric.errors import InputError
from rollfric.setup.lens import Calibration

MIN_VIEWS = 3
# Views whose boards' planes lie within this angle of one another count as one orientation:
# parallel planes add no constraint on the camera matrix (Zhang 2000), so copies of one view
# (or the board slid without tilting it) calibrate nothing however many there are.
MIN_TILT_DEG = 2.0
# The smallest image side: OpenCV's corner finder fails (an assertion) on images of 13 px and
# less, and a board's squares need a few pixels each.
MIN_IMAGE_PX = 32
# A calibration whose parameters are this uncertain is written but called suspect (exit 3):
# fx, fy over this fraction of their value, cx, cy over this fraction of the image's side ...
MAX_REL_U = 0.02
# ... or a distortion coefficient whose standard uncertainty moves a point at the edge of the
# area the boards covered by more than this (px): as much as MAX_RMS_PX allows the corners.
MAX_DISTORTION_U_PX = 1.0
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
    orientations: int = 0  # the views' distinct board orientations (MIN_TILT_DEG apart)
    suspects: tuple = ()  # why the fit is not to be trusted (parameters too uncertain); () if ok


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
        Images of different sizes or under MIN_IMAGE_PX a side, fewer than MIN_VIEWS views
        with a board found or fewer than MIN_VIEWS distinct board orientations among them
        (MIN_TILT_DEG apart), or a square size outside SQUARE_RANGE.

    Notes
    -----
    A fit whose parameters are too uncertain (MAX_REL_U, MAX_DISTORTION_U_PX) is returned
    with the reasons in ``suspects``; the caller decides (``rollfric calibrate`` exits 3).
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
        if min(size) < MIN_IMAGE_PX:
            raise InputError(f"image {name} is {size[0]} x {size[1]} px: too small to find a "
                             f"chessboard in (at least {MIN_IMAGE_PX} px a side)")
        try:
            ok, corners = cv2.findChessboardCorners(
                g, (cols, rows),
                flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
            if ok:
                corners = cv2.cornerSubPix(g, corners, (5, 5), (-1, -1), crit)
        except cv2.error as exc:  # OpenCV's assertions on images it cannot take
            raise InputError(f"OpenCV cannot search image {name} ({size[0]} x {size[1]} px) "
                             f"for a chessboard: {str(exc).strip().splitlines()[-1]}") from None
        if not ok:
            skipped.append(name)
            continue
        obj_pts.append(obj)
        img_pts.append(corners)
        used.append(name)
    if len(used) < MIN_VIEWS:
        raise InputError(f"a {cols} x {rows} chessboard was found in {len(used)} of "
                         f"{len(names)} image(s); at least {MIN_VIEWS} views are needed")
    flags = 0 if free_k3 else cv2.CALIB_FIX_K3
    try:
        rms, K, D, rvecs, _, std, _, _ = cv2.calibrateCameraExtended(
            obj_pts, img_pts, size, None, None, flags=flags)
    except cv2.error as exc:
        raise InputError(f"OpenCV cannot calibrate from these {len(used)} views: "
                         f"{str(exc).strip().splitlines()[-1]}") from None
    # the boards' plane normals: copies of one view have one, however K came out
    normals = [cv2.Rodrigues(r)[0][:, 2] for r in rvecs]
    orientations = count_orientations(normals, MIN_TILT_DEG)
    if orientations < MIN_VIEWS:
        raise InputError(
            f"the {len(used)} views show the board in {orientations} distinct orientation(s) "
            f"(board planes within {MIN_TILT_DEG:g} deg of one another count as one: copies of a"
            f" view or a board moved without tilting it); at least {MIN_VIEWS} are needed to fix"
            " the camera matrix: tilt the board by 10-45 deg about different axes")
    # stdDeviationsIntrinsics: fx, fy, cx, cy, k1, k2, p1, p2, k3, ... (0 for a fixed one)
    std = np.nan_to_num(np.asarray(std, dtype=float).ravel(), nan=np.inf)
    pts = np.concatenate(img_pts).reshape(-1, 2)
    suspects = _uncertain_parameters(K, std, size, pts)
    std = np.where(np.isfinite(std), std, 0.0)
    matrix_u = [[std[0], 0.0, std[2]], [0.0, std[1], std[3]], [0.0, 0.0, 0.0]]
    return ChessboardCalibration(
        calibration=Calibration(matrix=K.tolist(), distortion=D.ravel()[:5].tolist(),
                                matrix_u=matrix_u, distortion_u=std[4:9].tolist(),
                                image_size=tuple(int(v) for v in size)),
        rms_px=float(rms), used=tuple(used), skipped=tuple(skipped), image_size=size,
        orientations=orientations, suspects=tuple(suspects))


def count_orientations(normals, min_deg: float) -> int:
    """How many of the board planes' normals are ``min_deg`` or more apart.

    Parameters
    ----------
    normals : sequence of numpy.ndarray
        Unit normals of the board planes (the third column of each view's rotation).
    min_deg : float
        The angle (deg) under which two planes count as one orientation.

    Returns
    -------
    int
        The number of distinct orientations (greedy: each normal joins the first kept one
        within ``min_deg``, or is kept).
    """
    kept: list[np.ndarray] = []
    cos_min = np.cos(np.radians(min_deg))
    for n in normals:
        n = np.asarray(n, float) / np.linalg.norm(n)
        if all(abs(float(n @ k)) < cos_min for k in kept):
            kept.append(n)
    return len(kept)


def _uncertain_parameters(K, std, size, pts) -> list[str]:
    """Why a fit's parameters are too uncertain to trust (MAX_REL_U, MAX_DISTORTION_U_PX)."""
    K = np.asarray(K, float)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    out = []
    for name, value, u in (("fx", fx, std[0]), ("fy", fy, std[1])):
        if not u <= MAX_REL_U * abs(value):
            out.append(f"{name} {value:.1f} px has a standard uncertainty of {u:.3g} px "
                       f"({100 * u / abs(value):.2g} %, over {100 * MAX_REL_U:g} %)")
    for name, u, side in (("cx", std[2], size[0]), ("cy", std[3], size[1])):
        if not u <= MAX_REL_U * side:
            out.append(f"{name} has a standard uncertainty of {u:.3g} px (over "
                       f"{100 * MAX_REL_U:g} % of the image's {side} px)")
    # the normalised radius of the farthest corner: the edge of what the boards covered
    r = float(np.max(np.hypot((pts[:, 0] - cx) / fx, (pts[:, 1] - cy) / fy)))
    f = 0.5 * (abs(fx) + abs(fy))
    # a coefficient's shift at radius r: k1 r^3 f, k2 r^5 f, k3 r^7 f, p1, p2 up to 3 r^2 f
    for name, u, gain in (("k1", std[4], r ** 3), ("k2", std[5], r ** 5),
                          ("p1", std[6], 3 * r ** 2), ("p2", std[7], 3 * r ** 2),
                          ("k3", std[8] if len(std) > 8 else 0.0, r ** 7)):
        px = u * gain * f
        if not px <= MAX_DISTORTION_U_PX:
            out.append(f"distortion {name}'s standard uncertainty {u:.3g} moves a point at "
                       f"the edge of the boards' area by {px:.3g} px (over "
                       f"{MAX_DISTORTION_U_PX:g} px)")
    return out
