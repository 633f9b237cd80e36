"""``rollfric simulate``: ground-truth trajectories (argparse only; engines load in the handler)."""

from __future__ import annotations

from rollfric.cli.helpformat import HelpFormatter, example
from sim.engines import ENGINES

_HELP = """\
Simulate a ball rolling in a cylindrical trough and write its ground-truth trajectory at the
camera rate: CSV (t_s, theta_rad, theta_dot_rad_s, ball centre x/y/z in m, quaternion wxyz,
angular velocity in rad/s, normal force in N, slip speed in m/s; NaN where the engine has no
value) plus a JSON sidecar with the full scenario, engine version and settings.

Engines: reference (equation of motion, DOP853 to 1e-10: the truth), mujoco, pybullet.
Surfaces (mujoco/pybullet): tangent (default: one exact contact with the cylinder, unbiased),
mesh and heightfield (the naive faceted troughs; they bias mu, which is why they are offered).
A scenario TOML file (docs/formats/trajectory.md) may be given instead of, or as well as, flags;
flags override the file. mu is defined by M = mu * r * N.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("simulate", help="ground-truth trajectory from an engine",
                              description=_HELP,
                              formatter_class=HelpFormatter,
                              epilog=example("rollfric simulate --ball 10mm --mu 0.0079 "
                                             "--theta0-deg 20 --seconds 2 --out traj.csv",
                                             docs="docs/guide/simulate.md"))
    p.add_argument("scenario", nargs="?", help="scenario TOML file (optional)")
    p.add_argument("--engine", choices=list(ENGINES),
                   help="physics engine (default: the scenario's, reference)")
    p.add_argument("--surface", choices=["tangent", "mesh", "heightfield"],
                   help="the trough's contact surface, mujoco/pybullet (default: tangent)")
    p.add_argument("--ball", choices=["1.58mm", "10mm", "12.69mm"],
                   help="a thesis ball (sets diameter and mass)")
    p.add_argument("--mu", type=float, help="rolling friction coefficient (M = mu r N)")
    p.add_argument("--ball-diameter-mm", type=float,
                   help="ball diameter (mm; default: the thesis's 10 mm ball)")
    p.add_argument("--ball-mass-g", type=float, help="ball mass (g)")
    p.add_argument("--cylinder-radius-mm", type=float,
                   help="the trough's inner radius (mm; default: the thesis's 85.3 mm)")
    p.add_argument("--theta0-deg", type=float, help="release angle (deg, + = right)")
    p.add_argument("--theta-dot0-deg-s", type=float, help="initial angular speed (deg/s)")
    p.add_argument("--seconds", type=float, help="duration (s)")
    p.add_argument("--fps", type=float, help="sample (camera) rate (Hz)")
    p.add_argument("--seed", type=int, help="seed of the engine's random draws (default 0)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="engine option, e.g. timestep_s=1e-4 (repeatable)")
    p.add_argument("--progress", action="store_true", help="show a progress bar")
    p.add_argument("--out", required=True, help="output CSV path (sidecar: same name .json)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing CSV and sidecar (without it: refused, exit 2)")
    p.set_defaults(func=handle)


def _parse_option(text: str):
    from sim.scenario import ScenarioError

    if "=" not in text:
        raise ScenarioError(f"--option {text!r}: expected KEY=VALUE")
    key, value = text.split("=", 1)
    for conv in (int, float):
        try:
            return key.strip(), conv(value)
        except ValueError:
            pass
    return key.strip(), value.strip()


def scenario_from_args(args):
    from sim.scenario import Scenario, load_scenario, to_si

    base = load_scenario(args.scenario) if args.scenario else Scenario()
    changes: dict = {}
    if args.ball:
        t = Scenario.thesis(args.ball)
        changes.update(ball_diameter=t.ball_diameter, ball_mass=t.ball_mass)
    simple = {"mu": ("mu", ""), "ball_diameter_mm": ("ball_diameter", "mm"),
              "ball_mass_g": ("ball_mass", "g"), "cylinder_radius_mm": ("cylinder_radius", "mm"),
              "theta0_deg": ("theta0", "deg"), "theta_dot0_deg_s": ("theta_dot0", "deg"),
              "seconds": ("duration", ""), "fps": ("fps", "")}
    for arg, (field, unit) in simple.items():
        value = getattr(args, arg)
        if value is not None:
            changes[field] = to_si(value, unit)
    if args.seed is not None:
        changes["seed"] = args.seed
    if args.engine and args.engine != base.engine:
        changes["engine"] = args.engine
        changes["engine_options"] = {}
        if args.surface is None:
            changes["surface"] = "tangent"
    if args.surface:
        changes["surface"] = args.surface
    if args.option:
        opts = dict(changes.get("engine_options", base.engine_options))
        opts.update(_parse_option(o) for o in args.option)
        changes["engine_options"] = opts
    return base.replace(**changes) if changes else base


def check_outputs(out, *, overwrite: bool, inputs=()):
    """The CSV and its sidecar, checked before any work (rollfric.output.folder)."""
    from rollfric.output.folder import check_file, check_not_input
    from sim.trajectory import sidecar_path

    side = sidecar_path(out, check=True)
    for p, what in ((out, "--out"), (side, "the sidecar")):
        check_not_input(p, inputs, what)
        check_file(p, overwrite=overwrite, what=what)
    return side


def handle(args) -> int:
    import sim

    check_outputs(args.out, overwrite=args.overwrite, inputs=(args.scenario,))
    scenario = scenario_from_args(args)
    traj = sim.simulate(scenario, progress=args.progress)
    path = traj.to_csv(args.out)
    th = traj.theta
    print(f"{scenario.engine}/{scenario.surface}: {len(traj)} samples, theta "
          f"{th.min():+.5f}..{th.max():+.5f} rad, wall {traj.meta.get('wall_time_s', 0):.2f} s "
          f"-> {path}")
    return 0
