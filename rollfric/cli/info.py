"""``rollfric info``: what a recording holds, without measuring it."""

from __future__ import annotations

from rollfric.cli.helpformat import HelpFormatter, example

HELP = "what a recording holds (frames, size, bit depth, rates, shutter, trigger), unmeasured"


def register(sub) -> None:
    """Add the ``info`` subcommand and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subcommands of the ``rollfric`` parser.
    """
    p = sub.add_parser(
        "info", help=HELP, description=(
            "Print what a recording holds, reading only its header (and one frame): frame "
            "count, width and height, the stored dtype and the camera's effective bit depth, "
            "the frame rate the file states and the one its per-frame times give (both when "
            "they differ), the exposure in seconds, the start frame and trigger time, colour or "
            "mono, and the warnings rollfric measure would give on opening it. RECORDING is "
            "anything measure reads (TIFF stack, image folder, video, .cine, .cih/.cihx + "
            ".mraw, Zarr store). Exit status 0; 2 when it cannot be read (the reason on "
            "stderr)."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric info clip.cine",
                       docs="docs/guide/info-track.md"))
    p.add_argument("recording", metavar="RECORDING", help="TIFF stack, image folder, video, "
                   ".cine, .cih/.cihx (+ .mraw), or Zarr store")
    p.add_argument("--setup", metavar="SETUP.toml", default=None,
                   help="check the frame times against its camera.fps, as measure does "
                        "(default: against the rate the file states)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (keys n_frames, width, height, bit_depth, fps, "
                        "fps_timestamps, shutter_s, ...; null where the file says nothing)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``rollfric info``: print what the recording holds.

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
        An unreadable recording or setup; ``rollfric.cli.main.main`` reports it and exits with 2.
    """
    import json

    from rollfric.io.info import format_info, recording_info

    setup_fps = None
    if args.setup is not None:
        from rollfric.setup.model import load_setup

        setup_fps = load_setup(args.setup).fps
    info = recording_info(args.recording, setup_fps=setup_fps)
    print(json.dumps(info, indent=2) if args.json else format_info(info))
    return 0
