"""The camera sensor model, applied deterministically to a clean render.

Same inputs and seed -> the same bytes: every frame draws from its own generator seeded by
(seed, stream, frame index), and the fixed pattern (prnu, dsnu) from (seed, 0).
"""

from __future__ import annotations

import numpy as np

from synth.config import SensorConfig

GAMMA = 2.2  # pyrender's output encoding (linear colour ** (1 / 2.2))

_STREAM_FIXED = 0
_STREAM_FRAME = 1
_STREAM_BACKGROUND = 2


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

    def apply(self, counts: np.ndarray, scale: int, index: int | None) -> np.ndarray:
        """Sensor frame from a clean render in integer levels ``counts`` (0..scale = black..white
        display value); ``index``: frame number, None for the background frame.

        Shot noise is drawn in its Gaussian form (variance = electrons; the Poisson law differs
        from it by less than 1 % in rms above 20 electrons), with the read noise, from one
        standard-normal draw per pixel: e + sqrt(e + read^2) z.
        """
        s = self.config
        lut = self._lut(int(scale))
        electrons = lut[np.clip(counts, 0, scale)]
        if self.gain_map is not None:
            electrons = electrons * self.gain_map + self.offset_map
        var = None
        if s.shot_noise:
            var = np.maximum(electrons, 0.0)
            if s.read_noise > 0:
                var += np.float32(s.read_noise ** 2)
        elif s.read_noise > 0:
            var = np.float32(s.read_noise ** 2)
        if var is not None:
            stream = ([self.seed, _STREAM_BACKGROUND] if index is None
                      else [self.seed, _STREAM_FRAME, int(index)])
            rng = np.random.default_rng(stream)
            z = rng.standard_normal(electrons.shape, dtype=np.float32)
            electrons = electrons + np.sqrt(var) * z
        dn = electrons * np.float32(s.gain * s.max_dn / s.full_well) + np.float32(s.black_level)
        return np.clip(np.rint(dn), 0, s.max_dn).astype(s.dtype)
