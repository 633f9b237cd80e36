"""Overlay figures: the located ball circle and centre drawn on chosen frames (the thesis's
validation figure, paper 2 Figs. 9-10)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from rollfric.atomic import replacing


def choose_frames(track, k: int = 6) -> list[int]:
    """k frames spread over those where the ball was found.

    Parameters
    ----------
    track : pandas.DataFrame
        The track (columns ``frame`` and ``found``).
    k : int, optional
        How many.

    Returns
    -------
    list of int
        Frame numbers, increasing; empty when no frame was found.
    """
    found = track.index[track["found"] == 1].to_numpy()
    if len(found) == 0:
        return []
    pick = np.unique(np.linspace(0, len(found) - 1, min(k, len(found))).round().astype(int))
    return [int(track.loc[found[i], "frame"]) for i in pick]


def plot_overlays(source, track, path, *, frames: list[int] | None = None,
                  r_px: float | None = None, zoom: float = 2.5, info=None) -> Path:
    """One PNG of chosen frames, each cropped around the ball.

    Each shows the fitted circle (radius from the track, else ``r_px``), the centre, and the
    direction to the cylinder centre.

    Parameters
    ----------
    source : FrameSource
        The recording.
    track : pandas.DataFrame
        Its track.
    path : str or pathlib.Path
        The PNG to write (atomically).
    frames : list of int, optional
        The frames to draw (default: 6 spread over the found ones).
    r_px : float, optional
        Radius drawn where the track has none.
    zoom : float, optional
        Crop half-size in ball radii.
    info : rollfric.track.TrackInfo, optional
        The track's :class:`~rollfric.track.TrackInfo`: the cylinder centre (``center_px``,
        drawn as the direction to it) and the default radius (``ball_radius_px``); without it
        no direction is drawn and the default radius is 10 px.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        A frame outside the recording.
    """
    frames = choose_frames(track) if frames is None else list(frames)
    bad = [f for f in frames if not 0 <= int(f) < len(track)]
    if bad:
        from rollfric.errors import InputError

        raise InputError(f"overlay frame(s) {bad} outside the recording's 0..{len(track) - 1}")
    if not frames:
        frames = [0]
    center = info.center_px if info is not None else None
    r_default = r_px or (info.ball_radius_px if info is not None else 10.0)
    ncol = min(3, len(frames))
    nrow = math.ceil(len(frames) / ncol)
    fig = Figure(figsize=(4 * ncol, 4 * nrow))  # no pyplot: no backend, no global state
    axes = fig.subplots(nrow, ncol, squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    # grey levels to the camera's full scale where the file states it (a 12-bit camera's
    # frames in 16-bit words shown against 65535 are black)
    stated = getattr(source, "bit_depth_stated", None)
    for ax, f in zip(axes.ravel(), frames, strict=False):
        img = np.asarray(source[int(f)])
        vmax = float(2 ** int(stated) - 1) if stated else float(np.iinfo(img.dtype).max)
        row = track.loc[track["frame"] == f].iloc[0]
        h, w = img.shape
        if row["found"] == 1:
            x, y = float(row["x_px"]), float(row["y_px"])
            r = float(row["r_px"]) if "r_px" in row and np.isfinite(row["r_px"]) else r_default
        else:
            x, y, r = w / 2, h / 2, r_default
        half = zoom * r_default
        ax.imshow(img, cmap="gray", interpolation="nearest", vmin=0, vmax=vmax)
        ax.set_xlim(x - half, x + half)
        ax.set_ylim(y + half, y - half)
        if row["found"] == 1:
            t = np.linspace(0, 2 * np.pi, 361)
            ax.plot(x + r * np.cos(t), y + r * np.sin(t), "-", color="lime", lw=1.0)
            ax.plot([x], [y], "+", color="red", ms=12, mew=1.5)
            if center is not None:
                ax.plot([x, center[0]], [y, center[1]], ":", color="cyan", lw=0.8)
            ax.set_title(f"frame {f}: ({x:.2f}, {y:.2f}) px\n"
                         f"theta = {math.degrees(float(row['theta_rad'])):.3f} deg", fontsize=9)
        else:
            ax.set_title(f"frame {f}: ball not found", fontsize=9)
        ax.axis("on")
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    path = Path(path)
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110)
    return path
