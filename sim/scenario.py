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
from typing import Any

from rollfric.io.limits import MAX_SAMPLES
from rollfric.setup.model import (
    PLAUSIBLE,
    THESIS_BALLS,
    THESIS_TROUGH_RADIUS,
    Setup,
    check_plausible,
)
from rollfric.setup.tomlfile import read_toml
from sim.engines import ENGINES
from sim.errors import ScenarioError

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
        for name in ("ball_diameter", "ball_mass", "cylinder_radius", "duration", "fps",
                     "gravity", "pixel_size"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or v <= 0:
                raise ScenarioError(f"{name} must be a positive number, got {v!r}")
            if name in PLAUSIBLE:
                check_plausible(name, float(v), ScenarioError)
            object.__setattr__(self, name, float(v))
        for name in ("mu", "theta0", "theta_dot0"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ScenarioError(f"{name} must be a finite number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.mu < 0:
            raise ScenarioError(f"mu must not be negative, got {self.mu!r}")
        for name in ("mu_speed", "air_density", "air_cd"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or v < 0:
                raise ScenarioError(f"{name} must be a finite number >= 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.air_drag not in AIR_DRAGS:
            raise ScenarioError(f"air_drag must be one of {', '.join(AIR_DRAGS)}, "
                                f"got {self.air_drag!r}")
        for name in ("ovality", "ovality_angle", "tilt"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ScenarioError(f"{name} must be a finite number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if not 0 <= self.ovality <= MAX_OVALITY * self.cylinder_radius:
            raise ScenarioError(
                f"ovality ({self.ovality * 1e3:g} mm) must be between 0 and "
                f"{MAX_OVALITY:g} x the radius ({MAX_OVALITY * self.cylinder_radius * 1e3:g} mm)")
        if abs(self.tilt) > math.radians(MAX_TILT_DEG):
            raise ScenarioError(f"tilt ({math.degrees(self.tilt):g} deg) is beyond "
                                f"+-{MAX_TILT_DEG:g} deg")
        if self.ball_diameter >= 2 * self.cylinder_radius:
            raise ScenarioError(
                f"ball_diameter ({self.ball_diameter * 1e3:g} mm) must be smaller than the "
                f"trough diameter (2 x cylinder_radius = {self.cylinder_radius * 2e3:g} mm)")
        if abs(self.theta0) > math.radians(MAX_THETA0_DEG):
            raise ScenarioError(
                f"theta0 ({math.degrees(self.theta0):g} deg) is beyond +-{MAX_THETA0_DEG:g} deg: "
                "the ball would leave the trough wall or slip")
        # energy of rolling without slipping, (7/10) m (L theta')^2 = m g L (cos th - cos th0):
        # the highest angle the release speed reaches without friction
        try:
            cos_max = math.cos(self.theta0) - 0.7 * self.track_radius * self.theta_dot0 ** 2 \
                / self.gravity
        except OverflowError:
            cos_max = -math.inf
        if cos_max < math.cos(math.radians(MAX_THETA0_DEG)):
            reach = "over the top" if cos_max < -1 else \
                f"to {math.degrees(math.acos(cos_max)):.4g} deg"
            raise ScenarioError(
                f"theta_dot0 ({math.degrees(self.theta_dot0):g} deg/s) at theta0 "
                f"{math.degrees(self.theta0):g} deg would swing the ball {reach}, beyond "
                f"+-{MAX_THETA0_DEG:g} deg: it would leave the trough wall or slip")
        if self.engine not in ENGINES:
            raise ScenarioError(f"unknown engine {self.engine!r} (known: {', '.join(ENGINES)})")
        if self.surface not in SURFACES[self.engine]:
            raise ScenarioError(
                f"surface {self.surface!r} is not offered by engine {self.engine!r} "
                f"(known: {', '.join(SURFACES[self.engine])})")
        if self.tilt != 0.0 and self.engine == "reference":
            raise ScenarioError(
                "the reference engine integrates the planar equation of motion: a trough "
                "tilted along its length (cylinder.tilt_deg) makes the ball also roll along "
                "it, a 3D motion; simulate it with engine mujoco or pybullet")
        if self.ovality != 0.0 and self.engine == "reference" and (
                self.mu_speed != 0.0 or self.air_density != 0.0):
            raise ScenarioError(
                "the reference's out-of-round trough (cylinder.ovality_mm) has no "
                "speed-dependent friction or air drag (sim.losses): use one or the other, or "
                "engine mujoco or pybullet")
        if (self.tilt != 0.0 or self.ovality != 0.0) and self.surface != "tangent":
            raise ScenarioError(
                f"surface {self.surface!r} is a round trough of limited length; an "
                "out-of-round (cylinder.ovality_mm) or tilted (cylinder.tilt_deg) trough needs "
                "surface \"tangent\"")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ScenarioError(f"seed must be a non-negative integer, got {self.seed!r}")
        if not isinstance(self.engine_options, dict):
            raise ScenarioError(f"engine_options must be a table, got {self.engine_options!r}")
        defaults = _option_defaults(self.engine)
        for key, value in self.engine_options.items():
            if key not in defaults:
                raise ScenarioError(
                    f"unknown option {key!r} for engine {self.engine!r} "
                    f"(known: {', '.join(defaults) or 'none'})")
            want = type(defaults[key])
            if want is float and isinstance(value, int) and not isinstance(value, bool):
                value = float(value)
            if not isinstance(value, want) or (want is int and isinstance(value, bool)):
                raise ScenarioError(f"engine option {key} must be {want.__name__}, "
                                    f"got {value!r}")
            if isinstance(value, (int, float)) and not isinstance(value, bool) and value <= 0:
                raise ScenarioError(f"engine option {key} must be positive, got {value!r}")
        object.__setattr__(self, "engine_options", dict(sorted(self.engine_options.items())))
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
        from sim.section import Section

        return Section(self.cylinder_radius, self.ovality, self.ovality_angle)

    @property
    def n_samples(self) -> int:
        return int(math.floor(self.duration * self.fps + 1e-9)) + 1

    def times(self):
        import numpy as np

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
    if unit in ("mm", "g"):
        return float(value) / 1000.0
    if unit == "deg":
        return math.radians(value)
    return float(value)


_SCHEMA: dict[str, dict[str, tuple[str, str]]] = {
    # section -> key -> (field, unit name: "mm"/"g" divide by 1000, "deg" to radians)
    "cylinder": {"radius_mm": ("cylinder_radius", "mm"), "ovality_mm": ("ovality", "mm"),
                 "ovality_angle_deg": ("ovality_angle", "deg"), "tilt_deg": ("tilt", "deg")},
    "ball": {"diameter_mm": ("ball_diameter", "mm"), "mass_g": ("ball_mass", "g")},
    "camera": {"fps": ("fps", ""), "pixel_size_mm": ("pixel_size", "mm")},
    "environment": {"gravity_m_s2": ("gravity", ""),
                    "air_density_kg_m3": ("air_density", ""), "air_cd": ("air_cd", ""),
                    "air_drag": ("air_drag", "text")},
    "motion": {"mu": ("mu", ""), "theta0_deg": ("theta0", "deg"),
               "theta_dot0_deg_s": ("theta_dot0", "deg"),
               "seconds": ("duration", ""), "mu_speed_s_m": ("mu_speed", "")},
}
_ENGINE_KEYS = ("name", "surface", "seed", "options")


def scenario_from_dict(data: dict, source: str = "scenario") -> Scenario:
    """Build a Scenario from its TOML form, refusing unknown keys and non-numbers."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{source}: must be a table of sections, got {data!r}")
    kwargs: dict[str, Any] = {}
    for section, table in data.items():
        if section not in _SCHEMA and section != "engine":
            raise ScenarioError(f"{source}: unknown section [{section}] "
                                f"(known: {', '.join([*_SCHEMA, 'engine'])})")
        if not isinstance(table, dict):
            raise ScenarioError(f"{source}: [{section}] must be a table")
        if section == "engine":
            for key, value in table.items():
                if key not in _ENGINE_KEYS:
                    raise ScenarioError(f"{source}: unknown key engine.{key} "
                                        f"(known: {', '.join(_ENGINE_KEYS)})")
                field = {"name": "engine", "options": "engine_options"}.get(key, key)
                kwargs[field] = value
            continue
        for key, value in table.items():
            if key not in _SCHEMA[section]:
                raise ScenarioError(f"{source}: unknown key {section}.{key} "
                                    f"(known: {', '.join(_SCHEMA[section])})")
            field, unit = _SCHEMA[section][key]
            if unit == "text":
                if not isinstance(value, str):
                    raise ScenarioError(f"{source}: {section}.{key} must be a string, got "
                                        f"{value!r}")
                kwargs[field] = value
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ScenarioError(f"{source}: {section}.{key} must be a number, got {value!r}")
            kwargs[field] = to_si(value, unit)
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
