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

The air around the ball (:mod:`rollfric.fit.air`; drag, buoyancy, added mass in the fit)::

    [environment]
    air_density_kg_m3 = 1.20      # default: room air, 1.20 +- 0.03; 0: no air (a vacuum)
    air_viscosity_pa_s = 1.81e-5  # default: 1.81e-5 +- 0.03e-5
    air_cd = 1.2                  # optional: the ball's drag coefficient as measured; absent:
                                  # the wall-corrected Schiller-Naumann law of rollfric.fit.air

A file without ``air_density_kg_m3`` is in room air; a :class:`Setup` built in Python has no
air unless given (``air_density=0.0``), so code states the air it means.

Uncertain inputs: every numeric key ``K`` may have a companion ``K_u``, its standard
uncertainty in the same units and of the same shape (``radius_mm_u = 0.5``,
``center_px_u = [2.0, 2.0]``, ``fps_u = 0.05``, ...). A key without ``K_u`` is taken as exact.
They are kept in :attr:`Setup.uncertainty` in SI units under the field names
(``cylinder_radius``, ``center_px``, ...) and used by :mod:`rollfric.uncertainty.budget`.

The camera's lens calibration as ``cv2.calibrateCamera`` returns it (:mod:`rollfric.setup.lens`)::

    [camera]
    matrix = [[2400.0, 0.0, 639.5], [0.0, 2400.0, 511.5], [0.0, 0.0, 1.0]]   # px
    distortion = [-0.18, 0.0, 0.0, 0.0, 0.0]                                # k1 k2 p1 p2 k3

With a calibration, ``center_px`` and ``pixel_size_mm`` refer to the undistorted image.

A pinhole camera's depth (:mod:`rollfric.geometry.perspective`): the trough's contour is seen on an
edge
of the bore that is not in the ball's plane, and a camera whose optical axis is off the trough's
axis sees it about another centre. With the working distance the trough centre found from the
contour is moved to the ball's plane along the line of sight::

    [camera]
    working_distance_mm = 500.0   # pinhole (entrance pupil) to the ball's plane
    [cylinder]
    contour_depth_mm = -15.0      # the edge the contour is seen on: in front of (+) or
                                  # behind (-) the ball's plane (default 0)

The optical axis meets the image at the calibration's (cx, cy), else at the frame's centre.

The trough and camera as built (:mod:`rollfric.uncertainty.asbuilt`; each a budget row with
its ``_u``, none corrected)::

    [cylinder]
    tilt_deg = 0.0        # the axis tilted along its length (the lab's level reading)
    tilt_deg_u = 0.03     # its standard uncertainty; absent: the trough is taken as level
    ovality_mm = 0.0      # out-of-roundness D_max - D_min of the bore
    ovality_mm_u = 0.02
    [camera]
    yaw_deg = 0.0         # the optical axis swung sideways (yaw) / up or down (pitch)
    yaw_deg_u = 0.3       # against the trough's axis
    pitch_deg = 0.0
    pitch_deg_u = 0.3

The camera's effective bit depth, where the recording's file does not state it (a TIFF of 16-bit
words from a 12-bit camera)::

    [camera]
    bit_depth = 12   # the frames' values run 0..4095: every threshold is taken against that
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from rollfric.errors import InputError
from rollfric.fit.air import (
    AIR_VISCOSITY,
    AIR_VISCOSITY_U,
    ROOM_AIR_DENSITY,
    ROOM_AIR_DENSITY_U,
    WALL_FACTOR,
)
from rollfric.setup.lens import Calibration, CalibrationError, calibration_from_dict
from rollfric.setup.schema import (
    GRAM,
    MM,
    PLAUSIBLE,  # noqa: F401  (re-exported: the ranges are declared with the schema)
    Key,
    Messages,
    Schema,
    Unit,
    check_file,
    check_plausible,
    check_uncertainty,
    uncertain_keys,
)
from rollfric.setup.tomlfile import read_toml

STANDARD_GRAVITY = 9.81  # m/s^2, the value the thesis uses
# degrees in the lab file, radians in the Setup (``per``: back to degrees, as LAB_KEYS scales)
ANGLE_DEG = Unit("deg", math.pi / 180.0, 180.0 / math.pi)
# the fields of the trough and camera as built: budget rows of their own
# (rollfric.uncertainty.asbuilt), not inputs the budget's re-fits move
AS_BUILT_FIELDS = ("cylinder_tilt", "cylinder_ovality", "camera_yaw", "camera_pitch")
# the largest as-built tilt (trough axis, camera yaw/pitch) a setup takes, deg
MAX_ASBUILT_DEG = 10.0


class SetupError(InputError):
    """A setup file or value that cannot describe a real trough, ball and camera."""


@dataclasses.dataclass(frozen=True)
class Setup:
    """Geometry and camera of one measurement, in SI units.

    Attributes
    ----------
    cylinder_radius : float
        Bore radius R of the trough (m).
    ball_diameter : float
        Ball diameter 2r (m).
    ball_mass : float
        Ball mass (kg).
    fps : float
        Frame rate (1/s).
    pixel_size : float
        Size of one pixel in the plane of the ball's centre (m).
    center_px : tuple of float or None
        The cylinder axis in image pixels (x right, y down, origin at the centre of the
        top-left pixel), or None when it is to be found from the background.
    gravity : float
        Gravitational acceleration (m/s^2).
    air_density : float
        Density of the air around the ball (kg/m^3); 0: no air (:mod:`rollfric.fit.air`).
    air_viscosity : float
        Its dynamic viscosity (Pa s).
    air_cd : float or None
        The ball's drag coefficient as the lab measured it; None: the wall-corrected law.
    air_wall_factor : float
        The wall's factor on the free sphere's drag law (:data:`rollfric.fit.air.WALL_FACTOR`).
    cylinder_tilt : float
        The trough's axis tilted along its length, as the lab states it (rad; 0: level).
    cylinder_ovality : float
        The bore's out-of-roundness D_max - D_min (m; 0: round).
    camera_yaw, camera_pitch : float
        The camera's optical axis swung sideways / up or down against the trough's axis
        (rad). These four are not corrected: with their ``_u`` they are rows of the budget
        (:mod:`rollfric.uncertainty.asbuilt`).
    uncertainty : tuple
        Standard uncertainties of the fields above, SI (center_px: px, a pair), as
        ((field name, u), ...); a field not listed is exact.

    Raises
    ------
    SetupError
        A non-positive or non-finite value, a ball not smaller than the cylinder, a bad
        ``center_px`` or uncertainty.

    Examples
    --------
    >>> from rollfric import Setup
    >>> setup = Setup(cylinder_radius=85.3e-3, ball_diameter=10e-3, ball_mass=4.07612e-3,
    ...               fps=1000.0, pixel_size=0.1343e-3)
    >>> round(setup.track_radius * 1e3, 2)  # L = R - r, mm
    80.3
    >>> round(setup.ball_radius / setup.pixel_size, 2)  # the ball's radius, px
    37.23
    """

    cylinder_radius: float  # m
    ball_diameter: float  # m
    ball_mass: float  # kg
    fps: float  # frames per second
    pixel_size: float  # m per pixel in the plane of the ball centre
    center_px: tuple[float, float] | None = None
    gravity: float = STANDARD_GRAVITY
    # standard uncertainties of the fields above, SI (center_px: px, a pair):
    # ((field name, u), ...); a field not listed is exact
    uncertainty: tuple = ()
    calibration: Calibration | None = None  # the lens (rollfric.setup.lens); None: no distortion
    working_distance: float | None = None  # m, pinhole to the ball's plane; None: not given
    contour_depth: float | None = None  # m, the contour's edge in front of (+) the ball's
    # plane; None: not stated (from the contour's radius when working_distance is given)
    bit_depth: int | None = None  # the camera's effective bit depth (camera.bit_depth); None:
    # the recording's file states it, or the data tell (rollfric.io.bitdepth)
    air_density: float = 0.0  # kg/m^3; 0: no air (rollfric.fit.air)
    air_viscosity: float = AIR_VISCOSITY  # Pa s
    air_cd: float | None = None  # None: the wall-corrected drag law
    air_wall_factor: float = WALL_FACTOR
    cylinder_tilt: float = 0.0  # rad, the axis along its length (rollfric.uncertainty.asbuilt)
    cylinder_ovality: float = 0.0  # m, D_max - D_min of the bore
    camera_yaw: float = 0.0  # rad, against the trough's axis
    camera_pitch: float = 0.0  # rad

    def __post_init__(self) -> None:
        for name in ("cylinder_radius", "ball_diameter", "ball_mass", "fps", "pixel_size",
                     "gravity"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise SetupError(f"{name} must be a positive number, got {value!r}")
            check_plausible(name, value, SetupError)
        for name in ("air_density", "air_viscosity", "air_cd", "air_wall_factor"):
            value = getattr(self, name)
            if value is None and name == "air_cd":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value < 0 \
                    or (value == 0 and name != "air_density"):
                raise SetupError(f"{name} must be a finite number > 0 (air_density >= 0), "
                                 f"got {value!r}")
            if name in PLAUSIBLE:
                check_plausible(name, float(value), SetupError)
            object.__setattr__(self, name, float(value))
        for name in ("cylinder_tilt", "camera_yaw", "camera_pitch", "cylinder_ovality"):
            value = getattr(self, name)
            limit = math.radians(MAX_ASBUILT_DEG) if name != "cylinder_ovality" else \
                0.5 * self.cylinder_radius
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or not abs(value) <= limit \
                    or (name == "cylinder_ovality" and value < 0):
                raise SetupError(f"{name} must be a finite number within +-{limit:g} (SI; "
                                 f"ovality >= 0), got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.ball_diameter >= 2 * self.cylinder_radius:
            raise SetupError(
                f"ball_diameter ({self.ball_diameter * 1e3:g} mm) must be smaller than the "
                f"cylinder diameter ({2e3 * self.cylinder_radius:g} mm)")
        if self.center_px is not None:
            c = tuple(float(v) for v in self.center_px)
            if len(c) != 2 or not all(math.isfinite(v) for v in c):
                raise SetupError(f"center_px must be two finite numbers, got {self.center_px!r}")
            object.__setattr__(self, "center_px", c)
        object.__setattr__(self, "uncertainty", _check_uncertainty(self))
        if self.calibration is not None and not isinstance(self.calibration, Calibration):
            raise SetupError(f"calibration must be a rollfric.setup.lens.Calibration, got "
                             f"{self.calibration!r}")
        wd = self.working_distance
        if wd is not None and (isinstance(wd, bool) or not isinstance(wd, (int, float))
                               or not math.isfinite(wd) or not 1e-3 <= wd <= 1e3):
            raise SetupError(f"working_distance must be 1 mm .. 1 km, got {wd!r}")
        zc = self.contour_depth
        if zc is not None and (isinstance(zc, bool) or not isinstance(zc, (int, float))
                               or not math.isfinite(zc)
                               or (wd is not None and not abs(zc) < 0.5 * wd)):
            raise SetupError(f"contour_depth must be finite and nearer than half the working "
                             f"distance, got {zc!r}")
        bd = self.bit_depth
        if bd is not None and (isinstance(bd, bool) or not isinstance(bd, int)
                               or not 1 <= bd <= 16):
            raise SetupError(f"bit_depth must be a whole number of bits, 1..16, got {bd!r}")

    def u(self, name: str):
        """Standard uncertainty of one field.

        Parameters
        ----------
        name : str
            A field name, e.g. ``"cylinder_radius"``.

        Returns
        -------
        float, tuple of float or None
            SI (a pair for ``center_px``); None if the field is exact.
        """
        return dict(self.uncertainty).get(name)

    @property
    def ball_radius(self) -> float:
        """Ball radius r (m)."""
        return 0.5 * self.ball_diameter

    @property
    def track_radius(self) -> float:
        """R - r: radius of the circle the ball centre moves on (m)."""
        return self.cylinder_radius - self.ball_radius

    def replace(self, **changes) -> Setup:
        """A copy with some fields changed (checked again).

        Parameters
        ----------
        **changes
            Field names and their new values.

        Returns
        -------
        Setup
        """
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
        if self.calibration is not None:
            out["camera"].update(self.calibration.to_toml_dict())
        if self.working_distance is not None:
            out["camera"]["working_distance_mm"] = self.working_distance * 1e3
        if self.bit_depth is not None:
            out["camera"]["bit_depth"] = int(self.bit_depth)
        if self.contour_depth is not None:
            cyl["contour_depth_mm"] = self.contour_depth * 1e3
        # the trough and camera as built: written when stated (a value or its _u)
        for name, table in (("cylinder_tilt", cyl), ("cylinder_ovality", cyl),
                            ("camera_yaw", out["camera"]), ("camera_pitch", out["camera"])):
            if getattr(self, name) != 0.0 or self.u(name) is not None:
                _, key, scale = LAB_KEYS[name]
                table[key] = getattr(self, name) * scale
        env: dict = {}
        if self.gravity != STANDARD_GRAVITY:
            env["gravity_m_s2"] = self.gravity
        # always written: a file without it means room air
        env["air_density_kg_m3"] = self.air_density
        if self.air_viscosity != AIR_VISCOSITY or self.u("air_viscosity") is not None:
            env["air_viscosity_pa_s"] = self.air_viscosity
        if self.air_cd is not None:
            env["air_cd"] = self.air_cd
        out["environment"] = env
        for name, u in self.uncertainty:
            section, key, scale = LAB_KEYS[name]
            table = out.setdefault(section, {})
            if name == "gravity" and key not in table:
                table[key] = self.gravity
            if name == "air_cd" and self.air_cd is None:
                continue
            table[key + "_u"] = [float(v) for v in u] if isinstance(u, tuple) else u * scale
        return out


# What a setup file may hold, in the order it is read (rollfric.setup.schema)
SETUP_SCHEMA = Schema(
    sections={
        "cylinder": (
            Key("radius_mm", field="cylinder_radius", unit=MM, required=True, sign=">0",
                plausible="cylinder_radius", uncertain=True),
            Key("center_px", "pair", hint="must be [x, y] in pixels", uncertain=True),
            Key("contour_depth_mm", field="contour_depth", unit=MM,
                hint="must be a number (mm)"),
            Key("tilt_deg", field="cylinder_tilt", unit=ANGLE_DEG, default=0.0,
                bounds=(-MAX_ASBUILT_DEG, MAX_ASBUILT_DEG), uncertain=True,
                hint=f"must be the axis's tilt along its length in degrees, "
                     f"-{MAX_ASBUILT_DEG:g}..{MAX_ASBUILT_DEG:g}"),
            Key("ovality_mm", field="cylinder_ovality", unit=MM, default=0.0, sign=">=0",
                uncertain=True, hint="must be the bore's D_max - D_min in mm, >= 0")),
        "ball": (
            Key("diameter_mm", field="ball_diameter", unit=MM, required=True, sign=">0",
                plausible="ball_diameter", uncertain=True),
            Key("mass_g", field="ball_mass", unit=GRAM, required=True, sign=">0",
                plausible="ball_mass", uncertain=True)),
        "camera": (
            Key("fps", unit=Unit("Hz"), required=True, sign=">0", plausible="fps",
                uncertain=True),
            Key("pixel_size_mm", field="pixel_size", unit=MM, required=True, sign=">0",
                plausible="pixel_size", uncertain=True),
            # the lens, read by rollfric.setup.lens
            Key("matrix", "any", uncertain="own", read=False),
            Key("distortion", "any", uncertain="own", read=False),
            Key("image_size_px", "any", read=False),
            Key("working_distance_mm", field="working_distance", unit=MM, sign=">0"),
            *(Key(f"{k}_deg", field=f"camera_{k}", unit=ANGLE_DEG, default=0.0,
                  bounds=(-MAX_ASBUILT_DEG, MAX_ASBUILT_DEG), uncertain=True,
                  hint=f"must be the camera's {k} against the trough's axis in degrees, "
                       f"-{MAX_ASBUILT_DEG:g}..{MAX_ASBUILT_DEG:g}") for k in ("yaw", "pitch")),
            Key("bit_depth", "int", bounds=(1, 16),
                hint="must be the camera's effective bit depth, a whole number of bits 1..16 "
                     "(12 for a 12-bit camera)")),
        "environment": (
            Key("gravity_m_s2", field="gravity", unit=Unit("m/s^2"), sign=">0",
                plausible="gravity", default=STANDARD_GRAVITY, uncertain=True),
            Key("air_density_kg_m3", field="air_density", unit=Unit("kg/m^3"), sign=">=0",
                plausible="air_density", default=ROOM_AIR_DENSITY, uncertain=True),
            Key("air_viscosity_pa_s", field="air_viscosity", unit=Unit("Pa s"), sign=">0",
                plausible="air_viscosity", default=AIR_VISCOSITY, uncertain=True),
            Key("air_cd", unit=Unit("1"), sign=">0", plausible="air_cd", uncertain=True)),
    },
    error=SetupError,
    messages=Messages(finite="{source}: {section}.{key} must be positive, got {value!r}"),
    required=("cylinder", "ball", "camera"),
    uncertain_note=", each with an optional _u: its standard uncertainty",
)

# Setup field -> (section, lab key, factor from SI to the lab unit): the keys with a K_u
LAB_KEYS = {key.target: (section, key.name, key.unit.per)
            for section, key in uncertain_keys(SETUP_SCHEMA)}

def _check_uncertainty(setup: Setup) -> tuple:
    """The uncertainty pairs validated (known field, finite, >= 0; center_px: a pair, only
    with a center_px) and sorted by field name."""
    items = dict(setup.uncertainty)
    out = []
    for name, u in sorted(items.items()):
        if name not in LAB_KEYS:
            raise SetupError(f"uncertainty of unknown setup field {name!r} "
                             f"(known: {', '.join(LAB_KEYS)})")
        if name == "center_px":
            if setup.center_px is None:
                raise SetupError("center_px uncertainty given without center_px")
            vals = tuple(float(v) for v in u)
            if len(vals) != 2:
                raise SetupError(f"center_px uncertainty must be a pair, got {u!r}")
        else:
            if isinstance(u, bool) or not isinstance(u, (int, float)):
                raise SetupError(f"{name} uncertainty must be a number, got {u!r}")
            vals = (float(u),)
        if not all(math.isfinite(v) and v >= 0 for v in vals):
            raise SetupError(f"{name} uncertainty must be finite and >= 0, got {u!r}")
        out.append((name, vals if name == "center_px" else vals[0]))
    return tuple(out)


def setup_from_dict(data: dict, source: str = "setup") -> Setup:
    """Build a Setup from the lab-file form (mm, g, Hz; ``K_u`` the standard uncertainty of ``K``).

    Parameters
    ----------
    data : dict
        The parsed TOML tables ``[cylinder]``, ``[ball]``, ``[camera]`` and optionally
        ``[environment]``.
    source : str, optional
        Where it came from, for the error messages.

    Returns
    -------
    Setup
        In SI units.

    Raises
    ------
    SetupError
        An unknown, missing or bad key, named in the message.

    Examples
    --------
    >>> from rollfric import setup_from_dict
    >>> setup = setup_from_dict({
    ...     "cylinder": {"radius_mm": 85.3, "radius_mm_u": 0.05},
    ...     "ball": {"diameter_mm": 10.0, "mass_g": 4.07612},
    ...     "camera": {"fps": 1000, "pixel_size_mm": 0.1343}})
    >>> setup.cylinder_radius, round(setup.ball_mass * 1e3, 5), setup.fps  # m, g, Hz
    (0.0853, 4.07612, 1000.0)
    >>> round(dict(setup.uncertainty)["cylinder_radius"] * 1e3, 6)  # mm
    0.05
    >>> sorted(dict(setup.uncertainty))  # room air by default, with its uncertainties
    ['air_density', 'air_viscosity', 'cylinder_radius']
    """
    values = check_file(SETUP_SCHEMA, data, source)
    _check_ball_fits(values, source)
    _check_contour_depth(data, values, source)
    uncertainty = _read_uncertainties(data, values, source)
    try:
        calibration = calibration_from_dict(data["camera"], source)
    except CalibrationError as exc:
        raise SetupError(str(exc)) from None
    return Setup(calibration=calibration, uncertainty=uncertainty, **values)


def _check_ball_fits(values: dict, source: str) -> None:
    """The ball must be smaller than the trough's bore."""
    diameter, radius = values["ball_diameter"], values["cylinder_radius"]
    if diameter >= 2 * radius:
        raise SetupError(f"{source}: ball.diameter_mm ({diameter * 1e3:g}) must be smaller "
                         f"than the cylinder diameter (2 x cylinder.radius_mm = "
                         f"{2e3 * radius:g})")


def _check_contour_depth(data: dict, values: dict, source: str) -> None:
    """The contour's depth needs a perspective camera, and lies nearer than half its distance."""
    wd, zc = values.get("working_distance"), data["cylinder"].get("contour_depth_mm")
    if wd is None and zc is not None:  # an orthographic camera sees every depth alike
        raise SetupError(f"{source}: cylinder.contour_depth_mm is used only with "
                         "camera.working_distance_mm (the perspective of a camera at that "
                         "distance); give both, or neither")
    if wd is not None and zc is not None and not abs(zc) * 1e-3 < 0.5 * wd:
        raise SetupError(f"{source}: cylinder.contour_depth_mm ({zc:g}) must be nearer the "
                         f"ball's plane than half of camera.working_distance_mm")


def _read_uncertainties(data: dict, values: dict, source: str) -> tuple:
    """The ``K_u`` keys as (field, u) in SI; room air, when not given, with a room's spread."""
    uncertainty = []
    for section, key in uncertain_keys(SETUP_SCHEMA):
        value = data.get(section, {}).get(key.name + "_u")
        if value is not None:
            uncertainty.append((key.target, check_uncertainty(SETUP_SCHEMA, section, key, value,
                                                              source)))
    env = data.get("environment", {})
    for key, field, default_u in (("air_density_kg_m3", "air_density", ROOM_AIR_DENSITY_U),
                                  ("air_viscosity_pa_s", "air_viscosity", AIR_VISCOSITY_U)):
        if key not in env:
            uncertainty.append((field, default_u))
    if values["air_density"] == 0.0:  # no air: its viscosity acts on nothing
        uncertainty = [(n, u) for n, u in uncertainty if n != "air_viscosity"]
    return tuple(uncertainty)


def load_setup(path: str | Path) -> Setup:
    """Read a lab's setup TOML file (mm, g, Hz).

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

    Returns
    -------
    Setup
        In SI units.

    Raises
    ------
    SetupError
        The file is missing, not TOML, or has an unknown, missing or bad key.

    Examples
    --------
    >>> import tempfile, rollfric
    >>> from pathlib import Path
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = Path(tmp.name) / "setup.toml"
    >>> _ = path.write_text('''
    ... [cylinder]
    ... radius_mm = 85.3
    ... center_px = [640.0, 380.0]
    ... [ball]
    ... diameter_mm = 10.0
    ... mass_g = 4.07612
    ... [camera]
    ... fps = 1000
    ... pixel_size_mm = 0.1343
    ... ''')
    >>> setup = rollfric.load_setup(path)
    >>> setup.cylinder_radius, setup.center_px, setup.fps
    (0.0853, (640.0, 380.0), 1000.0)
    >>> tmp.cleanup()
    """
    return setup_from_dict(read_toml(path, "setup", SetupError), source=str(path))


def dumps_setup(setup: Setup) -> str:
    """The setup as a lab's TOML file text.

    Parameters
    ----------
    setup : Setup

    Returns
    -------
    str
        The lab-file form (mm, g, Hz), which :func:`load_setup` reads back.
    """
    lines = []
    for section, table in setup.to_toml_dict().items():
        lines.append(f"[{section}]")
        for key, value in table.items():
            if isinstance(value, list):
                text = "[" + ", ".join(
                    "[" + ", ".join(repr(float(x)) for x in v) + "]" if isinstance(v, list)
                    else repr(float(v)) for v in value) + "]"
            else:
                text = repr(float(value)) if isinstance(value, float) else str(value)
            lines.append(f"{key} = {text}")
        lines.append("")
    return "\n".join(lines)


def save_setup(setup: Setup, path: str | Path) -> None:
    """Write the setup as a lab's TOML file.

    Parameters
    ----------
    setup : Setup
    path : str or pathlib.Path
        Where to write (replaced if it exists).
    """
    Path(path).write_text(dumps_setup(setup))


# The three balls of the thesis on its 85.3 mm trough (thesis Table/NOTES).
THESIS_TROUGH_RADIUS = 85.3e-3
THESIS_BALLS = {  # diameter (m) -> mass (kg)
    "1.58mm": (1.58e-3, 0.01675e-3),
    "10mm": (10.00e-3, 4.07612e-3),
    "12.69mm": (12.69e-3, 8.35894e-3),
}


def thesis_setup(ball: str = "10mm", **changes) -> Setup:
    """The thesis's setup (85.3 mm trough, 1000 Hz, 0.1343 mm/px) with one of its balls.

    Parameters
    ----------
    ball : {"1.58mm", "10mm", "12.69mm"}, optional
        The thesis ball (sets diameter and mass).
    **changes
        Other fields to change.

    Returns
    -------
    Setup

    Raises
    ------
    SetupError
        An unknown ball.

    Examples
    --------
    >>> from rollfric import thesis_setup
    >>> setup = thesis_setup("12.69mm")
    >>> setup.ball_diameter, setup.ball_mass, setup.fps
    (0.01269, 0.00835894, 1000.0)
    >>> thesis_setup("10mm", fps=2000.0).fps
    2000.0
    """
    try:
        diameter, mass = THESIS_BALLS[ball]
    except KeyError:
        raise SetupError(f"unknown thesis ball {ball!r} (known: {', '.join(THESIS_BALLS)})")\
            from None
    base = Setup(cylinder_radius=THESIS_TROUGH_RADIUS, ball_diameter=diameter, ball_mass=mass,
                 fps=1000.0, pixel_size=0.1343e-3)
    return base.replace(**changes) if changes else base
