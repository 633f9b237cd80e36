"""``rollfric track``: from a recording to track.csv (and track.json), no fit."""

from __future__ import annotations

from rollfric.cli.helpformat import HelpFormatter, example

HELP = "locate the ball in a recording and write its track only (any number of frames)"

# the files track writes into DIR (rollfric.output.folder: --overwrite replaces only these)
OUTPUTS = {"track.csv": "file", "track.json": "file", "overlays.png": "file"}


def register(sub) -> None:
    """Add the ``track`` subcommand and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subcommands of the ``rollfric`` parser.
    """
    from rollfric.cli.measure import add_tracking_arguments

    p = sub.add_parser(
        "track", help=HELP, description=(
            "Locate the ball in every frame of a recording as rollfric measure does (the same "
            "backgrounds, locators, angles and frame times) and write OUT/track.csv (frame,t_s,"
            "x_px,y_px,theta_rad,found,flag) and OUT/track.json (what it was measured with: "
            "recording, setup, background, locator, frames found, warnings); with --plot also "
            "OUT/overlays.png. No fit, so no minimum length: a 15-frame clip is tracked. "
            "'rollfric fit OUT/track.csv' fits mu later. Exit status 0; 2 for bad input "
            "(nothing written)."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric track clip.cine --setup setup.toml --out tracked --plot",
                       docs="docs/guide/info-track.md"))
    add_tracking_arguments(p)
    p.add_argument("--plot", action="store_true", help="also write overlays.png")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--overwrite", action="store_true",
                   help="write into an existing non-empty DIR: track's own files (track.csv, "
                        "track.json, overlays.png) are replaced, or removed when not written "
                        "this time; other files are left alone")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``rollfric track``: locate the ball, write track.csv and track.json.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options (:func:`register`).

    Returns
    -------
    int
        0.

    Raises
    ------
    rollfric.errors.InputError
        Bad input (nothing written); ``rollfric.cli.main.main`` reports it and exits with 2.
    """
    from rollfric.cli.messages import to_stderr

    with to_stderr("track"):  # the library's info and warnings
        return _run(args)


def _run(args) -> int:
    import json

    from rollfric.cli.measure import check_tracking_outputs, write_track_csv
    from rollfric.io.readers import open_recording
    from rollfric.measurement import measure
    from rollfric.output.atomic import write_text
    from rollfric.output.folder import staged_folder
    from rollfric.output.jsonfile import json_safe

    out = check_tracking_outputs(args, OUTPUTS, "track")
    source = open_recording(args.recording)  # tracked, then its overlay frames drawn
    track, info, _ = measure(source, args.setup, args.background, method=args.method,
                             angle=args.angle, fit=False, progress=not args.no_progress,
                             median_frames=args.median_frames, times=args.times,
                             background_from=args.background_from)
    with staged_folder(out, OUTPUTS, overwrite=args.overwrite, command="track") as tmp:
        write_track_csv(track, tmp / "track.csv")
        summary = {"setup": args.setup if args.setup is not None
                   else "the recording's attrs", **info.json_keys(track)}
        write_text(tmp / "track.json", json.dumps(json_safe(summary), indent=2) + "\n")
        if args.plot:
            from rollfric.output.overlay import plot_overlays

            plot_overlays(source, track, tmp / "overlays.png", info=info)
    print(f"ball found in {info.n_found} of {info.n_frames} frames -> {out}")
    return 0
