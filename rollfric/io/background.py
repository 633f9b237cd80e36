"""The background of a recording that comes without one: the per-pixel median of frames spread
over it, repaired where the ball rested in most of them.

A median is the background only where the ball covers a pixel in fewer than half of the frames.
A ball released from rest that comes to rest again, filmed on, sits at its rest place in most
frames: the median holds it there, the frames with the ball at rest equal the median there (no
ball to find), and the frames with the ball elsewhere show the revealed backdrop at the rest
place as a ball-sized change that stays put. That "hole" is how it is found here: a ball-like
change at one place in nearly every frame that shows a change at all, while the ball itself
moves. Its disc (and that of a cast shadow at rest, found the same way) is then taken from the
median of the frames that show the hole, i.e. the frames in which the backdrop is visible there.
"""

from __future__ import annotations

import math

import numpy as np

from rollfric import locate
from rollfric.io.limits import check_memory

# a place counts as the median's ball when a change sits there in this share of the frames
# that show any change (the moving ball visits one place in far fewer)
HOLE_SHARE = 0.8
MIN_FRAMES_SHOWING = 3


def sample(source, max_frames: int = 41) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``max_frames`` frames spread evenly over the recording.

    Streamed: at most ``max_frames`` frames are held at once.

    Parameters
    ----------
    source : FrameSource
        The recording (``len``, ``shape``, ``dtype`` and ``source[i]``).
    max_frames : int, optional
        How many frames to sample (at least 3, at most the recording's length).

    Returns
    -------
    indices : numpy.ndarray
        The sampled frame indices, increasing.
    stack : numpy.ndarray
        The sampled frames, shape (k, H, W), the recording's dtype.
    """
    n = len(source)
    k = min(n, max(3, int(max_frames)))
    idx = np.unique(np.linspace(0, n - 1, k).round().astype(int))
    h, w = source.shape[1:]
    # the stack, its median and the repair's pixel grids
    check_memory(len(idx) * h * w * np.dtype(source.dtype).itemsize + 4 * 8 * h * w,
                 f"the median background of {len(idx)} frames of {w} x {h} px")
    stack = np.empty((len(idx),) + tuple(source.shape[1:]), dtype=source.dtype)
    for j, i in enumerate(idx):
        stack[j] = source[int(i)]
    return idx, stack


def median(stack: np.ndarray) -> np.ndarray:
    """Per-pixel median of a stack of frames, rounded to the frames' dtype.

    Parameters
    ----------
    stack : numpy.ndarray
        Frames, shape (k, ...).

    Returns
    -------
    numpy.ndarray
        The median over the first axis, in ``stack.dtype``.
    """
    return np.rint(np.median(stack, axis=0)).astype(stack.dtype)


def median_background(source, r_px: float, max_frames: int = 41, *,
                      full_scale: float | None = None) -> tuple[np.ndarray, list]:
    """The per-pixel median of up to ``max_frames`` frames, repaired where the ball rested.

    The discs where the ball (or its cast shadow) rested in most of the sampled frames are
    replaced by the median of the frames that show the backdrop there.

    Parameters
    ----------
    source : FrameSource
        The recording.
    r_px : float
        The ball's radius in pixels.
    max_frames : int, optional
        Frames in the median.
    full_scale : float, optional
        The camera's full scale, 2**bit_depth - 1 (DN), for the search of the ball in the
        sampled frames (:func:`rollfric.locate.coarse_candidates`); default the frames' word's.

    Returns
    -------
    background : numpy.ndarray
        The background image, the recording's dtype.
    notes : list of str
        What was repaired, or why it could not be (then a background image is needed).
    """
    idx, stack = sample(source, max_frames)
    bg, notes, _ = repaired_median(stack, r_px, full_scale=full_scale)
    return bg, notes


def repaired_median(stack: np.ndarray, r_px: float, *,
                    full_scale: float | None = None) -> tuple[np.ndarray, list, list]:
    """:func:`median_background` of sampled frames: (background, notes, sources).

    ``sources``: (disc mask, frame numbers in ``stack``) of each repaired disc, the frames
    its pixels were taken from (every other pixel is the median of all of them).
    """
    bg = median(stack)
    cands = [locate.coarse_candidates(f, bg, r_px, n_candidates=3, full_scale=full_scale)
             for f in stack]
    showing = [j for j, c in enumerate(cands) if c]
    quiet = len(stack) - len(showing)
    if quiet == 0:
        return bg, [], []
    if len(showing) < MIN_FRAMES_SHOWING:
        return bg, [f"the ball shows against the median background in only {len(showing)} "
                    f"of {len(stack)} sampled frames: if it rests in one place for most of the "
                    "recording the median holds it there; give a background image"], []
    holes = _holes([cands[j] for j in showing], r_px)
    if not holes:
        return bg, [], []
    repaired = bg.copy()
    h, w = bg.shape
    yy, xx = np.mgrid[0:h, 0:w]
    notes, sources = [], []
    for x, y, frames_with in holes:
        rad = 1.5 * r_px + 3.0
        disc = (xx - x) ** 2 + (yy - y) ** 2 <= rad * rad
        use = [showing[k] for k in frames_with]
        repaired[disc] = median(stack[use][:, disc])
        sources.append((disc, use))
        notes.append(f"the median background held a resting ball (or its shadow) at "
                     f"({x:.1f}, {y:.1f}) px, unseen in {quiet} of {len(stack)} sampled frames; "
                     f"that disc was taken from the {len(use)} frames showing the backdrop there")
    return repaired, notes, sources


def only_about(cands_per_frame: list, x0: float, y0: float, r_px: float) -> int:
    """Frames whose every candidate lies within r of (x0, y0) but none within r/2: the ball
    resting there against a median that holds it, whose rim's faint change is neither the
    backdrop revealed there nor a ball elsewhere (they count in no share of the place)."""
    n = 0
    for cs in cands_per_frame:
        d = [math.hypot(c[0] - x0, c[1] - y0) for c in cs]
        n += bool(d) and max(d) <= r_px and min(d) > 0.5 * r_px
    return n


def _holes(cands_per_frame: list, r_px: float) -> list:
    """Places (x, y, [frame numbers]) where a candidate sits within r/2 in at least HOLE_SHARE
    of the frames (those showing only a faint change about the place left out:
    :func:`only_about`)."""
    n = len(cands_per_frame)
    points = [(c[0], c[1], k) for k, cs in enumerate(cands_per_frame) for c in cs]
    holes = []
    for x0, y0, _ in points:
        if any(math.hypot(x0 - hx, y0 - hy) < r_px for hx, hy, _ in holes):
            continue
        near = [(x, y, k) for x, y, k in points if math.hypot(x - x0, y - y0) <= 0.5 * r_px]
        frames_with = sorted({k for _, _, k in near})
        n_eff = n - only_about(cands_per_frame, x0, y0, r_px)
        if len(frames_with) >= max(MIN_FRAMES_SHOWING, HOLE_SHARE * n_eff):
            xs = np.median([x for x, _, _ in near])
            ys = np.median([y for _, y, _ in near])
            holes.append((float(xs), float(ys), frames_with))
    return holes
