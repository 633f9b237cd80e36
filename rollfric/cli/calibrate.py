"""``rollfric calibrate``: chessboard images -> the setup file's [camera] matrix and distortion."""

from __future__ import annotations

from rollfric.cli.helpformat import HelpFormatter, example

HELP = "the lens calibration (camera matrix, distortion) from chessboard images"


def register(sub) -> None:
    """Add the ``calibrate`` command to the CLI.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``rollfric`` parser; the command's handler is :func:`run`.
    """
    p = sub.add_parser(
        "calibrate", help=HELP, description=(
            "Fit OpenCV's camera model to views of a printed chessboard (cv2.findChessboardCorners"
            " + cv2.calibrateCamera) and write the [camera] keys matrix and distortion that a "
            "setup file takes; rollfric measure then undistorts located centres and the trough's"
            " contour with them. Take 10-20 views of the board filling different parts of the "
            "frame, tilted, with the recording's lens, focus and resolution (the table states the "
            "images' size, image_size_px, and measure refuses frames of another size). Exit "
            "status 0: written; 2: bad input, nothing written (images under 32 px, fewer than "
            "3 boards found, or fewer than 3 distinct board orientations: copies of one view "
            "calibrate nothing); 3: written, but the rms reprojection error is over 1 px (the "
            "corners or the model do not fit: blur, a board that is not flat, a lens the model "
            "cannot take) or a parameter is too uncertain (fx, fy over 2 %, cx, cy over 2 % of "
            "the image, a distortion coefficient moving points by over 1 px)."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric calibrate board/*.png --board 9x6 --square-mm 10 "
                       "--out camera.toml",
                       docs="docs/formats/setup.md"))
    p.add_argument("images", nargs="+", metavar="IMAGE", help="chessboard images (any format "
                   "rollfric reads: PNG, TIFF, ...)")
    p.add_argument("--board", required=True, metavar="COLSxROWS",
                   help="inner corners per row and per column, e.g. 9x6 for 10 x 7 squares")
    p.add_argument("--square-mm", required=True, type=float, help="side of one square (mm)")
    p.add_argument("--out", required=True, metavar="CAMERA.toml",
                   help="where to write the [camera] table")
    p.add_argument("--free-k3", action="store_true",
                   help="fit k3 too (wide-angle lenses); by default k3 = 0")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``rollfric calibrate``: find the board in the images, write the [camera] table.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options of :func:`register`'s parser (``--square-mm`` in mm, converted to
        m for :func:`rollfric.setup.calibrate.calibrate_chessboard`).

    Returns
    -------
    int
        Exit status 0, or 3 when the rms reprojection error is over
        :data:`rollfric.setup.calibrate.MAX_RMS_PX` or a parameter's standard uncertainty is too
        large (:data:`rollfric.setup.calibrate.MAX_REL_U`,
        :data:`rollfric.setup.calibrate.MAX_DISTORTION_U_PX`); the table is written all the same.

    Raises
    ------
    rollfric.errors.InputError
        If ``--board`` is not COLSxROWS, ``--out`` is one of the images, a folder, or exists
        without ``--overwrite``, an image cannot be read, or the calibration refuses the
        input.
    """
    import sys
    from pathlib import Path

    from rollfric.errors import InputError
    from rollfric.io.readers import read_image
    from rollfric.output.atomic import write_text
    from rollfric.output.folder import check_file, check_not_input
    from rollfric.setup.calibrate import MAX_RMS_PX, calibrate_chessboard

    try:
        cols, rows = (int(v) for v in args.board.lower().split("x"))
    except ValueError:
        raise InputError(f"--board must be COLSxROWS like 9x6, got {args.board!r}") from None
    out = Path(args.out)
    # an input image is never replaced by the table, even with --overwrite
    check_not_input(out, args.images)
    check_file(out, overwrite=args.overwrite)
    images = [read_image(p) for p in args.images]
    res = calibrate_chessboard(images, (cols, rows), args.square_mm * 1e-3, names=args.images,
                               free_k3=args.free_k3)
    cal = res.calibration
    reasons = []
    if res.rms_px > MAX_RMS_PX:
        reasons.append(f"rms reprojection error {res.rms_px:.3f} px is over {MAX_RMS_PX:g} px: "
                       "the corners or the model do not fit (motion blur, a board that is not "
                       "flat, a lens the model cannot take; --free-k3 for a wide-angle lens)")
    if res.suspects:
        reasons.append("the views do not pin the parameters down: " + "; ".join(res.suspects)
                       + " (more views, tilted further, filling the frame's corners)")
    lines = [f"# rollfric calibrate: {cols} x {rows} inner corners, {args.square_mm:g} mm squares;"
             f" board found in {len(res.used)} of {len(args.images)} images; rms reprojection "
             f"error {res.rms_px:.3f} px; {res.image_size[0]} x {res.image_size[1]} px",
             *[f"# suspect: {reason}" for reason in reasons],
             "[camera]",
             "matrix = [" + ", ".join("[" + ", ".join(repr(float(v)) for v in r) + "]"
                                     for r in cal.matrix) + "]",
             "distortion = [" + ", ".join(repr(float(v)) for v in cal.distortion) + "]",
             "# standard uncertainties (cv2.calibrateCameraExtended); the budget propagates "
             "them",
             "matrix_u = [" + ", ".join("[" + ", ".join(repr(float(v)) for v in r) + "]"
                                       for r in cal.matrix_u) + "]",
             "distortion_u = [" + ", ".join(repr(float(v)) for v in cal.distortion_u) + "]",
             "# the images' size (width, height): rollfric measure refuses frames of another",
             f"image_size_px = [{res.image_size[0]}, {res.image_size[1]}]",
             ""]
    write_text(out, "\n".join(lines))
    for name in res.skipped:
        print(f"rollfric calibrate: no board found in {name} (left out)")
    print(f"fx {cal.matrix[0][0]:.1f} px, fy {cal.matrix[1][1]:.1f} px, centre "
          f"({cal.matrix[0][2]:.1f}, {cal.matrix[1][2]:.1f}) px, k1 {cal.distortion[0]:+.4f}; "
          f"rms {res.rms_px:.3f} px over {len(res.used)} views -> {out} (copy its [camera] keys"
          " into the setup file)")
    for reason in reasons:
        print(f"rollfric calibrate: suspect: {reason}", file=sys.stderr)
    return 3 if reasons else 0
    return 0
