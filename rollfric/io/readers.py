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
(:mod:`rollfric.track.tracker`) uses it when present. All the readers here have it: a crop of
the full frame, except that a Zarr ``frames`` array is sliced (only the chunks touched are
decoded), an uncompressed TIFF, a cine and an MRAW file are memory-mapped (only the region's
bytes are read), and an entry-point reader that has ``read`` is asked for the region itself.

Bad input (unreadable, truncated, mixed frame sizes, unsupported depth) raises
:class:`RecordingError`, naming the file and the frame.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from rollfric.io.formats.cine import CineSource
from rollfric.io.formats.photron import PhotronSource
from rollfric.io.formats.tiff import TiffSource, tiff_bit_depth
from rollfric.io.formats.zarrstore import open_zarr
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
                    self.bit_depth_stated = tiff_bit_depth(tif.pages.first, self.dtype)
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
            return open_zarr(path)
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
