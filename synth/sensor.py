"""The camera sensor model, applied deterministically to a clean render.

Same inputs and seed -> the same bytes. Any crop of a frame can be made without the rest of it,
to the byte the same crop of the full frame: the fixed pattern (prnu, dsnu, vignetting) is drawn
once per Sensor for the whole frame from (seed, 0) and sliced, and the per-pixel noise is a
function of (seed, stream, frame index, pixel) alone. Two noise generators (``noise``):

- ``"hash/1"`` (NOISE, what synth renders now): counter-based. Pixels x = 2k and 2k + 1 of row
  y take the two normals of one Marsaglia polar draw from the 64-bit hash (splitmix64's
  finaliser) of a per-frame key and the counter (y, k) (a rejected draw hashes the counter
  again with the next try number). The whole model - gamma table, fixed pattern, noise,
  quantisation - runs in one numba kernel over the pixels asked for (the normals of a block of
  rows first, phase by phase: the hashing, then the logs and square roots in a straight loop;
  then the block's pixels): the same bytes as a pair's draw at a time in one loop, in a few
  times less CPU than drawing the noise per tile.
- ``"tiles/1"`` (recordings rendered before it, read with the bytes they were made with): the
  noise drawn per fixed TILE x TILE tile, each from its own ``numpy.random.default_rng`` seeded
  by (seed, stream, frame index, tile row, tile column); a region draws every tile it touches
  whole.

The noise is drawn in float64 and rounded to float32 before use, so a last-bit difference in
``log`` between code paths cannot reach a pixel; the rest is float32 arithmetic in the order of
the tiles' NumPy code (no fused multiply-adds).
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.jit import njit
from synth.config import SensorConfig, SynthError

GAMMA = 2.2  # pyrender's output encoding (linear colour ** (1 / 2.2))

_STREAM_FIXED = 0
_STREAM_FRAME = 1
_STREAM_BACKGROUND = 2
TILE = 64  # px: the noise tile of "tiles/1" (fixed: changing it changes its recordings' bytes)
NOISE = "hash/1"  # the noise generator of new recordings
NOISES = ("hash/1", "tiles/1")
_M64 = (1 << 64) - 1
_GOLDEN = 0x9E3779B97F4A7C15


def _mix64(z: int) -> int:
    """splitmix64's finaliser on a Python int (mod 2**64): the kernel's ``_hash`` in Python."""
    z &= _M64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M64
    return z ^ (z >> 31)


def noise_key(seed: int, index: int | None) -> int:
    """The 64-bit key of frame ``index``'s noise (None: the background frame's) for "hash/1"."""
    stream, i = (_STREAM_BACKGROUND, 0) if index is None else (_STREAM_FRAME, int(index))
    k = _mix64(int(seed) + _GOLDEN)
    k = _mix64(k + stream * _GOLDEN)
    return _mix64(k + (i & _M64) * _GOLDEN)


@njit
def _hash(z):
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit
def _polar_draw(key, y, k):
    """The accepted Marsaglia polar draw (a, b, s = a^2 + b^2) of pixels 2k, 2k + 1 of row y:
    the hash of (key, y, k) and the try number, until 0 < s < 1."""
    gold = np.uint64(0x9E3779B97F4A7C15)
    gold2 = np.uint64(0xD1B54A32D192ED03)
    base = key + ((np.uint64(y) << np.uint64(32)) | np.uint64(k)) * gold
    t = np.uint64(0)
    inv = 1.0 / 2147483648.0
    while True:
        h = _hash(base + t * gold2)
        a = float(h >> np.uint64(32)) * inv - 1.0
        b = float(h & np.uint64(0xFFFFFFFF)) * inv - 1.0
        s = a * a + b * b
        if 0.0 < s < 1.0:
            return a, b, s
        t += np.uint64(1)


@njit
def _pair_normals(key, y, k):
    """The two standard normals (float32) of pixels 2k, 2k + 1 of row y."""
    a, b, s = _polar_draw(key, y, k)
    f = math.sqrt(-2.0 * math.log(s) / s)
    return np.float32(a * f), np.float32(b * f)


@njit
def _normals_kernel(key, y0, x0, out):
    h, w = out.shape
    for r in range(h):
        zb = np.float32(0.0)
        for c in range(w):
            x = x0 + c
            if c == 0 or (x & 1) == 0:
                za, zb = _pair_normals(key, y0 + r, x >> 1)
                out[r, c] = za if (x & 1) == 0 else zb
            else:
                out[r, c] = zb
    return out


ROWS = 32  # rows of a region whose normals the sensor kernel draws before their pixels


@njit
def _block_draws(key, y, p0, npair, a_out, b_out, f_out):
    """Pairs p0 .. p0 + npair - 1 of row y: each accepted polar draw's (a, b) into a_out,
    b_out and its s into f_out (the factor sqrt(-2 log s / s) is taken after, over the row)."""
    for q in range(npair):
        a, b, s = _polar_draw(key, y, p0 + q)
        a_out[q] = a
        b_out[q] = b
        f_out[q] = s


@njit(nogil=True)  # nogil: a reader thread overlaps the locator
def _apply_kernel(counts, base, has_base, lut, gain, offset, has_pattern, noisy, shot,
                  read_var, k, black, max_dn, key, y0, x0, out):
    """The sensor model of :meth:`Sensor.apply` over one region, "hash/1" noise. The normals
    of up to ROWS rows are drawn phase by phase - every pair's accepted (a, b, s) (the
    branchy hashing), then every pair's factor sqrt(-2 log s / s) in a straight loop, then
    each row's normals a f, b f - and then the rows' pixels: each value is computed as
    :func:`_pair_normals` computes it (the same bytes), the independent logs and square roots
    of a straight loop overlapping in the CPU (25-30 % less CPU than a pair's draw and factor
    at a time, for a tracker's 102 x 102 px region: 162 -> 117 us). ``has_base``: the clean
    level is ``counts + base`` (a recording's clean difference and background), added here."""
    h, w = counts.shape
    top = lut.shape[0] - 1
    zero = np.float32(0.0)
    zrow = np.zeros(w, np.float32)
    p0 = x0 >> 1
    npair = ((x0 + w - 1) >> 1) - p0 + 1  # the pairs pixels x0 .. x0 + w - 1 belong to
    odd = x0 & 1  # pixel c is x0 + c: pair (c + odd) >> 1, its b when c + odd is odd
    rows = min(h, ROWS)
    da = np.empty((rows, npair))
    db = np.empty((rows, npair))
    df = np.empty((rows, npair))
    for r0 in range(0, h, rows):
        nr = min(rows, h - r0)
        if noisy:
            for rr in range(nr):
                _block_draws(key, y0 + r0 + rr, p0, npair, da[rr], db[rr], df[rr])
            for rr in range(nr):
                for q in range(npair):
                    s = df[rr, q]
                    df[rr, q] = math.sqrt(-2.0 * math.log(s) / s)
        for rr in range(nr):
            r = r0 + rr
            if noisy:
                for c in range(w):
                    q = (c + odd) >> 1
                    if (c + odd) & 1:
                        zrow[c] = np.float32(db[rr, q] * df[rr, q])
                    else:
                        zrow[c] = np.float32(da[rr, q] * df[rr, q])
            for c in range(w):
                v = counts[r, c] + base[r, c] if has_base else counts[r, c] + 0
                e = lut[0 if v < 0 else (top if v > top else v)]
                if has_pattern:
                    e = e * gain[r, c] + offset[r, c]
                if noisy:
                    var = read_var
                    if shot:
                        var = (e if e > zero else zero) + read_var
                    e = e + np.sqrt(var) * zrow[c]
                d = np.rint(e * k + black)
                out[r, c] = 0 if d < 0 else (max_dn if d > max_dn else d)
    return out


def _fixed_pattern(sensor: SensorConfig, shape, seed: int):
    """(gain map, offset map in electrons), or (None, None) when both are off."""
    if sensor.prnu == 0 and sensor.dsnu == 0 and sensor.vignetting == 0:
        return None, None
    rng = np.random.default_rng([seed, _STREAM_FIXED])
    h, w = shape
    gain = np.ones(shape)
    if sensor.vignetting > 0:
        y, x = np.ogrid[0:h, 0:w]  # a column and a row, broadcast: mgrid's values, 13x faster
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
    """A sensor with its fixed pattern drawn for one frame shape and seed.

    Parameters
    ----------
    sensor : SensorConfig
        The sensor model's parameters.
    shape : tuple of int
        (H, W) of the frames.
    seed : int
        Seed of the fixed pattern and the noise.
    noise : str
        The per-pixel noise generator, one of NOISES: NOISE ("hash/1") for new recordings,
        "tiles/1" for those rendered before it.
    """

    def __init__(self, sensor: SensorConfig, shape, seed: int, noise: str = NOISE):
        if noise not in NOISES:
            raise SynthError(f"unknown sensor noise generator {noise!r} (known: "
                             f"{', '.join(NOISES)}): a recording from a newer synth?")
        self.config = sensor
        self.shape = tuple(shape)
        self.seed = int(seed)
        self.noise = noise
        self.gain_map, self.offset_map = _fixed_pattern(sensor, self.shape, self.seed)
        if self.gain_map is not None:
            self.gain_map = self.gain_map.astype(np.float32)
            self.offset_map = self.offset_map.astype(np.float32)
        self._luts: dict = {}
        # what every "hash/1" region passes its kernel: set once
        s = sensor
        self._hash_args = (bool(s.shot_noise or s.read_noise > 0), bool(s.shot_noise),
                           np.float32(s.read_noise ** 2) if s.read_noise > 0 else np.float32(0.0),
                           np.float32(s.gain * s.max_dn / s.full_well),
                           np.float32(s.black_level), int(s.max_dn))
        self._none = np.zeros((1, 1), dtype=np.float32)
        self._no_base = np.zeros((1, 1), dtype=np.int32)
        self._key_frames = _mix64(_mix64(self.seed + _GOLDEN) + _STREAM_FRAME * _GOLDEN)
        self._key_background = noise_key(self.seed, None)

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

        The same as the crop of the full frame's draws. "hash/1": each pixel's own draw;
        "tiles/1": only the TILE x TILE tiles the region touches are drawn, each whole, from its
        own generator.

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
        if self.noise == "hash/1":
            out = np.empty((y1 - y0, x1 - x0), dtype=np.float32)
            return _normals_kernel(np.uint64(noise_key(self.seed, index)), y0, x0, out)
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
              roi: tuple[int, int, int, int] | None = None, *,
              base: np.ndarray | None = None) -> np.ndarray:
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
        base : numpy.ndarray, optional
            Integer levels of the same shape added to ``counts`` (a recording's clean
            background under its clean difference): the result is ``apply(counts + base,
            ...)``'s, without the sum's array.

        Returns
        -------
        numpy.ndarray
            Digital numbers in the sensor's dtype (uint8 or uint16).
        """
        s = self.config
        y0, y1, x0, x1 = roi = self._roi(counts, roi)
        if base is not None and base.shape != counts.shape:
            raise ValueError(f"base of shape {base.shape} does not match counts "
                             f"{counts.shape}")
        lut = self._lut(int(scale))
        if self.noise == "hash/1":
            return self._apply_hash(counts, base, lut, index, y0, y1, x0, x1)
        if base is not None:
            counts = counts + base
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

    def _apply_hash(self, counts, base, lut, index, y0, y1, x0, x1) -> np.ndarray:
        out = np.empty((y1 - y0, x1 - x0), dtype=self.config.dtype)
        if self.gain_map is not None:
            gain, offset = self.gain_map[y0:y1, x0:x1], self.offset_map[y0:y1, x0:x1]
        else:
            gain = offset = self._none
        # a frame's key from its stream's (noise_key's first two mixes, made once)
        key = self._key_background if index is None else \
            _mix64(self._key_frames + (int(index) & _M64) * _GOLDEN)
        return _apply_kernel(np.asarray(counts), self._no_base if base is None else base,
                             base is not None, lut, gain, offset, self.gain_map is not None,
                             *self._hash_args, np.uint64(key), y0, x0, out)
