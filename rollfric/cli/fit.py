"""``rollfric fit``: fit mu to an angle series in a CSV file."""

from __future__ import annotations

import argparse

from rollfric.cli.helpformat import HelpFormatter, example
from rollfric.registry import FIT_METHODS

HELP = "fit mu to a track (t_s, theta_rad) with the equation of motion"


def register(sub) -> None:
    """Add the ``fit`` command to the CLI.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``rollfric`` parser; the command's handler is :func:`run`.
    """
    p = sub.add_parser(
        "fit", help=HELP, description=(
            "Fit the rolling friction coefficient mu (M = mu r N) to an angle series theta(t). "
            "TRACK.csv needs columns t_s and theta_rad (others are ignored but found: rows with "
            "an empty theta_rad or found = 0, e.g. frames where no ball was found, are left "
            "out). Writes a JSON file "
            "with mu, mu_stderr, theta0_rad, omega0_rad_s, rms_residual_rad, method and more, "
            "and the quality checks' verdict (quality: ok or suspect, quality_reasons). Exit "
            "status 0: ok; 2: bad input (nothing written); 3: a suspect fit (written, the "
            "reasons on stderr)."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric fit result/track.csv --setup setup.toml --out fit.json --plot",
                       docs="docs/guide/fit.md"))
    p.add_argument("track", metavar="TRACK.csv", help="CSV with columns t_s,theta_rad")
    p.add_argument("--setup", required=True, metavar="SETUP.toml",
                   help="lab setup file (cylinder radius, ball diameter and mass, camera)")
    p.add_argument("--out", required=True, metavar="FIT.json", help="where to write the result")
    p.add_argument("--method", default="lsq", choices=list(FIT_METHODS),
                   help="lsq: least squares of the equation of motion (default); paper1_eps: "
                        "the first paper's analytic eps iteration (small ball, small angles); "
                        "paper2_grid: the second paper's grid search (slow)")
    p.add_argument("--offset", action="store_true",
                   help="also fit a constant angle offset of the trough bottom")
    add_model_argument(p)
    p.add_argument("--plot", action="store_true",
                   help="also write the angle-vs-model figure beside FIT.json (.png) and the "
                        "uncertainty budget's bar chart (_budget.png)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing FIT.json (and its figures); without it an existing "
                        "output is refused (exit 2)")
    add_budget_arguments(p)
    p.set_defaults(func=run)


def add_model_argument(parser) -> None:
    """The ``--model`` option of ``rollfric fit`` and ``rollfric measure``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser.
    """
    parser.add_argument("--model", default="coulomb", choices=["coulomb", "speed", "velocity"],
                        help="friction law fitted: coulomb (constant mu, default) or speed "
                             "(mu0 + mu1 |theta'|, mu = mu0; 'velocity' is the same); either "
                             "way the laws are tested against each other (fit.json "
                             "friction_law; lsq only)")


def add_budget_arguments(parser) -> None:
    """The uncertainty budget's options of ``rollfric fit`` and ``rollfric measure``.

    Kept here, not in :mod:`rollfric.uncertainty.budget`, so that building the parser (``--help``)
    imports neither SciPy nor numba.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser; ``--fit-length``, ``--monte-carlo``, ``--seed``,
        ``--second-order`` and ``--first-order`` (deprecated, no effect) are added.
    """
    parser.add_argument("--fit-length", action="store_true",
                        help="self-calibration: also fit L = R - r (the radius of the ball "
                             "centre's path); mu and its budget then use the fitted L")
    parser.add_argument("--monte-carlo", type=int, default=0, metavar="N",
                        help="check the budget by N Monte-Carlo draws of the uncertain inputs "
                             "(JCGM 101), each a re-fit")
    parser.add_argument("--seed", type=int, default=0, help="seed of the Monte-Carlo draws")
    parser.add_argument("--second-order", action="store_true",
                        help="add the second-order row to the budget (GUM 5.1.2: the inputs' "
                             "interactions and curvature; 4 re-fits per pair of uncertain "
                             "inputs and 2 per input)")
    # deprecated, no effect (the budget is first order unless --second-order is given):
    # accepted for old scripts, hidden from --help
    parser.add_argument("--first-order", action="store_true", help=argparse.SUPPRESS)


def read_track(path):
    """t_s and theta_rad columns of a track CSV, as float arrays (empty cells -> NaN).

    A ``found`` column (as ``rollfric measure`` writes it) is honoured: a row marked 0 is left
    out like an empty angle (a warning says how many had an angle), so frames can be struck
    out by hand.

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file.

    Returns
    -------
    t : numpy.ndarray
        Times, s.
    theta : numpy.ndarray
        Angles, rad (NaN for empty cells).

    Raises
    ------
    rollfric.errors.InputError
        If the file is missing, a folder or not a readable CSV, lacks a column, holds a
        non-numeric value or a ``found`` other than 1/0/true/false, or fails
        :func:`check_track`.
    """
    import logging

    import numpy as np
    import pandas as pd

    from rollfric.errors import InputError

    try:
        df = pd.read_csv(path)
    except FileNotFoundError:
        raise InputError(f"track file not found: {path}") from None
    except IsADirectoryError:
        raise InputError(f"track file {path} is a directory") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError,
            ValueError) as exc:
        raise InputError(f"{path}: not a readable CSV file: {exc}") from None
    missing = [c for c in ("t_s", "theta_rad") if c not in df.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)} "
                         f"(found: {', '.join(map(str, df.columns))})")
    try:
        t = pd.to_numeric(df["t_s"], errors="raise").to_numpy(float)
        theta = pd.to_numeric(df["theta_rad"], errors="raise").to_numpy(float)
    except (ValueError, TypeError) as exc:
        raise InputError(f"{path}: non-numeric value in t_s or theta_rad: {exc}") from None
    if "found" in df.columns:  # rollfric measure's column: a row marked 0 is not a sample
        found = df["found"].map(lambda v: _FOUND.get(str(v).strip().lower()))
        if found.isna().any():
            i = int(np.flatnonzero(found.isna().to_numpy())[0])
            raise InputError(f"{path}: row {i + 1} has found = {df['found'].iloc[i]!r}; "
                             "found must be 1 or 0 (true or false)")
        dropped = ~found.to_numpy(bool) & np.isfinite(theta)
        if dropped.any():
            logging.getLogger(__name__).warning(
                f"{path}: {int(dropped.sum())} row(s) with found = 0 and an angle left out")
            theta = np.where(dropped, np.nan, theta)
    if "still" in df.columns:  # rollfric measure's held start and rest: not the motion
        still = df["still"].fillna("").astype(str).str.strip().isin(("held", "rest"))
        held = still.to_numpy(bool) & np.isfinite(theta)
        if held.any():
            logging.getLogger(__name__).warning(
                f"{path}: {int(held.sum())} row(s) marked still (held or rest) left out")
            theta = np.where(held, np.nan, theta)
    return check_track(t, theta, path)


_FOUND = {"1": True, "true": True, "1.0": True, "0": False, "false": False, "0.0": False}


def check_track(t, theta, path, fps: float | None = None):
    """(t, theta) if they can be an angle series; InputError naming the file otherwise.

    Every row needs a finite time, and the times must increase; theta may be empty (NaN: no
    ball found) but a value must be finite and an angle in radians (|theta| <= pi); with the
    setup's ``fps``, the span of the times may not hold more than the sample limit
    (:data:`rollfric.io.limits.MAX_SAMPLES`).

    Parameters
    ----------
    t : numpy.ndarray
        Times, s.
    theta : numpy.ndarray
        Angles, rad (NaN: no ball).
    path : str or os.PathLike
        The file they came from, for messages.
    fps : float or None
        The setup's frame rate, Hz; None skips the sample limit.

    Returns
    -------
    t, theta : numpy.ndarray
        The inputs, unchanged.

    Raises
    ------
    rollfric.errors.InputError
        If a time is not finite, the times do not increase, an angle is infinite or beyond
        pi in size, or the span exceeds the sample limit.
    """
    import math

    import numpy as np

    from rollfric.errors import InputError
    from rollfric.io.limits import MAX_SAMPLES

    bad = ~np.isfinite(t)
    if bad.any():
        raise InputError(f"{path}: t_s is empty or not finite in {int(bad.sum())} row(s), the "
                         f"first data row {int(np.argmax(bad)) + 1}")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        i = int(np.argmax(~(np.diff(t) > 0)))
        raise InputError(f"{path}: the times t_s do not increase (data rows {i + 1} and "
                         f"{i + 2}: {t[i]:g}, {t[i + 1]:g})")
    big = np.isinf(theta) | (np.abs(np.nan_to_num(theta)) > math.pi)
    if big.any():
        i = int(np.argmax(big))
        raise InputError(f"{path}: theta_rad = {theta[i]:g} in data row {i + 1} is not an angle "
                         "in radians (|theta| <= pi; degrees by mistake?)")
    if fps is not None and t.size > 1 and (t[-1] - t[0]) * fps > MAX_SAMPLES:
        raise InputError(f"{path}: the times span {t[-1] - t[0]:g} s, {(t[-1] - t[0]) * fps:.3g} "
                         f"frames at {fps:g} Hz: more than the limit of {MAX_SAMPLES:,} samples")
    return t, theta


def check_outputs(out, *, plot: bool, overwrite: bool, inputs=()):
    """The paths ``rollfric fit`` writes (FIT.json; with ``plot`` FIT.png and FIT_budget.png),
    checked before any work (:mod:`rollfric.output.folder`); returns the three paths.

    Parameters
    ----------
    out : str or os.PathLike
        The ``--out`` path (FIT.json).
    plot : bool
        Whether the figures will be written.
    overwrite : bool
        Whether existing outputs may be replaced.
    inputs : iterable of path
        The command's input files, which no output may be.

    Returns
    -------
    out, png, budget_png : pathlib.Path
        FIT.json, FIT.png and FIT_budget.png.

    Raises
    ------
    rollfric.output.folder.OutputError
        If two outputs are one path, an output is an input, or an output exists without
        ``overwrite`` (the figures checked only with ``plot`` or ``overwrite``) or cannot be
        written.
    """

    from rollfric.output.folder import check_distinct, check_file, check_not_input, named

    out = named(out)  # "." and "..": a folder, refused as one by check_file
    png = out.with_suffix(".png")
    budget_png = out.with_name(out.stem + "_budget.png")
    check_distinct([out, png, budget_png], "--out and its figures (--plot)")
    for p in (out, png, budget_png):
        check_not_input(p, inputs)
    check_file(out, overwrite=overwrite)
    if plot or overwrite:
        for p in (png, budget_png):
            check_file(p, overwrite=overwrite, what="the figure")
    return out, png, budget_png


def run(args) -> int:
    """Run ``rollfric fit``: read the track and setup, fit mu, write FIT.json (and figures).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options of :func:`register`'s parser.

    Returns
    -------
    int
        Exit status: 0 ok, 3 a suspect fit (written, reasons on stderr).

    Raises
    ------
    rollfric.errors.InputError
        On bad input (the CLI turns it into exit status 2).
    """
    from rollfric.cli.messages import to_stderr

    with to_stderr("fit"):  # the library's info and warnings on stderr
        return _run(args)


def _run(args) -> int:
    from rollfric.fit.estimate import fit_mu
    from rollfric.output.folder import remove_stale
    from rollfric.output.jsonfile import save_fit
    from rollfric.setup.model import load_setup
    from rollfric.uncertainty.law import fitted_model, verdict
    from rollfric.uncertainty.measured import Measurement
    from rollfric.uncertainty.report import run_budget, with_budget_reason

    out, png, budget_png = check_outputs(args.out, plot=args.plot, overwrite=args.overwrite,
                                         inputs=(args.track, args.setup))
    setup = load_setup(args.setup)
    t, theta = check_track(*read_track(args.track), args.track, fps=setup.fps)
    kw = {"model": fitted_model(args.model)} if args.method == "lsq" else {}
    result = fit_mu(t, theta, setup, method=args.method, offset=args.offset, **kw)
    meas = Measurement(setup=setup, t=t, theta=theta)
    keys, budget = run_budget(meas, result, args)
    result = with_budget_reason(result, budget)
    result, keys["friction_law"] = verdict(meas, result, args.model)
    # the setup it was fitted with, so that runs can be compared (rollfric combine)
    save_fit(result, out, **keys, setup=setup.to_toml_dict())
    if args.plot:
        from rollfric.output.plots import plot_budget, plot_fit

        plot_fit(t, theta, result, png)
        if budget is not None:
            plot_budget(budget, budget_png)
    if args.overwrite:  # figures of an earlier fit do not stay beside this one
        written = {png, budget_png} if args.plot and budget is not None else \
            {png} if args.plot else set()
        remove_stale(out.parent, [p.name for p in (png, budget_png) if p not in written])
    unc = f"+- {result.mu_stderr:.2g} (standard error)" if budget is None else \
        f"+- {budget.u_mu:.2g} (u), U = {budget.U_mu:.2g} (k = 2)"
    mu = result.mu if budget is None else budget.mu
    print(f"mu = {mu:.6f} {unc} ({result.method}), "
          f"rms residual {result.rms_residual:.3g} rad, {result.n_samples} samples -> {out}")
    return report_quality("fit", result)


def report_quality(command: str, result) -> int:
    """Print a suspect result's reasons on stderr; the exit status: 0 ok, 3 suspect.

    Parameters
    ----------
    command : str
        The command's name, for the message.
    result : FitResult
        The result; suspect when its ``quality_reasons`` are not empty.

    Returns
    -------
    int
        0 when ok, 3 when suspect.
    """
    import sys

    if not result.quality_reasons:
        return 0
    print(f"rollfric {command}: suspect measurement ({len(result.quality_reasons)} reason(s); "
          "written with quality = suspect):", file=sys.stderr)
    for r in result.quality_reasons:
        print(f"  [{r.code}] {r.message}", file=sys.stderr)
    return 3
