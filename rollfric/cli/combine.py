"""``rollfric combine``: repeated releases of one setup combined into one mu."""

from __future__ import annotations

from rollfric.cli.helpformat import HelpFormatter, example

HELP = "combine repeated releases of one setup (fit.json files) into one mu"


def register(sub) -> None:
    """Add the ``combine`` command to the CLI.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``rollfric`` parser; the command's handler is :func:`run`.
    """
    p = sub.add_parser(
        "combine", help=HELP, description=(
            "Combine N releases of one ball in one setup (the fit.json files of rollfric "
            "measure or rollfric fit): the weighted mean of their mu, weighted by the "
            "independent (statistical) part of each budget; its uncertainty keeps the shared "
            "part (the setup's inputs, common to every release), which does not average down. "
            "The scatter is checked with the Birge ratio; above its 95 % range the result is "
            "widened and suspect. Exit status 0: ok; 2: bad input (files of different setups, "
            "not a fit.json, fewer than two runs; nothing written); 3: a result to be looked "
            "at (written, the reasons on stderr)."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric combine run1/fit.json run2/fit.json run3/fit.json "
                       "--out combined.json",
                       docs="docs/guide/combine.md"))
    p.add_argument("fits", nargs="+", metavar="FIT.json", help="the releases' fit.json files")
    p.add_argument("--out", default=None, metavar="COMBINED.json",
                   help="where to write the result (default: printed only)")
    p.add_argument("--include-suspect", action="store_true",
                   help="keep runs whose quality is suspect (the result is then suspect); by "
                        "default they are left out with a warning")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing COMBINED.json; without it an existing output is "
                        "refused (exit 2)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``rollfric combine``: read the fit.json files, combine, print and write.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options of :func:`register`'s parser.

    Returns
    -------
    int
        Exit status: 0 ok, 3 a suspect result (written, reasons on stderr).

    Raises
    ------
    rollfric.errors.InputError
        On bad input (the CLI turns it into exit status 2).
    """
    from rollfric.cli.messages import to_stderr

    with to_stderr("combine"):
        return _run(args)


def _run(args) -> int:
    import json
    import sys

    from rollfric.output.atomic import write_text
    from rollfric.output.folder import check_file, check_not_input
    from rollfric.output.jsonfile import json_safe
    from rollfric.uncertainty.combine import combine_files, format_summary

    out = None
    if args.out is not None:
        check_not_input(args.out, args.fits)
        out = check_file(args.out, overwrite=args.overwrite)
    combined, _ = combine_files(args.fits, include_suspect=args.include_suspect)
    if out is not None:
        write_text(out, json.dumps(json_safe(combined.to_json()), indent=2) + "\n")
    print(format_summary(combined, out))
    if not combined.quality_reasons:
        return 0
    print(f"rollfric combine: result to be looked at ({len(combined.quality_reasons)} "
          "reason(s); written with quality = suspect):", file=sys.stderr)
    for r in combined.quality_reasons:
        print(f"  [{r['code']}] {r['message']}", file=sys.stderr)
    return 3
