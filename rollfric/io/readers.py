"""Reading recordings: frames streamed one at a time, never the whole sequence in memory.

A recording is one of

- a multi-page TIFF (``.tif``/``.tiff``), one grayscale page per frame (tifffile);
- a folder of image files (PNG, TIFF, BMP, JPEG, ...), frames in the natural order of the file
  names (``img_9`` before ``img_10``; OpenCV);
- a video file (``.avi``, ``.mp4``, ``.mkv``, ``.mov``), read in order (OpenCV VideoCapture);
- a Phantom ``.cine`` file (:mod:`rollfric.io.formats.cine`) or a Photron ``.cih``/``.cihx`` header
  with its ``.mraw`` (:mod:`rollfric.io.formats.photron`), memory-mapped;
- a Zarr store (a directory, e.g. ``rec.zarr``) holding an array ``frames`` (T, H, W), or read by
  the first ``rollfric.zarr_readers`` entry point that accepts it (the project's contract).

Every reader returns a *FrameSource*: ``len(src)``, ``src[i]`` -> one (H, W) uint8 or uint16
frame, and the attributes ``shape`` (T, H, W), ``dtype``, ``fps`` (float or None),
``background`` ((H, W) array or None) and ``attrs`` (dict), and optionally ``timestamps``
((T,) float seconds from frame 0, strictly increasing: the camera's own per-frame times, or
None). Colour images are converted to grayscale.

Regions of interest (an optional part of the FrameSource contract): a FrameSource MAY have
``read(i, roi)``, roi = (y0, y1, x0, x1) integers with ``0 <= y0 < y1 <= H`` and
``0 <= x0 < x1 <= W``, returning frame i's region ``[y0:y1, x0:x1]``: the same bytes as
``src[i][y0:y1, x0:x1]``, ideally without making the rest of the frame. The tracking loop
(:mod:`rollfric.track.tracker`) uses it when present. All the readers here have it: a crop of the
full
frame, except that a Zarr ``frames`` array is sliced (only the chunks touched are decoded), an
uncompressed TIFF, a cine and an MRAW file are memory-mapped (only the region's bytes are
read), and an entry-point reader that has ``read`` is asked for the region itself.

Bad input (unreadable, truncated, mixed frame sizes, unsupported depth) raises
:class:`RecordingError`, naming the file and the frame.
"""

from __future__ import annotations

import importlib.metadata
import math
import re
from pathlib import Path

import numpy as np

from rollfric.errors import InputError
from rollfric.io.bitdepth import bits_for, check_bits, dtype_bits
from rollfric.io.formats.cine import CineSource
from rollfric.io.formats.photron import PhotronSource
from rollfric.io.limits import check_memory
from rollfric.io.source import (  # noqa: F401  (FrameSource, RegionSource: the readers' protocol)
    BaseSource,
    FrameSource,
    RecordingError,
    RegionSource,
    _to_gray,
    check_roi,
)

_Source = BaseSource  # the name the readers below (and older code) use

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg", ".pgm", ".ppm", ".jp2",
                  ".webp")
VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov", ".m4v", ".mpg", ".mpeg", ".wmv")
TIFF_SUFFIXES = (".tif", ".tiff")
CINE_SUFFIXES = (".cine",)
PHOTRON_SUFFIXES = (".cih", ".cihx", ".mraw")
ZARR_ENTRY_POINT_GROUP = "rollfric.zarr_readers"


class TiffSource(_Source):
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
        self.bit_depth_stated = _tiff_bit_depth(first, self.dtype)

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


def _tiff_bit_depth(page, dtype) -> int | None:
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


def natural_key(name: str) -> tuple:
    """Sort key of a file name in natural order: its runs of digits compared as numbers.

    ``img_9.png`` comes before ``img_10.png`` (plain sorting puts it after, and a camera that
    numbers its files without leading zeros would have its frames shuffled); names numbered with
    leading zeros keep their plain order. Ties (``img_09`` and ``img_9``) fall back to the
    plain name. As scikit-image's ``ImageCollection`` orders its files.

    Parameters
    ----------
    name : str
        A file name.

    Returns
    -------
    tuple
        ((text, number, text, ..., text), name): texts and numbers alternate, so two keys
        never compare a text with a number.
    """
    parts = re.split(r"(\d+)", name)
    return tuple(int(p) if i % 2 else p for i, p in enumerate(parts)), name


class FolderSource(_Source):
    """A folder of image files, frames in the natural order of the file names
    (:func:`natural_key`)."""

    def __init__(self, path: Path) -> None:
        files = sorted((p for p in path.iterdir()
                        if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES),
                       key=lambda p: natural_key(p.name))
        if not files:
            raise RecordingError(f"{path}: the folder holds no image files "
                                 f"({', '.join(IMAGE_SUFFIXES)})")
        self.files = files
        first = _imread(files[0])
        super().__init__(str(path), len(files), first.shape, first.dtype)
        if files[0].suffix.lower() in TIFF_SUFFIXES and self.dtype != np.uint8:
            import tifffile

            try:  # the first image's MaxSampleValue / BitsPerSample, as for a TIFF stack
                with tifffile.TiffFile(files[0]) as tif:
                    self.bit_depth_stated = _tiff_bit_depth(tif.pages.first, self.dtype)
            except Exception:  # read by OpenCV above; a tag tifffile cannot read states nothing
                self.bit_depth_stated = None

    def __getitem__(self, i: int) -> np.ndarray:
        i = self._index(i)
        return self._check(_imread(self.files[i]), i)


def _imread(path: Path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise RecordingError(f"{path}: unreadable image file (corrupt, truncated or not an "
                             "image)")
    return _to_gray(img, str(path))


def read_image(path: str | Path) -> np.ndarray:
    """One grayscale image, e.g. a background.

    Parameters
    ----------
    path : str or pathlib.Path
        An image file (8 or 16 bit; colour is converted to grayscale), a TIFF (a stack gives its
        first page) or a ``.npy`` array.

    Returns
    -------
    numpy.ndarray
        The image (H, W).

    Raises
    ------
    RecordingError
        The file is missing or unreadable.

    Examples
    --------
    A colour PNG, read as one grayscale image:

    >>> import tempfile, cv2, numpy as np, rollfric
    >>> from pathlib import Path
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = str(Path(tmp.name) / "background.png")
    >>> cv2.imwrite(path, np.full((48, 64, 3), 200, np.uint8))
    True
    >>> image = rollfric.read_image(path)
    >>> image.shape, image.dtype, int(image[0, 0])
    ((48, 64), dtype('uint8'), 200)
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such file")
    if path.suffix.lower() in TIFF_SUFFIXES:
        import tifffile

        try:
            with tifffile.TiffFile(path) as tif:
                img = tif.pages.first.asarray()
        except Exception as exc:
            raise RecordingError(f"{path}: not a readable TIFF file ({exc})") from None
        return _to_gray(img, str(path))
    if path.suffix.lower() == ".npy":
        try:
            img = np.load(path, allow_pickle=False)
        except Exception as exc:  # numpy raises several types for broken headers and data
            raise RecordingError(f"{path}: not a readable .npy image ({exc})") from None
        return _to_gray(np.asarray(img), str(path))
    return _imread(path)


class VideoSource(_Source):
    """A video file read in order with OpenCV (seeks only when asked out of order)."""

    def __init__(self, path: Path) -> None:
        import cv2

        self._cv2 = cv2
        self._path = path
        self._cap = cv2.VideoCapture(str(path))
        if not self._cap.isOpened():
            raise RecordingError(f"{path}: OpenCV cannot open this video file")
        n = int(round(self._cap.get(cv2.CAP_PROP_FRAME_COUNT)))
        ok, frame = self._cap.read()
        if not ok or frame is None or n <= 0:
            raise RecordingError(f"{path}: the video holds no readable frames")
        frame = _to_gray(frame, f"{path} frame 0")
        self._next = 1
        self._last = (0, frame)
        super().__init__(str(path), n, frame.shape, frame.dtype)
        self.bit_depth_stated = 8 * self.dtype.itemsize  # OpenCV decodes video to 8 bits
        fps = self._cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if fps and math.isfinite(fps) and fps > 0 else None

    def __getitem__(self, i: int) -> np.ndarray:
        i = self._index(i)
        if self._last[0] == i:
            return self._last[1]
        if i != self._next:
            self._cap.set(self._cv2.CAP_PROP_POS_FRAMES, i)
        ok, frame = self._cap.read()
        if not ok or frame is None:
            raise RecordingError(f"{self.name}: cannot read frame {i} of {len(self)} (truncated "
                                 "or corrupt video?)")
        frame = self._check(frame, i)
        self._next = i + 1
        self._last = (i, frame)
        return frame


class ZarrArraySource(_Source):
    """A Zarr store with an array ``frames`` (T, H, W) uint8/uint16 (optional ``background``
    (H, W) and ``timestamps`` (T,): each frame's time in seconds)."""

    def __init__(self, group, path: Path) -> None:
        arr = group["frames"]
        if arr.ndim != 3:
            raise RecordingError(f"{path}: array 'frames' must be (T, H, W), got shape "
                                 f"{arr.shape}")
        if np.dtype(arr.dtype) not in (np.uint8, np.uint16):
            raise RecordingError(f"{path}: array 'frames' has dtype {arr.dtype} "
                                 "(uint8 or uint16 wanted)")
        self._arr = arr
        super().__init__(str(path), arr.shape[0], arr.shape[1:], arr.dtype)
        self.attrs = dict(group.attrs)
        self.bit_depth_stated = _stated_bits(self.attrs.get("bit_depth"), self.dtype, str(path))
        fps = self.attrs.get("fps")
        self.fps = float(fps) if isinstance(fps, (int, float)) and fps > 0 else None
        if "background" in group:
            self.background = np.asarray(group["background"][...])
        if "timestamps" in group:  # the camera's time of each frame (s)
            ts = np.asarray(group["timestamps"][...], dtype=float).reshape(-1)
            self.timestamps = ts - ts[0] if ts.size else ts

    def __getitem__(self, i: int) -> np.ndarray:
        i = self._index(i)
        try:
            img = np.asarray(self._arr[i])
        except Exception as exc:
            raise RecordingError(f"{self.name}: cannot read frame {i} ({exc})") from None
        return self._check(img, i)

    def _read_roi(self, i: int, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        try:
            return np.asarray(self._arr[i, y0:y1, x0:x1])
        except Exception as exc:
            raise RecordingError(f"{self.name}: cannot read frame {i} ({exc})") from None


def _stated_bits(value, dtype, name: str) -> int | None:
    """A bit depth a store or reader states (``bit_depth``), checked against its frames' word;
    None when it states none."""
    if value is None:
        return None
    try:
        bits = check_bits(value, f"{name}: its bit_depth")
    except InputError as exc:
        raise RecordingError(str(exc)) from None
    if bits > dtype_bits(dtype):
        raise RecordingError(f"{name}: its bit_depth {bits} exceeds its {dtype_bits(dtype)}-bit "
                             "frames")
    return bits


def zarr_reader_entry_points() -> list:
    """The installed ``rollfric.zarr_readers`` entry points.

    Returns
    -------
    list of importlib.metadata.EntryPoint
        Sorted by name.
    """
    eps = importlib.metadata.entry_points(group=ZARR_ENTRY_POINT_GROUP)
    return sorted(eps, key=lambda ep: ep.name)


def _open_zarr(path: Path):
    import zarr

    try:
        group = zarr.open_group(str(path), mode="r")
    except Exception as exc:
        raise RecordingError(f"{path}: not a readable Zarr store ({exc})") from None
    if "frames" in group:
        return ZarrArraySource(group, path)
    tried = []
    for ep in zarr_reader_entry_points():
        tried.append(ep.name)
        try:
            opener = ep.load()
        except Exception as exc:
            raise RecordingError(f"{path}: the Zarr reader '{ep.name}' ({ep.value}) cannot be "
                                 f"loaded: {exc}") from None
        src = opener(group)
        if src is not None:
            return _WrappedSource(src, f"{path} (reader {ep.name})", group)
    raise RecordingError(
        f"{path}: Zarr store without an array 'frames', and no '{ZARR_ENTRY_POINT_GROUP}' "
        f"reader accepted it (tried: {', '.join(tried) or 'none installed'})")


class _WrappedSource(_Source):
    """A FrameSource from an entry point, with rollfric's frame checks around it."""

    def __init__(self, src, name: str, group) -> None:
        self._src = src
        shape = tuple(int(v) for v in src.shape)
        if len(shape) != 3 or len(src) != shape[0]:
            raise RecordingError(f"{name}: reader gave inconsistent shape {shape} for "
                                 f"{len(src)} frames")
        super().__init__(name, shape[0], shape[1:], src.dtype)
        self.fps = getattr(src, "fps", None)
        self.concurrent_reads = getattr(src, "concurrent_reads", False) is True
        stamps = getattr(src, "timestamps", None)
        self.timestamps = None if stamps is None else np.asarray(stamps, dtype=float)
        bg = getattr(src, "background", None)
        self.background = None if bg is None else np.asarray(bg)
        attrs = dict(group.attrs)
        attrs.update(dict(getattr(src, "attrs", None) or {}))
        self.attrs = attrs
        # the reader's own statement of the camera's depth, else the store's attribute
        stated = getattr(src, "bit_depth_stated", None)
        if stated is None and not isinstance(getattr(type(src), "bit_depth", None), property):
            stated = getattr(src, "bit_depth", None)
        self.bit_depth_stated = _stated_bits(attrs.get("bit_depth") if stated is None
                                             else stated, self.dtype, name)

    def __getitem__(self, i: int) -> np.ndarray:
        i = self._index(i)
        return self._check(np.asarray(self._src[i]), i)

    def _read_roi(self, i: int, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        if not callable(getattr(self._src, "read", None)):
            return self[i][y0:y1, x0:x1]
        img = np.asarray(self._src.read(i, (y0, y1, x0, x1)))
        if img.shape != (y1 - y0, x1 - x0) or img.dtype != self.dtype:
            raise RecordingError(f"{self.name}: the reader's read({i}, {(y0, y1, x0, x1)}) gave "
                                 f"a {img.dtype} array of shape {img.shape}, not "
                                 f"{self.dtype} {(y1 - y0, x1 - x0)}")
        return img


def open_recording(path: str | Path):
    """Open a recording as a FrameSource.

    Parameters
    ----------
    path : str or Path
        A TIFF stack, a folder of images, a video file, a Zarr store, a Phantom ``.cine`` file,
        or a Photron ``.cih``/``.cihx`` header (or its ``.mraw``).

    Returns
    -------
    FrameSource
        See the module's docstring.

    Raises
    ------
    RecordingError
        The file is missing, of an unknown format, or unreadable (the message names it).

    Examples
    --------
    A TIFF stack of five 48 x 64 frames:

    >>> import tempfile, numpy as np, tifffile, rollfric
    >>> from pathlib import Path
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = Path(tmp.name) / "frames.tif"
    >>> frames = np.arange(5, dtype=np.uint8)[:, None, None] * np.ones((48, 64), np.uint8)
    >>> tifffile.imwrite(path, frames, photometric="minisblack")
    >>> source = rollfric.open_recording(path)
    >>> len(source), source.shape, source.dtype
    (5, (5, 48, 64), dtype('uint8'))
    >>> int(source[3][0, 0])
    3
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such file or folder")
    if path.is_dir():
        if (path / "zarr.json").exists() or (path / ".zgroup").exists() \
                or path.suffix.lower() == ".zarr":
            return _open_zarr(path)
        return FolderSource(path)
    suffix = path.suffix.lower()
    if suffix in TIFF_SUFFIXES:
        return TiffSource(path)
    if suffix in VIDEO_SUFFIXES:
        return VideoSource(path)
    if suffix in CINE_SUFFIXES:
        return CineSource(path)
    if suffix in PHOTRON_SUFFIXES:
        return PhotronSource(path)
    raise RecordingError(f"{path}: unknown recording format '{suffix}' (TIFF stack, folder of "
                         f"images, video {', '.join(VIDEO_SUFFIXES)}, Phantom .cine, Photron "
                         ".cih/.cihx + .mraw, or Zarr store)")


def check_background(background: np.ndarray, source, what: str = "background") -> np.ndarray:
    """The background as a 2-D array of the frames' size.

    Parameters
    ----------
    background : array_like
        The background image (colour is converted to grayscale).
    source : FrameSource
        The recording it belongs to.
    what : str, optional
        Its name in the error message.

    Returns
    -------
    numpy.ndarray
        The grayscale background (H, W).

    Raises
    ------
    RecordingError
        Its size or bit depth differs from the frames'.
    """
    bg = _to_gray(np.asarray(background), what)
    if bg.shape != tuple(source.shape[1:]):
        raise RecordingError(f"{what} is {bg.shape[1]}x{bg.shape[0]} px but the frames are "
                             f"{source.shape[2]}x{source.shape[1]} px")
    dt = getattr(source, "dtype", None)
    # 0..255 against 0..65535 finds no ball (the byte order does not matter here)
    if dt is not None and np.dtype(dt).itemsize != bg.dtype.itemsize:
        raise RecordingError(f"{what} is {8 * bg.dtype.itemsize}-bit but the frames are "
                             f"{8 * np.dtype(dt).itemsize}-bit: give a background of the "
                             "recording's bit depth")
    return bg
