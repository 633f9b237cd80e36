"""Overlay figures: the located ball circle and centre drawn on chosen frames (the thesis's
validation figure, paper 2 Figs. 9-10)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from rollfric.errors import InputError
from rollfric.output.atomic import replacing


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
    info : rollfric.track.track_info.TrackInfo, optional
        The track's :class:`~rollfric.track.track_info.TrackInfo`: the cylinder centre
        (``center_px``,
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


def plot_full_frame(source, track, info, path, *, frame: int | None = None) -> Path:
    """The whole frame with the trough's axis, the circle the ball's centre runs on, the
    located path and the ball: where the measurement looked and what it found.

    Parameters
    ----------
    source : FrameSource
        The recording.
    track : pandas.DataFrame
        Its track (``x_px``, ``y_px``, ``found``, ``theta_rad``).
    info : rollfric.track.track_info.TrackInfo
        How it was measured: ``center_px`` (the trough's axis), ``track_radius_px`` (the
        radius of the centre's path, R - r) and ``ball_radius_px``.
    path : str or pathlib.Path
        The PNG to write (atomically).
    frame : int, optional
        The frame shown (default: the found frame farthest from the bottom, where the angle
        is largest).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from matplotlib.patches import Circle

    found = (track["found"].to_numpy() == 1) & np.isfinite(track["x_px"].to_numpy(float))
    theta = track["theta_rad"].to_numpy(float)
    if frame is None:
        frame = int(np.nanargmax(np.where(found, np.abs(theta), -np.inf))) if found.any() else 0
    img = np.asarray(source[int(frame)])
    h, w = img.shape
    cx, cy = info.center_px
    L = info.track_radius_px
    r = info.ball_radius_px
    fig = Figure(figsize=(9, 9 * h / w + 0.6))
    ax = fig.subplots()
    ax.imshow(img, cmap="gray", interpolation="nearest", extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    phi = np.linspace(-np.pi / 2, np.pi / 2, 181)  # the lower half: where a ball can roll
    ax.plot(cx + L * np.sin(phi), cy + L * np.cos(phi), "--", color="tab:orange", lw=1,
            label=f"the centre's circle, R - r = {L:.1f} px")
    ax.plot([cx, cx], [cy, cy + L], ":", color="tab:orange", lw=1)
    ax.plot(cx, cy, "+", color="tab:orange", ms=12, mew=2, label="the trough's axis")
    x = track["x_px"].to_numpy(float)
    y = track["y_px"].to_numpy(float)
    ax.plot(x[found], y[found], "-", color="tab:cyan", lw=0.8, label="located path")
    if found[frame]:
        ax.add_patch(Circle((x[frame], y[frame]), r, fill=False, color="tab:red", lw=1.2))
        ax.plot([cx, x[frame]], [cy, y[frame]], "-", color="tab:red", lw=0.8,
                label=f"frame {frame}: theta = {np.degrees(theta[frame]):+.2f} deg")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
    ax.set_title(f"frame {frame} of {len(track)}: {int(found.sum())} frames located")
    fig.tight_layout()
    path = Path(path)
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110)
    return path
