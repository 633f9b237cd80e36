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

    def apply(self, clean: np.ndarray, index: int | None) -> np.ndarray:
        """clean: display values in [0, 1] (H, W); index: frame number, None = background."""
        s = self.config
        irradiance = np.clip(clean, 0.0, 1.0) ** GAMMA
        electrons = irradiance * (s.full_well * s.exposure / s.reference_exposure)
        if self.gain_map is not None:
            electrons = electrons * self.gain_map + self.offset_map
        stream = ([self.seed, _STREAM_BACKGROUND] if index is None
                  else [self.seed, _STREAM_FRAME, int(index)])
        noisy = s.shot_noise or s.read_noise > 0
        if noisy:
            rng = np.random.default_rng(stream)
            if s.shot_noise:
                electrons = rng.poisson(np.maximum(electrons, 0.0)).astype(float)
            if s.read_noise > 0:
                electrons = electrons + s.read_noise * rng.standard_normal(electrons.shape)
        dn = electrons * (s.gain * s.max_dn / s.full_well) + s.black_level
        return np.clip(np.rint(dn), 0, s.max_dn).astype(s.dtype)
