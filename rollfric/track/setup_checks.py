"""Checks of a setup against a recording and its track, before and after the tracking.

The ball's radius in pixels (:func:`ball_radius_px`), the setup a Zarr recording carries
(:func:`setup_from_recording`), a setup whose ball cannot be seen in the frames
(:func:`check_setup_fits`) and a track whose ball contradicts the setup (:func:`check_track_fits`).
"""

from __future__ import annotations

import json
import math
import tomllib

import pandas as pd

from rollfric.errors import InputError
from rollfric.setup.lens import CalibrationError, check_image_size
from rollfric.setup.model import Setup, SetupError, setup_from_dict


def ball_radius_px(setup: Setup) -> float:
    """The setup's ball radius in pixels.

    Parameters
    ----------
    setup : Setup

    Returns
    -------
    float
        ball radius / pixel size.
    """
    return setup.ball_radius / setup.pixel_size



def setup_from_recording(source) -> Setup:
    """The setup stored in a Zarr recording's attributes.

    Parameters
    ----------
    source : FrameSource
        A recording whose ``attrs["setup"]`` holds the lab-file form (dict, JSON or TOML text).

    Returns
    -------
    Setup

    Raises
    ------
    SetupError
        The recording holds no setup, or a bad one.
    """
    data = source.attrs.get("setup") if hasattr(source, "attrs") else None
    if data is None:
        raise SetupError(f"{source.name}: no setup given (--setup) and the recording holds "
                         "none in its attrs")
    if isinstance(data, str):
        try:
            data = json.loads(data)
        except ValueError:
            try:
                data = tomllib.loads(data)
            except tomllib.TOMLDecodeError as exc:
                raise SetupError(f"{source.name} attrs['setup']: neither JSON nor valid TOML "
                                 f"({exc})") from None
    if not isinstance(data, dict):
        raise SetupError(f"{source.name} attrs['setup']: a table of the setup file's sections "
                         f"wanted, got {type(data).__name__}")
    return setup_from_dict(dict(data), source=f"{source.name} attrs['setup']")


def check_setup_fits(setup: Setup, shape: tuple[int, int, int]) -> None:
    """Refuse a setup whose ball cannot be seen in frames of this size.

    Parameters
    ----------
    setup : Setup
    shape : tuple of int
        (T, H, W) of the recording.

    Raises
    ------
    SetupError
        The ball is under 1.5 px in radius or larger than the frame, (with ``center_px``)
        its track circle does not cross the frame, or the lens calibration was made on images
        of another size (:func:`rollfric.setup.lens.check_image_size`).
    """
    _, h, w = shape
    try:
        check_image_size(setup.calibration, w, h)
    except CalibrationError as exc:
        raise SetupError(str(exc)) from None
    r = ball_radius_px(setup)
    if r < 1.5:
        raise SetupError(f"the setup's ball is {2 * r:.2f} px across (diameter "
                         f"{setup.ball_diameter * 1e3:g} mm / pixel {setup.pixel_size * 1e3:g} "
                         "mm): too small to locate")
    if 2 * r >= min(h, w):
        raise SetupError(f"the setup's ball is {2 * r:.0f} px across but the frames are "
                         f"{w}x{h} px: check ball.diameter_mm and camera.pixel_size_mm")
    if setup.center_px is not None:
        xc, yc = setup.center_px
        L = setup.track_radius / setup.pixel_size
        # nearest and farthest frame points from the axis: the track circle must cross the frame
        nx, ny = min(max(xc, 0), w - 1), min(max(yc, 0), h - 1)
        near = math.hypot(nx - xc, ny - yc)
        far = max(math.hypot(cx - xc, cy - yc) for cx in (0, w - 1) for cy in (0, h - 1))
        if not (near - r <= L <= far + r):
            raise SetupError(f"with center_px = ({xc:g}, {yc:g}) and a track radius of "
                             f"{L:.0f} px the ball never appears in the {w}x{h} px frames: "
                             "check center_px, cylinder.radius_mm and camera.pixel_size_mm")



def check_track_fits(df: pd.DataFrame, setup: Setup) -> None:
    """Refuse a track whose ball radius contradicts the setup, or without any ball found.

    Parameters
    ----------
    df : pandas.DataFrame
        The track of :func:`track_recording`.
    setup : Setup
        The setup used.

    Raises
    ------
    rollfric.errors.InputError
        The ball was found in no frame.
    rollfric.setup.model.SetupError
        The ball's median fitted radius is more than 10 % off the setup's.
    """
    found = df["found"] == 1
    if not found.any():
        # the ball is looked for along the path the setup's centre and L = R - r put it on: a
        # camera pitched 8 deg moves a 3 px ball's path off it by its radius
        where = ("; and does it run where cylinder.center_px and L = R - r put its path (a "
                 "camera pitched or yawed against the trough moves the path off it)?"
                 if setup.center_px is not None else "?")
        raise InputError(
            f"the ball was found in none of the {len(df)} frames: is it in the recording, is the "
            f"background right, and is its size right (setup: {ball_radius_px(setup):.1f}"
            f" px radius){where}")
    rfit = df.loc[found, "r_px"].dropna()
    r_px = ball_radius_px(setup)
    if len(rfit) and abs(float(rfit.median()) - r_px) > 0.1 * r_px:
        raise SetupError(f"the setup does not fit the images: the ball measures "
                         f"{float(rfit.median()):.1f} px in radius, the setup says {r_px:.1f} px"
                         " (ball.diameter_mm / camera.pixel_size_mm)")
