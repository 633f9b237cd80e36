"""One validation case: what is simulated, how it is filmed, how it is measured.

A case file is TOML with three sections (every key optional; the defaults are the built-in
case of ``rollfric validate``)::

    name = "default"

    [scenario]                 # the sim scenario form (sim/scenario.py), bench units
    ball = { diameter_mm = 10.0, mass_g = 4.07612 }
    environment = { air_density_kg_m3 = 1.204, air_drag = "law" }   # room air
    motion = { mu = 0.0079, theta0_deg = 20.0, seconds = 2.0 }
    engine = { name = "reference", surface = "tangent" }

    [render]                   # synth
    lighting = "thesis"        # lighting preset: thesis, dim, harsh, uneven, flat, backlit
    intensity_scale = 1.0      # multiplies every lamp's intensity
    lamp_spread = 1.0          # multiplies every lamp's x (sideways distance from the axis)
    lamp_dy_mm = 0.0           # moves every lamp up (+) or down
    lamp_dz_mm = 0.0           # moves every lamp towards (+) or away from the ball plane
    ambient = 0.03             # (optional) overrides the preset's ambient light
    noise = "realistic"        # sensor preset: none, realistic, noisy, 10bit, 12bit, 14bit, dark
    motion_blur = 1            # sub-frames integrated over the exposure (1: none)
    supersample = 1            # ss x ss samples per pixel (plus 4x MSAA)
    shadows = true
    renderer = "pyrender"      # or "mitsuba": path traced (rollfric[mitsuba]; spp etc. in
                               #   [render.scene]: mitsuba_spp, mitsuba_base_spp, ...)
    seed = 0                   # seed of the sensor noise (and of Mitsuba's samples)
    [render.sensor]            # overrides of the preset: read_noise, full_well, shot_noise,
    read_noise = 8.0           #   exposure, gain, bit_depth, prnu, dsnu, vignetting, ...
    [render.camera]            # width, height, center_px, projection, working_distance
    width = 1280
    roll_deg = 0.5             # camera rolled: the trough bottom appears at theta = +0.5 deg
    yaw_deg = 0.0              # optical axis turned towards +x / +y about the ball plane's
    pitch_deg = 0.0            #   axis point (the trough's faces shift by 15 mm x sin)
    principal_px = [639.5, 511.5]   # perspective: the optical axis in the image (default
                               #   center_px: the pinhole on the trough's axis)
    lens_distortion = [-0.18, 0.0, 0.0, 0.0, 0.0]   # OpenCV k1 k2 p1 p2 k3 (synth.distortion)
    lens_matrix = [[2400.0, 0.0, 639.5], [0.0, 2400.0, 511.5], [0.0, 0.0, 1.0]]
    f_number = 8.0             # a thin lens (synth.defocus): blur varying with depth
    focus_distance_mm = 485.0  #   in focus from the lens (default: working distance = ball)
    focal_length_mm = 50.0     #   (default 50 mm; aperture diameter f / N)
    [render.timing]            # the camera's timing (synth.camera_clock), drawn with render.seed
    jitter_us = 5.0            # each exposure's start about frame / fps: std. dev. (us)
    drop_rate = 0.001          # each frame lost with this probability
    dropped = [120, 640]       # camera frames lost (numbered as taken; on top of drop_rate)
    timestamps = true          # the recording carries each frame's real time (default false)
    [render.video]             # the recording measured as a compressed video (synth.video)
    codec = "mjpeg"            # "mjpeg" (.avi, quality = JPEG quality 1..100) or "h264"
    quality = 75               #   (.mp4, quality = x264's crf 0..51: lower is better)

    [lab]                      # blind mode: the lab's setup file (validation/lab.py)
    cylinder = { radius_mm = 85.3, radius_mm_u = 0.05 }   # nominal values the lab types
    center_error_px = [0.3, -0.2]   # the lab measured the trough centre (absent: contour)
    draw = false               # true: as-built values drawn from nominal +- _u (lab.seed)

    [measure]                  # rollfric
    locator = "subpixel"       # subpixel, thesis-large, thesis-small
    fit = "lsq"                # lsq, paper1_eps, paper2_grid
    offset = "auto"            # fit the trough bottom's angle: true, false, "auto" (rollfric's
                               # default: when the track has three turning points or more)
    oracle = false             # true: rollfric gets the exact geometry and center_px
    budget = true              # the uncertainty budget (u_mu, U_mu, z_budget, ...); false: off
    second_order = false       # true: the budget with its second-order row (--second-order)

Blind mode (the default): rollfric gets only what a lab has: the [lab] setup file (nominal
values; no center_px unless the lab measured it), the recording and its background. The
[scenario] is the as-built truth. ``measure.oracle = true`` hands rollfric the renderer's own
setup instead (exact geometry and center_px), to isolate the locator.

A case is kept as this plain dict (validated by :func:`case_from_dict`), so sweeps can address
any key by its dotted path (``render.sensor.read_noise``) and hash it.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import sim
from rollfric.errors import InputError
from rollfric.setup.model import setup_from_dict
from rollfric.setup.schema import Key, Messages, Schema, check_section
from synth import config as sc
from synth.camera import CameraModel
from synth.camera_clock import FrameTiming
from synth.video import VideoSpec
from validation.case_dict import (
    CaseError,
    case_id,
    default_case_dict,
    load_case_dict,
    merge_case,
)
from validation.lab import apply_asbuilt, parse_lab

# render.camera angles in lab units: roll_deg (the trough bottom appears at +roll_deg), yaw_deg
# and pitch_deg (the optical axis turned towards +x / +y about the ball plane's axis point)
ANGLE_KEYS = {"roll_deg": "roll", "yaw_deg": "yaw", "pitch_deg": "pitch"}
# render.camera thin lens (synth.defocus) in lab units: f_number (a plain number) with the
# distance in focus from the lens (default: the working distance, the ball's plane) and the
# lens's focal length (default 50 mm), both in mm
MM_KEYS = {"focus_distance_mm": "focus_distance", "focal_length_mm": "focal_length"}
LOCATORS = ("subpixel", "thesis-large", "thesis-small")
FITS = ("lsq", "paper1_eps", "paper2_grid")

# The case's own tables (rollfric.setup.schema); [scenario] and [lab] have their own readers,
# render.sensor/camera/scene override synth's dataclasses (checked against their fields)
CASE_SCHEMA = Schema(
    sections={
        "render": (
            Key("lighting", "str"), Key("intensity_scale", "float"),
            Key("lamp_spread", "float"), Key("lamp_dy_mm", "float"), Key("lamp_dz_mm", "float"),
            Key("ambient", "float"), Key("noise", "str"), Key("motion_blur", "int"),
            Key("supersample", "int"), Key("shadows", "bool"), Key("seed", "int"),
            Key("sensor", "table"), Key("camera", "table"), Key("scene", "table"),
            Key("lamps", "list"), Key("renderer", "str"), Key("timing", "table"),
            Key("video", "table")),
        # synth.camera_clock.FrameTiming in lab units
        "render.timing": (Key("jitter_us", "float"), Key("drop_rate", "float"),
                          Key("dropped", "list"), Key("timestamps", "bool")),
        "render.video": (Key("codec", "str"), Key("quality", "int")),  # synth.video
        "measure": (Key("locator", "str", choices=LOCATORS), Key("fit", "str", choices=FITS),
                    Key("offset", ("bool", "str")), Key("oracle", "bool"),
                    Key("budget", "bool"), Key("second_order", "bool")),
    },
    error=CaseError,
    messages=Messages(not_table="{source}: {section} must be a table, got {value!r}",
                      unknown_key="unknown key {source}: {section}.{key} (known: {known})",
                      kind_names=()),
)


# -- dict helpers ---------------------------------------------------------------------------


# -- the validated case ---------------------------------------------------------------------

@dataclasses.dataclass(frozen=True, eq=False)
class Case:
    """A validated case: the sim scenario, synth's scene and sensor, rollfric's methods."""

    name: str
    scenario: object  # sim.Scenario
    scene: object  # synth.config.SceneConfig
    sensor: object  # synth.config.SensorConfig
    render_seed: int
    locator: str
    fit: str
    offset: bool | str  # True, False or "auto"
    data: dict  # the case dict it came from (merged over the defaults)
    oracle: bool = False  # rollfric gets the exact setup and center_px (else blind mode)
    lab: object = None  # validation.lab.Lab: the lab's nominal setup and the as-built truth
    timing: object = None  # synth.camera_clock.FrameTiming: the camera's jitter and dropped frames
    video: object = None  # synth.video.VideoSpec: measured through a compressed video

    @property
    def mode(self) -> str:
        """``"blind"`` (rollfric gets the lab's setup file) or ``"oracle"`` (the exact geometry)."""
        return "oracle" if self.oracle else "blind"

    def lab_setup_dict(self) -> dict:
        """The setup file the lab hands rollfric in blind mode (lab-file form)."""
        return self.lab.setup_dict(self.scene.camera.center_px, self.scene.camera)

    @property
    def case_id(self) -> str:
        """The case's id (:func:`case_id` of its data)."""
        return case_id(self.data)

    def to_toml(self) -> str:
        """The case as TOML text; running that file runs the same case.

        Returns
        -------
        str
        """
        return dumps_case(self.data)


def _case_seeded_lab(d: dict) -> dict:
    """The case's ``[lab]`` table with ``seed = "case"`` resolved: the draws seeded by the
    case's own id (the hash of everything else in the case), so that every case of a sweep
    gets its own as-built setup instead of one draw per ``render.seed``."""
    lab = d.get("lab", {})
    if not isinstance(lab, dict) or lab.get("seed") != "case":
        return lab
    rest = {**d, "lab": {k: v for k, v in lab.items() if k != "seed"}}
    return {**lab, "seed": int(case_id(rest), 16)}


def case_from_dict(d: dict, source: str = "case") -> Case:
    """Validate a case dict (as from TOML, merged over the defaults) into a :class:`Case`.

    Parameters
    ----------
    d : dict
        The case in its TOML form.
    source : str, optional
        Where it came from, for the error messages.

    Returns
    -------
    Case

    Raises
    ------
    CaseError
        An unknown or bad key, named in the message.
    """

    d = merge_case(default_case_dict(), d, source)
    r = check_section(CASE_SCHEMA, "render", d.get("render", {}), source)
    try:
        scenario, lab, drawn = _scenario_and_lab(d, r, source)
    except InputError as exc:
        raise CaseError(str(exc)) from None
    m = check_section(CASE_SCHEMA, "measure", d.get("measure", {}), source)
    if m.get("offset", "auto") not in (True, False, "auto"):
        raise CaseError(f"{source}: measure.offset must be true, false or \"auto\", "
                        f"got {m['offset']!r}")
    try:
        lighting = _lighting(r, source)
        sensor = sc.noise_preset(r.get("noise", "realistic"))
        sensor_over = dict(r.get("sensor", {}))
        _known(sensor_over, sensor, f"{source}: render.sensor")
        sensor = dataclasses.replace(sensor, **sensor_over)
        cam = _camera(r, CameraModel(pixel_size=scenario.pixel_size), drawn, source)
        scene_over = dict(r.get("scene", {}))
        scene = sc.SceneConfig(camera=cam, lighting=lighting)
        _known(scene_over, scene, f"{source}: render.scene")
        for k in ("motion_blur", "supersample", "shadows", "renderer"):
            if k in r:
                scene_over[k] = r[k]
        scene = dataclasses.replace(scene, **scene_over)
    except CaseError:
        raise
    except InputError as exc:
        raise CaseError(f"{source}: render: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise CaseError(f"{source}: render: {exc}") from None
    seed = r.get("seed", 0)
    if seed < 0:
        raise CaseError(f"{source}: render.seed must be >= 0, got {seed!r}")
    name = d.get("name", "case")
    if not isinstance(name, str):
        raise CaseError(f"{source}: name must be a string")
    timing = _timing(r.get("timing"), source)
    video = _video(r.get("video"), source)
    case = Case(name=name, scenario=scenario, scene=scene, sensor=sensor, render_seed=seed,
                locator=m.get("locator", "subpixel"), fit=m.get("fit", "lsq"),
                offset=m.get("offset", "auto"), data=d, oracle=m.get("oracle", False), lab=lab,
                timing=timing, video=video)

    try:
        setup_from_dict(case.lab_setup_dict(), source=f"{source} [lab]")
    except InputError as exc:
        raise CaseError(str(exc)) from None
    return case


def _scenario_and_lab(d: dict, r: dict, source: str) -> tuple:
    """The as-built scenario, the lab's side and the draws it made ("section.key" -> value):
    the [scenario] read, the [lab] read against it, the scenario rebuilt with the draws."""

    scenario = sim.scenario_from_dict(d.get("scenario", {}), source=f"{source} [scenario]")
    as_toml = scenario.to_toml_dict()
    cam_px = dict(r.get("camera", {})).get("pixel_size")
    if isinstance(cam_px, (int, float)) and not isinstance(cam_px, bool):
        as_toml["camera"]["pixel_size_mm"] = float(cam_px) * 1e3  # the camera's own
    seed0 = r.get("seed", 0)
    lab, drawn = parse_lab(_case_seeded_lab(d), as_toml, source=source,
                           default_seed=seed0 if isinstance(seed0, int) else 0)
    if drawn:
        scenario = sim.scenario_from_dict(apply_asbuilt(d.get("scenario", {}), drawn),
                                          source=f"{source} [scenario] (as built)")
    return scenario, lab, drawn


def _lighting(r: dict, source: str):
    """render's lighting preset with its lamps (or render.lamps) scaled, spread and moved."""

    lighting = sc.lighting_preset(r.get("lighting", "thesis"))
    lamps = r.get("lamps")
    if lamps is not None:
        lamps = tuple(sc.Lamp(**_lamp_si(lp, source)) for lp in lamps)
    else:
        lamps = lighting.lamps
    scale = r.get("intensity_scale", 1.0)
    spread = r.get("lamp_spread", 1.0)
    dy = r.get("lamp_dy_mm", 0.0) / 1000.0
    dz = r.get("lamp_dz_mm", 0.0) / 1000.0
    if scale < 0:
        raise CaseError(f"{source}: render.intensity_scale must be >= 0, got {scale!r}")
    lamps = tuple(dataclasses.replace(
        lp, intensity=lp.intensity * scale,
        position=(lp.position[0] * spread, lp.position[1] + dy, lp.position[2] + dz))
        for lp in lamps)
    return dataclasses.replace(lighting, lamps=lamps, ambient=r.get("ambient", lighting.ambient))


def _camera(r: dict, cam, drawn: dict, source: str):
    """The camera ``cam`` with render.camera's overrides (angles in deg, lens distances in mm)."""
    cam_over = dict(r.get("camera", {}))
    if "camera.pixel_size_mm" in drawn:
        cam_over.pop("pixel_size", None)  # the drawn as-built pixel size
    _known({k: v for k, v in cam_over.items() if k not in ANGLE_KEYS and k not in MM_KEYS},
           cam, f"{source}: render.camera")
    if "center_px" in cam_over:
        cam_over["center_px"] = tuple(cam_over["center_px"])
    for key, field in ANGLE_KEYS.items():  # lab units (deg) -> the camera's radians
        if key in cam_over:
            cam_over[field] = math.radians(_finite(cam_over.pop(key),
                                                   f"{source}: render.camera.{key}"))
    for key, field in MM_KEYS.items():  # lab units (mm) -> the camera's metres
        if key in cam_over:
            cam_over[field] = _finite(cam_over.pop(key),
                                      f"{source}: render.camera.{key}") / 1000.0
    if "f_number" in cam_over:
        cam_over["f_number"] = _finite(cam_over["f_number"], f"{source}: render.camera.f_number")
    return dataclasses.replace(cam, **cam_over)


def _timing(table, source: str):
    """render.timing (lab units) -> synth.camera_clock.FrameTiming, or None."""
    if table is None:
        return None

    t = check_section(CASE_SCHEMA, "render.timing", table, source)
    dropped = t.get("dropped", [])
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in dropped):
        raise CaseError(f"{source}: render.timing.dropped must be a list of frame numbers, "
                        f"got {dropped!r}")
    try:
        return FrameTiming(jitter=t.get("jitter_us", 0.0) * 1e-6,
                           drop_rate=t.get("drop_rate", 0.0), dropped=tuple(dropped),
                           timestamps=t.get("timestamps", False))
    except InputError as exc:
        raise CaseError(f"{source}: render.timing: {exc}") from None


def _video(table, source: str):
    """render.video -> synth.video.VideoSpec, or None."""
    if table is None:
        return None

    v = check_section(CASE_SCHEMA, "render.video", table, source)
    try:
        return VideoSpec(**v)
    except InputError as exc:
        raise CaseError(f"{source}: render.video: {exc}") from None


def _finite(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise CaseError(f"{where} must be a finite number, got {v!r}")
    return float(v)


def _known(over: dict, obj, where: str) -> None:
    names = {f.name for f in dataclasses.fields(obj)}
    for k in over:
        if k not in names:
            raise CaseError(f"unknown key {where}.{k} (known: {', '.join(sorted(names))})")


def _lamp_si(lp: dict, source: str) -> dict:
    """A lamp table in bench units (position_mm, target_mm, intensity, cones in deg) -> SI."""
    if not isinstance(lp, dict):
        raise CaseError(f"{source}: render.lamps entries must be tables")
    out = {}
    for k, v in lp.items():
        if k in ("position_mm", "target_mm"):
            out[k[:-3]] = tuple(float(x) / 1000.0 for x in v)
        elif k in ("inner_cone_deg", "outer_cone_deg"):
            out[k[:-4]] = math.radians(v)
        elif k == "intensity":
            out[k] = float(v)
        else:
            raise CaseError(f"{source}: unknown lamp key {k!r} (position_mm, target_mm, "
                            "intensity, inner_cone_deg, outer_cone_deg)")
    return out


def load_case(path: str | Path) -> Case:
    """Read and validate a case TOML file (merged over the defaults).

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    Case

    Raises
    ------
    CaseError
        A missing or invalid file, an unknown or bad key.
    """
    return case_from_dict(load_case_dict(path), source=str(path))


def dumps_case(d: dict) -> str:
    """The case dict as TOML text (tables nested; loads back to the same dict).

    Parameters
    ----------
    d : dict

    Returns
    -------
    str
    """
    def fmt(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float):
            return repr(v) if math.isfinite(v) else ("nan" if v != v else
                                                     ("inf" if v > 0 else "-inf"))
        if isinstance(v, int):
            return str(v)
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(fmt(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {fmt(x)}" for k, x in v.items()) + " }"
        raise TypeError(f"cannot write {v!r} to TOML")

    lines: list[str] = []

    def table(prefix: str, t: dict):
        scalars = {k: v for k, v in t.items() if not isinstance(v, dict)}
        subs = {k: v for k, v in t.items() if isinstance(v, dict)}
        if prefix and (scalars or not subs):
            lines.append(f"[{prefix}]")
        lines.extend(f"{k} = {fmt(v)}" for k, v in scalars.items())
        if scalars or not subs:
            lines.append("")
        for k, v in subs.items():
            table(f"{prefix}.{k}" if prefix else k, v)

    table("", d)
    return "\n".join(lines)
