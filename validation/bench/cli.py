"""``rollfric bench``: register the subcommand (argparse only; work in validation.bench.run)."""

from __future__ import annotations

from rollfric.cli.helpformat import HelpFormatter, example

SECTION_NAMES = ("fitting", "simulation", "rendering", "recognition", "end-to-end",
                 "sweeps")


def register(sub) -> None:
    p = sub.add_parser(
        "bench", help="speed and accuracy of every stage beside its baseline",
        description=(
            "Measure, in one run on this machine, every stage beside the baseline a user would "
            "pick instead: the least-squares fit vs the thesis's grid search; each physics "
            "engine's exact tangent contact vs a naive triangle mesh; the tile renderer vs "
            "plain full-frame pyrender; the default locator vs the thesis's locators, OpenCV "
            "HoughCircles and scikit-image RANSAC beside the Cramer-Rao bound; the default "
            "validate case end to end; and a sweep's cases/hour on a local 2-worker cluster and "
            "on a dask scheduler with workers started apart. Writes OUT/bench.md (a Markdown "
            "table) and OUT/bench.json. Times are medians of repeats; ratios are the headline."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric bench --quick --out bench-out",
                       docs="docs/guide/bench.md"))
    p.add_argument("--out", default="bench-out", metavar="DIR", help="output directory")
    p.add_argument("--quick", action="store_true",
                   help="smaller inputs and fewer repeats (under 2 minutes, for CI smoke runs)")
    p.add_argument("--only", nargs="+", choices=SECTION_NAMES, metavar="SECTION",
                   help=f"run only these sections ({', '.join(SECTION_NAMES)})")
    p.add_argument("--overwrite", action="store_true",
                   help="replace bench.md and bench.json in an existing non-empty DIR (other "
                        "files are left alone); without it such a DIR is refused (exit 2)")
    p.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from validation.bench.run import run_bench

    rows, meta = run_bench(args.out, quick=args.quick, sections=args.only,
                           overwrite=args.overwrite)
    print((Path(args.out) / "bench.md").read_text())
    return 0
