"""A Zarr store recording: an array ``frames`` (T, H, W) with its attributes, or a store
that the first ``rollfric.zarr_readers`` entry point accepting it reads (the project's
contract), with rollfric's frame checks around that reader.
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np

from rollfric.errors import InputError
from rollfric.io.bitdepth import check_bits, dtype_bits
from rollfric.io.source import BaseSource, RecordingError

ZARR_ENTRY_POINT_GROUP = "rollfric.zarr_readers"


class ZarrArraySource(BaseSource):
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


def open_zarr(path: Path):
    """The FrameSource of the Zarr store at ``path``: its array ``frames``, else the first
    entry-point reader that accepts it (:class:`RecordingError` when none does)."""
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
            return EntryPointSource(src, f"{path} (reader {ep.name})", group)
    raise RecordingError(
        f"{path}: Zarr store without an array 'frames', and no '{ZARR_ENTRY_POINT_GROUP}' "
        f"reader accepted it (tried: {', '.join(tried) or 'none installed'})")


class EntryPointSource(BaseSource):
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
