"""Blind mode: what the lab knows (its setup file) against what was built (the truth).

A case's ``[lab]`` table is the lab's setup file, in the lab-file form of
:mod:`rollfric.setup.model` (mm, g, Hz): the *nominal* values the lab would type. Every key is
optional; a key not given is the as-built value of the ``[scenario]`` (a lab that knows it
exactly)::

    [lab]
    draw = false               # true: draw the as-built values from the nominal +- their _u
    seed = 0                   # seed of those draws (default: render.seed, the case seed;
                               # "case": the case's own id, a different draw in every case)
    center_error_px = [0.3, -0.2]   # the lab measured the trough centre, with this error (px);
                                    # absent: no center_px, rollfric finds it from the contour
    center_px_u = [2.0, 2.0]   # the stated uncertainty of that measurement (px); with draw,
                               # the error is drawn from it (added to center_error_px, if any)
    lens_calibrated = true     # the lab calibrated the lens exactly (its [camera] matrix and
                               # distortion are the rendering lens's)
    [lab.cylinder]
    radius_mm = 85.3
    radius_mm_u = 0.05         # standard uncertainty of radius_mm (same unit)
    [lab.ball]
    diameter_mm = 10.0
    [lab.camera]
    fps = 1000.0
    pixel_size_mm = 0.1343
    matrix = [[2400.0, 0.0, 639.5], [0.0, 2400.0, 511.5], [0.0, 0.0, 1.0]]  # or a calibration
    distortion = [-0.18, 0.0, 0.0, 0.0, 0.0]                               # of its own

The as-built truth (what sim simulates and synth films) is the ``[scenario]``'s values, so a
case keys a known error by stating both (``scenario.cylinder.radius_mm = 85.5`` with
``lab.cylinder.radius_mm = 85.3``). With ``draw = true`` every quantity that has a ``_u`` key is
instead drawn as nominal + u z, z standard normal, from the seed and the key's name (the same
seed gives the same draws, each key its own stream). The lab's setup file handed to rollfric is
the nominal values with their ``_u`` keys (rollfric's setup reads the ``_u`` keys as the
stated uncertainties when it knows them).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import math

import numpy as np

from rollfric.errors import InputError
from rollfric.setup.model import setup_from_dict, thesis_setup
from rollfric.setup.schema import Key, Messages, Schema, check_section, check_value

# the lab-file keys a case may state as nominal values (section -> keys); the same keys name
# the as-built value in the [scenario] (sim.scenario's TOML form)
NOMINAL_KEYS = {
    "cylinder": ("radius_mm",),
    "ball": ("diameter_mm", "mass_g"),
    "camera": ("fps", "pixel_size_mm"),
    "environment": ("gravity_m_s2", "air_density_kg_m3"),
}
TOP_KEYS = ("draw", "seed", "center_error_px", "center_px_u", "lens_calibrated")
CALIBRATION_KEYS = ("matrix", "distortion")
# what the lab states about its camera's depth (rollfric.geometry.perspective), copied into its
# setup
# file as given: no as-built counterpart in the scenario (the camera's are render.camera keys)
STATED_KEYS = {"camera": ("working_distance_mm",), "cylinder": ("contour_depth_mm",)}


class LabError(InputError):
    """A [lab] table that cannot describe a lab's setup (the message names the key)."""


def _lab_section(sec: str, keys: tuple) -> tuple:
    """The keys of ``[lab.<sec>]``: the nominal values, their ``_u``, the lens, the stated."""
    return (*(Key(k, sign=">=0" if k == "air_density_kg_m3" else ">0") for k in keys),
            *(Key(f"{k}_u", sign=">=0") for k in keys),
            *(Key(k, "any", read=False) for k in (CALIBRATION_KEYS if sec == "camera" else ())),
            # a depth may lie in front of or behind the ball's plane
            *(Key(k, sign="" if k == "contour_depth_mm" else ">0")
              for k in STATED_KEYS.get(sec, ())))


# The [lab] table and its sections (rollfric.setup.schema), in lab units
LAB_SCHEMA = Schema(
    sections={
        "lab": (Key("draw", "bool", hint="must be true or false"),
                Key("seed", "int", sign=">=0", hint="must be a non-negative integer or \"case\""),
                Key("center_error_px", "any", read=False), Key("center_px_u", "any", read=False),
                Key("lens_calibrated", "bool", hint="must be true or false"),
                *(Key(sec, "any", read=False) for sec in NOMINAL_KEYS)),
        **{f"lab.{sec}": _lab_section(sec, keys) for sec, keys in NOMINAL_KEYS.items()},
    },
    error=LabError,
    messages=Messages(not_table="{source}: {section} must be a table",
                      kind="{source}: {section}.{key} must be a finite number, got {value!r}",
                      finite="{source}: {section}.{key} must be a finite number, got {value!r}",
                      sign="{source}: {section}.{key} must be {sign}, got {value!r}"),
)


@dataclasses.dataclass(frozen=True)
class Lab:
    """The lab's side of a blind case.

    ``nominal``: "section.key" -> the value the lab types (lab units); ``tolerance``: the
    stated standard uncertainties ("section.key" -> u); ``asbuilt``: the truth of each
    nominal key (lab units); ``center_error_px``: the error of the lab's trough-centre
    measurement (None: not measured)."""

    nominal: dict
    tolerance: dict
    asbuilt: dict
    center_error_px: tuple[float, float] | None
    draw: bool
    seed: int
    center_u: tuple[float, float] | None = None  # the lab's stated u of its centre (px)
    calibration: dict | None = None  # the lab's [camera] matrix and distortion
    lens_calibrated: bool = False  # the lab's calibration is the rendering lens
    stated: dict = dataclasses.field(default_factory=dict)  # "section.key" -> STATED_KEYS value

    def setup_dict(self, center_px: tuple[float, float] | None = None, camera=None) -> dict:
        """The lab's setup file (lab-file form) with the nominal values, their ``_u`` keys and,
        when the lab measured it, ``center_px`` = the true ``center_px`` + the error (in the
        undistorted image when the lab has a lens calibration, else where the ``camera``'s
        lens puts the axis)."""
        out: dict = {}
        for dotted, value in self.nominal.items():
            sec, key = dotted.split(".")
            out.setdefault(sec, {})[key] = value
            if dotted in self.tolerance and setup_reads_tolerances():
                out[sec][f"{key}_u"] = self.tolerance[dotted]
        for dotted, value in self.stated.items():
            sec, key = dotted.split(".")
            out.setdefault(sec, {})[key] = value
        cal = self.calibration
        if cal is None and self.lens_calibrated and camera is not None \
                and camera.lens is not None:
            cal = {"matrix": [list(r) for r in camera.lens.matrix],
                   "distortion": list(camera.lens.distortion)}
        if cal is not None:
            out.setdefault("camera", {}).update(cal)
        elif camera is not None and center_px is not None:
            center_px = tuple(camera.recorded(np.asarray(center_px, dtype=float)))
        if self.center_error_px is not None and center_px is not None:
            out.setdefault("cylinder", {})["center_px"] = [
                float(center_px[0]) + self.center_error_px[0],
                float(center_px[1]) + self.center_error_px[1]]
            if self.center_u is not None and setup_reads_tolerances():
                out["cylinder"]["center_px_u"] = list(self.center_u)
        return out

    def errors(self) -> dict:
        """"section.key" -> nominal - as-built (lab units), for every nominal key."""
        return {k: self.nominal[k] - self.asbuilt[k] for k in self.nominal}


@functools.cache
def setup_reads_tolerances() -> bool:
    """Whether rollfric's setup file takes ``_u`` keys (stated uncertainties); until it does,
    the lab's tolerances drive only the as-built draws and are left out of its setup file."""
    d = thesis_setup().to_toml_dict()
    d["cylinder"]["radius_mm_u"] = 0.1
    try:
        setup_from_dict(d)
    except InputError:
        return False
    return True


def _number(v, where: str, positive: bool = True) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise LabError(f"{where} must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise LabError(f"{where} must be positive, got {v!r}")
    if not positive and v < 0:
        raise LabError(f"{where} must be >= 0, got {v!r}")
    return float(v)


def standard_normal(seed: int, key: str) -> float:
    """One standard-normal draw for ``key`` from ``seed``: its own stream per key name, so
    adding a tolerance to one key leaves the others' draws unchanged."""
    k = int.from_bytes(hashlib.sha256(key.encode()).digest()[:8], "little")
    return float(np.random.default_rng([int(seed), k]).standard_normal())


def parse_lab(table: dict, scenario_toml: dict, *, default_seed: int = 0,
              source: str = "case") -> tuple[Lab, dict]:
    """Validate a case's ``[lab]`` table against the scenario it goes with.

    ``scenario_toml``: the scenario's full TOML form (``sim.Scenario.to_toml_dict()``, every
    key present) before any draw. Returns the :class:`Lab` and the scenario overrides
    ("section.key" -> as-built value in lab units) that the draws make (empty without
    ``draw``).
    """
    if not isinstance(table, dict):
        raise LabError(f"{source}: [lab] must be a table")
    top = check_section(LAB_SCHEMA, "lab", table, source)
    draw, seed = top.get("draw", False), top.get("seed", default_seed)
    if "seed" not in table:  # the case's seed, checked as the lab's
        check_value(LAB_SCHEMA, "lab", LAB_SCHEMA.keys("lab")["seed"], seed, source)
    ce, cu = _center(table, draw, seed, source)
    nominal, tol, asbuilt, overrides, stated = {}, {}, {}, {}, {}
    for sec, keys in NOMINAL_KEYS.items():
        t = check_section(LAB_SCHEMA, f"lab.{sec}", table.get(sec, {}), source)
        for k in keys:
            dotted = f"{sec}.{k}"
            # a lab may state no air (0) over a truth in air: its fit then leaves the drag out
            truth = float(scenario_toml[sec][k])
            nom = nominal[dotted] = t.get(k, truth)
            if f"{k}_u" in t:
                tol[dotted] = t[f"{k}_u"]
            if draw and dotted in tol:
                truth = nom + tol[dotted] * standard_normal(seed, dotted)
                if truth <= 0:
                    raise LabError(f"{source}: the draw of {dotted} from {nom:g} +- "
                                   f"{tol[dotted]:g} is not positive")
                overrides[dotted] = truth
            asbuilt[dotted] = truth
        stated.update({f"{sec}.{k}": t[k] for k in STATED_KEYS.get(sec, ()) if k in t})
    lens_cal = top.get("lens_calibrated", False)
    cam = table.get("camera", {})
    calibration = {k: cam[k] for k in CALIBRATION_KEYS if k in cam} or None
    if calibration is not None and lens_cal:
        raise LabError(f"{source}: lab.lens_calibrated and lab.camera.matrix/distortion "
                       "both give the lab's calibration: keep one")
    return Lab(nominal=nominal, tolerance=tol, asbuilt=asbuilt, center_error_px=ce,
               draw=draw, seed=seed, center_u=cu, calibration=calibration,
               lens_calibrated=lens_cal, stated=stated), overrides


def _center(table: dict, draw: bool, seed: int, source: str) -> tuple:
    """The error of the lab's trough-centre measurement (px; drawn from its stated u with
    ``draw``) and that stated u, each None when not given."""
    ce = table.get("center_error_px")
    if ce is not None:
        if not isinstance(ce, (list, tuple)) or len(ce) != 2:
            raise LabError(f"{source}: lab.center_error_px must be [dx, dy] in pixels, "
                           f"got {ce!r}")
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                   and math.isfinite(v) for v in ce):
            raise LabError(f"{source}: lab.center_error_px must be two finite numbers (px), "
                           f"got {ce!r}")
        ce = (float(ce[0]), float(ce[1]))
    cu = table.get("center_px_u")
    if cu is not None:
        if isinstance(cu, (int, float)) and not isinstance(cu, bool):
            cu = [cu, cu]
        if not isinstance(cu, (list, tuple)) or len(cu) != 2:
            raise LabError(f"{source}: lab.center_px_u must be [ux, uy] in pixels, got {cu!r}")
        cu = tuple(_number(v, f"{source}: lab.center_px_u", positive=False) for v in cu)
        if draw:  # the lab's centre measurement: its error drawn from its stated u
            base = ce or (0.0, 0.0)
            ce = tuple(base[i] + cu[i] * standard_normal(seed, f"cylinder.center_px.{axis}")
                       for i, axis in enumerate("xy"))
        elif ce is None:
            raise LabError(f"{source}: lab.center_px_u needs lab.center_error_px (the lab "
                           "measured the centre) or lab.draw = true (its error drawn)")
    return ce, cu


def apply_asbuilt(scenario_dict: dict, overrides: dict) -> dict:
    """The [scenario] dict with the drawn as-built values set (lab units, same keys)."""
    out = copy.deepcopy(scenario_dict)
    for dotted, value in overrides.items():
        sec, key = dotted.split(".")
        out.setdefault(sec, {})[key] = value
    return out
