"""The measurement setup: trough, ball, camera.

Public values are SI (m, kg, s). A lab's setup file is TOML in the units people
write down at the bench (mm, g, Hz)::

    [cylinder]
    radius_mm = 85.3
    center_px = [640.0, 380.0]   # optional: found from the background image when absent
    [ball]
    diameter_mm = 10.0
    mass_g = 4.07612
    [camera]
    fps = 1000
    pixel_size_mm = 0.1343

Optional keys: ``[cylinder] center_px``, ``[environment] gravity_m_s2`` (default 9.81).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from rollfric.errors import InputError
from rollfric.tomlfile import read_toml

STANDARD_GRAVITY = 9.81  # m/s^2, the value the thesis uses


class SetupError(InputError):
    """A setup file or value that cannot describe a real trough, ball and camera."""


@dataclasses.dataclass(frozen=True)
class Setup:
    """Geometry and camera of one measurement, in SI units.

    ``center_px`` is the cylinder axis in image pixels (x right, y down, origin at the
    centre of the top-left pixel), or None when it is to be found from the background.
    """

    cylinder_radius: float  # m
    ball_diameter: float  # m
    ball_mass: float  # kg
    fps: float  # frames per second
    pixel_size: float  # m per pixel in the plane of the ball centre
    center_px: tuple[float, float] | None = None
    gravity: float = STANDARD_GRAVITY

    def __post_init__(self) -> None:
        for name in ("cylinder_radius", "ball_diameter", "ball_mass", "fps", "pixel_size",
                     "gravity"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise SetupError(f"{name} must be a positive number, got {value!r}")
        if self.ball_diameter >= 2 * self.cylinder_radius:
            raise SetupError(
                f"ball_diameter ({self.ball_diameter * 1e3:g} mm) must be smaller than the "
                f"cylinder diameter ({2e3 * self.cylinder_radius:g} mm)")
        if self.center_px is not None:
            c = tuple(float(v) for v in self.center_px)
            if len(c) != 2 or not all(math.isfinite(v) for v in c):
                raise SetupError(f"center_px must be two finite numbers, got {self.center_px!r}")
            object.__setattr__(self, "center_px", c)

    @property
    def ball_radius(self) -> float:
        return 0.5 * self.ball_diameter

    @property
    def track_radius(self) -> float:
        """R - r: radius of the circle the ball centre moves on (m)."""
        return self.cylinder_radius - self.ball_radius

    def replace(self, **changes) -> Setup:
        return dataclasses.replace(self, **changes)

    def to_toml_dict(self) -> dict:
        """The lab-file form (mm, g, Hz) of this setup."""
        cyl: dict = {"radius_mm": self.cylinder_radius * 1e3}
        if self.center_px is not None:
            cyl["center_px"] = list(self.center_px)
        out = {
            "cylinder": cyl,
            "ball": {"diameter_mm": self.ball_diameter * 1e3, "mass_g": self.ball_mass * 1e3},
            "camera": {"fps": self.fps, "pixel_size_mm": self.pixel_size * 1e3},
        }
        if self.gravity != STANDARD_GRAVITY:
            out["environment"] = {"gravity_m_s2": self.gravity}
        return out


# What a setup file may hold: section -> {key: required?}
_SCHEMA = {
    "cylinder": {"radius_mm": True, "center_px": False},
    "ball": {"diameter_mm": True, "mass_g": True},
    "camera": {"fps": True, "pixel_size_mm": True},
    "environment": {"gravity_m_s2": False},
}
_REQUIRED_SECTIONS = ("cylinder", "ball", "camera")


def setup_from_dict(data: dict, source: str = "setup") -> Setup:
    """Build a Setup from the lab-file form, refusing unknown, missing or bad keys."""
    for section in data:
        if section not in _SCHEMA:
            raise SetupError(f"{source}: unknown section [{section}] "
                             f"(known: {', '.join(_SCHEMA)})")
    for section in _REQUIRED_SECTIONS:
        if section not in data:
            raise SetupError(f"{source}: missing section [{section}]")
    for section, table in data.items():
        if not isinstance(table, dict):
            raise SetupError(f"{source}: [{section}] must be a table")
        for key in table:
            if key not in _SCHEMA[section]:
                raise SetupError(f"{source}: unknown key {section}.{key} "
                                 f"(known: {', '.join(_SCHEMA[section])})")
        for key, required in _SCHEMA[section].items():
            if required and key not in table:
                raise SetupError(f"{source}: missing key {section}.{key}")

    def number(section: str, key: str) -> float:
        value = data[section][key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SetupError(f"{source}: {section}.{key} must be a number, got {value!r}")
        if not math.isfinite(value) or value <= 0:
            raise SetupError(f"{source}: {section}.{key} must be positive, got {value!r}")
        return float(value)

    center = data["cylinder"].get("center_px")
    if center is not None:
        if (not isinstance(center, list) or len(center) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                           and math.isfinite(v) for v in center)):
            raise SetupError(f"{source}: cylinder.center_px must be [x, y] in pixels, "
                             f"got {center!r}")
    radius = number("cylinder", "radius_mm") * 1e-3
    diameter = number("ball", "diameter_mm") * 1e-3
    if diameter >= 2 * radius:
        raise SetupError(f"{source}: ball.diameter_mm ({diameter * 1e3:g}) must be smaller "
                         f"than the cylinder diameter (2 x cylinder.radius_mm = "
                         f"{2e3 * radius:g})")
    gravity = (number("environment", "gravity_m_s2")
               if "gravity_m_s2" in data.get("environment", {}) else STANDARD_GRAVITY)
    return Setup(
        cylinder_radius=radius,
        ball_diameter=diameter,
        ball_mass=number("ball", "mass_g") * 1e-3,
        fps=number("camera", "fps"),
        pixel_size=number("camera", "pixel_size_mm") * 1e-3,
        center_px=None if center is None else (float(center[0]), float(center[1])),
        gravity=gravity,
    )


def load_setup(path: str | Path) -> Setup:
    """Read a lab's setup TOML file (mm, g, Hz)."""
    return setup_from_dict(read_toml(path, "setup", SetupError), source=str(path))


def dumps_setup(setup: Setup) -> str:
    """The setup as a lab's TOML file text."""
    lines = []
    for section, table in setup.to_toml_dict().items():
        lines.append(f"[{section}]")
        for key, value in table.items():
            if isinstance(value, list):
                text = "[" + ", ".join(repr(float(v)) for v in value) + "]"
            else:
                text = repr(float(value)) if isinstance(value, float) else str(value)
            lines.append(f"{key} = {text}")
        lines.append("")
    return "\n".join(lines)


def save_setup(setup: Setup, path: str | Path) -> None:
    Path(path).write_text(dumps_setup(setup))


# The three balls of the thesis on its 85.3 mm trough (thesis Table/NOTES).
THESIS_TROUGH_RADIUS = 85.3e-3
THESIS_BALLS = {  # diameter (m) -> mass (kg)
    "1.58mm": (1.58e-3, 0.01675e-3),
    "10mm": (10.00e-3, 4.07612e-3),
    "12.69mm": (12.69e-3, 8.35894e-3),
}


def thesis_setup(ball: str = "10mm", **changes) -> Setup:
    """The thesis's setup (85.3 mm trough, 1000 Hz, 0.1343 mm/px) with one of its balls."""
    try:
        diameter, mass = THESIS_BALLS[ball]
    except KeyError:
        raise SetupError(f"unknown thesis ball {ball!r} (known: {', '.join(THESIS_BALLS)})")\
            from None
    base = Setup(cylinder_radius=THESIS_TROUGH_RADIUS, ball_diameter=diameter, ball_mass=mass,
                 fps=1000.0, pixel_size=0.1343e-3)
    return base.replace(**changes) if changes else base
