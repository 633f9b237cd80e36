"""The lab's error sources of the ``systematics`` study, and which one a case of it has.

Each :class:`Source` of :data:`SOURCES` recognises its cases by their parameters (a row of the
sweep table) and gives its magnitude in the table's unit and whether rollfric's correction of
it was on. A case's source is the first of :data:`SOURCES` that recognises it
(:func:`classify`); a case no source recognises (a source added to the sweep file by someone
else) is its own source, named after its swept keys, its magnitude the first number among
their values.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable

# swept keys that say how a case was measured, not which error it has
CORRECTION_KEYS = ("measure.offset", "lab.lens_calibrated", "lab.camera.matrix",
                   "lab.camera.distortion", "measure.oracle", "render.seed", "stages")


def cell_number(v):
    """A number from a table cell (None, NaN, bool and text are None)."""
    if isinstance(v, bool) or v is None:
        return None
    if isinstance(v, str):
        try:
            v = json.loads(v)
        except ValueError:
            return None
        return cell_number(v) if not isinstance(v, list) else None
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _list(v):
    if isinstance(v, str):
        try:
            v = json.loads(v)
        except ValueError:
            return None
    return list(v) if isinstance(v, (list, tuple)) else None


def _offset_on(row) -> bool:
    v = row.get("measure.offset")
    return not (v is False or v == "false" or v == "False")


@dataclasses.dataclass(frozen=True)
class Source:
    """One error source of the study.

    Attributes
    ----------
    name : str
        What the table calls it.
    unit : str
        The magnitude's unit.
    magnitude : callable
        row (dict: the sweep's parameters and metrics) -> the source's magnitude, or None when
        the case is not this source's.
    typical : str
        A lab's range and where it comes from.
    corrected : callable or None
        row -> whether rollfric's correction of this source was on; None: rollfric has none.
    origin : bool
        Magnitude 0 is no error (the interpolation starts from (0, 0)).
    """

    name: str
    unit: str
    magnitude: Callable
    typical: str
    corrected: Callable | None = None
    origin: bool = True


def _lab_err(col: str, scale: Callable = lambda e, row: -e):
    def f(row):
        e = cell_number(row.get(f"lab_err_{col}"))
        if e is None or e == 0.0:
            return None
        return scale(e, row)
    return f


def _rel(col: str, factor: float):
    def scale(e, row):
        nominal = cell_number(row.get(f"lab_{col}"))
        return -e / nominal * factor if nominal else None
    return scale


def _center(i: int):
    def f(row):
        v = _list(row.get("lab.center_error_px"))
        if v is None or len(v) != 2 or v[i] == 0 or v[1 - i] != 0:
            return None
        return float(v[i])
    return f


def _key(key: str, index: int | None = None, when: Callable | None = None):
    def f(row):
        if when is not None and not when(row):
            return None
        v = row.get(key)
        if index is not None:
            v = _list(v)
            v = v[index] if v is not None and len(v) > index else None
        v = cell_number(v)
        return None if v is None or v == 0.0 else v
    return f


def _lens_calibrated(row) -> bool:
    v = row.get("lab.lens_calibrated")
    return v is True or v == "true" or v == "True" or row.get("lab.camera.matrix") is not None


def _aperture(at_ball: bool):
    """Defocus (render.camera.f_number): the aperture's diameter f / N (mm), for a case focused
    on the ball's plane (``at_ball``) or elsewhere (the trough's front face)."""
    def f(row):
        n = cell_number(row.get("render.camera.f_number"))
        if n is None:
            return None
        wd = (cell_number(row.get("render.camera.working_distance")) or 0.5) * 1000.0
        focus = cell_number(row.get("render.camera.focus_distance_mm"))
        if (focus is None or abs(focus - wd) < 0.01) != at_ball:
            return None
        return (cell_number(row.get("render.camera.focal_length_mm")) or 50.0) / n
    return f


SOURCES: tuple[Source, ...] = (
    Source("trough radius as built - nominal", "mm",
           _lab_err("cylinder_radius_mm"),
           "+-0.1 .. 0.3 mm: the bore of a machined block (the thesis gives 85.3 mm without a "
           "tolerance)"),
    Source("ball diameter as built - nominal", "mm", _lab_err("ball_diameter_mm"),
           "+-0.02 mm: a caliper reading (grade balls are better than 1 um)"),
    Source("pixel scale as built - nominal", "%",
           _lab_err("camera_pixel_size_mm", _rel("camera_pixel_size_mm", 100.0)),
           "+-0.5 %: a ruler in the ball's plane"),
    Source("frame rate as built - nominal", "ppm",
           _lab_err("camera_fps", _rel("camera_fps", 1e6)),
           "+-100 ppm: the camera's crystal"),
    Source("trough centre measured by the lab, x error", "px", _center(0),
           "+-1 .. 2 px by eye on the background (the thesis: within 1 px)", _offset_on),
    # the fitted offset does not touch a centre off along y (it scales the angles): no correction
    Source("trough centre measured by the lab, y error", "px", _center(1),
           "+-1 .. 2 px by eye on the background"),
    Source("camera roll", "deg", _key("render.camera.roll_deg"),
           "+-1 deg levelled by eye, +-0.1 .. 0.2 deg with a spirit level on the camera",
           _offset_on),
    Source("lens k1 at fx = 2400 px", "1",
           _key("render.camera.lens_distortion", 0),
           "-0.05 .. -0.2: C-mount lenses of 12 .. 25 mm", _lens_calibrated),
    Source("pinhole camera at working distance", "m",
           _key("render.camera.working_distance",
                when=lambda row: row.get("render.camera.projection") == "perspective"),
           "0.3 .. 1 m (the ball's plane 15 mm behind the trough's front face)",
           lambda row: cell_number(row.get("lab.camera.working_distance_mm")) is not None,
           origin=False),
    Source("camera pitch (optical axis tilted up or down)", "deg",
           _key("render.camera.pitch_deg"), "+-1 deg: a camera aligned by eye"),
    Source("camera yaw (optical axis tilted sideways)", "deg", _key("render.camera.yaw_deg"),
           "+-1 deg: a camera aligned by eye"),
    Source("trough out of round (D_max - D_min), major axis horizontal", "mm",
           _key("scenario.cylinder.ovality_mm",
                when=lambda row: (cell_number(row.get("scenario.cylinder.ovality_angle_deg"))
                                  or 0.0) == 0.0),
           "tens of um: a machined bore (rollfric fits the contour's ellipse and warns)"),
    Source("trough out of round (D_max - D_min), major axis vertical", "mm",
           _key("scenario.cylinder.ovality_mm",
                when=lambda row: cell_number(
                    row.get("scenario.cylinder.ovality_angle_deg")) == 90.0),
           "tens of um: a machined bore (rollfric fits the contour's ellipse and warns)"),
    Source("trough axis tilted along its length", "deg", _key("scenario.cylinder.tilt_deg"),
           "0.01 .. 0.05 deg: levelled with a spirit level"),
    Source("frame-time jitter (standard deviation)", "us", _key("render.timing.jitter_us"),
           "below 1 us for a high-speed camera's clock; tens of us for a webcam"),
    Source("dropped frames (rate), found from the motion", "1",
           _key("render.timing.drop_rate",
                when=lambda row: row.get("render.timing.timestamps") not in (True, "true",
                                                                             "True")),
           "none in a high-speed camera's memory; a USB or capture path can drop frames"),
    Source("dropped frames (rate), the recording's timestamps", "1",
           _key("render.timing.drop_rate",
                when=lambda row: row.get("render.timing.timestamps") in (True, "true", "True")),
           "as above, in a format that keeps each frame's time (cine, Zarr)"),
    Source("MJPEG video, quality (100 = best)", "1",
           _key("render.video.quality", when=lambda row: row.get("render.video.codec") == "mjpeg"),
           "75 .. 95: a camera program's export", origin=False),
    Source("H.264 video, crf (0 = lossless)", "1",
           _key("render.video.quality", when=lambda row: row.get("render.video.codec") == "h264"),
           "18 .. 28: a video export for sharing", origin=False),
    Source("defocus, focus on the trough's front face: aperture f / N", "mm", _aperture(False),
           "f/2.8 .. f/16 of a 50 mm lens (17.9 .. 3.1 mm): a lab focuses on what it sees "
           "sharpest, the contour 15 mm before the ball"),
    Source("defocus, focus on the ball's plane: aperture f / N", "mm", _aperture(True),
           "f/2.8 .. f/16 of a 50 mm lens (17.9 .. 3.1 mm)"),
    Source("air drag, Cd (room air 1.2 kg/m^3)", "1",
           _key("scenario.environment.air_cd",
                when=lambda row: (cell_number(row.get("scenario.environment.air_density_kg_m3"))
                                  or 0.0) > 0),
           "always there: Cd 0.47 (smooth sphere) .. 1-4 at Re 30 .. 170 near a wall"),
    Source("rolling resistance rising with speed, mu_speed", "s/m",
           _key("scenario.motion.mu_speed_s_m"),
           "unknown for steel on aluminium; rollfric's --model velocity fits it"),
)


def classify(row: dict, swept: list[str]) -> tuple[str, float | None, str, object]:
    """(source name, magnitude, unit, corrected) of one case.

    Parameters
    ----------
    row : dict
        The case's row of the sweep table (parameters and metrics).
    swept : list of str
        The sweep's swept keys (for sources not in :data:`SOURCES`).

    Returns
    -------
    tuple
        The source's name ("none" for a case without an error), its magnitude (None for
        "none"), its unit and whether rollfric's correction was on (None: it has none).
    """
    for s in SOURCES:
        m = s.magnitude(row)
        if m is not None:
            return s.name, m, s.unit, (None if s.corrected is None else bool(s.corrected(row)))
    keys = [k for k in swept if k not in CORRECTION_KEYS and row.get(k) is not None
            and not (isinstance(row.get(k), float) and math.isnan(row.get(k)))]
    if not keys:
        return "none", None, "", None
    mag = None
    for k in keys:
        v = row.get(k)
        lst = _list(v)
        mag = cell_number(lst[0]) if lst else cell_number(v)
        if mag is not None:
            break
    corrected = None
    if "measure.offset" in swept and row.get("measure.offset") is not None:
        corrected = _offset_on(row)
    return ", ".join(keys), mag, "", corrected
