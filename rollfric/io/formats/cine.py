"""Phantom ``.cine`` files (Vision Research), read with pims' Cine reader plus memory-mapped
region reads.

pims (:class:`pims.Cine`) parses the file: the CINEFILEHEADER, the BITMAPINFOHEADER, the SETUP
(frame rate), the tagged blocks (per-frame TIME64 times and exposures) and the table of image
offsets. Its frame read decodes the whole frame from a ``file.read``; here the frames of an
uncompressed monochrome file (8 or 16 bits a pixel, stored bottom row first as pims reads them)
are read through ``numpy.memmap`` instead, so a region of interest reads only its own rows and
columns (a 100 x 100 px region of a 1280 x 1024 px frame touches 1 % of its bytes). Packed 10-
and 12-bit frames are decoded whole by pims, then cropped; packed 10-bit (P10) codes are
linearised with the maker's table (:mod:`rollfric.io.formats.phantom_lut`: 12-bit values, which pims
does not do). Colour and compressed files are refused (InputError): rollfric measures
monochrome frames.

``bit_depth_stated``: the SETUP's real bit depth (``real_bpp``), 12 for P10 frames.

Times: the per-frame ``image_time_only`` block (TIME64: seconds since 1970 in 32.32 fixed point,
2**-32 s resolution) gives ``timestamps`` as seconds from the first frame; the SETUP's frame rate
is ``fps``. ``attrs`` hold the time of frame 0 from the trigger, the first image number, the
median exposure and the camera's bit depth, the trigger's date and time, and the step of the
frame times (``timestamp_resolution_s``: 1 us for a camera whose clock counts microseconds,
so that its intervals, 28 or 29 us at 35087 Hz, are not taken for dropped frames).
"""

from __future__ import annotations

import datetime
import math
from pathlib import Path

import numpy as np

from rollfric.io.formats.phantom_lut import P10_BITS, P10_TO_LINEAR
from rollfric.io.source import BaseSource, RecordingError


class CineSource(BaseSource):
    """A Phantom ``.cine`` recording as a FrameSource (monochrome, uncompressed or packed)."""

    def __init__(self, path: str | Path) -> None:
        from pims.cine import Cine

        path = Path(path)
        name = str(path)
        try:
            cine = Cine(str(path))
        except Exception as exc:  # pims raises struct.error, KeyError, TypeError, ...
            raise RecordingError(f"{path}: not a readable Phantom cine file ({type(exc).__name__}"
                                 f": {exc}; truncated header or missing tagged blocks?)") from None
        self._cine = cine
        if cine.header_dict.get("type") != b"CI":
            raise RecordingError(f"{path}: not a Phantom cine file (no 'CI' signature)")
        if not hasattr(cine, "image_locations"):
            raise RecordingError(f"{path}: truncated cine file: its table of image offsets is "
                                 "missing")
        if cine.compression != 0 or cine.cfa != 0:
            raise RecordingError(f"{path}: colour or compressed cine file (compression "
                                 f"{cine.compression}, CFA {cine.cfa}): rollfric reads monochrome "
                                 "cine files; export the recording as monochrome")
        w, h = int(cine.bitmapinfo_dict["bi_width"]), abs(int(cine.bitmapinfo_dict["bi_height"]))
        n = int(cine.image_count)
        if w <= 0 or h <= 0:
            raise RecordingError(f"{path}: cine header gives a {w}x{h} px frame")
        if n == 0:
            raise RecordingError(f"{path}: the recording holds no frames")
        self._size = path.stat().st_size
        self._mm = np.memmap(path, dtype=np.uint8, mode="r")
        self._locs = np.asarray(cine.image_locations, dtype=np.int64).reshape(-1)
        if len(self._locs) != n:
            raise RecordingError(f"{path}: the cine header says {n} images, its offset table "
                                 f"holds {len(self._locs)}")
        self.name = name  # for the messages of _frame_span before BaseSource.__init__
        self._npx = h * w
        # bits a pixel from frame 0's image size, as pims does: 8, 16, or 10/12 packed
        self._bits = 8 * self._frame_span(0)[1] // self._npx
        if self._bits not in (8, 10, 12, 16):
            raise RecordingError(f"{path}: frame 0 holds {self._bits} bits a pixel (8, 16 or "
                                 "10/12 packed wanted)")
        self._packed = self._bits in (10, 12)
        super().__init__(name, n, (h, w), np.uint8 if self._bits == 8 else np.uint16)
        # the last frame must be whole: a file cut short fails here, not half-way through a run
        self._frame_span(n - 1)
        fps = cine.frame_rate
        self.fps = float(fps) if fps and math.isfinite(fps) and fps > 0 else None
        self.timestamps, notes = _timestamps(cine, n)
        exposures = cine.all_exposures
        shutter_us = cine.setup_fields_dict.get("shutter")  # the SETUP's, whole microseconds
        exposure = float(np.median(exposures)) if exposures else \
            (float(shutter_us) * 1e-6 if shutter_us else None)
        real = int(cine.setup_fields_dict.get("real_bpp") or 0)
        word = 8 if self._bits == 8 else 16
        if self._bits == 10:
            self.bit_depth_stated = P10_BITS  # the maker's table gives 12-bit linear values
        elif 0 < real <= word:
            self.bit_depth_stated = real
        elif self._bits in (8, 12):
            self.bit_depth_stated = self._bits
        self.attrs = {
            "format": "phantom-cine",
            "camera_bit_depth": self.bit_depth_stated or self._bits,
            "colour": "mono",
            "first_image_no": int(cine.header_dict["first_image_no"]),
            "start_frame": int(cine.header_dict["first_image_no"]),
            "total_image_count": int(cine.header_dict["total_image_count"]),
            "exposure_s": exposure,
            "shutter_s": exposure,
            "trigger_time": _trigger_time(cine),
            "time_notes": notes,
        }
        if self.timestamps is not None:
            self.attrs["frame0_from_trigger_s"] = _frame0_from_trigger(cine)
            self.attrs["timestamp_resolution_s"] = _resolution(cine)

    def _frame_span(self, i: int) -> tuple[int, int]:
        """(byte offset, byte count) of frame i's pixels; RecordingError when it is not whole."""
        off = int(self._locs[i])
        if off < 0 or off + 8 > self._size:
            raise RecordingError(f"{self.name}: truncated cine file: frame {i} starts at byte "
                                 f"{off}, the file has {self._size}")
        ann = int(self._mm[off:off + 4].view("<u4")[0])
        if ann < 8 or off + ann > self._size:
            raise RecordingError(f"{self.name}: frame {i}: bad annotation size {ann} (truncated "
                                 "or corrupt cine file)")
        size = int(self._mm[off + ann - 4:off + ann].view("<u4")[0])
        start = off + ann
        if start + size > self._size:
            raise RecordingError(f"{self.name}: truncated cine file: frame {i} needs bytes "
                                 f"{start}..{start + size}, the file ends at {self._size}")
        bits = getattr(self, "_bits", None)
        if bits is not None and size * 8 != self._npx * bits:
            raise RecordingError(f"{self.name}: frame {i} holds {size} bytes, not one "
                                 f"{self._npx} px frame of {bits} bits a pixel")
        return start, size

    def _pixels(self, i: int) -> np.ndarray:
        """Frame i as stored: (H, W), bottom row first, memory-mapped (nothing read yet)."""
        start, size = self._frame_span(i)
        h, w = self.shape[1:]
        dt = np.dtype("<u2") if self._bits == 16 else np.dtype(np.uint8)
        return self._mm[start:start + size].view(dt).reshape(h, w)

    def __getitem__(self, i: int) -> np.ndarray:
        i = self._index(i)
        if self._packed:
            self._frame_span(i)
            try:
                img = np.asarray(self._cine.get_frame(i))
            except Exception as exc:
                raise RecordingError(f"{self.name}: cannot decode packed frame {i} ({exc})") \
                    from None
            if self._bits == 10:
                # P10 codes are not linear in the light: the maker's table linearises them
                img = P10_TO_LINEAR[np.minimum(img, 1023)]
            return self._check(img.astype(self.dtype, copy=False), i)
        return np.ascontiguousarray(self._pixels(i)[::-1], dtype=self.dtype)

    def _read_roi(self, i: int, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        if self._packed:
            return np.ascontiguousarray(self[i][y0:y1, x0:x1])
        h = self.shape[1]
        # stored bottom row first: image rows y0..y1-1 are stored rows h-y1..h-y0-1, reversed
        rows = self._pixels(i)[h - y1:h - y0, x0:x1]
        return np.ascontiguousarray(rows[::-1], dtype=self.dtype)


def _timestamps(cine, n: int) -> tuple[np.ndarray | None, list[str]]:
    """(seconds of each frame from frame 0, notes) from the TIME64 block, or (None, notes)."""
    stamps = cine.frame_time_stamps
    if not stamps:
        return None, ["the cine file holds no per-frame times"]
    if len(stamps) != n:
        return None, [f"the cine file's time block holds {len(stamps)} times for {n} frames: "
                      "not used"]
    d0, f0 = stamps[0]
    t = np.array([(d - d0).total_seconds() + (f - f0) for d, f in stamps])
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        return None, ["the cine file's per-frame times do not increase from frame to frame: "
                      "not used"]
    return t, []


def _frame0_from_trigger(cine) -> float:
    d0, f0 = cine.frame_time_stamps[0]
    tt = cine.trigger_time
    return (d0 - tt["datetime"]).total_seconds() + (f0 - tt["second_fraction"])


def _trigger_time(cine) -> str | None:
    """The trigger's date and time (the header's TIME64: seconds since 1970 UTC, 32.32 fixed
    point) as ISO 8601 text in UTC to the microsecond, or None. pims gives it in the local
    time zone of the computer reading the file."""
    try:
        t64 = int(cine.header_dict["trigger_time"])
        when = datetime.datetime.fromtimestamp(t64 >> 32, datetime.UTC)
        return (when + datetime.timedelta(seconds=(t64 & 0xFFFFFFFF) / 2 ** 32)).isoformat()
    except (KeyError, TypeError, ValueError, OverflowError, OSError):
        return None


# a TIME64 is 32.32 fixed point; older cameras fill its fraction from a microsecond clock
TIME64_STEP = 2.0 ** -32
CLOCK_STEPS = (1e-6, 1e-7)  # the coarser of these that every frame time lies on
CLOCK_TOL_S = 2e-9  # off a step by at most this: on it (the real files: 0.8 ns at most)


def _resolution(cine) -> float:
    """The step of the frame times (s): 1e-6 when every frame's TIME64 fraction is a whole
    number of microseconds (within CLOCK_TOL_S), else 1e-7 likewise, else 2**-32."""
    frac = np.array([f for _, f in cine.frame_time_stamps], dtype=float)
    for step in CLOCK_STEPS:
        k = frac / step
        if np.all(np.abs(k - np.round(k)) * step <= CLOCK_TOL_S):
            return step
    return TIME64_STEP
