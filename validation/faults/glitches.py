"""Glitched frames, as a lab's recordings have them: a seeded generator on frame arrays.

:func:`glitch_frames` takes a (T, H, W) stack and returns a glitched copy and what was done
to which frame, so a test can check that the measurement rejects every frame that no longer
shows the ball where it was at that frame's time. Kinds:

- ``band``: a band of rows (3-24) replaced by uniform noise (a corrupt transfer);
- ``swap``: frames i and i + ``swap_gap`` exchanged (both are wrong);
- ``repeat``: frame i + 1 replaced by a copy of frame i (a dropped frame re-sent);
- ``flash``: the frame ``flash_gain`` times brighter (a flash, a lamp's surge), clipped;
- ``bar``: a bar (mid-grey, 0.4 ball radii wide) across the ball for ``bar_frames``
  consecutive frames, sweeping over it (needs the ball's positions, ``centers``).

Everything random comes from ``seed``: same seed, same frames.
"""

from __future__ import annotations

import dataclasses

import numpy as np

KINDS = ("band", "swap", "repeat", "flash")


@dataclasses.dataclass(frozen=True)
class Glitch:
    """One glitched frame: its index, the kind, and whether its ball is misplaced (its pixels
    no longer show the ball where it was at this frame's time, e.g. a swapped frame)."""

    frame: int
    kind: str
    misplaced: bool = True


class _FreeFrames:
    """The frames not glitched yet (nor next to a glitched one), ``margin`` at both ends kept
    out; picks free frames with ``rng``."""

    def __init__(self, n: int, margin: int, rng):
        self.n, self.margin, self.rng = n, margin, rng
        self.taken = np.zeros(n, dtype=bool)
        self.taken[:margin] = self.taken[n - margin:] = True

    def free(self, i: int, span: int = 1) -> bool:
        return 0 <= i and i + span <= self.n \
            and not self.taken[max(0, i - 1):i + span + 1].any()

    def pick(self, span: int = 1, tries: int = 1000) -> int | None:
        for _ in range(tries):
            i = int(self.rng.integers(self.margin, max(self.margin + 1,
                                                       self.n - self.margin - span)))
            if self.free(i, span):
                return i
        return None


def glitch_frames(frames, *, seed: int, rate: float = 0.015, kinds=KINDS,
                  swap_gap: int = 40, flash_gain: float = 1.3, bar_frames: int = 25,
                  centers=None, r_px: float | None = None, band_on_ball: float = 0.5,
                  margin: int = 8):
    """A glitched copy of ``frames`` and the list of :class:`Glitch` (sorted by frame).

    ``rate``: share of the frames glitched by each of ``kinds`` (a swap counts its two frames,
    a repeat the copied-over one); glitches do not overlap and leave ``margin`` frames at both
    ends alone. ``centers`` (T, 2) px and ``r_px``: where the ball is (for the bar, and to put
    a share ``band_on_ball`` of the bands across the ball's rows); without them no bar.
    """
    src = np.asarray(frames)
    if src.ndim != 3:
        raise ValueError(f"frames must be a (T, H, W) stack, got shape {src.shape}")
    out = src.copy()
    n = src.shape[0]
    rng = np.random.default_rng(seed)
    full = np.iinfo(src.dtype).max if np.issubdtype(src.dtype, np.integer) else 1.0
    slots = _FreeFrames(n, margin, rng)
    glitches: list[Glitch] = []
    if centers is not None and r_px is not None and bar_frames > 0:
        glitches += _bar(out, slots, np.asarray(centers, dtype=float), r_px, bar_frames, full)
    per_kind = max(1, int(round(rate * n)))
    for kind in kinds:
        if kind not in KINDS:
            raise ValueError(f"unknown glitch kind {kind!r} (known: {', '.join(KINDS)})")
        count = per_kind // 2 if kind == "swap" else per_kind
        for _ in range(max(1, count)):
            glitches += _glitch(kind, src, out, slots, full, swap_gap=swap_gap,
                                flash_gain=flash_gain, centers=centers, r_px=r_px,
                                band_on_ball=band_on_ball)
    glitches.sort(key=lambda g: g.frame)
    return out, glitches


def _bar(out, slots: _FreeFrames, centers, r_px: float, bar_frames: int, full) -> list[Glitch]:
    """A mid-grey bar, 0.4 ball radii wide, sweeping across the ball over ``bar_frames``
    consecutive free frames (none where no such run is free)."""
    i0 = slots.pick(bar_frames)
    if i0 is None:
        return []
    slots.taken[i0:i0 + bar_frames] = True
    half = 0.2 * r_px
    w = out.shape[2]
    glitches = []
    for k in range(bar_frames):
        i = i0 + k
        cx = centers[i0 + bar_frames // 2, 0] + (k / (bar_frames - 1) - 0.5) * 2 * r_px
        x0, x1 = max(0, int(round(cx - half))), min(w, int(round(cx + half)) + 1)
        out[i, :, x0:x1] = np.asarray(0.5 * full).astype(out.dtype)
        glitches.append(Glitch(i, "bar"))
    return glitches


def _glitch(kind: str, src, out, slots: _FreeFrames, full, *, swap_gap: int,
            flash_gain: float, centers, r_px: float | None,
            band_on_ball: float) -> list[Glitch]:
    """One glitch of ``kind`` on free frames of ``out`` (``src``: the frames as recorded);
    none where no frame is free for it."""
    rng = slots.rng
    if kind == "swap":
        i = slots.pick()
        if i is None or not slots.free(i + swap_gap):
            return []
        j = i + swap_gap
        out[i], out[j] = src[j], src[i]
        slots.taken[i] = slots.taken[j] = True
        return [Glitch(i, "swap"), Glitch(j, "swap")]
    if kind == "repeat":
        i = slots.pick(2)
        if i is None:
            return []
        out[i + 1] = src[i]
        slots.taken[i:i + 2] = True
        return [Glitch(i + 1, "repeat")]
    if kind == "flash":
        i = slots.pick()
        if i is None:
            return []
        out[i] = np.clip(src[i].astype(np.float64) * flash_gain, 0, full).astype(src.dtype)
        slots.taken[i] = True
        return [Glitch(i, "flash", misplaced=False)]
    # band
    i = slots.pick()
    if i is None:
        return []
    h, w = src.shape[1:]
    rows = int(rng.integers(3, 25))
    on_ball = centers is not None and r_px is not None and rng.random() < band_on_ball
    if on_ball:
        cy = float(np.asarray(centers)[i, 1])
        # rows within the ball's, or the ball's within the rows (a small ball)
        lo, hi = sorted((cy - r_px, cy + r_px - rows))
        y0 = int(np.clip(rng.uniform(lo, hi), 0, h - rows))
    else:
        y0 = int(rng.integers(0, h - rows))
    noise = rng.uniform(0, full, (rows, w))
    out[i, y0:y0 + rows] = noise.astype(src.dtype)
    slots.taken[i] = True
    return [Glitch(i, "band", misplaced=on_ball)]
