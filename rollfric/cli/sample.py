"""``rollfric sample``: the shipped sample recording, written where a user can measure it."""

from __future__ import annotations

import shlex

from rollfric.cli.helpformat import HelpFormatter, example

HELP = "write the shipped sample recording (400 frames) and its setup.toml to a folder"


def register(sub) -> None:
    """Add the ``sample`` subcommand and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subcommands of the ``rollfric`` parser.
    """
    p = sub.add_parser(
        "sample", help=HELP, description=(
            "Write DIR/frames.tif (400 frames at 1000 Hz of a 10 mm steel ball rolling in an "
            "85.3 mm trough, rendered by rollfric's validation suite with room lighting and "
            "sensor noise; a lossless compressed TIFF stack) and DIR/setup.toml (what the lab "
            "knows: trough, ball, camera), then print the rollfric measure command to run on "
            "them. Exit status 0; 2 when DIR exists and is not empty (without --overwrite) or "
            "cannot be written."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric sample demo",
                       "rollfric measure demo/frames.tif --setup demo/setup.toml "
                       "--out demo/result --plot",
                       docs="docs/guide/measure.md"))
    p.add_argument("dir", metavar="DIR", help="folder to write (created when absent)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace frames.tif and setup.toml in an existing DIR (its other files "
                        "are left alone)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``rollfric sample``: write the sample and print the command that measures it.

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
        DIR may not be written; ``rollfric.cli.main.main`` reports it and exits with 2.
    """
    from rollfric.sample import RECORDING, SETUP, write_sample

    out = write_sample(args.dir, overwrite=args.overwrite)
    size = (out / RECORDING).stat().st_size
    print(f"wrote {out / RECORDING} ({size / 1e6:.1f} MB, 400 frames) and {out / SETUP}")
    print("measure it with:")
    q = shlex.quote
    print(f"  rollfric measure {q(str(out / RECORDING))} --setup {q(str(out / SETUP))} "
          f"--out {q(str(out / 'result'))}")
    return 0
