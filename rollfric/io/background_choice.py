"""The background a measurement uses: the given image, the recording's own, or one made.

:func:`resolve_background` chooses and checks it: an image (a multi-page TIFF refused: a
recording given as the background), the recording's stored one, or one made from sampled
frames (the per-pixel median repaired where the ball rested, the maximum of a backlit rig, or
a flat field at the backlight's level), made free of the ball where it goes
(:mod:`rollfric.io.ballfree`).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import tifffile

from rollfric.errors import InputError
from rollfric.io import ballfree
from rollfric.io import readers as io
from rollfric.io.background import repaired_median, sample

logger = logging.getLogger(__name__)

# sampled frames the same as the next (a held start, a ball at rest): fewer than this share of
# the ball's area changed by more than STILL_SIGMAS robust sigmas of their difference (a
# moving ball changes 1.5-2.5 x its area between two samples, a still one none)
STILL_SHARE = 0.25
STILL_SIGMAS = 6.0
STILL_RUN_SHARE = 0.1  # of the sampled frames, at the least, in a still run left out


def _moving(idx, stack, r_px: float):
    """The sampled frames to make a median of: all but a run at the start or end in which
    nothing moves (a held start, a ball at rest: each frame the same as the next to the noise,
    fewer than STILL_SHARE of the ball's area changed beyond STILL_SIGMAS robust sigmas; a tenth
    of the samples at least), which holds the ball in place and would put it in the median;
    all when fewer than a quarter would be left. Returns (mask, note or '')."""
    s = stack.astype(np.float32)
    if s.ndim == 4:
        s = s.mean(axis=3)
    same = []
    for a, b in zip(s[:-1], s[1:], strict=True):
        d = a - b
        d -= np.median(d)  # a flicker's or exposure's change of the whole frame
        sigma = 1.4826 * float(np.median(np.abs(d)))
        same.append(np.sum(np.abs(d) > max(STILL_SIGMAS * sigma, 1.0))
                    < STILL_SHARE * math.pi * r_px * r_px)
    same = np.array(same, dtype=bool)
    k = len(s)
    head = int(np.argmin(same)) if not same.all() else k - 1  # pairs still from the start
    tail = int(np.argmin(same[::-1])) if not same.all() else k - 1
    moving = np.ones(k, dtype=bool)
    # a run of a tenth of the samples at least: a ball released from rest moves less than a
    # pixel between the first few samples of a short clip, and a median is not spoiled by them
    least = max(2, math.ceil(STILL_RUN_SHARE * k))
    if head >= least:  # frames 0 .. head - 1 still (the last of the run is where it moves off)
        moving[:head] = False
    if tail >= least:
        moving[k - tail:] = False
    if moving.all() or moving.sum() < max(3, k // 4):
        return np.ones(k, dtype=bool), ""
    parts = ([f"the first {head} (a held start, frames {idx[0]}-{idx[head - 1]})"]
             if not moving[0] else []) + \
        ([f"the last {tail} (the ball at rest from frame {idx[k - tail]})"]
         if not moving[-1] else [])
    return moving, (f"the median background is made from the {int(moving.sum())} sampled "
                    f"frames in which the ball moves, not {' or '.join(parts)}: a still ball "
                    "would be in it")


def _tiff_pages(path) -> int:
    """Pages in a TIFF file (1 for other files, and for a TIFF tifffile cannot read: reading it
    as an image then says what is wrong)."""
    if Path(path).suffix.lower() not in io.TIFF_SUFFIXES:
        return 1
    try:
        with tifffile.TiffFile(path) as tif:
            return len(tif.pages)
    except Exception:  # noqa: BLE001 - any failure is read_image's to report
        return 1


def resolve_background(source, background, *, r_px: float, median_frames: int = 41,
                       kind: str = "median", full_scale: float | None = None):
    """The background: the given image, the recording's own, or one made from the frames.

    Made from ``median_frames`` frames spread over the recording, by ``kind``
    (:data:`rollfric.io.ballfree.KINDS`): "median", the per-pixel median
    (:func:`rollfric.io.background.median_background`), repaired where the ball of radius
    ``r_px`` rested in most of the frames; "max", the per-pixel maximum less its noise bias
    (a backlit rig's dark ball, :func:`rollfric.io.ballfree.max_background`); "clip", a flat
    field at the backlight's level (:func:`rollfric.io.ballfree.clip_background`). The median
    and the maximum are then made free of the ball where it goes
    (:func:`rollfric.io.ballfree.check_ball_free`), or refused. The notes say what was repaired
    or rebuilt, also as warnings of this module's logger.

    Parameters
    ----------
    source : FrameSource
        The recording.
    background : numpy.ndarray, str, pathlib.Path or None
        An image, an image file, or None.
    r_px : float
        The ball's radius (px).
    median_frames : int, optional
        Frames in the median.
    kind : {"median", "max", "clip"}, optional
        How a background is made from the frames when none is given.
    full_scale : float, optional
        The camera's full scale (DN) the ball is searched with in the sampled frames.

    Returns
    -------
    background : numpy.ndarray
        (H, W), the frames' size.
    description : str
        Where it came from (written to fit.json).
    notes : list of str
        What was repaired, or why not.

    Raises
    ------
    RecordingError
        An unreadable image, or one of another size than the frames.
    InputError
        An unknown ``kind``, or one given with a background image; a background made from
        the frames that holds the ball (:func:`rollfric.io.ballfree.check_ball_free`).
    """
    if kind not in ballfree.KINDS:
        raise InputError(f"unknown background {kind!r} (known: {', '.join(ballfree.KINDS)})")
    if background is not None and kind != "median":
        raise InputError(f"a background image and --background-from {kind} are two "
                         "backgrounds: give one")
    if background is not None:
        if isinstance(background, np.ndarray):
            return io.check_background(background, source), "given array", []
        pages = _tiff_pages(background)
        if pages > 1:
            raise InputError(f"background {background} holds {pages} pages (a recording?): give"
                             " one image of the scene without the ball, or no --background to"
                             " use the median of the recording's frames")
        bg = io.read_image(background)
        return io.check_background(bg, source, f"background {background}"), str(background), []
    if getattr(source, "background", None) is not None and kind == "median":
        return io.check_background(source.background, source, "the recording's background"), \
            "stored in the recording", []
    k = min(len(source), median_frames)
    idx, stack = sample(source, median_frames)
    if kind == "clip":
        bg, level = ballfree.clip_background(stack)
        logger.info(f"background: a flat field at the backlight's level, {level:g} DN")
        return bg, (f"clip level: a flat field at {level:g} DN (the backlight's level, the "
                    f"{ballfree.CLIP_PERCENTILE:g}th percentile of the median of {k} frames)"), []
    if kind == "max":
        bg, sigma = ballfree.max_background(stack)
        desc = (f"per-pixel maximum of {k} frames less its noise bias ({sigma:.3g} DN noise x "
                f"{ballfree.expected_max_normal(len(stack)):.3f})")
        bg, notes = ballfree.check_ball_free(stack, bg, r_px, kind="max", sigma=sigma,
                                             what=f"the per-pixel maximum of {k} frames",
                                             full_scale=full_scale)
    else:
        logger.info(f"no background given: using the per-pixel median of {k} frames spread "
                    "over the recording")
        moving, still_note = _moving(idx, stack, r_px)
        if still_note:
            stack, k = stack[moving], int(moving.sum())
        bg, notes, sources = repaired_median(stack, r_px, full_scale=full_scale)
        notes = ([still_note] if still_note else []) + notes
        desc = f"per-pixel median of {k} frames" + (", repaired" if notes else "")
        bg, more = ballfree.check_ball_free(stack, bg, r_px, sources=sources,
                                            what=f"the per-pixel median of {k} frames",
                                            full_scale=full_scale)
        notes = notes + more
        desc += ", rebuilt where it held the ball" if more else ""
    for msg in notes:
        logger.warning(msg)
    return bg, desc, notes
