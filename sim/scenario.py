"""Scenario: everything that defines one simulated run, in SI units.

A scenario file is TOML in bench units (mm, g, Hz, degrees), a superset of the lab setup file
(``rollfric.setup.model``): every key is optional and defaults to the thesis's 10 mm ball::

    [cylinder]
    radius_mm = 85.3
    ovality_mm = 0.0        # out-of-round bore: D_max - D_min of an ellipse (sim.section)
    ovality_angle_deg = 0.0 # its major axis from the horizontal, counter-clockwise
    tilt_deg = 0.0          # the axis tilted along its length (> 0: the far end up): the
                            # ball also rolls along the trough (mujoco, pybullet only)
    [ball]
    diameter_mm = 10.0
    mass_g = 4.07612
    [camera]
    fps = 1000
    pixel_size_mm = 0.1343
    [environment]
    gravity_m_s2 = 9.81
    air_density_kg_m3 = 0.0 # air drag on the ball, off; room air 1.2 (sim.losses)
    air_cd = 0.47           # the ball's drag coefficient
    air_drag = "constant"   # "constant": air_cd; "law": rollfric.fit.air's drag law (Cd at the
                            # instant's Re, wall factor) with buoyancy and added mass
    [motion]
    mu = 0.0079
    theta0_deg = 20.0
    theta_dot0_deg_s = 0.0
    seconds = 4.0
    mu_speed_s_m = 0.0      # mu(v) = mu + mu_speed_s_m v, v the centre's speed (sim.losses)
    [engine]
    name = "reference"      # reference | mujoco | pybullet
    surface = "tangent"     # tangent (accurate) | mesh | heightfield (naive, biased)
    seed = 0
    [engine.options]        # engine settings, see sim.engines.<name>.DEFAULTS
    timestep_s = 1e-4
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from rollfric.io.limits import MAX_SAMPLES
from rollfric.setup.model import THESIS_BALLS, THESIS_TROUGH_RADIUS, Setup
from rollfric.setup.schema import (
    BENCH_GRAM,
    BENCH_MM,
    DEG,
    NONE,
    PLAUSIBLE,
    Key,
    Messages,
    Schema,
    check_file,
    read_section,
)
from rollfric.setup.tomlfile import read_toml
from sim.engines import ENGINES
from sim.errors import ScenarioError
from sim.section import Section

SURFACES = {
    "reference": ("tangent",),
    "mujoco": ("tangent", "mesh", "heightfield"),
    "pybullet": ("tangent", "mesh", "heightfield"),
}
MAX_THETA0_DEG = 80.0
MAX_OVALITY = 0.1  # of the mean radius
MAX_TILT_DEG = 10.0
AIR_DRAGS = ("constant", "law")


# fields written only when not zero (sim.section's out-of-round and tilted trough)
_OPTIONAL_FIELDS = ("ovality", "ovality_angle", "tilt")


def _option_defaults(engine: str) -> dict:
    return ENGINES.load(engine).DEFAULTS


_POSITIVE, _FINITE = "must be a positive number", "must be a finite number"
_NONNEG = "must be a finite number >= 0"
# The Python form's fields, in the order they are checked (rollfric.setup.schema)
FIELDS = Schema(
    sections={"fields": (
        *(Key(name, sign=">0", plausible=name if name in PLAUSIBLE else None, hint=_POSITIVE)
          for name in ("ball_diameter", "ball_mass", "cylinder_radius", "duration", "fps",
                       "gravity", "pixel_size")),
        *(Key(name, hint=_FINITE) for name in ("mu", "theta0", "theta_dot0")),
        *(Key(name, sign=">=0", hint=_NONNEG) for name in ("mu_speed", "air_density",
                                                           "air_cd")),
        Key("air_drag", "any", choices=AIR_DRAGS),
        *(Key(name, hint=_FINITE) for name in ("ovality", "ovality_angle", "tilt")),
        Key("seed", "int", sign=">=0", hint="must be a non-negative integer"),
        Key("engine_options", "table", hint="must be a table"))},
    error=ScenarioError,
    messages=Messages(hint="{key} {hint}, got {value!r}", label="{key}",
                      choice="{key} must be one of {known}, got {value!r}"),
)


def _check_trough(s: Scenario) -> None:
    """The bore's ovality and tilt within their ranges; the ball fits the trough."""
    if not 0 <= s.ovality <= MAX_OVALITY * s.cylinder_radius:
        raise ScenarioError(
            f"ovality ({s.ovality * 1e3:g} mm) must be between 0 and "
            f"{MAX_OVALITY:g} x the radius ({MAX_OVALITY * s.cylinder_radius * 1e3:g} mm)")
    if abs(s.tilt) > math.radians(MAX_TILT_DEG):
        raise ScenarioError(f"tilt ({math.degrees(s.tilt):g} deg) is beyond "
                            f"+-{MAX_TILT_DEG:g} deg")
    if s.ball_diameter >= 2 * s.cylinder_radius:
        raise ScenarioError(
            f"ball_diameter ({s.ball_diameter * 1e3:g} mm) must be smaller than the "
            f"trough diameter (2 x cylinder_radius = {s.cylinder_radius * 2e3:g} mm)")


def _check_swing(s: Scenario) -> None:
    """The release angle, and the highest angle its speed reaches, within the trough wall."""
    if abs(s.theta0) > math.radians(MAX_THETA0_DEG):
        raise ScenarioError(
            f"theta0 ({math.degrees(s.theta0):g} deg) is beyond +-{MAX_THETA0_DEG:g} deg: "
            "the ball would leave the trough wall or slip")
    # energy of rolling without slipping, (7/10) m (L theta')^2 = m g L (cos th - cos th0):
    # the highest angle the release speed reaches without friction
    try:
        cos_max = math.cos(s.theta0) - 0.7 * s.track_radius * s.theta_dot0 ** 2 / s.gravity
    except OverflowError:
        cos_max = -math.inf
    if cos_max < math.cos(math.radians(MAX_THETA0_DEG)):
        reach = "over the top" if cos_max < -1 else \
            f"to {math.degrees(math.acos(cos_max)):.4g} deg"
        raise ScenarioError(
            f"theta_dot0 ({math.degrees(s.theta_dot0):g} deg/s) at theta0 "
            f"{math.degrees(s.theta0):g} deg would swing the ball {reach}, beyond "
            f"+-{MAX_THETA0_DEG:g} deg: it would leave the trough wall or slip")


def _check_engine(s: Scenario) -> None:
    """A known engine, a surface it offers, and a trough and losses it can simulate."""
    if s.engine not in ENGINES:
        raise ScenarioError(f"unknown engine {s.engine!r} (known: {', '.join(ENGINES)})")
    if s.surface not in SURFACES[s.engine]:
        raise ScenarioError(
            f"surface {s.surface!r} is not offered by engine {s.engine!r} "
            f"(known: {', '.join(SURFACES[s.engine])})")
    if s.tilt != 0.0 and s.engine == "reference":
        raise ScenarioError(
            "the reference engine integrates the planar equation of motion: a trough "
            "tilted along its length (cylinder.tilt_deg) makes the ball also roll along "
            "it, a 3D motion; simulate it with engine mujoco or pybullet")
    if s.ovality != 0.0 and s.engine == "reference" and (
            s.mu_speed != 0.0 or s.air_density != 0.0):
        raise ScenarioError(
            "the reference's out-of-round trough (cylinder.ovality_mm) has no "
            "speed-dependent friction or air drag (sim.losses): use one or the other, or "
            "engine mujoco or pybullet")
    if (s.tilt != 0.0 or s.ovality != 0.0) and s.surface != "tangent":
        raise ScenarioError(
            f"surface {s.surface!r} is a round trough of limited length; an "
            "out-of-round (cylinder.ovality_mm) or tilted (cylinder.tilt_deg) trough needs "
            "surface \"tangent\"")


def _check_engine_options(s: Scenario) -> dict:
    """The engine settings, each known to the engine and of its default's type (> 0)."""
    defaults = _option_defaults(s.engine)
    for key, value in s.engine_options.items():
        if key not in defaults:
            raise ScenarioError(
                f"unknown option {key!r} for engine {s.engine!r} "
                f"(known: {', '.join(defaults) or 'none'})")
        want = type(defaults[key])
        if want is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, want) or (want is int and isinstance(value, bool)):
            raise ScenarioError(f"engine option {key} must be {want.__name__}, "
                                f"got {value!r}")
        if isinstance(value, (int, float)) and not isinstance(value, bool) and value <= 0:
            raise ScenarioError(f"engine option {key} must be positive, got {value!r}")
    return dict(sorted(s.engine_options.items()))


@dataclasses.dataclass(frozen=True)
class Scenario:
    """One simulated run (SI units: m, kg, s, rad).

    Defaults are the thesis's 10 mm ball on its 85.3 mm trough, mu = 0.0079, released at rest
    at 20 degrees, 4 s sampled at 1000 Hz, exact reference engine.
    """

    ball_diameter: float = THESIS_BALLS["10mm"][0]
    ball_mass: float = THESIS_BALLS["10mm"][1]
    cylinder_radius: float = THESIS_TROUGH_RADIUS
    mu: float = 0.0079
    theta0: float = math.radians(20.0)
    theta_dot0: float = 0.0
    duration: float = 4.0
    fps: float = 1000.0
    engine: str = "reference"
    surface: str = "tangent"
    engine_options: dict = dataclasses.field(default_factory=dict, hash=False)
    seed: int = 0
    gravity: float = 9.81
    pixel_size: float = 0.1343e-3
    # losses the fitter does not assume (sim.losses): mu(v) = mu + mu_speed v (s/m), air drag
    mu_speed: float = 0.0
    air_density: float = 0.0  # kg/m^3; 0: no drag
    air_cd: float = 0.47
    air_drag: str = "constant"  # "constant" (air_cd) or "law" (rollfric.fit.air, the fitter's)
    ovality: float = 0.0  # m, D_max - D_min of an elliptic bore (sim.section.Section)
    ovality_angle: float = 0.0  # rad, its major axis from world x, counter-clockwise
    tilt: float = 0.0  # rad, the trough axis tilted along its length, the far end up for
    # tilt > 0: in the trough's frame gravity is g (0, -cos tilt, sin tilt), the ball drifts
    # along +z, towards the camera

    def __post_init__(self) -> None:
        for name, value in read_section(FIELDS, "fields", {
                key.name: getattr(self, key.name) for key in FIELDS.sections["fields"]},
                "scenario").items():
            object.__setattr__(self, name, value)
        if self.mu < 0:
            raise ScenarioError(f"mu must not be negative, got {self.mu!r}")
        _check_trough(self)
        _check_swing(self)
        _check_engine(self)
        object.__setattr__(self, "engine_options", _check_engine_options(self))
        n = self.duration * self.fps
        if n > MAX_SAMPLES:
            raise ScenarioError(f"duration x fps = {self.duration:g} s x {self.fps:g} Hz = "
                                f"{n:.4g} samples, more than the limit of {MAX_SAMPLES:,}")
        if self.n_samples < 2:
            raise ScenarioError(f"duration x fps gives {self.n_samples} sample(s): need >= 2")

    # ---- derived values
    @property
    def ball_radius(self) -> float:
        return 0.5 * self.ball_diameter

    @property
    def track_radius(self) -> float:
        """L = R - r, the radius of the ball centre's circle (m)."""
        return self.cylinder_radius - self.ball_radius

    @property
    def section(self):
        """The trough's cross-section (:class:`sim.section.Section`)."""
        return Section(self.cylinder_radius, self.ovality, self.ovality_angle)

    @property
    def n_samples(self) -> int:
        return int(math.floor(self.duration * self.fps + 1e-9)) + 1

    def times(self):
        return np.arange(self.n_samples, dtype=float) / self.fps

    def options(self) -> dict:
        """The engine settings actually used: defaults overridden by engine_options."""
        out = dict(_option_defaults(self.engine))
        out.update(self.engine_options)
        return out

    def setup(self, pixel_size: float | None = None) -> Setup:
        """The lab setup (rollfric.setup.model.Setup) a camera filming this scenario would have."""
        return Setup(cylinder_radius=self.cylinder_radius, ball_diameter=self.ball_diameter,
                     ball_mass=self.ball_mass, fps=self.fps,
                     pixel_size=self.pixel_size if pixel_size is None else pixel_size,
                     gravity=self.gravity, air_density=self.air_density)

    def replace(self, **changes) -> Scenario:
        return dataclasses.replace(self, **changes)

    @classmethod
    def thesis(cls, ball: str = "10mm", **changes) -> Scenario:
        """The thesis trough with one of its balls ("1.58mm", "10mm", "12.69mm")."""
        try:
            d, m = THESIS_BALLS[ball]
        except KeyError:
            raise ScenarioError(f"unknown thesis ball {ball!r} "
                                f"(known: {', '.join(THESIS_BALLS)})") from None
        return cls(ball_diameter=d, ball_mass=m, **changes)

    # ---- dict forms
    def to_dict(self) -> dict:
        """SI form (field name -> value), exact round trip through from_dict; the trough's
        ovality and tilt only when not zero (files of round, level troughs are unchanged)."""
        return {f.name: (dict(getattr(self, f.name)) if f.name == "engine_options"
                         else getattr(self, f.name)) for f in dataclasses.fields(self)
                if not (f.name in _OPTIONAL_FIELDS and getattr(self, f.name) == 0.0)}

    @classmethod
    def from_dict(cls, data: dict) -> Scenario:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ScenarioError(f"unknown scenario field(s) {unknown} (known: {sorted(names)})")
        return cls(**data)

    def to_toml_dict(self) -> dict:
        out = {
            "cylinder": {"radius_mm": self.cylinder_radius * 1e3,
                         **({"ovality_mm": self.ovality * 1e3} if self.ovality else {}),
                         **({"ovality_angle_deg": math.degrees(self.ovality_angle)}
                            if self.ovality_angle else {}),
                         **({"tilt_deg": math.degrees(self.tilt)} if self.tilt else {})},
            "ball": {"diameter_mm": self.ball_diameter * 1e3, "mass_g": self.ball_mass * 1e3},
            "camera": {"fps": self.fps, "pixel_size_mm": self.pixel_size * 1e3},
            "environment": {"gravity_m_s2": self.gravity,
                            "air_density_kg_m3": self.air_density, "air_cd": self.air_cd,
                            **({"air_drag": self.air_drag}
                               if self.air_drag != "constant" else {})},
            "motion": {"mu": self.mu, "theta0_deg": math.degrees(self.theta0),
                       "theta_dot0_deg_s": math.degrees(self.theta_dot0),
                       "seconds": self.duration, "mu_speed_s_m": self.mu_speed},
            "engine": {"name": self.engine, "surface": self.surface, "seed": self.seed,
                       "options": dict(self.engine_options)},
        }
        return out

    @classmethod
    def from_toml_dict(cls, data: dict, source: str = "scenario") -> Scenario:
        return scenario_from_dict(data, source)

    @classmethod
    def from_toml(cls, path: str | Path) -> Scenario:
        return load_scenario(path)


def to_si(value: float, unit: str) -> float:
    """Bench unit -> SI: mm and g divide by 1000 (exact for typed decimals), deg -> rad."""
    return {"mm": BENCH_MM, "g": BENCH_GRAM, "deg": DEG}.get(unit, NONE).to_si(value)


# The TOML form (bench units): section -> keys; [engine]'s values are checked by Scenario
SCHEMA = Schema(
    sections={
        "cylinder": (Key("radius_mm", field="cylinder_radius", unit=BENCH_MM),
                     Key("ovality_mm", field="ovality", unit=BENCH_MM),
                     Key("ovality_angle_deg", field="ovality_angle", unit=DEG),
                     Key("tilt_deg", field="tilt", unit=DEG)),
        "ball": (Key("diameter_mm", field="ball_diameter", unit=BENCH_MM),
                 Key("mass_g", field="ball_mass", unit=BENCH_GRAM)),
        "camera": (Key("fps"), Key("pixel_size_mm", field="pixel_size", unit=BENCH_MM)),
        "environment": (Key("gravity_m_s2", field="gravity"),
                        Key("air_density_kg_m3", field="air_density"), Key("air_cd"),
                        Key("air_drag", "str")),
        "motion": (Key("mu"), Key("theta0_deg", field="theta0", unit=DEG),
                   Key("theta_dot0_deg_s", field="theta_dot0", unit=DEG),
                   Key("seconds", field="duration"), Key("mu_speed_s_m", field="mu_speed")),
        "engine": (Key("name", "any", field="engine"), Key("surface", "any"),
                   Key("seed", "any"), Key("options", "any", field="engine_options")),
    },
    error=ScenarioError,
    messages=Messages(finite=None),
)


def scenario_from_dict(data: dict, source: str = "scenario") -> Scenario:
    """Build a Scenario from its TOML form, refusing unknown keys and non-numbers."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{source}: must be a table of sections, got {data!r}")
    kwargs = check_file(SCHEMA, data, source)
    try:
        return Scenario(**kwargs)
    except ScenarioError as exc:
        raise ScenarioError(f"{source}: {exc}") from None


def load_scenario(path: str | Path) -> Scenario:
    """Read a scenario TOML file (mm, g, Hz, degrees; see the module docstring)."""
    return scenario_from_dict(read_toml(path, "scenario", ScenarioError), source=str(path))


def dumps_scenario(scenario: Scenario) -> str:
    """The scenario as TOML text (round-trips through load_scenario)."""
    def fmt(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float):
            return repr(v)
        if isinstance(v, int):
            return str(v)
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        raise TypeError(v)

    lines = []
    d = scenario.to_toml_dict()
    for section, table in d.items():
        opts = table.pop("options", None) if section == "engine" else None
        lines.append(f"[{section}]")
        lines += [f"{k} = {fmt(v)}" for k, v in table.items()]
        lines.append("")
        if opts:
            lines.append("[engine.options]")
            lines += [f"{k} = {fmt(v)}" for k, v in opts.items()]
            lines.append("")
    return "\n".join(lines)
