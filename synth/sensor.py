"""The camera sensor model, applied deterministically to a clean render.

Same inputs and seed -> the same bytes. The model is block-local, so any crop of a frame can be
made without the rest of it: the per-pixel noise is drawn per fixed TILE x TILE tile of the
frame, each tile from its own generator seeded by (seed, stream, frame index, tile row, tile
column) (``numpy.random.default_rng``); the fixed pattern (prnu, dsnu, vignetting) is drawn once
per Sensor for the whole frame from (seed, 0) and sliced. A crop is therefore exactly the same
crop of the full frame.
"""

from __future__ import annotations

import numpy as np

from synth.config import SensorConfig

GAMMA = 2.2  # pyrender's output encoding (linear colour ** (1 / 2.2))

_STREAM_FIXED = 0
_STREAM_FRAME = 1
_STREAM_BACKGROUND = 2
TILE = 64  # px: the noise tile (fixed: changing it changes every recording's bytes)


def _fixed_pattern(sensor: SensorConfig, shape, seed: int):
    """(gain map, offset map in electrons), or (None, None) when both are off."""
    if sensor.prnu == 0 and sensor.dsnu == 0 and sensor.vignetting == 0:
        return None, None
    rng = np.random.default_rng([seed, _STREAM_FIXED])
    h, w = shape
    gain = np.ones(shape)
    if sensor.vignetting > 0:
        y, x = np.mgrid[0:h, 0:w]
        r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2
                                                                    + ((h - 1) / 2) ** 2)
        gain = gain * (1.0 - sensor.vignetting * r2)
    prnu = rng.standard_normal(shape)
    dsnu = rng.standard_normal(shape)
    if sensor.prnu > 0:
        gain = gain * (1.0 + sensor.prnu * prnu)
    offset = sensor.dsnu * np.abs(dsnu)  # dark signal is never negative
    return gain, offset


class Sensor:
    """A sensor with its fixed pattern drawn for one frame shape and seed."""

    def __init__(self, sensor: SensorConfig, shape, seed: int):
        self.config = sensor
        self.shape = tuple(shape)
        self.seed = int(seed)
        self.gain_map, self.offset_map = _fixed_pattern(sensor, self.shape, self.seed)
        if self.gain_map is not None:
            self.gain_map = self.gain_map.astype(np.float32)
            self.offset_map = self.offset_map.astype(np.float32)
        self._luts: dict = {}

    def _lut(self, scale: int) -> np.ndarray:
        """Electrons (before the fixed pattern) for each clean integer level 0..scale."""
        lut = self._luts.get(scale)
        if lut is None:
            s = self.config
            levels = np.arange(scale + 1, dtype=np.float64) / scale
            lut = (levels ** GAMMA * (s.full_well * s.exposure / s.reference_exposure))
            lut = lut.astype(np.float32)
            self._luts[scale] = lut
        return lut

    def _roi(self, counts: np.ndarray, roi) -> tuple[int, int, int, int]:
        h, w = self.shape
        if roi is None:
            roi = (0, h, 0, w)
        y0, y1, x0, x1 = (int(v) for v in roi)
        if not (0 <= y0 < y1 <= h and 0 <= x0 < x1 <= w):
            raise ValueError(f"roi {tuple(roi)} (y0, y1, x0, x1) is not inside the {w}x{h} "
                             "frame")
        if counts.shape != (y1 - y0, x1 - x0):
            raise ValueError(f"counts of shape {counts.shape} do not match the roi {tuple(roi)}")
        return y0, y1, x0, x1

    def normals(self, index: int | None, roi) -> np.ndarray:
        """The standard-normal draws of one frame over a region.

        Only the TILE x TILE tiles the region touches are drawn, each whole, from its own generator,
        so a crop of the full frame's draws is the same.

        Parameters
        ----------
        index : int or None
            Frame number; None for the background frame.
        roi : tuple of int
            (y0, y1, x0, x1) of the region.

        Returns
        -------
        numpy.ndarray
            float32 draws, shape (y1 - y0, x1 - x0).
        """
        y0, y1, x0, x1 = roi
        key = ([self.seed, _STREAM_BACKGROUND, 0] if index is None
               else [self.seed, _STREAM_FRAME, int(index)])
        out = np.empty((y1 - y0, x1 - x0), dtype=np.float32)
        for ty in range(y0 // TILE, (y1 - 1) // TILE + 1):
            ya, yb = max(y0, ty * TILE), min(y1, (ty + 1) * TILE)
            for tx in range(x0 // TILE, (x1 - 1) // TILE + 1):
                xa, xb = max(x0, tx * TILE), min(x1, (tx + 1) * TILE)
                z = np.random.default_rng(key + [ty, tx]).standard_normal((TILE, TILE),
                                                                          dtype=np.float32)
                out[ya - y0:yb - y0, xa - x0:xb - x0] = z[ya - ty * TILE:yb - ty * TILE,
                                                          xa - tx * TILE:xb - tx * TILE]
        return out

    def apply(self, counts: np.ndarray, scale: int, index: int | None,
              roi: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Sensor frame from a clean render.

        The result is the same crop of the full frame's sensor output, to the byte. Shot noise is
        drawn in its Gaussian form (variance = electrons; the Poisson law differs from it by less
        than 1 % in rms above 20 electrons), with the read noise, from one standard-normal draw per
        pixel: e + sqrt(e + read^2) z.

        Parameters
        ----------
        counts : numpy.ndarray
            The clean render in integer levels (0..scale = black..white display value).
        scale : int
            The level of white.
        index : int or None
            Frame number; None for the background frame.
        roi : tuple of int, optional
            (y0, y1, x0, x1) of the frame that ``counts`` covers (default: the whole frame).

        Returns
        -------
        numpy.ndarray
            Digital numbers in the sensor's dtype (uint8 or uint16).
        """
        s = self.config
        y0, y1, x0, x1 = roi = self._roi(counts, roi)
        lut = self._lut(int(scale))
        electrons = lut[np.clip(counts, 0, scale)]
        if self.gain_map is not None:
            electrons = (electrons * self.gain_map[y0:y1, x0:x1]
                         + self.offset_map[y0:y1, x0:x1])
        var = None
        if s.shot_noise:
            var = np.maximum(electrons, 0.0)
            if s.read_noise > 0:
                var += np.float32(s.read_noise ** 2)
        elif s.read_noise > 0:
            var = np.float32(s.read_noise ** 2)
        if var is not None:
            electrons = electrons + np.sqrt(var) * self.normals(index, roi)
        dn = electrons * np.float32(s.gain * s.max_dn / s.full_well) + np.float32(s.black_level)
        return np.clip(np.rint(dn), 0, s.max_dn).astype(s.dtype)
