"""``rollfric validate`` and ``rollfric sweep`` (argparse only; the work loads in handlers)."""

from __future__ import annotations

from pathlib import Path

from rollfric.cli.helpformat import HelpFormatter, example
from sim.engines import ENGINES

_VALIDATE_HELP = """\
The main job: run one case end to end -- scenario -> sim (ground-truth trajectory) -> synth
(rendered 1000 Hz camera frames with a sensor model) -> rollfric (locate the ball, angles, fit
mu) -> metrics against the truth -- print a short summary and write a report directory (the
angle-vs-model plot, the centre-error histogram and error vs time, overlay frames, metrics.json,
the track and the truth).

Without CASE.toml it runs the built-in default: the thesis's 10 mm ball, mu = 0.0079, released
at 20 deg, thesis lighting (two lamps beside the camera), the "realistic" 8-bit sensor noise,
the full 1280 x 1024 thesis camera, 2 s of 1000 Hz frames (six half-swings; most of its time
is rendering; how long it takes: the end-to-end section of the benchmarks page,
docs/benchmarks.md).

CASE.toml has the sections [scenario] (the sim scenario form: [scenario.ball], [scenario.motion],
[scenario.engine], ...: the as-built truth), [render] (lighting, noise, motion_blur,
[render.sensor], [render.camera], ...), [lab] (the lab's setup file: nominal values, _u
tolerances, center_error_px) and [measure] (locator, fit, offset, oracle); see
docs/lab-validation.md. A plain sim scenario file (top-level [ball], [motion], ...) is accepted
too. Flags override the file.

Blind mode (the default): rollfric gets only what a lab has: the [lab] setup file (nominal
values, no center_px unless the lab measured it: the trough centre comes from its contour), the
recording and its background. --set measure.oracle=true hands it the exact setup and center_px.

Metrics: mu_true, mu_recovered, mu_bias_rel (against the configured mu), mu_engine (the same
fitter on the engine's ground-truth theta(t)), mu_engine_bias_rel, mu_pipeline_bias_rel (the
measurement against mu_engine: the pipeline's own bias), mu_stderr, mu_true_within_stderr,
center_rms_px / center_max_px / center_bias_x_px / center_bias_y_px (located centre minus
the rendered silhouette's centre), theta_rms_rad, found_fraction, and per-stage timings.
"""

_SWEEP_HELP = """\
Run a grid (or list) of validation cases on Dask distributed and collect one row per case
(parameters and metrics as columns) in DIR/results.parquet and DIR/results.csv, with plots of
the metrics against each swept parameter in DIR/plots/.

Every finished case is written at once to DIR/parts/<case_id>.parquet (case_id: a hash of the
case's full parameters), so an interrupted or crashed sweep loses nothing: run the same command
again and it resumes with the cases not yet done. A failed case is recorded with its error (and
retried on resume only with --retry-failed); a worker that dies is replaced and its case re-run.

By default a local cluster of worker processes (one renderer each, PYOPENGL_PLATFORM=egl) is
started; --scheduler ADDRESS uses an existing cluster instead (its workers must see DIR when
--keep-recordings is used). Example studies ship with the package: `rollfric sweep --list`.
Exit code 0 when every case is ok, 1 when some failed, 2 on bad input.

--from-recordings SRC measures the recordings a sweep kept in SRC (--keep-recordings) again with
the current code, without rendering: the same metrics, written to DIR (not SRC); with
--set measure.oracle=true the same recordings in oracle mode (setup from the recording).

SWEEP.toml:
  [sweep]   name, mode = "grid" | "list", seeds = N (repeat each case with render seeds 0..N-1)
  [base]    a case (same sections as `rollfric validate`'s CASE.toml)
  [grid]    "dotted.key" = [values...]   e.g. "render.sensor.read_noise" = [0, 8, 20]
  [[cases]] "dotted.key" = value ...     (mode = "list": one table per case)
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "validate", help="the main job: one case end to end against the truth, with a report",
        description=_VALIDATE_HELP, formatter_class=HelpFormatter,
        epilog=example("rollfric validate --out report",
                       "rollfric validate --lighting harsh --seed 3 --out report-harsh",
                       docs="docs/guide/validate.md"))
    p.add_argument("case", nargs="?", metavar="CASE.toml",
                   help="case (or plain scenario) TOML file; default: the built-in case")
    p.add_argument("--engine", choices=list(ENGINES),
                   help="physics engine for the ground truth (default: the case's, reference)")
    p.add_argument("--seconds", type=float, help="duration of the recording (s)")
    p.add_argument("--mu", type=float, help="configured rolling friction coefficient")
    p.add_argument("--lighting", help="synth lighting preset (thesis, dim, harsh, uneven, flat)")
    p.add_argument("--noise", help="synth sensor preset (none, realistic, noisy, 12bit, dark)")
    p.add_argument("--seed", type=int, help="seed of the sensor noise (render.seed)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override any case key, e.g. render.motion_blur=8 (repeatable)")
    p.add_argument("--out", default="rollfric-report", metavar="DIR",
                   help="report directory")
    p.add_argument("--keep-recording", action="store_true",
                   help="keep the rendered recording in DIR/recording.zarr")
    p.add_argument("--overwrite", action="store_true",
                   help="write into an existing non-empty DIR: the report's own files are "
                        "replaced (or removed when not written this time), others left alone; "
                        "without it an existing non-empty DIR is refused (exit 2)")
    p.add_argument("--json", action="store_true",
                   help="print the metrics as one JSON object instead of the summary")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=handle_validate)

    s = subparsers.add_parser(
        "sweep", help="many validation cases on Dask, one table row per case, with plots",
        description=_SWEEP_HELP, formatter_class=HelpFormatter,
        epilog=example("rollfric sweep --list", "rollfric sweep blur --out blur-study",
                       docs="docs/guide/sweep.md"))
    s.add_argument("sweep", nargs="?", metavar="SWEEP.toml",
                   help="sweep file, or the name of a shipped study (see --list)")
    s.add_argument("--out", metavar="DIR", help="results directory (required to run)")
    s.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of an existing Dask scheduler (default: a local cluster)")
    s.add_argument("--workers", type=int, default=2,
                   help="worker processes of the local cluster")
    s.add_argument("--keep-recordings", action="store_true",
                   help="keep every case's recording under DIR/recordings/ with index.csv")
    s.add_argument("--from-recordings", metavar="SRC",
                   help="no render: measure again the recordings a sweep kept in SRC "
                        "(--keep-recordings), with the current code; results into --out DIR "
                        "(another folder); --set takes only measure.* keys then")
    s.add_argument("--retry-failed", action="store_true",
                   help="on resume, run again the cases recorded as failed")
    s.add_argument("--list", action="store_true", help="list the shipped example sweeps")
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="set a case key in every case (the sweep's [base]), e.g. "
                        "measure.oracle=true: the same study measured otherwise (other case "
                        "ids: resume it with the same --set; repeatable)")
    s.add_argument("--dry-run", action="store_true",
                   help="print the cases (id and parameters) without running them")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.add_argument("--overwrite", action="store_true",
                   help="start afresh in a DIR that holds results (the sweep's own files there "
                        "are removed first, others stay); without it a DIR of the same sweep is "
                        "resumed and any other non-empty DIR is refused (exit 2)")
    s.set_defaults(func=handle_sweep)


def _parse_set(items: list[str]) -> dict:
    import tomllib

    from rollfric.errors import InputError

    out = {}
    for item in items:
        if "=" not in item:
            raise InputError(f"--set {item!r}: expected KEY=VALUE")
        key, text = (x.strip() for x in item.split("=", 1))
        try:
            value = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            value = text  # a bare word: a string
        out[key] = value
    return out


def handle_validate(args) -> int:
    import json
    import os

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    import synth.pipeline
    from rollfric.output.folder import check_folder, check_not_input
    from validation import case as case_mod
    from validation import case_dict as CD

    check_not_input(args.out, (args.case,))
    # a folder that is refused before the case is read (without the report's file names, which
    # only --overwrite needs: run_case checks them before any work)
    check_folder(args.out, {}, overwrite=args.overwrite, command="validate")
    overrides = _parse_set(args.set)
    if args.engine:
        overrides["scenario.engine.name"] = args.engine
    if args.seconds is not None:
        overrides["scenario.motion.seconds"] = args.seconds
    if args.mu is not None:
        overrides["scenario.motion.mu"] = args.mu
    if args.lighting:
        overrides["render.lighting"] = args.lighting
    if args.noise:
        overrides["render.noise"] = args.noise
    if args.seed is not None:
        overrides["render.seed"] = args.seed
    base = CD.load_case_dict(args.case) if args.case else CD.default_case_dict()
    case = case_mod.case_from_dict(CD.apply_overrides(base, overrides),
                                   source=args.case or "built-in case")
    # the render's fork server first: its imports (~1 s) on the other core while this process
    # imports the measurement and the report (~1.2 s)
    synth.pipeline.prepare_render(case.scene, case.scenario.n_samples)
    from validation import e2e

    result = e2e.run_case(case, keep_recording=args.keep_recording, report_dir=args.out,
                          progress=not args.no_progress and not args.json,
                          overwrite=args.overwrite)
    from validation import report

    if args.json:
        print(json.dumps(report.json_safe(result.metrics), sort_keys=True))
    else:
        print(report.summary_text(result, args.out))
    return 0


def handle_sweep(args) -> int:
    import os

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from rollfric.errors import InputError
    from validation import sweep as sweep_mod

    if args.list:
        for name, path, doc in sweep_mod.shipped_sweeps():
            print(f"{name:14s} {doc}   ({path})")
        return 0
    if args.from_recordings:
        from validation.sweep_table import recorded_sweep

        spec = recorded_sweep(args.from_recordings, _parse_set(args.set))
        if args.sweep and sweep_mod.load_sweep(args.sweep).name != spec.name:
            raise InputError(f"--from-recordings {args.from_recordings} holds sweep "
                             f"{spec.name!r}, not {args.sweep!r}")
        if args.out and Path(args.out).resolve() == Path(args.from_recordings).resolve():
            raise InputError("--out must be another folder than --from-recordings (the "
                             "recorded results stay as they are)")
        if args.keep_recordings:
            raise InputError("--keep-recordings with --from-recordings: the recordings stay "
                             "in the recorded sweep's folder")
    elif not args.sweep:
        raise InputError("give a SWEEP.toml (or a shipped study name, see --list)")
    else:
        spec = sweep_mod.load_sweep(args.sweep, _parse_set(args.set))
    if args.dry_run:
        for c in spec.cases:
            print(c.case_id, " ".join(f"{k}={v!r}" for k, v in c.params.items()))
        print(f"{len(spec.cases)} case(s)")
        return 0
    if not args.out:
        raise InputError("--out DIR is required to run a sweep")
    from validation.sweep_run import run_sweep  # the measurement's imports: not for --list

    summary = run_sweep(spec, args.out, scheduler=args.scheduler, n_workers=args.workers,
                        keep_recordings=args.keep_recordings,
                        retry_failed=args.retry_failed, progress=not args.no_progress,
                        overwrite=args.overwrite)
    print(summary.text())
    return 0 if summary.n_failed == 0 else 1
