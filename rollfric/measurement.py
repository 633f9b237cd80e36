"""The measurement as a recipe: from a recording to its track, how it was measured, and mu.

:func:`measure` is a sequence of steps, each a function where its concept lives: open the
recording and read the camera's bit depth and frame times -> the background
(:func:`rollfric.io.background_choice.resolve_background`) -> the trough's centre
(:func:`rollfric.geometry.trough_center.trough_center`) -> the track
(:func:`rollfric.track.tracker.track_recording`) -> a held start and a rest
(:mod:`rollfric.track.still`) -> the camera's motion (:mod:`rollfric.track.camera_motion`) ->
the fit (the offset decision :mod:`rollfric.fit.offset`, frames lost where the ball turns
:func:`rollfric.track.dropped_frames.turning_gaps`) -> the ellipses' checks
(:mod:`rollfric.geometry.ellipse_checks`) -> the quality (:mod:`rollfric.uncertainty.quality`).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import time

import numpy as np

from rollfric.errors import InputError
from rollfric.fit import estimate as fitmod
from rollfric.fit.offset import resolve_offset
from rollfric.fit.start import MIN_SAMPLES
from rollfric.geometry.ellipse_checks import contour_check, path_check, path_replaces_contour
from rollfric.geometry.theta import ANGLES
from rollfric.geometry.trough_center import trough_center
from rollfric.io import bitdepth
from rollfric.io import readers as io
from rollfric.io.background_choice import resolve_background
from rollfric.registry import LOCATORS
from rollfric.setup.model import Setup, load_setup
from rollfric.track.camera_motion import correct_for_motion
from rollfric.track.dropped_frames import turning_gaps
from rollfric.track.precision import estimate_precision
from rollfric.track.setup_checks import (
    ball_radius_px,
    check_setup_fits,
    check_track_fits,
    setup_from_recording,
)
from rollfric.track.steadied import SteadiedSource
from rollfric.track.still import mark_still, median_without_still
from rollfric.track.timestamps import (
    TIMES_FPS,
    fps_mismatch,
    frame_times,
    irregular_message,
    located_frames_reason,
)
from rollfric.track.tracker import track_recording
from rollfric.uncertainty import quality

logger = logging.getLogger(__name__)  # messages: info (what was done), warning (check this)


def measure(recording, setup: Setup | str | None = None, background=None, *,
            method: str = "subpixel", angle: str = "atan2", fit_method: str = "lsq",
            offset: bool | str = "auto", fit: bool = True, progress: bool = False,
            median_frames: int = 41, fit_kwargs: dict | None = None,
            times: str = "auto", drops: bool = True,
            segments: int | str = "auto", background_from: str = "median"):
    """Measure mu from a recording: (track DataFrame, TrackInfo, FitResult or None).

    ``recording``: a path (see :func:`rollfric.io.readers.open_recording`) or a FrameSource.
    ``setup``: a Setup, a path to a setup TOML, or None to take it from the recording's attrs.
    ``background``: an image path or array; None: the recording's own, else the per-pixel
    median of ``median_frames`` frames (reported in ``info.background``).
    Messages go to the ``rollfric`` loggers (this module's and its steps'): info (what was
    chosen), warning (what to check; the warnings are also in ``info.warnings``).
    ``method``: "subpixel" (default), "thesis-large" or "thesis-small".
    ``times``: "auto" (the recording's per-frame timestamps when it has them, else frame /
    camera.fps) or "fps" (always frame / camera.fps); see
    :func:`rollfric.track.timestamps.frame_times`.
    ``drops``: without timestamps, find dropped frames from the ball's steps
    (:func:`rollfric.track.dropped_frames.find_gaps`) and, with the "lsq" fit, where it turns
    (:func:`rollfric.track.dropped_frames.turning_gaps`), and move the later frames' t_s by the
    periods lost.
    ``offset``: fit the angle of the trough's bottom too (True), not (False), or "auto" (the
    default): where the data support it (:func:`rollfric.fit.offset.offset_supported`), which
    corrects a camera rolled about its axis (0.5 deg of roll: mu +0.67 % without the offset).
    The track has the columns TRACK_COLUMNS (+ r_px, sigma_px, inlier_frac); the
    :class:`rollfric.track.track_info.TrackInfo` beside it holds the setup used, center_px,
    background, n_frames, n_found, the locator, the warnings and the rest.

    Parameters
    ----------
    recording : str, path-like or FrameSource
        The recording.
    setup : Setup, str, path-like or None
        The setup, a setup TOML, or None: the recording's own.
    background : str, path-like, numpy.ndarray or None
        The background image without the ball.
    method, angle, times : str
        The locator, the angle formula and the frame times (above).
    fit_method : str
        How mu is fitted (:func:`rollfric.fit.estimate.fit_mu`).
    offset : bool or "auto"
        Fit the angle of the trough's bottom.
    fit : bool
        Fit mu; False returns the track only, its centres as located (the camera's motion
        is not looked for).
    progress : bool
        Show a progress bar on stderr.
    median_frames : int
        Frames in the median background when there is none.
    background_from : {"median", "max", "clip"}
        How the background is made from the frames when none is given
        (:func:`rollfric.io.background_choice.resolve_background`): the per-pixel median (default),
        or for a backlit rig (a dark ball on a bright field) the per-pixel maximum less its
        noise bias, or a flat field at the backlight's level. A median or maximum that holds
        the ball where it goes is rebuilt from the frames clear of it, or refused.
    fit_kwargs : dict or None
        More keywords of :func:`rollfric.fit.estimate.fit_mu`.
    drops : bool
        Find and repair dropped frames (above).
    segments : int or "auto"
        Track the recording in this many segments
        (:func:`rollfric.track.tracker.track_recording`).

    Returns
    -------
    track : pandas.DataFrame
        One row a frame (above).
    info : rollfric.track.track_info.TrackInfo
        How the track was measured (above).
    result : rollfric.fit.estimate.FitResult or None
        The fit, its quality reasons including the track's
        (:func:`rollfric.uncertainty.quality.check_track`);
        None when ``fit=False``.

    Raises
    ------
    rollfric.errors.InputError
        Bad input: an unreadable recording, an unknown method, angle or offset, too few frames
        (refused on opening, before the tracking) or found frames to fit.
    rollfric.setup.model.SetupError
        A setup that does not fit the images (recording size, trough contour, ball radius).

    Examples
    --------
    The sample recording shipped with rollfric (400 frames of a 10 mm steel ball rendered
    with mu = 0.0079), measured with its lab setup file:

    >>> import tempfile, rollfric
    >>> from pathlib import Path
    >>> from rollfric.sample import write_sample
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = write_sample(Path(tmp.name) / "sample")
    >>> track, info, result = rollfric.measure(folder / "frames.tif", folder / "setup.toml")
    >>> len(track), int(track["found"].sum())
    (400, 400)
    >>> round(result.mu, 4), result.quality
    (0.0079, 'ok')
    >>> tmp.cleanup()
    """

    stages = _Stages()
    source, setup = _opened(recording, setup, angle=angle, method=method, fit=fit)
    camera = _camera(source, setup, times)
    stages.lap("open")
    bg = _Background(*resolve_background(source, background, median_frames=median_frames,
                                          r_px=ball_radius_px(setup), kind=background_from,
                                          full_scale=camera.full_scale))
    stages.lap("background")
    axis = _trough_center(bg.image, setup, source.shape, camera.full_scale)
    stages.lap("trough centre")
    track = functools.partial(_tracked, source, setup, method=method, angle=angle,
                              center=axis.center, progress=progress, times=camera.track_times,
                              drops=drops, segments=segments,
                              bit_depth=camera.bits)
    df, info = track(bg.image)
    still_notes = mark_still(df, setup)
    if still_notes and bg.notes and bg.desc.startswith("per-pixel median"):
        # the ball held or at rest made the median hold it: the median of the other frames
        df, info, still_notes, bg = _without_still(source, df, info, still_notes, bg, setup,
                                                   median_frames, camera.full_scale, track)
    if fit:  # the measurement's; without a fit the track as located
        def steadied(shifts):  # tracked again with the frames moved back (a moved camera)
            return functools.partial(_tracked, SteadiedSource(source, shifts), *track.args[1:],
                                     **track.keywords)(bg.image)

        df, info = correct_for_motion(source, bg.image, df, info, setup, angle,
                                      retrack=steadied)
        if (info.camera_motion or {}).get("kind") in ("bump", "drift"):
            still_notes = mark_still(df, setup)
    n_found = int(df["found"].sum())  # what the track was measured with, into its TrackInfo
    info = dataclasses.replace(info, setup=setup, background=bg.desc, center_source=axis.source,
                               background_from="given" if background is not None else
                               "recording" if bg.desc == "stored in the recording" else
                               background_from,
                               center_u_px=axis.center_u,
                               n_frames=len(df), n_found=n_found,
                               recording=str(getattr(source, "name", recording)),
                               times=camera.times,
                               warnings=info.warnings + tuple(bg.notes) + axis.notes
                               + tuple(camera.notes) + tuple(still_notes))
    if n_found < len(df):
        logger.info(f"ball not found in {len(df) - n_found} of {len(df)} frames"
                    + (" (left out of the fit)" if fit else ""))
    stages.lap("tracking")
    result = None
    if fit:
        result, info, used = _fitted(df, info, setup, offset=offset, fit_method=fit_method,
                                     fit_kwargs=fit_kwargs, drops=drops, stages=stages)
        info, result = _checked(df, info, result, setup, axis, bg.coded, offset=used,
                                angle=angle, fit_method=fit_method, fit_kwargs=fit_kwargs,
                                stages=stages)
        info = _with_precision(source, bg.image, df, info, result)
        stages.lap("locator precision")
    return df, dataclasses.replace(info, seconds=stages.seconds), result


def _with_precision(source, background, df, info, result):
    """The info with the locator's precision on these frames: the Cramér-Rao bound from a
    few tens of found frames and the fit's reached scatter along the path."""
    rms = getattr(result, "rms_residual", None)
    prec = estimate_precision(source, background, df, r_px=info.ball_radius_px,
                              rms_residual_rad=rms if rms is not None and np.isfinite(rms)
                              else None, track_radius_px=info.track_radius_px)
    return dataclasses.replace(info, locator_precision=prec.json())


class _Stages:
    """The wall time of each stage of a measurement (``TrackInfo.seconds``)."""

    def __init__(self) -> None:
        self.seconds: dict = {}  # stage -> wall time (s)
        self._mark = time.perf_counter()

    def lap(self, stage: str) -> None:
        """Add the time since the last lap to ``stage``."""
        now = time.perf_counter()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + now - self._mark
        self._mark = now


@dataclasses.dataclass(frozen=True)
class _Camera:
    """The camera's bit depth and the frame times, with the notes on them."""

    bits: int
    full_scale: float
    t: np.ndarray
    times: str  # TrackInfo.times
    notes: list

    @property
    def track_times(self):
        """The times the tracker is given: None where they are frame / camera.fps."""
        return None if self.times == TIMES_FPS else self.t


@dataclasses.dataclass(frozen=True)
class _Background:
    """The background image, where it came from, and its notes."""

    image: np.ndarray
    desc: str
    notes: list
    suspect: bool = True  # whether its notes make the measurement suspect

    @property
    def coded(self) -> list:
        """The notes that make the measurement suspect."""
        return self.notes if self.suspect else []


def _opened(recording, setup, *, angle: str, method: str, fit: bool):
    """The recording opened and its setup, the request checked before any frame is tracked:
    (source, setup)."""
    source = io.open_recording(recording) if isinstance(recording, (str, bytes)) or \
        hasattr(recording, "__fspath__") else recording
    if setup is None:
        setup = setup_from_recording(source)
    elif not isinstance(setup, Setup):
        setup = load_setup(setup)
    if angle not in ANGLES:
        raise InputError(f"unknown angle method {angle!r} (known: {', '.join(ANGLES)})")
    LOCATORS.check(method)
    check_setup_fits(setup, source.shape)
    if fit and len(source) < MIN_SAMPLES:  # refused before any frame is tracked
        raise InputError(f"{getattr(source, 'name', recording)}: the recording has only "
                         f"{len(source)} frames: at least {MIN_SAMPLES} are needed to fit "
                         "mu; rollfric track writes the track of a recording of any length")
    return source, setup


def _camera(source, setup: Setup, times: str) -> _Camera:
    """The camera's bit depth and the frame times; their notes logged as warnings."""
    # the camera's bit depth: every threshold and the saturation test use its full scale
    bits, bits_how, bits_notes = bitdepth.resolve_bit_depth(source, setup.bit_depth)
    fs = bitdepth.full_scale(bits)
    logger.info(f"the camera's bit depth: {bits} (from the {bits_how}; full scale {fs:.0f} DN)")
    t, times_desc, time_notes = frame_times(source, setup.fps, times)
    # a recording with its own per-frame times is checked against them (frame_times), one
    # without against the rate in its header
    fps_note = fps_mismatch(getattr(source, "fps", None), setup.fps) \
        if times_desc == TIMES_FPS else None
    time_notes = time_notes + ([fps_note] if fps_note else []) + bits_notes
    for msg in time_notes:
        logger.warning(msg)
    return _Camera(bits=bits, full_scale=fs, t=t, times=times_desc, notes=time_notes)


def _trough_center(background, setup: Setup, shape, full_scale: float):
    """The trough's centre (:func:`rollfric.geometry.trough_center.trough_center`), the setup
    checked with a centre found from the contour, then the contour's notes logged."""
    axis = trough_center(background, setup, shape, full_scale=full_scale)
    if setup.center_px is None:
        check_setup_fits(setup.replace(center_px=axis.center), shape)
    for note in axis.notes:
        logger.warning(note)
    return axis


def _tracked(source, setup: Setup, background, **kwargs):
    """:func:`rollfric.track.tracker.track_recording`, its ball radius and found frames
    checked (:func:`rollfric.track.setup_checks.check_track_fits`)."""
    df, info = track_recording(source, setup, background, **kwargs)
    check_track_fits(df, setup)
    return df, info


def _without_still(source, df, info, still_notes, bg: _Background, setup: Setup,
                   median_frames: int, full_scale: float, track):
    """The median background made again from the frames in which the ball is neither held
    nor at rest, and the recording tracked again with it where it differs: (df, info,
    still_notes, bg). The background's notes then say so and no longer make the measurement
    suspect."""
    got = median_without_still(source, df, bg.image, ball_radius_px(setup), median_frames,
                               full_scale=full_scale)
    if got is None:
        return df, info, still_notes, bg
    image, same, k2 = got
    if not same:
        logger.warning("the median background differs from the median of the frames "
                       "in which the ball is neither held nor at rest: tracking again "
                       "with the latter")
        df, info = track(image)
        still_notes = mark_still(df, setup)
        desc = (f"per-pixel median of the {k2} sampled frames in which the ball is "
                "neither held nor at rest")
    else:
        image = bg.image
        desc = bg.desc + (f" (as the median of the {k2} sampled frames in which the ball is "
                          "neither held nor at rest)")
    notes = [f"{m} (the ball held or at rest there: the median of the {k2} sampled "
             "frames without it agrees)" if same else
             f"{m} (the ball held or at rest there: tracked again with the median of "
             f"the {k2} sampled frames without it)" for m in bg.notes]
    return df, info, still_notes, _Background(image, desc, notes, suspect=False)


def _swing(df):
    """The track's times, its angles with a held start and a rest left out (NaN; no part of
    the swing), and those rows."""
    t_s, th = df["t_s"].to_numpy(), df["theta_rad"].to_numpy()
    still_rows = (df["still"] != "").to_numpy()  # a held start, a rest: not the motion
    return t_s, np.where(still_rows, np.nan, th), still_rows


def _fitted(df, info, setup: Setup, *, offset, fit_method: str, fit_kwargs, drops: bool,
            stages: _Stages):
    """mu fitted to the track: the offset decided, then frames lost where the ball turns
    found (``df``'s t_s moved): (result, info, whether the offset was fitted)."""
    if len(df) < MIN_SAMPLES:
        raise InputError(f"the recording has only {len(df)} frames: at least "
                         f"{MIN_SAMPLES} are needed to fit mu")
    if info.n_found < MIN_SAMPLES:
        raise InputError(f"the ball was found in only {info.n_found} of {len(df)} frames: at "
                         f"least {MIN_SAMPLES} are needed to fit mu")
    t_s, th, _ = _swing(df)
    use, why = resolve_offset(offset, t_s, th, setup, fit_method)
    info = dataclasses.replace(info, offset_fitted=use, offset_reason=why)
    if offset == "auto":
        logger.info(f"angle offset of the trough bottom {'fitted' if use else 'not fitted'}: "
                    f"{why}")
    result = fitmod.fit_mu(t_s, th, setup, method=fit_method, offset=use, **(fit_kwargs or {}))
    stages.lap("fit")
    if info.times == TIMES_FPS and drops and fit_method == "lsq":
        t_new, result, turned = turning_gaps(t_s, th, result, setup, use, fit_kwargs)
        if turned:
            df["t_s"] = t_new
            dropped = tuple(sorted(info.frames_dropped + turned))
            msg = (f"{len(turned)} dropped frame(s) found where the ball turns (after "
                   f"frame(s) {', '.join(str(k) for k, _ in turned)}), by the fit: the "
                   "later frames' t_s are moved by a period each")
            logger.warning(msg)
            info = dataclasses.replace(info, frames_dropped=dropped,
                                       warnings=info.warnings + (msg,))
        stages.lap("turning points")
    return result, info, use


def _checked(df, info, result, setup: Setup, axis, bg_coded, *, offset: bool, angle: str,
             fit_method: str, fit_kwargs, stages: _Stages):
    """The measurement's checks: the contour's and the path's ellipses (a tilted camera
    corrected), then the quality reasons of the background, the ball's radius, the timing,
    the swing's coverage and the track added to the fit's: (info, result)."""
    t_s, th, still_rows = _swing(df)
    coded = [("background_repaired", f"{msg}: a background image without the ball "
              "(--background) rules out a trace of it") for msg in bg_coded]
    if axis.ellipse is not None:
        info, ell_coded = contour_check(axis.ellipse, info, t_s, th, setup, result, offset,
                                        fit_method, fit_kwargs)
        coded += ell_coded
        stages.lap("ellipse check")
    info, result, path_coded = path_check(df, info, axis.center, setup, result, offset,
                                          fit_method, fit_kwargs, angle)
    info, coded = path_replaces_contour(info, coded + path_coded)
    stages.lap("path check")
    coded += [("ball_radius", msg) for msg in info.warnings_radius]
    if info.timing_irregular:
        coded.append(("timing", irregular_message(info.timing_irregular)))
    if info.located_irregular:
        coded.append(("located_frames", located_frames_reason(info)))
    # a held start and a rest are no part of the swing (their times left out)
    swung = result if not still_rows.any() or np.shape(result.t) != still_rows.shape else \
        dataclasses.replace(result, t=np.where(still_rows, np.nan, result.t))
    side = quality.swing_coverage_reason(df["found"].to_numpy() == 1, swung, setup)
    if side is not None:
        coded.append((side.code, side.message))
    track_reasons = quality.check_track(df, setup, axis.center, warnings=coded,
                                        flag_counts=info.flags)
    # a period off is judged again with the ball's path in the image: it tells a wrong
    # radius from a camera clock that is off
    seen = quality.track_radius_seen(df, setup, axis.center)
    fit_reasons = tuple(result.quality_reasons) if seen is None else tuple(
        quality.period_with_image(r, setup, seen) for r in result.quality_reasons)
    result = dataclasses.replace(result, quality_reasons=fit_reasons + tuple(track_reasons))
    stages.lap("checks")
    return info, result
