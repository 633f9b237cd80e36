"""``rollfric measure``: from a recording to track.csv and fit.json."""

from __future__ import annotations

from rollfric.cli.fit import add_budget_arguments, add_model_argument
from rollfric.cli.helpformat import HelpFormatter, example
from rollfric.registry import FIT_METHODS, LOCATORS

HELP = "locate the ball in a recording, write its track and fit mu"


def register(sub) -> None:
    """Add the ``measure`` subcommand and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subcommands of the ``rollfric`` parser.
    """
    p = sub.add_parser(
        "measure", help=HELP, description=(
            "Measure rolling friction from a recording: locate the ball in every frame "
            "(background subtraction, then a locator), compute theta about the cylinder centre "
            "(from setup center_px, else from the trough contour in the background), and fit mu "
            "(M = mu r N) with the equation of motion. RECORDING is a multi-page TIFF, a folder "
            "of images (sorted by name), a video file, a Phantom .cine file, a Photron .cih/.cihx "
            "header (with its .mraw beside it), or a Zarr store (array 'frames', or read by a "
            "rollfric.zarr_readers entry point). Writes OUT/track.csv (frame,t_s,x_px,"
            "y_px,theta_rad,found; empty coordinates where no ball was found) and OUT/fit.json "
            "(as 'rollfric fit', plus n_frames and n_found); with --plot also OUT/fit.png and "
            "OUT/overlays.png. Nothing is written when the input is bad (exit status 2); a "
            "measurement that fails a quality check is written with quality = suspect and its "
            "reasons in fit.json, the reasons on stderr, and exit status 3."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric sample demo",
                       "rollfric measure demo/frames.tif --setup demo/setup.toml "
                       "--out demo/result --plot",
                       docs="docs/guide/measure.md"))
    add_tracking_arguments(p)
    p.add_argument("--fit-method", default="lsq", choices=list(FIT_METHODS),
                   help="how mu is fitted (see rollfric fit)")
    p.add_argument("--offset", nargs="?", const="on", default="auto",
                   choices=["auto", "on", "off"],
                   help="fit the angle of the trough's bottom (a camera rolled about its axis): "
                        "auto = when the track has three turning points or more; --offset = on")
    add_model_argument(p)
    p.add_argument("--plot", action="store_true",
                   help="also write fit.png (angle vs model) and overlays.png")
    p.add_argument("--overlay-frames", default=None, metavar="I,J,...",
                   help="frames drawn in overlays.png (default: 6 spread over the found ones)")
    add_budget_arguments(p)
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--overwrite", action="store_true",
                   help="write into an existing non-empty DIR: measure's own files (track.csv, "
                        "fit.json, fit.png, budget.png, overlays.png) are replaced, or removed "
                        "when not written this time; other files are left alone")
    p.set_defaults(func=run)


def add_tracking_arguments(p) -> None:
    """The options of ``measure`` and ``track`` that say how the track is measured: RECORDING,
    --setup, the background (--background, --median-frames), --method, --angle, --times and
    --no-progress.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser.
    """
    p.add_argument("recording", metavar="RECORDING", help="TIFF stack, image folder, video, "
                   ".cine, .cih/.cihx (+ .mraw), or Zarr store")
    p.add_argument("--setup", metavar="SETUP.toml", default=None,
                   help="lab setup file; may be omitted for a Zarr recording whose attrs hold "
                        "'setup'")
    p.add_argument("--background", metavar="BG", default=None,
                   help="background image without the ball (default: the recording's own, else "
                        "the per-pixel median of --median-frames frames)")
    p.add_argument("--background-from", default="median", choices=["median", "clip", "max"],
                   help="the background made from the frames when none is given: median "
                        "(per-pixel median, default), or for a backlit rig (a dark ball on a "
                        "bright field) clip (a flat field at the backlight's level) or max "
                        "(per-pixel maximum less its noise bias); a median or maximum that "
                        "still holds the ball where it goes is rebuilt from the frames clear "
                        "of it, or refused (exit 2)")
    p.add_argument("--median-frames", type=int, default=41,
                   help="frames in the median background when none is given")
    p.add_argument("--method", default="subpixel", choices=list(LOCATORS),
                   help="ball locator: subpixel (robust silhouette circle fit, default), "
                        "thesis-large (paper 2 steps 1-7), thesis-small (paper 1, 15x15 window)")
    p.add_argument("--angle", default="atan2", choices=["atan2", "arcsin"],
                   help="theta = atan2(x - xc, y - yc), or the thesis's arcsin((x - xc) / L)")
    p.add_argument("--times", default="auto", choices=["auto", "fps"],
                   help="t_s of each frame: auto = the recording's own per-frame timestamps when "
                        "it has them (a .cine's), else frame / camera.fps; fps = always "
                        "frame / camera.fps")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


# the files measure writes into DIR (rollfric.output.folder: --overwrite replaces only these)
OUTPUTS = {"track.csv": "file", "fit.json": "file", "fit.png": "file", "budget.png": "file",
           "overlays.png": "file"}


def check_tracking_outputs(args, outputs: dict, command: str):
    """Check, before any work, the output folder and the tracking options of ``measure`` or
    ``track``: DIR is none of the inputs, its own files may be written (``--overwrite``), and
    ``--median-frames`` is at least 3.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options (:func:`add_tracking_arguments`, ``--out``, ``--overwrite``).
    outputs : dict
        The command's own files in DIR (name -> "file").
    command : str
        The command's name for the messages.

    Returns
    -------
    pathlib.Path
        DIR.

    Raises
    ------
    rollfric.errors.InputError
        A refused output or option (nothing written).
    """
    from rollfric.errors import InputError
    from rollfric.output.folder import check_folder, check_not_input, named

    out = named(args.out)  # "." and "..": the folder by its name
    inputs = (args.recording, args.setup, args.background)
    check_not_input(out, inputs)
    for name in outputs:  # --overwrite replaces or removes these: never an input of this run
        check_not_input(out / name, inputs, what="the output")
    check_folder(out, outputs, overwrite=args.overwrite, command=command)
    if args.median_frames < 3:
        raise InputError(f"--median-frames must be at least 3, got {args.median_frames}")
    return out


def write_track_csv(track, path) -> None:
    """The track's TRACK_COLUMNS as track.csv (empty where no ball was found), then
    ``x_u_px``, ``y_u_px``: the centre's standard uncertainty per axis.

    Parameters
    ----------
    track : pandas.DataFrame
        From :func:`rollfric.measurement.measure`.
    path : pathlib.Path
        The file to write.
    """
    from rollfric.track.tracker import TRACK_COLUMNS

    csv = track[TRACK_COLUMNS].copy()
    # the locator's sigma is the rms of both axes together (the pixel fit's
    # sqrt(var_x + var_y)): each axis's share, where the ball was found
    u = track["sigma_px"].where((track["found"] == 1) & track["x_px"].notna()) / 2 ** 0.5 \
        if "sigma_px" in track else float("nan")
    csv["x_u_px"] = u
    csv["y_u_px"] = u
    csv.to_csv(path, index=False, float_format="%.6f", na_rep="")


def remove_legacy_leftovers(out) -> list:
    """Remove the hidden ``.DIR.XXXXXXXX`` folders that earlier versions of measure left beside
    DIR when killed (named by tempfile.mkdtemp, without a PID): only folders made as mkdtemp
    makes them (mode 0700) that hold nothing but measure's own output names (or temporary
    files) are removed, so a user's ``.DIR.20261124`` of earlier results stays.

    Parameters
    ----------
    out : str or path-like
        The output folder DIR.

    Returns
    -------
    list of pathlib.Path
        The folders removed (none when DIR's parent cannot be listed).
    """
    import re
    import shutil
    import stat
    from pathlib import Path

    out = Path(out)
    pat = re.compile(rf"^\.{re.escape(out.name)}\.[a-z0-9_]{{8}}$")
    removed = []
    try:
        entries = list(out.parent.iterdir())
    except OSError:
        return removed
    for p in entries:
        if not (pat.match(p.name) and p.is_dir() and not p.is_symlink()):
            continue
        try:  # tempfile.mkdtemp makes its folders 0700: a user's ".DIR.20261124" is not one
            if stat.S_IMODE(p.stat().st_mode) != 0o700:
                continue
        except OSError:
            continue
        names = [c.name for c in p.iterdir()]
        if all(n in OUTPUTS or n.startswith(".") and ".part-" in n for n in names):
            shutil.rmtree(p, ignore_errors=True)
            removed.append(p)
    return removed


def run(args) -> int:
    """Run ``rollfric measure``: measure the recording, write track.csv and fit.json.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options (:func:`register`).

    Returns
    -------
    int
        The exit status: 0 a good result, 3 a measurement written with quality "suspect".

    Raises
    ------
    rollfric.errors.InputError
        Bad input (a setup that does not fit the images included); nothing is written, and
        ``rollfric.cli.main.main`` reports it and exits with status 2.
    """
    from rollfric.cli.messages import to_stderr

    with to_stderr("measure"):  # the library's info and warnings, as before
        return _run(args)


def _run(args) -> int:

    from rollfric.cli.fit import report_quality
    from rollfric.errors import InputError
    from rollfric.measurement import measure
    from rollfric.output.folder import staged_folder
    from rollfric.output.jsonfile import save_fit
    from rollfric.uncertainty.law import fitted_model, verdict
    from rollfric.uncertainty.measured import measurement_from_track
    from rollfric.uncertainty.report import check_arguments, run_budget, with_budget_reason

    out = check_tracking_outputs(args, OUTPUTS, "measure")
    frames = None
    if args.overlay_frames:
        try:
            frames = [int(v) for v in args.overlay_frames.split(",") if v.strip()]
        except ValueError:
            raise InputError(f"--overlay-frames must be frame numbers like 0,100,200, got "
                             f"{args.overlay_frames!r}") from None
    check_arguments(args)
    if args.offset == "on" and args.fit_method == "paper2_grid":  # refused before the tracking
        raise InputError("--offset: paper2_grid fits no angle offset (the thesis's procedure "
                         "has none)")
    track, info, result = measure(args.recording, args.setup, args.background, method=args.method,
                            angle=args.angle, fit_method=args.fit_method,
                                  offset={"on": True, "off": False}.get(args.offset, "auto"),
                                  progress=not args.no_progress,
                                  median_frames=args.median_frames, times=args.times,
                                  background_from=args.background_from,
                                  fit_kwargs={"model": fitted_model(args.model)}
                                  if args.fit_method == "lsq" else None)
    meas = measurement_from_track(track, info)
    keys, budget = run_budget(meas, result, args)
    result = with_budget_reason(result, budget)
    result, keys["friction_law"] = verdict(meas, result, args.model)
    remove_legacy_leftovers(out)
    with staged_folder(out, OUTPUTS, overwrite=args.overwrite, command="measure") as tmp:
        write_track_csv(track, tmp / "track.csv")
        extra = {**info.json_keys(track, fitted=True), **keys,
                 # the setup it was measured with (rollfric combine compares runs by it)
                 "setup": info.setup.to_toml_dict()}
        save_fit(result, tmp / "fit.json", **extra)
        if args.plot:
            from rollfric.io.readers import open_recording
            from rollfric.output.overlay import plot_overlays
            from rollfric.output.plots import plot_budget, plot_fit

            plot_fit(track["t_s"].to_numpy(), track["theta_rad"].to_numpy(), result,
                     tmp / "fit.png")
            if budget is not None:
                plot_budget(budget, tmp / "budget.png")
            plot_overlays(open_recording(args.recording), track, tmp / "overlays.png",
                          frames=frames, info=info)
    unc = f"+- {result.mu_stderr:.2g} (standard error)" if budget is None else \
        f"+- {budget.u_mu:.2g} (u), U = {budget.U_mu:.2g} (k = 2)"
    mu = result.mu if budget is None else budget.mu
    print(f"mu = {mu:.6f} {unc} ({result.method}); ball found in "
          f"{info.n_found} of {info.n_frames} frames -> {out}")
    ce = info.contour_ellipse
    if ce is not None:
        print(f"contour ellipse: axis ratio {ce['axis_ratio']:.5f}, major axis at "
              f"{ce['angle_deg']:.1f} deg; implied mu bias {100 * ce['mu_bias_if_camera']:+.3f} % "
              f"(camera yaw/pitch) or {100 * ce['mu_bias_if_trough']:+.3f} % (trough out of round)")
    pe = info.path_ellipse
    if pe is not None and pe.get("verdict") not in (None, "round"):
        cam, tr = (f"{v:.6g}" if v is not None else "?" for v in (pe["mu_if_camera"],
                                                                    pe["mu_if_trough"]))
        print(f"path ellipse: axis ratio {pe['axis_ratio']:.5f}, major axis at "
              f"{pe['angle_deg']:.1f} deg, {pe['verdict']}: mu {cam} if the camera is "
              f"tilted, {tr} if the trough is out of round")
    return report_quality("measure", result)
