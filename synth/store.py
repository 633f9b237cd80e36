"""Synthetic recordings as Zarr v3 stores, read lazily.

Layout (a directory ``REC.zarr``)::

    background_clean  (H, W)     uint16/uint32  clean render without the ball: the sum over RGB
                                                and supersamples (white = attrs background_scale)
    clean_diff        (T, H, W)  int16/int32    clean frame minus background, in the same units
                                                summed over the motion-blur sub-frames
                                                (white = attrs frame_scale); chunks of one
                                                frame's CHUNK x CHUNK px, only those the ball
                                                and its shadows change written (the rest is
                                                fill 0); stores rendered before: one chunk a
                                                frame
    truth/<column>    (T,)       float64        exact ground truth, see TRUTH_COLUMNS
    timestamps        (T,)       float64        optional: each frame's time (s), the camera's
                                                clock (render(timing=...), synth.camera_clock)
    background_ideal_clean (H', W')             with a lens only: the ideal render the lens
                                                bends into the frames (synth.distortion: 4 x 4
                                                of its pixels a frame pixel)

Root attributes: ``format``, ``setup`` (the lab setup, TOML form), ``scene``, ``sensor``,
``sensor_noise`` (the noise generator, ``synth.sensor.NOISES``; absent: "tiles/1", the stores
rendered before it), ``seed``, ``scenario``, ``versions``, ``fps``, ``n_frames``, scales, and
with a camera timing (:mod:`synth.camera_clock`) ``timing`` (its jitter, drop rate and the camera
frames lost, ``dropped_frames``).

Frames are made when read: clean frame -> the seeded sensor model (``synth.sensor``), the same
bytes on every read. ``frames.read(i, (y0, y1, x0, x1))`` makes only that region of interest
(the sensor model applied to it alone): the same bytes as ``frames[i][y0:y1, x0:x1]``. rollfric
reads it through the entry point ``rollfric.zarr_readers`` -> ``synth.store:open_frames``.

The chunk files of ``clean_diff`` are read and written by :mod:`synth.chunks` where the store
has the pipeline's layout (a region read decodes only the chunks it touches).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from rollfric.io.source import check_roi
from synth.chunks import chunk_files
from synth.config import SensorConfig, SynthError

FORMAT = "rollfric-synth-recording/1"
# a RAM-backed folder for temporary recordings (Linux), and what a frame is allowed to take
SCRATCH = "/dev/shm"
SCRATCH_FRAME_BYTES = 65536  # ~30x a default frame's chunks (8.2 MB for 4000 frames)
SCRATCH_SPARE_BYTES = 256 * 2**20


def scratch_dir(n_frames: int) -> str | None:
    """Where a temporary recording of ``n_frames`` frames (one deleted after use, as
    ``rollfric validate``'s) is written fastest: a RAM-backed folder (``SCRATCH``) when it
    exists, is writable and has room for ``SCRATCH_FRAME_BYTES`` a frame plus
    ``SCRATCH_SPARE_BYTES``; else None (the system's temporary folder).

    A recording is ~2 chunk files a frame, and creating a file on a disk's file system can cost
    more than rendering the frame (docs/how/renderer.md).

    Parameters
    ----------
    n_frames : int
        Frames of the recording.

    Returns
    -------
    str or None
        The folder for ``tempfile.mkdtemp(dir=...)``.
    """
    import shutil

    try:
        if not (os.path.isdir(SCRATCH) and os.access(SCRATCH, os.W_OK | os.X_OK)):
            return None
        free = shutil.disk_usage(SCRATCH).free
    except OSError:
        return None
    need = int(n_frames) * SCRATCH_FRAME_BYTES + SCRATCH_SPARE_BYTES
    return SCRATCH if free >= need else None

TRUTH_COLUMNS = {
    "t_s": "time of the exposure centre (s)",
    "theta_rad": "ball angle about the cylinder axis (rad)",
    "theta_dot_rad_s": "angular velocity about the axis (rad/s)",
    "x_px": "projected sphere centre, x (px; through a lens: its distorted position)",
    "y_px": "projected sphere centre, y (px)",
    "sil_x_px": "centre of the ball's silhouette, x (px; differs in perspective; through a "
                "lens: the distorted position of the ideal silhouette's centre)",
    "sil_y_px": "centre of the ball's silhouette, y (px)",
    "r_px": "ball radius in pixels (area-equivalent radius of the silhouette)",
    "cx_px": "cylinder axis in the image, x (px; in the ideal, undistorted image)",
    "cy_px": "cylinder axis in the image, y (px)",
}


class SynthFrames:
    """FrameSource over a synthetic recording (lazy: one frame decoded per access).

    ``concurrent_reads`` (True): frames and regions may be read from several threads at once
    (each read opens its own chunk files; the sensor model keeps no state between reads), so
    rollfric tracks a long recording's segments on as many threads
    (:func:`rollfric.track.tracker.track_segments`).
    """

    concurrent_reads = True

    def __init__(self, group):
        a = dict(group.attrs)
        self.attrs = a
        self._diff = group["clean_diff"]
        self._bg = np.asarray(group["background_clean"][...], dtype=np.int64)
        self.frame_scale = float(a["frame_scale"])
        self.background_scale = float(a["background_scale"])
        self.subframes = int(a["subframes"])
        self.sensor_config = SensorConfig(**a["sensor"])
        self.seed = int(a["seed"])
        self.shape = tuple(self._diff.shape)
        self.dtype = np.dtype(self.sensor_config.dtype)
        self.fps = float(a["fps"]) if a.get("fps") else None
        self._bg_scaled = (self._bg * self.subframes).astype(np.int32)
        self.noise = str(a.get("sensor_noise", "tiles/1"))
        from synth.sensor import Sensor  # its numba kernels: not where a render process is

        self._sensor = Sensor(self.sensor_config, self.shape[1:], self.seed, self.noise)
        self._background = None
        self._chunk_file = chunk_files(group, self._diff)
        # the camera's own time of each frame (render(timing=...) with timestamps), from frame 0
        self.timestamps = None
        if "timestamps" in group:
            ts = np.asarray(group["timestamps"][...], dtype=np.float64)
            self.timestamps = ts - ts[0]

    def __len__(self) -> int:
        return self.shape[0]

    def clean_counts(self, i: int, roi: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Clean frame i in integer levels (0..frame_scale = black..white display value), or
        its region ``roi`` = (y0, y1, x0, x1)."""
        i = self._index(i)
        if roi is None:
            return self._bg_scaled + self._diff_region(i, None)
        y0, y1, x0, x1 = self._roi(roi)
        return self._bg_scaled[y0:y1, x0:x1] + self._diff_region(i, (y0, y1, x0, x1))

    def _diff_region(self, i: int, roi) -> np.ndarray:
        """clean_diff of frame i (or its region) as int32."""
        if self._chunk_file is not None:
            h, w = self.shape[1:]
            return self._chunk_file(i, (0, h, 0, w) if roi is None else roi)
        if roi is None:
            return np.asarray(self._diff[i], dtype=np.int32)
        y0, y1, x0, x1 = roi
        return np.asarray(self._diff[i, y0:y1, x0:x1], dtype=np.int32)

    def clean(self, i: int) -> np.ndarray:
        """Clean display values in [0, 1] of frame i (float64)."""
        return self.clean_counts(i) / self.frame_scale

    def clean_background(self) -> np.ndarray:
        """Clean display values in [0, 1] of the background frame (float64).

        Returns
        -------
        numpy.ndarray
            (H, W).
        """
        return self._bg / self.background_scale

    def __getitem__(self, i: int) -> np.ndarray:
        i = self._index(i)
        # clean_counts(i), the background's levels added in the sensor's kernel
        return self._sensor.apply(self._diff_region(i, None), int(self.frame_scale), i,
                                  base=self._bg_scaled)

    def read(self, i: int, roi: tuple[int, int, int, int]) -> np.ndarray:
        """Region ``roi`` = (y0, y1, x0, x1) of frame i, ``0 <= y0 < y1 <= H``,
        ``0 <= x0 < x1 <= W``: the same bytes as ``self[i][y0:y1, x0:x1]``, made from the
        clean chunks and sensor tiles the region touches only."""
        i = self._index(i)
        y0, y1, x0, x1 = roi = self._roi(roi)
        return self._sensor.apply(self._diff_region(i, roi), int(self.frame_scale), i, roi,
                                  base=self._bg_scaled[y0:y1, x0:x1])

    def _roi(self, roi) -> tuple[int, int, int, int]:
        return check_roi(roi, self.shape[1:])

    @property
    def background(self) -> np.ndarray:
        """The background frame (no ball) as the camera records it (its own noise draw)."""
        if self._background is None:
            self._background = self._sensor.apply(self._bg.astype(np.int32),
                                                  int(self.background_scale), None)
        return self._background

    def _index(self, i) -> int:
        if isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)):
            raise TypeError(f"frame index must be an integer, got {type(i).__name__}")
        n = self.shape[0]
        if not -n <= i < n:
            raise IndexError(f"frame {i} out of range for {n} frames")
        return int(i) % n

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]




def open_frames(group) -> SynthFrames | None:
    """Entry point ``rollfric.zarr_readers``: a FrameSource if ``group`` is a synth recording."""
    try:
        fmt = group.attrs.get("format")
    except AttributeError:
        return None
    if fmt != FORMAT:
        return None
    return SynthFrames(group)


@dataclasses.dataclass(frozen=True)
class Recording:
    """A synth recording opened for reading (:func:`open_recording`).

    Attributes
    ----------
    frames : SynthFrames
        The frames with the sensor model applied when read (a FrameSource).
    background : numpy.ndarray
        The background frame through the same sensor model.
    truth : pandas.DataFrame
        The exact ground truth, one row per frame.
    attrs : dict
        The store's attributes (setup, scene, sensor, seed, scenario, versions, ...).
    path : pathlib.Path
        The store.
    """
    frames: SynthFrames
    background: np.ndarray
    truth: object  # pandas.DataFrame, one row per frame
    attrs: dict
    path: Path

    def __len__(self) -> int:
        return len(self.frames)


def open_recording(path) -> Recording:
    """Open a synthetic recording: frames (lazy), background, truth (DataFrame), attrs."""
    import zarr

    path = Path(path)
    if not path.exists():
        raise SynthError(f"recording not found: {path}")
    try:
        group = zarr.open_group(str(path), mode="r")
    except Exception as exc:  # zarr raises several types for a non-store
        raise SynthError(f"{path}: not a Zarr store ({exc})") from None
    frames = open_frames(group)
    if frames is None:
        raise SynthError(f"{path}: not a synth recording (attrs format != {FORMAT!r})")
    truth, attrs = read_truth(group)
    return Recording(frames=frames, background=frames.background, truth=truth,
                     attrs=attrs, path=path)


def read_truth(group):
    """A synth recording's truth table and attributes, without opening its frames (no sensor
    model set up, no background drawn through it: ~0.1 s for a 1280 x 1024 recording).

    Parameters
    ----------
    group : str, pathlib.Path or zarr.Group
        The recording (synth's Zarr store), or its group opened for reading.

    Returns
    -------
    truth : pandas.DataFrame
        One row a frame (index "frame"), the columns of :data:`TRUTH_COLUMNS`.
    attrs : dict
        The store's attributes.
    """
    import pandas as pd
    import zarr

    if isinstance(group, (str, Path)):
        group = zarr.open_group(str(group), mode="r")
    tg = group["truth"]
    truth = pd.DataFrame({name: np.asarray(tg[name][...]) for name in TRUTH_COLUMNS})
    truth.index.name = "frame"
    return truth, dict(group.attrs)
