"""A turned or moved camera, as a lab's recordings have it: drawn recordings with a known truth.

- :func:`turned_centres`: the ball centre's exact path (angles about the trough axis) seen by
  an orthographic camera yawed (turned about the vertical) or pitched (about the horizontal)
  against the trough axis: the path's image is an ellipse, the ball's silhouette stays a disc
  of radius r (orthographic), so frames are drawn analytically
  (:func:`synth.drawn.frames.make_frames`).
- :func:`moved_frames`: frames shifted by a camera bump (a step from one frame on) or a drift
  (a shift growing linearly), sub-pixel by bilinear resampling (``cv2.warpAffine``), the edges
  replicated.
"""

from __future__ import annotations

import math

import cv2
import numpy as np


def turned_centres(theta, track_radius_px: float, center, *, yaw_deg: float = 0.0,
                   pitch_deg: float = 0.0) -> np.ndarray:
    """Image centres (T, 2) px of a ball at angles ``theta`` (rad, from the bottom) on a path
    of radius ``track_radius_px`` about ``center`` (the axis's image in the ball's plane), seen
    by an orthographic camera yawed by ``yaw_deg`` (x compressed by cos yaw) and pitched by
    ``pitch_deg`` (y compressed by cos pitch). Image y down."""
    th = np.asarray(theta, dtype=float)
    cx, cy = center
    x = cx + math.cos(math.radians(yaw_deg)) * track_radius_px * np.sin(th)
    y = cy + math.cos(math.radians(pitch_deg)) * track_radius_px * np.cos(th)
    return np.column_stack([x, y])


def camera_shift(n: int, *, bump_at: int | None = None, bump_px=(0.0, 0.0),
                 drift_px=(0.0, 0.0)) -> np.ndarray:
    """The camera's image shift (T, 2) px per frame: ``bump_px`` from frame ``bump_at`` on,
    plus a drift growing linearly from 0 at frame 0 to ``drift_px`` at the last frame."""
    s = np.zeros((n, 2))
    if bump_at is not None:
        s[bump_at:] += np.asarray(bump_px, dtype=float)
    s += np.linspace(0.0, 1.0, n)[:, None] * np.asarray(drift_px, dtype=float)[None, :]
    return s


def moved_frames(frames, shift) -> list:
    """``frames`` with each frame's content moved by ``shift[i]`` = (dx, dy) px (the scene
    seen dx right, dy down), resampled bilinearly with the edges replicated."""
    out = []
    for f, (dx, dy) in zip(frames, np.asarray(shift, dtype=float), strict=True):
        if dx == 0.0 and dy == 0.0:
            out.append(f.copy())
            continue
        m = np.float32([[1, 0, dx], [0, 1, dy]])
        g = cv2.warpAffine(f.astype(np.float32), m, (f.shape[1], f.shape[0]),
                           flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if np.issubdtype(f.dtype, np.integer):
            g = np.clip(np.rint(g), 0, np.iinfo(f.dtype).max)
        out.append(g.astype(f.dtype))
    return out


def turned_image(image, center, *, yaw_deg: float = 0.0, pitch_deg: float = 0.0):
    """A float image of the scene (the trough's contour about ``center``) as the turned
    camera of :func:`turned_centres` sees it: compressed about ``center`` by cos yaw across
    x and cos pitch across y (area-resampled, the edges replicated; the contour's plane taken
    as the ball's)."""
    cx, cy = math.cos(math.radians(yaw_deg)), math.cos(math.radians(pitch_deg))
    m = np.float32([[cx, 0, center[0] * (1 - cx)], [0, cy, center[1] * (1 - cy)]])
    img = np.asarray(image, dtype=np.float32)
    return cv2.warpAffine(img, m, (img.shape[1], img.shape[0]), flags=cv2.INTER_AREA,
                          borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
