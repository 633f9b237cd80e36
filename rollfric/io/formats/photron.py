"""Photron ``.cih``/``.cihx`` + ``.mraw`` recordings: the header parsed by
:mod:`rollfric.io.formats.cih`, the frames memory-mapped here.

The header (``.cih`` "key : value" text or ``.cihx`` XML, any case of the extension) is read
by :func:`rollfric.io.formats.cih.read_cih`: frame count, size, frame rate ("Record Rate(fps)"),
bit depth ("Color Bit" 8, 12 or 16), the effective bits and their side, the exposure, the start
frame (frame 0's number from the trigger), the colour type. The ``.mraw`` beside it (same stem,
either case) is the frames back to back, no headers: 8-bit, 16-bit little-endian, or 12-bit
packed (two pixels in three bytes, big-endian nibble order, as pyMRAW's ``nb_read_uint12``).

pyMRAW's own frame reader is not used: a 12-bit file it decodes whole into memory (2 bytes a
pixel of every frame: 10.5 GB for 4001 frames of 1280 x 1024 px) with a numba kernel compiled
on import. Here every format is a ``numpy.memmap``, and a region of interest reads and unpacks
only its own bytes (12-bit: the 3-byte pairs of its columns in its rows; with an odd frame width
rows do not start on a pair, so its rows are unpacked whole) - the same pixels as pyMRAW's.

``bit_depth_stated``: the header's effective bit depth ("EffectiveBit Depth", at most the word's
"Color Bit"), the word's own depth where the effective bits are on the high side.

MRAW holds no per-frame times: ``timestamps`` is None, ``fps`` the header's record rate.
Colour files are refused: "Color Type" Color, and Raw (the sensor's own values) from a colour
camera (a Photron model name with "-C", e.g. ``type 1100K-C``: a Bayer mosaic); Raw from a
monochrome camera ("-M") is monochrome.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from rollfric.io.formats.cih import read_cih
from rollfric.io.source import BaseSource, RecordingError


def _beside(path: Path, suffix: str) -> Path | None:
    """The file of ``path``'s stem with ``suffix`` in the case of ``path``'s own suffix, else in
    the other case (a camera writes ``BALL.CIHX`` beside ``BALL.MRAW``); None if neither is."""
    upper = path.suffix.isupper()
    for s in ((suffix.upper(), suffix) if upper else (suffix, suffix.upper())):
        p = path.with_suffix(s)
        if p.is_file():
            return p
    return None


def _header_and_data(path: Path) -> tuple[Path, Path]:
    """(header file, .mraw file) of a recording given by either."""
    if path.suffix.lower() == ".mraw":
        for suffix in (".cihx", ".cih"):
            head = _beside(path, suffix)
            if head is not None:
                return head, path
        raise RecordingError(f"{path}: no .cih or .cihx header beside it ({path.stem}.cih): "
                             "the header gives the frame size and bit depth")
    data = _beside(path, ".mraw")
    if data is not None:
        return path, data
    raise RecordingError(f"{path}: the frames file {path.with_suffix('.mraw').name} is missing "
                         "beside the header")


def colour_type(cih: dict) -> str:
    """"mono" or "colour": the header's "Color Type" (Mono, Color, or Raw, which is a colour
    camera's Bayer mosaic when its model name says "-C")."""
    kind = str(cih.get("Color Type", "Mono")).strip().lower()
    if kind == "mono":
        return "mono"
    if kind == "raw":
        model = str(cih.get("Camera Type", ""))
        return "colour" if re.search(r"\d+K-C\b|-C-", model) else "mono"
    return "colour"


def data_bit_depth(cih: dict, bits: int) -> int:
    """The bits of the stored values: the camera's effective bits when they sit in the lower
    bits of each value ("EffectiveBit Side" Lower), the container's when the higher ones do (an
    8-bit file of a 12-bit camera holds its upper 8 bits) or the header gives none."""
    eff = cih.get("EffectiveBit Depth")
    side = str(cih.get("EffectiveBit Side", "Lower")).strip().lower()
    if isinstance(eff, int) and 0 < eff < bits and side == "lower":
        return eff
    return bits


def unpack12(packed: np.ndarray) -> np.ndarray:
    """12-bit packed pixels to uint16: the last axis holds 3-byte pairs (3k bytes -> 2k pixels).

    Byte a, b, c hold pixels p0 = a << 4 | b >> 4 and p1 = (b & 15) << 8 | c.

    Parameters
    ----------
    packed : numpy.ndarray
        uint8, last axis a multiple of 3.

    Returns
    -------
    numpy.ndarray
        uint16, the last axis 2/3 as long.
    """
    b = packed.reshape(packed.shape[:-1] + (-1, 3)).astype(np.uint16)
    out = np.empty(b.shape[:-1] + (2,), dtype=np.uint16)
    out[..., 0] = (b[..., 0] << 4) | (b[..., 1] >> 4)
    out[..., 1] = ((b[..., 1] & 0xF) << 8) | b[..., 2]
    return out.reshape(packed.shape[:-1] + (-1,))


class PhotronSource(BaseSource):
    """A Photron recording (``.cih``/``.cihx`` header + ``.mraw`` frames) as a FrameSource."""

    def __init__(self, path: str | Path) -> None:
        path = Path(path)
        head, data = _header_and_data(path)
        self._head, self._data = head, data
        cih = read_cih(head)
        try:
            n = int(cih["Total Frame"])
            w, h = int(cih["Image Width"]), int(cih["Image Height"])
            bits = int(cih["Color Bit"])
            fmt = str(cih.get("File Format", "MRaw"))
        except (KeyError, TypeError, ValueError) as exc:
            raise RecordingError(f"{head}: Photron header without a valid {exc} entry") from None
        if fmt.lower() != "mraw":
            raise RecordingError(f"{head}: the header says the frames are stored as {fmt!r}; "
                                 "rollfric reads MRAW")
        if colour_type(cih) != "mono" or bits not in (8, 12, 16):
            raise RecordingError(f"{head}: {cih.get('Color Type', '')} {bits}-bit frames of a "
                                 f"{cih.get('Camera Type', 'camera')}: rollfric reads monochrome"
                                 " 8-, 12- and 16-bit MRAW; export the recording as monochrome")
        if w <= 0 or h <= 0 or n <= 0:
            raise RecordingError(f"{head}: the header gives {n} frames of {w}x{h} px")
        npx = n * h * w
        need = 3 * ((npx + 1) // 2) if bits == 12 else npx * bits // 8
        size = data.stat().st_size
        if size < need:
            per = h * w * bits / 8
            raise RecordingError(f"{data}: truncated MRAW file: {n} frames of {w}x{h} px at "
                                 f"{bits} bits need {need} bytes, the file has {size} "
                                 f"({int(size // per)} whole frames)")
        super().__init__(str(path), n, (h, w), np.uint8 if bits == 8 else np.uint16)
        self._bits = bits
        if bits == 12:
            self._mm = np.memmap(data, dtype=np.uint8, mode="r", shape=(need,))
        else:
            dt = np.uint8 if bits == 8 else np.dtype("<u2")
            self._mm = np.memmap(data, dtype=dt, mode="r", shape=(n, h, w))
        fps = cih.get("Record Rate(fps)")
        self.fps = float(fps) if isinstance(fps, (int, float)) and math.isfinite(fps) \
            and fps > 0 else None
        eff, side = cih.get("EffectiveBit Depth"), str(cih.get("EffectiveBit Side", "Lower"))
        if isinstance(eff, int) and 0 < eff and side.lower() != "higher":
            self.bit_depth_stated = min(eff, bits)  # values in the word's low bits
        elif bits in (8, 12) or (isinstance(eff, int) and side.lower() == "higher"):
            self.bit_depth_stated = bits  # packed, or left-aligned: the word's full range
        self.attrs = {
            "format": "photron-mraw",
            "header": str(head),
            "camera": cih.get("Camera Type"),
            "date": cih.get("Date"),
            "camera_bit_depth": data_bit_depth(cih, bits),
            "effective_bit_depth": cih.get("EffectiveBit Depth"),
            "effective_bit_side": cih.get("EffectiveBit Side"),
            "colour": colour_type(cih),
            "shutter_s": cih["shutter_s"],
            "start_frame": start if isinstance(start := cih.get("Start Frame"), int) else None,
        }
        if self.attrs["start_frame"] is not None and self.fps:
            # frame 0's time from the trigger: its number from the trigger frame, in periods
            self.attrs["frame0_from_trigger_s"] = self.attrs["start_frame"] / self.fps

    def __getitem__(self, i: int) -> np.ndarray:
        i = self._index(i)
        return self._read_roi(i, 0, self.shape[1], 0, self.shape[2])

    def _read_roi(self, i: int, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        if self._bits != 12:
            return np.array(self._mm[i, y0:y1, x0:x1], dtype=self.dtype)
        h, w = self.shape[1:]
        first = i * h * w  # pixel index of the frame's first pixel in the file
        if w % 2 == 0:
            # every row starts on a 3-byte pair: read the pairs of columns x0..x1 only
            a, b = x0 // 2, (x1 + 1) // 2
            rows = self._mm[3 * (first // 2):3 * ((first + h * w) // 2)].reshape(h, w // 2, 3)
            px = unpack12(rows[y0:y1, a:b].reshape(y1 - y0, 3 * (b - a)))
            return np.ascontiguousarray(px[:, x0 - 2 * a:x1 - 2 * a])
        # odd width: rows y0..y1 unpacked whole, then cropped
        p0, p1 = first + y0 * w, first + y1 * w
        q0, q1 = p0 // 2, (p1 + 1) // 2
        px = unpack12(np.asarray(self._mm[3 * q0:3 * q1]))[p0 - 2 * q0:p1 - 2 * q0]
        return np.ascontiguousarray(px.reshape(y1 - y0, w)[:, x0:x1])
