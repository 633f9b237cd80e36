"""What a recording holds, without measuring it: ``rollfric info`` (:func:`recording_info`).

The frame count and size, the stored dtype and the camera's effective bit depth, the frame
rate the file states and the one its per-frame times give, the exposure, the start frame and
trigger time, colour or mono, and the warnings ``rollfric measure`` would give on opening it
(the frame times against the rate; too few frames to fit mu). Every format
:func:`rollfric.io.readers.open_recording` reads; only the header and the first frame are read (a
video's or an image folder's first frame, to tell colour from mono).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rollfric.fit.start import MIN_SAMPLES
from rollfric.io.readers import open_recording
from rollfric.track.timestamps import TIMES_RATE_TOL, fps_mismatch, frame_times

# the keys of recording_info's dict, in the order `rollfric info` prints them
KEYS = ("recording", "format", "n_frames", "width", "height", "dtype", "bit_depth",
        "bit_depth_from", "colour", "fps", "fps_timestamps", "timestamp_resolution_s",
        "duration_s", "shutter_s", "start_frame", "frame0_from_trigger_s", "trigger_time",
        "camera", "background_stored", "warnings")


def _format(src, path: Path) -> str:
    fmt = src.attrs.get("format")
    if isinstance(fmt, str):
        return fmt
    return {"TiffSource": "tiff", "FolderSource": "image folder", "VideoSource": "video",
            "ZarrArraySource": "zarr", "EntryPointSource": "zarr (entry-point reader)"}.get(
        type(src).__name__, type(src).__name__)


def bit_depth(src) -> tuple[int, str]:
    """(bits, where from): the camera's effective bit depth of the stored values.

    Parameters
    ----------
    src : FrameSource
        The recording.

    Returns
    -------
    bits : int
        The reader's ``bit_depth``, else ``attrs["camera_bit_depth"]``, else the dtype's bits.
    source : str
        "file" (the first two) or "dtype".
    """
    for value in (getattr(src, "bit_depth", None), src.attrs.get("camera_bit_depth")):
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value > 0:
            return int(value), "file"
    return 8 * np.dtype(src.dtype).itemsize, "dtype"


def _colour(src, path: Path) -> str | None:
    """"mono", "colour, read as grey" (the image readers convert it), or None (unknown)."""
    kind = src.attrs.get("colour")
    if isinstance(kind, str):
        return kind
    name = type(src).__name__
    raw = None
    try:
        if name == "TiffSource":
            samples = getattr(src._tif.pages.first, "samplesperpixel", 1)
            return "colour, read as grey" if samples in (3, 4) else "mono"
        if name == "FolderSource":
            import cv2

            raw = cv2.imread(str(src.files[0]), cv2.IMREAD_UNCHANGED)
        elif name == "VideoSource":
            import cv2

            cap = cv2.VideoCapture(str(path))
            ok, raw = cap.read()
            cap.release()
            if not ok:
                return None
        else:
            return "mono"  # a Zarr array (T, H, W) holds one value a pixel
    except Exception:  # noqa: BLE001 - an unknown colour is no reason to refuse the file
        return None
    if raw is None or raw.ndim == 2 or raw.shape[2] == 1:
        return "mono"
    # OpenCV decodes even a grey video to three channels: colour only where they differ
    same = np.array_equal(raw[..., 0], raw[..., 1]) and np.array_equal(raw[..., 1], raw[..., 2])
    return "mono" if same else "colour, read as grey"


def _number(v):
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return int(v)
    if isinstance(v, (float, np.floating)) and np.isfinite(v):
        return float(v)
    return None


def recording_info(recording, setup_fps: float | None = None) -> dict:
    """What a recording holds, as ``rollfric info`` prints it.

    Parameters
    ----------
    recording : str or path-like
        Any recording :func:`rollfric.io.readers.open_recording` reads.
    setup_fps : float, optional
        The setup's camera.fps (Hz): the frame times are checked against it as ``rollfric
        measure`` does; None: against the rate the file states.

    Returns
    -------
    dict
        The keys of :data:`KEYS`: ``n_frames``, ``width``, ``height`` (px), ``dtype``,
        ``bit_depth`` (the camera's effective bits; ``bit_depth_from`` "file" or "dtype"),
        ``colour``, ``fps`` (the rate the file states, Hz, or None), ``fps_timestamps`` (the
        rate of the file's per-frame times, median interval, or None),
        ``timestamp_resolution_s``, ``duration_s`` (frames' span), ``shutter_s`` (exposure, s),
        ``start_frame`` (frame 0's number from the trigger), ``frame0_from_trigger_s``,
        ``trigger_time`` (ISO 8601), ``camera``, ``background_stored`` and ``warnings`` (list
        of str). Values the file does not hold are None.

    Raises
    ------
    rollfric.io.readers.RecordingError
        The recording cannot be read (the message names it).
    """
    path = Path(recording)
    src = open_recording(path)
    n, h, w = src.shape
    a = src.attrs
    bits, bits_from = bit_depth(src)
    fps = _number(getattr(src, "fps", None))
    stamps = getattr(src, "timestamps", None)
    fps_ts = None
    if stamps is not None and len(stamps) > 1:
        d = np.diff(np.asarray(stamps, dtype=float))
        if np.all(np.isfinite(d)) and np.median(d) > 0:
            fps_ts = float(1.0 / np.median(d))
    rate = fps_ts or fps
    if stamps is not None and len(stamps) == n and n > 1:
        duration = float(stamps[-1] - stamps[0])
    else:
        duration = (n - 1) / rate if rate else None
    warnings = [str(m) for m in a.get("time_notes", []) or []]
    if setup_fps:  # as measure opens it
        warnings += frame_times(src, setup_fps)[2]
        if stamps is None:
            note = fps_mismatch(fps, setup_fps)
            warnings += [note] if note else []
    elif fps_ts:  # the times' spacing, then their rate against the header's
        warnings += frame_times(src, fps_ts)[2]
        step = _number(a.get("timestamp_resolution_s")) or 0.0
        if fps and abs(fps_ts / fps - 1.0) > TIMES_RATE_TOL + step * fps_ts:
            warnings.append(f"the header says {fps:g} frames/s, the per-frame times "
                            f"{fps_ts:.6g}: measure uses the times (--times fps: the setup's "
                            "camera.fps)")
    elif not fps:
        warnings.append("the recording states no frame rate: measure uses the setup's "
                        "camera.fps")
    if n < MIN_SAMPLES:
        warnings.append(f"{n} frames: rollfric measure needs at least {MIN_SAMPLES} to fit mu; "
                        "rollfric track writes the track of any length")
    shutter = _number(a.get("shutter_s", a.get("exposure_s")))
    info = {
        "recording": str(path),
        "format": _format(src, path),
        "n_frames": int(n), "width": int(w), "height": int(h),
        "dtype": str(np.dtype(src.dtype)),
        "bit_depth": bits, "bit_depth_from": bits_from,
        "colour": _colour(src, path),
        "fps": fps, "fps_timestamps": fps_ts,
        "timestamp_resolution_s": _number(a.get("timestamp_resolution_s")),
        "duration_s": duration,
        "shutter_s": shutter,
        "start_frame": _number(a.get("start_frame")),
        "frame0_from_trigger_s": _number(a.get("frame0_from_trigger_s")),
        "trigger_time": a.get("trigger_time") if isinstance(a.get("trigger_time"), str)
        else None,
        "camera": a.get("camera") if isinstance(a.get("camera"), str) else None,
        "background_stored": getattr(src, "background", None) is not None,
        "warnings": warnings,
    }
    return {k: info[k] for k in KEYS}


def _seconds(v: float) -> str:
    if v == 0:
        return "0 s"
    for unit, f in (("s", 1.0), ("ms", 1e3), ("us", 1e6), ("ns", 1e9)):
        if abs(v) * f >= 1 or unit == "ns":
            return f"{v * f:.6g} {unit}"
    return f"{v:g} s"


def format_info(info: dict) -> str:
    """``rollfric info``'s text: one "name: value" line each, what the file does not hold left
    out, both frame rates where they differ.

    Parameters
    ----------
    info : dict
        From :func:`recording_info`.

    Returns
    -------
    str
        The lines, ending in the warnings (``warning: ...``), if any.
    """
    lines = [("recording", info["recording"]), ("format", info["format"]),
             ("frames", f"{info['n_frames']} of {info['width']} x {info['height']} px"),
             ("pixels", f"{info['dtype']}, {info['bit_depth']}-bit camera values"
              + (" (from the dtype: the file does not say)"
                 if info["bit_depth_from"] == "dtype" else ""))]
    if info["colour"]:
        lines.append(("colour", info["colour"]))
    fps, fts = info["fps"], info["fps_timestamps"]
    if fps is not None:
        lines.append(("frame rate", f"{fps:g} Hz (header)"))
    if fts is not None and (fps is None or abs(fts - fps) > 1e-6 * fts):
        lines.append(("frame rate", f"{fts:.6g} Hz (the per-frame times)"))
    if fts is not None and info["timestamp_resolution_s"]:
        lines.append(("time step", _seconds(info["timestamp_resolution_s"])))
    if info["duration_s"] is not None:
        lines.append(("duration", _seconds(info["duration_s"])))
    if info["shutter_s"] is not None:
        lines.append(("shutter", _seconds(info["shutter_s"])))
    if info["start_frame"] is not None:
        lines.append(("start frame", f"{info['start_frame']} (frame 0's number from the "
                                     "trigger)"))
    if info["frame0_from_trigger_s"] is not None:
        lines.append(("frame 0", f"{_seconds(info['frame0_from_trigger_s'])} from the trigger"))
    if info["trigger_time"]:
        lines.append(("trigger", info["trigger_time"]))
    if info["camera"]:
        lines.append(("camera", info["camera"]))
    if info["background_stored"]:
        lines.append(("background", "stored in the recording"))
    width = max(len(k) for k, _ in lines)
    out = [f"{k + ':':<{width + 1}} {v}" for k, v in lines]
    out += [f"warning: {m}" for m in info["warnings"]]
    return "\n".join(out)
