"""Frame times: the recording's timestamps or frame / camera.fps, and what they tell.

:func:`frame_times` reads and checks a recording's own per-frame times (their unit, their rate
against the setup's, their spacing), :func:`fps_mismatch` a header's rate; the messages of the
dropped frames and of the irregular steps found from the ball's motion
(:mod:`rollfric.track.dropped_frames`), and the quality reason of the frames the locator lost
(:func:`located_frames_reason`).
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.errors import InputError
from rollfric.track import plausibility
from rollfric.track.track_info import TrackInfo

TIMES = ("auto", "fps")
# the recording's timestamps are checked against the setup's rate and for even spacing
TIMES_RATE_TOL = 1e-3  # relative: a median interval further from 1 / camera.fps is reported
TIMES_JITTER_TOL = 0.01  # relative: an interval further from the median one is reported
TIMES_FPS = "frame / camera.fps"  # TrackInfo.times when the times are not the recording's
# timestamps whose median step is ~1000 or ~1e6 frame periods of the setup's rate are in ms or
# us, not s (read as seconds they gave mu 0.297 for 0.02): within this factor of the unit's
# ratio (a camera clock 10 % off, or a setup's rate that is, is still told from 1000x)
TIMES_UNITS = (("ms", 1e-3), ("us", 1e-6))
TIMES_UNIT_FACTOR = 1.5
# the frame flags that do not depend on the frame times (the tracker's and the plausibility
# checks' but jump and duplicate, which a timing error also raises): an irregular step at or
# next to such a frame is the locator's (rollfric.track.dropped_frames.split_irregular)
LOCATOR_FLAGS = tuple(f for f in plausibility.FLAGS if f not in ("jump", "duplicate"))


def fps_mismatch(recording_fps, setup_fps: float) -> str | None:
    """A note when the recording carries a frame rate other than the setup's, else None.

    The setup's rate is the one used: a high-speed camera's video export often carries a
    playback rate (25, 30 fps), not the rate the frames were taken at.

    Parameters
    ----------
    recording_fps : float or None
        The frame rate in the recording's header (Hz); None or 0 when it has none.
    setup_fps : float
        The setup's camera.fps (Hz).

    Returns
    -------
    str or None
        The note, or None when the rates agree to 1e-6 or the recording gives none.
    """
    if not recording_fps or abs(recording_fps - setup_fps) <= 1e-6 * setup_fps:
        return None
    return (f"the recording says {recording_fps:g} frames/s, the setup {setup_fps:g} Hz: times "
            "use the setup's (camera.fps); a video export's rate is often a playback rate")


def frame_times(source, setup_fps: float, times: str = "auto"):
    """(t, description, notes): the time (s) of each frame of ``source`` from frame 0.

    ``times="auto"``: the recording's own per-frame times when it has them (``timestamps``, e.g.
    a Phantom cine's TIME64 block: the camera's clock, so a dropped frame or a rate other than
    the nominal one shows), else frame / ``setup_fps``; ``"fps"``: always frame / ``setup_fps``.
    ``notes`` say where the timestamps disagree with the setup's rate (by more than
    TIMES_RATE_TOL and the clock's step) or are unevenly spaced (an interval more than
    TIMES_JITTER_TOL from the median one, beyond the step of the camera's clock,
    ``attrs["timestamp_resolution_s"]``: times rounded to whole microseconds are 28 or 29 us
    apart at 35087 Hz, no dropped frame). Timestamps whose steps are ~1000 or ~1e6 of the
    setup's frame periods (within TIMES_UNIT_FACTOR) are read as ms or us, and a note names
    the unit.

    Parameters
    ----------
    source : FrameSource
        The recording; its ``timestamps`` (s) are used when it has them.
    setup_fps : float
        The setup's camera.fps (Hz).
    times : str
        "auto" or "fps".

    Returns
    -------
    t : numpy.ndarray
        The time of each frame (s), 0 at frame 0.
    description : str
        "the recording's timestamps" or "frame / camera.fps".
    notes : list of str
        What to check about the timestamps.

    Raises
    ------
    rollfric.errors.InputError
        An unknown ``times``.
    """
    if times not in TIMES:
        raise InputError(f"unknown times {times!r} (known: {', '.join(TIMES)})")
    n = len(source)
    stamps = getattr(source, "timestamps", None) if times == "auto" else None
    if stamps is None:
        return np.arange(n) / setup_fps, TIMES_FPS, []
    t = np.asarray(stamps, dtype=float)
    if t.shape != (n,) or not np.all(np.isfinite(t)) or (n > 1 and np.any(np.diff(t) <= 0)):
        return np.arange(n) / setup_fps, TIMES_FPS, [
            "the recording's timestamps are not one increasing time a frame: times use the "
            "setup's camera.fps"]
    t = t - t[0]
    notes = []
    if n > 1:
        ratio = float(np.median(np.diff(t))) * setup_fps
        for unit, scale in TIMES_UNITS:
            if abs(math.log(ratio * scale)) <= math.log(TIMES_UNIT_FACTOR):
                t = t * scale
                notes.append(f"the recording's timestamps step by {ratio / setup_fps:.6g} a "
                             f"frame, {ratio:.4g} x the setup's frame period (camera.fps = "
                             f"{setup_fps:g} Hz): they are in {unit}, not seconds, and are "
                             f"read as {unit}")
                break
        d = np.diff(t)
        dt = float(np.median(d))
        # a clock that counts in steps (a cine's microseconds) makes intervals a step apart
        res = (getattr(source, "attrs", None) or {}).get("timestamp_resolution_s")
        res = float(res) if isinstance(res, (int, float)) and res > 0 else 0.0
        if abs(dt * setup_fps - 1.0) > TIMES_RATE_TOL + res * setup_fps:
            notes.append(f"the recording's timestamps are {dt * 1e3:.6g} ms apart (median: "
                         f"{1 / dt:.6g} frames/s), the setup says {setup_fps:g} Hz: times are "
                         "the recording's timestamps; check camera.fps")
        off = np.abs(d - dt) > TIMES_JITTER_TOL * dt + res
        if off.any():
            notes.append(f"{int(off.sum())} of the recording's {n - 1} frame intervals differ "
                         f"from the median {dt * 1e3:.6g} ms by more than "
                         f"{100 * TIMES_JITTER_TOL:g} % ({float(d.min()) * 1e3:.6g} to "
                         f"{float(d.max()) * 1e3:.6g} ms: dropped frames?); times are the "
                         "recording's timestamps")
    return t, "the recording's timestamps", notes


def dropped_message(gaps) -> str:
    """The message of the dropped frames found (:func:`rollfric.track.dropped_frames.find_gaps`).

    Parameters
    ----------
    gaps : rollfric.track.dropped_frames.Gaps

    Returns
    -------
    str
    """
    where = ", ".join(f"{m} after frame {k}" for k, m in gaps.dropped[:8])
    more = f" and {len(gaps.dropped) - 8} more" if len(gaps.dropped) > 8 else ""
    return (f"{gaps.n_dropped} dropped frame(s) found from the ball's steps ({where}{more}): "
            "the later frames' t_s are moved by the periods lost; a step slower than "
            f"{gaps.min_step_px:.2g} px a frame (near the turning points) would hide one")


def irregular_message(irregular) -> str:
    """The message (and quality reason "timing") of steps that fit no whole number of periods.

    Parameters
    ----------
    irregular : sequence of (int, float)
        (frame, step ratio) pairs (:attr:`rollfric.track.dropped_frames.Gaps.irregular`).

    Returns
    -------
    str
    """
    return (f"{_irregular_steps(irregular)}: the timing is irregular there and cannot be "
            "repaired from the motion; a recording with timestamps would tell")


def _irregular_steps(steps) -> str:
    """"N step(s) of the ball fit no whole number of frame periods (frame k (r x), ...)"."""
    where = ", ".join(f"frame {k} ({r:.2f} x)" for k, r in steps[:8])
    return f"{len(steps)} step(s) of the ball fit no whole number of frame periods ({where})"


def located_irregular_message(located_irregular) -> str:
    """The message of irregular steps among frames the locator lost or got wrong.

    Parameters
    ----------
    located_irregular : sequence of (int, float)
        (frame, step ratio) pairs (:attr:`TrackInfo.located_irregular`).

    Returns
    -------
    str
    """
    return (f"{_irregular_steps(located_irregular)} at frames the locator lost or that failed "
            "the plausibility checks: the located centres are off there (a ball in shadow, half "
            "lit), not the timing")


def located_frames_reason(info: TrackInfo) -> str:
    """The quality reason "located_frames": what the locator lost or got wrong, with the
    irregular steps it caused (:attr:`TrackInfo.located_irregular`).

    Parameters
    ----------
    info : TrackInfo

    Returns
    -------
    str
    """
    bad = ", ".join(f"{k} {v}" for k, v in info.flags.items() if k in LOCATOR_FLAGS)
    return (f"the ball was located and accepted in {info.n_found} of {info.n_frames} frames "
            f"({100.0 * info.n_found / max(info.n_frames, 1):.1f} %; {bad}); "
            + located_irregular_message(info.located_irregular)
            + ": the centres next to the lost and rejected frames may be off too (check the "
            "lighting, the shadows, the overlays)")
