"""What a recording is to the measurement: the :class:`FrameSource` protocol, the readers'
common base :class:`BaseSource` and their error :class:`RecordingError`.

The readers themselves are in :mod:`rollfric.io.readers` (TIFF, image folders, video, Zarr) and
:mod:`rollfric.io.formats` (camera files); :func:`rollfric.io.readers.open_recording` picks one.
"""

from __future__ import annotations

import logging
from typing import Protocol, runtime_checkable

import numpy as np

from rollfric.errors import InputError
from rollfric.io.bitdepth import resolve_bit_depth
from rollfric.io.limits import MAX_FRAME_PIXELS


@runtime_checkable
class FrameSource(Protocol):
    """A recording as the measurement reads it (what every reader here returns).

    Attributes
    ----------
    shape : tuple of int
        (T, H, W): frames, rows, columns.
    dtype : numpy.dtype
        uint8 or uint16.
    bit_depth : int
        The camera's effective bit depth: the frames' values run 0..2**bit_depth - 1 (12 for a
        12-bit camera's frames in 16-bit words); every threshold, floor and saturation test
        is taken against that full scale (:mod:`rollfric.io.bitdepth`).
    fps : float or None
        The frame rate the file states, if any.
    background : ndarray or None
        An (H, W) background image the recording holds, if any.
    attrs : dict
        Whatever else the file holds (a synthetic recording's setup, ...).

    A reader may also have ``timestamps``: (T,) float seconds from frame 0, the camera's own
    per-frame times (None or absent: frames at ``fps``), and ``concurrent_reads``: True when
    its frames and regions may be read from several threads at once (the tracker then locates
    a long recording's segments on as many threads; absent or False: one thread reads).
    """

    shape: tuple[int, int, int]
    dtype: np.dtype
    bit_depth: int
    fps: float | None
    background: np.ndarray | None
    attrs: dict

    def __len__(self) -> int:
        """The number of frames T."""
        ...

    def __getitem__(self, i: int) -> np.ndarray:
        """Frame i as an (H, W) array."""
        ...


@runtime_checkable
class RegionSource(FrameSource, Protocol):
    """A :class:`FrameSource` that reads regions of interest (the optional part of the
    contract, see the module docstring): the tracking loop reads only where it looks."""

    def read(self, i: int, roi: tuple[int, int, int, int]) -> np.ndarray:
        """Region ``roi`` of frame ``i``: the bytes of ``self[i][y0:y1, x0:x1]``.

        Parameters
        ----------
        i : int
            Frame index.
        roi : tuple of int
            (y0, y1, x0, x1), ``0 <= y0 < y1 <= H``, ``0 <= x0 < x1 <= W``.

        Returns
        -------
        numpy.ndarray
            (y1 - y0, x1 - x0), the frames' dtype.
        """
        ...


def check_roi(roi, frame_shape) -> tuple[int, int, int, int]:
    """Check a region of interest against the frame size.

    Parameters
    ----------
    roi : sequence of int
        (y0, y1, x0, x1).
    frame_shape : tuple of int
        (H, W) of the frames.

    Returns
    -------
    tuple of int
        (y0, y1, x0, x1) as integers, a non-empty region inside the frame.

    Raises
    ------
    TypeError
        ``roi`` is not four integers.
    IndexError
        The region is empty or reaches outside the frame.
    """
    try:
        y0, y1, x0, x1 = roi
        y0, y1, x0, x1 = int(y0), int(y1), int(x0), int(x1)
    except (TypeError, ValueError):
        raise TypeError(f"roi must be (y0, y1, x0, x1) integers, got {roi!r}") from None
    h, w = frame_shape
    if not (0 <= y0 < y1 <= h and 0 <= x0 < x1 <= w):
        raise IndexError(f"roi {(y0, y1, x0, x1)} (y0, y1, x0, x1) is not a non-empty "
                         f"region of the {w}x{h} px frames")
    return y0, y1, x0, x1


class RecordingError(InputError):
    """A recording (or background image) that cannot be read as a sequence of frames.

    An :class:`~rollfric.errors.InputError`: the message names the file (and the frame at
    fault, where one is); the command line prints it and exits with status 2.

    Examples
    --------
    >>> import rollfric
    >>> try:
    ...     rollfric.open_recording("no-such-recording.tif")
    ... except rollfric.RecordingError as exc:
    ...     print(exc)
    no-such-recording.tif: no such file or folder
    """


def _to_gray(img: np.ndarray, what: str) -> np.ndarray:
    """One (H, W) uint8/uint16 frame from whatever an image reader returned."""
    import cv2

    if img.ndim == 3 and img.shape[2] in (3, 4):
        code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        img = cv2.cvtColor(img, code)
    elif img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim != 2:
        raise RecordingError(f"{what}: expected a 2-D grayscale image, got shape {img.shape}")
    if img.dtype not in (np.uint8, np.uint16):
        raise RecordingError(f"{what}: unsupported pixel type {img.dtype} (8 or 16 bit wanted)")
    return img


class BaseSource:
    """Common part of the readers: shape, dtype, frame-size check, region reads (a reader
    subclasses it and defines ``__getitem__``, and ``_read_roi`` when it can read a region
    without the whole frame)."""

    fps: float | None = None
    timestamps: np.ndarray | None = None
    background: np.ndarray | None = None
    concurrent_reads: bool = False  # a file handle's reads are not safe from two threads
    bit_depth_stated: int | None = None  # the camera's bit depth as the file states it
    _bit_depth_data: int | None = None  # the depth found once when asked

    @property
    def bit_depth(self) -> int:
        """The camera's effective bit depth: the file's (``bit_depth_stated``, unless a few
        sampled frames exceed it), 8 for 8-bit frames, else the smallest that holds the largest
        value of a few sampled frames (a warning says so; found once, by
        :func:`rollfric.io.bitdepth.resolve_bit_depth`, which the measurement calls with the
        setup's ``camera.bit_depth``)."""
        if self._bit_depth_data is None:
            bits, _, notes = resolve_bit_depth(self)
            for msg in notes:
                logging.getLogger(__name__).warning(msg)
            self._bit_depth_data = bits
        return self._bit_depth_data

    def __init__(self, name: str, n: int, hw: tuple[int, int], dtype) -> None:
        self.name = name
        self.shape = (int(n), int(hw[0]), int(hw[1]))
        self.dtype = np.dtype(dtype)
        self.attrs: dict = {}
        if n == 0:
            raise RecordingError(f"{name}: the recording holds no frames")
        h, w = self.shape[1:]
        if h < 1 or w < 1 or h * w > MAX_FRAME_PIXELS:
            raise RecordingError(f"{name}: frames of {w} x {h} px (corrupt header?): a frame "
                                 f"must hold 1..{MAX_FRAME_PIXELS:,} pixels")

    def __len__(self) -> int:
        return self.shape[0]

    def _index(self, i: int) -> int:
        i = int(i)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"frame {i} out of range (0..{len(self) - 1})")
        return i

    def _check(self, img: np.ndarray, i: int) -> np.ndarray:
        img = _to_gray(img, f"{self.name} frame {i}")
        if img.shape != self.shape[1:]:
            raise RecordingError(
                f"{self.name}: frames of mixed sizes: frame {i} is {img.shape[1]}x{img.shape[0]}"
                f" px, frame 0 is {self.shape[2]}x{self.shape[1]} px")
        if img.dtype != self.dtype:
            raise RecordingError(f"{self.name}: frames of mixed bit depth: frame {i} is "
                                 f"{img.dtype}, frame 0 is {self.dtype}")
        return img

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]

    def _roi(self, roi) -> tuple[int, int, int, int]:
        return check_roi(roi, self.shape[1:])

    def read(self, i: int, roi: tuple[int, int, int, int]) -> np.ndarray:
        """Region ``roi`` of frame ``i``: the same bytes as ``self[i][y0:y1, x0:x1]``.

        Parameters
        ----------
        i : int
            Frame index.
        roi : tuple of int
            (y0, y1, x0, x1), ``0 <= y0 < y1 <= H``, ``0 <= x0 < x1 <= W``.

        Returns
        -------
        numpy.ndarray
            (y1 - y0, x1 - x0), the frames' dtype.

        Raises
        ------
        TypeError, IndexError
            A malformed region, or one outside the frame.
        """
        i = self._index(i)
        return self._read_roi(i, *self._roi(roi))

    def _read_roi(self, i: int, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        return self[i][y0:y1, x0:x1]
