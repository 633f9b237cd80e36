"""A case as a plain dict: the built-in defaults, dotted-key overrides, the case file read and
merged, and the case's identity (a hash of its canonical JSON).

Sweeps address any key of a case by its dotted path (``render.sensor.read_noise``) and hash it;
:func:`validation.case.case_from_dict` checks such a dict and makes the typed
:class:`validation.case.Case` of it.
"""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path

from rollfric.errors import InputError
from rollfric.setup.tomlfile import read_toml


class CaseError(InputError):
    """A validation case that cannot be run (the message names the bad key)."""

TOP_KEYS = ("name", "scenario", "render", "lab", "measure")

SCENARIO_SECTIONS = ("cylinder", "ball", "camera", "environment", "motion", "engine")

DEFAULT_SECONDS = 2.0

ROOM_AIR_DENSITY = 1.204  # kg/m^3, dry air at 20 C and 1013 hPa (sim.losses)

def default_case_dict() -> dict:
    """The built-in case of ``rollfric validate``.

    The thesis's 10 mm ball, mu 0.0079, in room air (1.204 kg/m^3, drag by rollfric.fit.air's law,
    which the lab's setup file states by its density), thesis lighting, realistic noise, the
    full 1280 x 1024 thesis camera, 2 s of 1000 Hz frames, no motion-blur sub-frames (the blur
    study covers blur; 4 sub-frames would triple the render time).

    Returns
    -------
    dict
        The case in its TOML form (a new dict on every call).
    """
    return {
        "name": "default",
        "scenario": {
            "ball": {"diameter_mm": 10.0, "mass_g": 4.07612},
            # room air, with the drag law the fitter models (the lab's setup carries the
            # density, not the engine's Cd: rollfric.fit.air)
            "environment": {"air_density_kg_m3": ROOM_AIR_DENSITY, "air_drag": "law"},
            "motion": {"mu": 0.0079, "theta0_deg": 20.0, "seconds": DEFAULT_SECONDS},
            "engine": {"name": "reference", "surface": "tangent", "seed": 0},
        },
        "render": {"lighting": "thesis", "noise": "realistic", "motion_blur": 1,
                   "supersample": 1, "shadows": True, "seed": 0},
        "measure": {"locator": "subpixel", "fit": "lsq", "offset": "auto"},
    }

def small_case_dict(seconds: float = 0.4) -> dict:
    """A cheap case for tests and quick checks.

    The 10 mm ball swinging 8 deg, seen by a cropped 320 x 112 px camera that just holds its
    path, no motion blur. The crop shows too little of the trough's contour to find its centre:
    the lab measured it (error 0).

    Parameters
    ----------
    seconds : float, optional
        Length of the recording (s).

    Returns
    -------
    dict
        The case in its TOML form.
    """
    d = default_case_dict()
    d["name"] = "small"
    d["scenario"]["motion"].update(theta0_deg=8.0, seconds=seconds)
    d["render"].update(motion_blur=1, camera={"width": 320, "height": 112,
                                              "center_px": [160.0, -540.0]})
    d["lab"] = {"center_error_px": [0.0, 0.0]}
    return d

def _merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out

def set_dotted(d: dict, key: str, value) -> None:
    """``d["a"]["b"]["c"] = value`` for key ``"a.b.c"``, creating tables on the way.

    Parameters
    ----------
    d : dict
        Nested tables, changed in place.
    key : str
        Dotted key.
    value
        The value to set.

    Raises
    ------
    CaseError
        An empty part of the key, or a part that is a value, not a table.
    """
    parts = key.split(".")
    if not all(parts):
        raise CaseError(f"bad parameter key {key!r}")
    cur = d
    for p in parts[:-1]:
        nxt = cur.setdefault(p, {})
        if not isinstance(nxt, dict):
            raise CaseError(f"parameter {key!r}: {p!r} is not a table")
        cur = nxt
    cur[parts[-1]] = copy.deepcopy(value)

def get_dotted(d: dict, key: str, default=None):
    """``d["a"]["b"]["c"]`` for key ``"a.b.c"``.

    Parameters
    ----------
    d : dict
        Nested tables.
    key : str
        Dotted key.
    default : optional
        Returned when the key is absent.

    Returns
    -------
    object
        The value, or ``default``.
    """
    cur = d
    for p in key.split("."):
        if not isinstance(cur, dict) or p not in cur:
            return default
        cur = cur[p]
    return cur

def apply_overrides(base: dict, overrides: dict) -> dict:
    """A copy of a case with dotted-key overrides set.

    Parameters
    ----------
    base : dict
        The case (not modified).
    overrides : dict
        Dotted keys and their values, e.g. ``{"render.motion_blur": 4}``.

    Returns
    -------
    dict
    """
    out = copy.deepcopy(base)
    for k, v in overrides.items():
        set_dotted(out, k, v)
    return out

def load_case_dict(path: str | Path) -> dict:
    """A case TOML file merged over the defaults.

    A plain sim scenario file (top-level [ball], [motion], ...) is taken as the [scenario] of a
    default case.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

    Returns
    -------
    dict
        The case in its TOML form.

    Raises
    ------
    CaseError
        A missing or invalid file, or an unknown top-level key.
    """
    data = read_toml(path, "case", CaseError)
    if data and set(data) <= set(SCENARIO_SECTIONS):
        data = {"scenario": data}
    return merge_case(default_case_dict(), data, source=str(path))

def merge_case(base: dict, data: dict, source: str = "case") -> dict:
    """A case merged over a base, table by table.

    Parameters
    ----------
    base : dict
        The base case.
    data : dict
        The case read from a file.
    source : str, optional
        Where it came from, for the error message.

    Returns
    -------
    dict

    Raises
    ------
    CaseError
        An unknown top-level key.
    """
    unknown = sorted(set(data) - set(TOP_KEYS))
    if unknown:
        raise CaseError(f"{source}: unknown top-level key(s) {unknown} "
                        f"(known: {', '.join(TOP_KEYS)})")
    return _merge(base, data)

def canonical_json(d: dict) -> str:
    """Canonical JSON of a dict: sorted keys, no spaces (the input of :func:`case_id`).

    Parameters
    ----------
    d : dict

    Returns
    -------
    str
    """
    return json.dumps(d, sort_keys=True, separators=(",", ":"), default=str)

def case_id(d: dict) -> str:
    """12 hex digits of SHA-256 over the case's canonical JSON (its name left out).

    Parameters
    ----------
    d : dict
        The case in its TOML form.

    Returns
    -------
    str
    """
    body = {k: v for k, v in d.items() if k != "name"}
    return hashlib.sha256(canonical_json(body).encode()).hexdigest()[:12]
