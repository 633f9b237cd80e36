"""Camera files written by the tests: Phantom .cine (built here, field by field) and Photron
.cih/.cihx + .mraw (pyMRAW's writer; 12-bit packed and .cihx built here)."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

EPOCH_S = 1_700_000_000  # the TIME64 seconds of the first frame (2023-11-14)


def time64(t: float) -> int:
    """EPOCH_S + t seconds since 1970 as a Phantom TIME64: 32.32 fixed point (t small, so that
    its fraction keeps its float precision)."""
    sec = int(np.floor(t))
    frac = int(round((t - sec) * 2 ** 32))
    if frac == 2 ** 32:
        sec, frac = sec + 1, 0
    return ((EPOCH_S + sec) << 32) | frac


def _pack_fields(fields, values: dict) -> bytes:
    """The fields (name, struct format) packed little-endian one after the other, as pims reads
    them: every field zero (or empty) unless given in ``values``."""
    out = []
    for name, fmt in fields:
        s = struct.Struct("<" + fmt)
        v = values.get(name)
        if v is None:
            v = s.unpack(bytes(s.size))
        elif not isinstance(v, tuple):
            v = (v,)
        out.append(s.pack(*v))
    return b"".join(out)


def write_cine(path, frames, *, fps: float = 1000.0, times=None, trigger=None, packed12=False,
               first_image_no: int = 0, annotation: bytes = b"rollfric",
               packed10=False) -> Path:
    """A minimal valid monochrome .cine file: CINEFILEHEADER, BITMAPINFOHEADER, SETUP (frame
    rate), tagged blocks 1002 (TIME64 per frame) and 1003 (exposure per frame), the image
    offsets, then each frame: annotation (size, bytes, image size) and the pixels, bottom row
    first (8 or 16 bit), or top row first 12-bit packed (as pims reads packed frames), or
    ``packed10``: the frames' values (< 1024) as P10 codes, 10-bit packed (the maker's
    compression 256).

    ``times``: seconds of each frame from frame 0 (default i / fps); ``trigger``: the trigger's
    time from frame 0 (default 0)."""
    from pims.cine import (
        BITMAP_INFO_FIELDS,
        HEADER_FIELDS,
        SETUP_FIELDS,
        _sixteen2ten,
        _sixteen2twelve,
    )

    frames = np.asarray(frames)
    n, h, w = frames.shape
    bits = 8 if frames.dtype == np.uint8 else 16
    times = np.arange(n) / fps if times is None else np.asarray(times, dtype=float)
    trigger = 0.0 if trigger is None else float(trigger)
    header_size = struct.calcsize("<" + "".join(f for _, f in HEADER_FIELDS))
    bmp_size = struct.calcsize("<" + "".join(f for _, f in BITMAP_INFO_FIELDS))
    setup_len = sum(struct.calcsize("<" + f) for _, f in SETUP_FIELDS)
    blocks = []
    stamps = [time64(t) for t in times]
    blocks.append(struct.pack("<IHH", 8 + 8 * n, 1002, 1) + struct.pack(f"<{n}Q", *stamps))
    expo = [int(0.0002 * 2 ** 32)] * n
    blocks.append(struct.pack("<IHH", 8 + 4 * n, 1003, 0) + struct.pack(f"<{n}I", *expo))
    tagged = b"".join(blocks)
    off_bmp = header_size
    off_setup = off_bmp + bmp_size
    off_offsets = off_setup + setup_len + len(tagged)
    data_start = off_offsets + 8 * n
    if packed10:
        image_size = h * w * 10 // 8
        images = [_sixteen2ten(f.astype(np.uint16).ravel()).tobytes() for f in frames]
    elif packed12:
        image_size = h * w * 12 // 8
        images = [_sixteen2twelve(f.astype(np.uint16).ravel()).tobytes() for f in frames]
    else:
        image_size = h * w * bits // 8
        dt = "<u2" if bits == 16 else np.uint8
        images = [np.ascontiguousarray(f[::-1]).astype(dt).tobytes() for f in frames]
    ann_size = 8 + len(annotation)
    offsets = [data_start + i * (ann_size + image_size) for i in range(n)]
    header = _pack_fields(HEADER_FIELDS, {
        "type": b"CI", "header_size": header_size, "compression": 0, "version": 1,
        "first_movie_image": first_image_no, "total_image_count": n,
        "first_image_no": first_image_no, "image_count": n, "off_image_header": off_bmp,
        "off_setup": off_setup, "off_image_offsets": off_offsets,
        "trigger_time": time64(trigger)})
    bmp = _pack_fields(BITMAP_INFO_FIELDS, {
        "bi_size": bmp_size, "bi_width": w, "bi_height": h, "bi_planes": 1,
        "bi_bit_count": 16 if packed12 or packed10 else bits,
        "bi_compression": 256 if packed10 else 1024 if packed12 else 0,
        "bi_image_size": image_size})
    setup = _pack_fields(SETUP_FIELDS, {
        "frame_rate_16": min(int(fps), 65535), "length": setup_len, "im_width": w,
        "im_height": h, "frame_rate": int(round(fps)), "software_version": 702,
        "real_bpp": 10 if packed10 else 12 if packed12 else bits, "cfa": 0})
    assert len(setup) == setup_len
    with open(path, "wb") as f:
        f.write(header + bmp + setup + tagged + struct.pack(f"<{n}Q", *offsets))
        for img in images:
            f.write(struct.pack("<I", ann_size) + annotation + struct.pack("<I", image_size))
            f.write(img)
    return Path(path)


def pack12(frames) -> bytes:
    """uint16 pixels (< 4096) as Photron's 12-bit packed stream: two pixels in three bytes."""
    p = np.asarray(frames, dtype=np.uint16).ravel()
    if p.size % 2:
        p = np.append(p, 0)
    a, b = p[0::2], p[1::2]
    out = np.empty((p.size // 2, 3), dtype=np.uint8)
    out[:, 0] = a >> 4
    out[:, 1] = ((a & 0xF) << 4) | (b >> 8)
    out[:, 2] = b & 0xFF
    return out.tobytes()


def write_mraw(path, frames, *, fps: float = 1000.0, bits: int | None = None,
               start_frame: int = 0) -> tuple[Path, Path]:
    """(cih, mraw) of a Photron recording written by pyMRAW (8 and 16 bit); ``bits=12``: the
    .cih from pyMRAW, the .mraw packed here."""
    import pyMRAW

    frames = np.asarray(frames)
    bits = bits or (8 if frames.dtype == np.uint8 else 16)
    info = {"Record Rate(fps)": int(fps) if float(fps).is_integer() else fps,
            "Start Frame": start_frame, "Camera Type": "test"}
    if bits == 12:
        info.update({"Color Bit": 12, "EffectiveBit Depth": 12})
    mraw, cih = pyMRAW.save_mraw(frames, str(path), bit_depth=8 if bits == 8 else 16,
                                 info_dict=info)
    if bits == 12:
        Path(mraw).write_bytes(pack12(frames))
    return Path(cih), Path(mraw)


def write_cihx(path, n: int, h: int, w: int, *, fps: float, bits: int) -> Path:
    """A minimal Photron .cihx (XML) header with the entries pyMRAW reads."""
    xml = f"""<?xml version="1.0" encoding="UTF-8" standalone="yes"?>
<cih>
<fileInfo><date>2024/01/01</date></fileInfo>
<basicInfo><comment>rollfric test</comment></basicInfo>
<deviceInfo><deviceName>test</deviceName></deviceInfo>
<recordInfo><recordRate>{fps:g}</recordRate><shutterSpeed>5000</shutterSpeed></recordInfo>
<frameInfo><totalFrame>{n}</totalFrame><recordedFrame>{n}</recordedFrame></frameInfo>
<imageDataInfo>
<resolution><width>{w}</width><height>{h}</height></resolution>
<effectiveBit><depth>{min(bits, 12)}</depth><side>Lower</side></effectiveBit>
<colorInfo><bit>{bits}</bit></colorInfo>
</imageDataInfo>
<imageFileInfo><fileFormat>MRaw</fileFormat></imageFileInfo>
</cih>
"""
    Path(path).write_text(xml, encoding="utf-8")
    return Path(path)
