"""Small synthetic recordings for the measure tests: a ball on the equation of motion, drawn
analytically (synth.drawn.frames), in a 360 x 240 frame with a 200 px trough."""

from __future__ import annotations

import dataclasses
import logging
import math
import threading

import numpy as np

from rollfric.fit import eom
from rollfric.io.readers import RecordingError
from rollfric.setup.model import Setup
from synth.drawn.frames import Scene, make_frames

R = 85.3e-3
PIX = R / 200.0  # the trough's radius is 200 px


@dataclasses.dataclass
class Recording:
    setup: Setup
    scene: Scene
    background: np.ndarray
    frames: list
    centers: np.ndarray  # (T, 2) px, NaN where no ball
    theta: np.ndarray
    t: np.ndarray


def make_recording(n=160, *, mu=0.02, theta0=0.5, fps=200.0, bit_depth=8, noise=0.0,
                   missing=(), seed=0, center=(180.0, 20.0), width=360, height=240,
                   with_center=False, ball_mm=6.0, trough_visible=True) -> Recording:
    setup = Setup(cylinder_radius=R, ball_diameter=ball_mm * 1e-3, ball_mass=4e-3, fps=fps,
                  pixel_size=PIX, center_px=center if with_center else None)
    r_px = setup.ball_radius / PIX
    L = setup.track_radius / PIX
    fs = 255.0 if bit_depth == 8 else 65535.0
    scene = Scene(width=width, height=height, center=center, R_px=200.0, r_px=r_px,
                  wall_px=20 if trough_visible else -10, bit_depth=bit_depth,
                  noise=noise * fs / 255.0)
    t = np.arange(n) / fps
    theta, _, _ = eom.solve_reference(theta0, 0.0, mu, t, track_radius=setup.track_radius)
    centers = np.array([(center[0] + L * math.sin(a), center[1] + L * math.cos(a))
                        for a in theta])
    centers[list(missing)] = np.nan
    todraw = [(None, None) if np.isnan(c[0]) else tuple(c) for c in centers]
    bg, frames = make_frames(scene, todraw, seed=seed)
    return Recording(setup, scene, bg, frames, centers, theta, t)


def messages(caplog) -> list[str]:
    """rollfric's log records as the command prints them: warnings prefixed "warning: "."""
    return [("warning: " if r.levelno >= logging.WARNING else "") + r.getMessage()
            for r in caplog.records if r.name.startswith("rollfric")]


def write_lab(folder, n=60, noise=1.0):
    """A lab's files in ``folder``: ``rec.tif`` (``n`` drawn frames), ``bg.tif``,
    ``setup.toml`` and the exact angles as ``track.csv``; returns ``folder``."""
    import tifffile

    from rollfric.setup.model import save_setup

    rec = make_recording(n, noise=noise)
    tifffile.imwrite(folder / "rec.tif", np.stack(rec.frames))
    tifffile.imwrite(folder / "bg.tif", rec.background)
    save_setup(rec.setup, folder / "setup.toml")
    lines = ["t_s,theta_rad"] + [f"{a:.17g},{b:.17g}" for a, b in zip(rec.t, rec.theta,
                                                                        strict=True)]
    (folder / "track.csv").write_text("\n".join(lines) + "\n")
    return folder


class MemorySource:
    """An in-memory RegionSource (frames and regions as a reader gives them) that records which
    threads read it (``threads``) and every region read (``reads``).

    ``bad``: frame -> the first column whose reads fail (0: the whole frame is corrupt; a
    whole-frame read of a bad frame always fails). ``concurrent``: its ``concurrent_reads``
    (rollfric may read it from several threads at once)."""

    def __init__(self, frames, *, concurrent=False, bad=None):
        self.frames = frames
        self.shape = (len(frames),) + frames[0].shape
        self.dtype = frames[0].dtype
        self.fps = None
        self.background = None
        self.attrs = {}
        self.concurrent_reads = concurrent
        self.bad = dict(bad or {})
        self.threads = set()
        self.reads = []

    def __len__(self):
        return self.shape[0]

    def __getitem__(self, i):
        self.threads.add(threading.get_ident())
        if i in self.bad:
            raise RecordingError(f"frame {i} is corrupt")
        return self.frames[i].copy()

    def read(self, i, roi):
        self.threads.add(threading.get_ident())
        y0, y1, x0, x1 = roi
        self.reads.append((i, roi))
        if i in self.bad and x1 > self.bad[i]:
            raise RecordingError(f"frame {i} is corrupt" if self.bad[i] == 0 else
                                 f"frame {i}'s columns from {self.bad[i]} are corrupt")
        return self.frames[i][y0:y1, x0:x1].copy()
