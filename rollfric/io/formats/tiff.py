"""A multi-page TIFF recording (``.tif``/``.tiff``), one grayscale page per frame (tifffile):
pages memory-mapped where they are uncompressed, the camera's bit depth from the tags.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rollfric.io.bitdepth import bits_for, dtype_bits
from rollfric.io.limits import check_memory
from rollfric.io.source import BaseSource, RecordingError


class TiffSource(BaseSource):
    """A multi-page TIFF, one page a frame (or a single page holding a (T, H, W) stack)."""

    def __init__(self, path: Path) -> None:
        import logging

        import tifffile

        # tifffile logs what it finds wrong in a file's structure; the checks below refuse
        # such a file with a message of their own, so its log line would only say it twice
        tiff_log = logging.getLogger("tifffile")
        tiff_log.addFilter(_drop_record)
        try:
            try:
                self._tif = tifffile.TiffFile(path)
                pages = self._tif.pages
                n = len(pages)
                first = pages.first
                shape = tuple(first.shape)
            except Exception as exc:  # tifffile raises several types for broken files
                raise RecordingError(f"{path}: not a readable TIFF file ({exc})") from None
            _check_ifd_chain(self._tif, path, n)
        finally:
            tiff_log.removeFilter(_drop_record)
        colour = len(shape) == 3 and shape[-1] in (3, 4)
        if not (len(shape) == 2 or colour or (n == 1 and len(shape) == 3)) \
                or not all(isinstance(v, int) and v > 0 for v in shape):
            raise RecordingError(f"{path}: the first page holds an array of shape {shape}, not "
                                 "an image (corrupt file?)")
        self._stack = None
        if n == 1 and len(shape) == 3 and not colour:
            # one page holding a whole (T, H, W) stack: memory-map it if possible
            try:
                self._stack = self._tif.asarray(out="memmap")
            except Exception:
                check_memory(math.prod(shape) * np.dtype(first.dtype).itemsize,
                             f"{path}: its one compressed page of {shape} pixels")
                try:
                    self._stack = self._tif.asarray()
                except Exception as exc:  # tifffile raises several types for broken files
                    raise RecordingError(f"{path}: cannot read the stack (truncated or corrupt "
                                         f"file? {exc})") from None
            n, hw = self._stack.shape[0], self._stack.shape[1:]
        else:
            hw = shape[:2]
        self._path = path
        self._mmap = None  # the whole file, memory-mapped for region reads of plain pages
        super().__init__(str(path), n, hw, first.dtype)
        self.bit_depth_stated = tiff_bit_depth(first, self.dtype)

    def __getitem__(self, i: int) -> np.ndarray:
        i = self._index(i)
        if self._stack is not None:
            return self._check(np.asarray(self._stack[i]), i)
        try:
            page = self._tif.pages[i]
            img = page.asarray()
        except Exception as exc:
            raise RecordingError(f"{self.name}: cannot read frame {i} (truncated or corrupt "
                                 f"file? {exc})") from None
        return self._check(img, i)

    def _read_roi(self, i: int, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        if self._stack is not None:  # (T, H, W) of one dtype, memory-mapped when possible
            return np.array(self._stack[i, y0:y1, x0:x1])
        try:
            page = self._tif.pages[i]
            plain = (page.is_memmappable and tuple(page.shape) == self.shape[1:]
                     and np.dtype(page.dtype) == self.dtype)
        except Exception:
            plain = False
        if not plain:  # compressed, tiled, colour, ...: decode the page, then crop
            return self[i][y0:y1, x0:x1]
        if self._mmap is None:
            self._mmap = np.memmap(self._path, dtype=np.uint8, mode="r")
        h, w = self.shape[1:]
        dt = self.dtype.newbyteorder(self._tif.byteorder)
        off = int(page.dataoffsets[0])
        if off < 0 or off + h * w * dt.itemsize > self._mmap.size:
            raise RecordingError(f"{self.name}: cannot read frame {i}: its data lies beyond the "
                                 f"end of the file (truncated or corrupt file?)")
        img = self._mmap[off:off + h * w * dt.itemsize].view(dt).reshape(h, w)
        return np.ascontiguousarray(img[y0:y1, x0:x1], dtype=self.dtype)


def tiff_bit_depth(page, dtype) -> int | None:
    """The camera's bit depth a TIFF page states: from ``MaxSampleValue`` (4095: 12 bits), else
    ``BitsPerSample`` unless it is only the 16-bit word every writer uses for uint16 data (that
    says nothing of the camera: the setup's ``camera.bit_depth`` or the data then tell)."""
    word = dtype_bits(dtype)
    try:
        tag = page.tags.get("MaxSampleValue")
        vmax = tag.value if tag is not None else None
        if isinstance(vmax, (tuple, list)):
            vmax = max(vmax) if vmax else None
        bps = page.bitspersample
    except Exception:  # a tag tifffile cannot decode states nothing
        return None if word > 8 else 8
    if isinstance(vmax, (int, np.integer)) and 0 < int(vmax) < 2 ** word:
        return bits_for(int(vmax))
    if isinstance(bps, (int, np.integer)) and 0 < int(bps) < 16:
        return min(int(bps), word)
    return None


def _drop_record(record) -> bool:
    """A logging filter that drops every record."""
    return False


def _check_ifd_chain(tif, path: Path, n: int) -> None:
    """Refuse a TIFF whose chain of page directories does not end: tifffile stops, with only a
    log line, at a next-page offset beyond the end of the file or at a directory it cannot read,
    so a file cut between two pages would read as a shorter recording."""
    import struct

    try:
        t = tif.tiff
        fh = tif.filehandle
        offset = int(tif.pages[n - 1].offset)
        fh.seek(offset)
        tagno = struct.unpack(t.tagnoformat, fh.read(t.tagnosize))[0]
        fh.seek(offset + t.tagnosize + tagno * t.tagsize)
        nxt = int(struct.unpack(t.offsetformat, fh.read(t.offsetsize))[0])
    except Exception as exc:  # struct, OSError, tifffile's own: the directory is cut short
        raise RecordingError(f"{path}: cannot read the directory of page {n} (truncated or "
                             f"corrupt file? {exc})") from None
    if nxt != 0:
        where = "lies beyond the end of the file" if nxt >= fh.size else "is unreadable"
        raise RecordingError(f"{path}: the directory of page {n + 1} {where}: only {n} whole "
                             f"page(s) (truncated or corrupt file?)")
