"""A recording saved as a compressed video, the way camera software exports one.

Two codecs, each in the container camera software writes it to:

- ``mjpeg``: Motion-JPEG in an AVI, one baseline JPEG a frame (8-bit grayscale, one component)
  at a JPEG quality of 1..100 (the IJG scale of libjpeg, which OpenCV's ``imencode`` uses: 95, 75
  and 50 are the usual "high", "default" and "low" settings of an export dialog). Every frame is
  coded alone (no motion prediction).
- ``h264``: H.264 in an MP4 (libx264 through PyAV, preset "medium", 4:2:0 chroma, limited
  "TV" range 16..235, as ffmpeg-based exporters write it) at a constant rate factor ``crf``
  0..51 (18: visually lossless, 23: x264's default, 28: small files). Frames are predicted from
  each other (group of pictures 250).

The frames are written at 8 bits: a sensor of more bits is shifted down, as an export does. The
container's frame rate is ``playback_fps`` if given (camera software often writes a playback
rate such as 30 fps), else the recording's.

PyAV (``av``) writes both containers; rollfric reads them back with OpenCV (``VideoCapture``,
:mod:`rollfric.io.readers`), the path a lab's video takes.
"""

from __future__ import annotations

import dataclasses
import fractions
from pathlib import Path

import numpy as np

from synth.config import SynthError
from synth.store import open_recording

CODECS = {"mjpeg": ".avi", "h264": ".mp4"}
QUALITY_RANGE = {"mjpeg": (1, 100), "h264": (0, 51)}
DEFAULT_QUALITY = {"mjpeg": 75, "h264": 23}
H264_PRESET = "medium"
H264_GOP = 250
# The same frames give the same bytes on any machine: x264 takes its thread count (PyAV: slices)
# from the CPUs unless told, so it is fixed here (frame threads); and with x264's macroblock tree
# (its default rate-control lookahead) the P frames differed from the second encoder of a process
# on (half of the runs on an AMD EPYC with AVX-512, even with one thread; deterministic with x264's
# assembly off or the tree off: memory left from an earlier encoder), so the tree is off. Without
# it the rate control spreads the quality more evenly over static and moving areas; the codec and
# its artefacts (block DCT, motion compensation) are the same.
H264_THREADS = 4
H264_PARAMS = "no-mbtree=1"


@dataclasses.dataclass(frozen=True)
class VideoSpec:
    """How a recording is compressed.

    Attributes
    ----------
    codec : str
        "mjpeg" (AVI) or "h264" (MP4).
    quality : int or None
        JPEG quality 1..100 (mjpeg) or crf 0..51 (h264, lower is better); None: the codec's
        default (75, 23).
    playback_fps : float or None
        The frame rate written in the container (Hz); None: the recording's.
    """

    codec: str = "mjpeg"
    quality: int | None = None
    playback_fps: float | None = None

    def __post_init__(self) -> None:
        if self.codec not in CODECS:
            raise SynthError(f"video codec must be one of {', '.join(CODECS)}, got "
                             f"{self.codec!r}")
        q = DEFAULT_QUALITY[self.codec] if self.quality is None else self.quality
        lo, hi = QUALITY_RANGE[self.codec]
        if isinstance(q, bool) or not isinstance(q, (int, np.integer)) or not lo <= q <= hi:
            what = "JPEG quality" if self.codec == "mjpeg" else "crf"
            raise SynthError(f"video quality ({what}) of {self.codec} must be an integer "
                             f"{lo}..{hi}, got {self.quality!r}")
        object.__setattr__(self, "quality", int(q))
        if self.playback_fps is not None and not self.playback_fps > 0:
            raise SynthError(f"video playback_fps must be > 0, got {self.playback_fps!r}")

    @property
    def suffix(self) -> str:
        """The container's file suffix (".avi" or ".mp4")."""
        return CODECS[self.codec]


def to_8bit(img: np.ndarray, bit_depth: int) -> np.ndarray:
    """A frame of ``bit_depth`` bits as 8 bits (shifted down, as an 8-bit export does).

    Parameters
    ----------
    img : numpy.ndarray
        (H, W) uint8 or uint16.
    bit_depth : int
        The sensor's bits (8, 10, 12).

    Returns
    -------
    numpy.ndarray
        (H, W) uint8.
    """
    if img.dtype == np.uint8:
        return img
    return (np.asarray(img, dtype=np.uint16) >> (int(bit_depth) - 8)).astype(np.uint8)


def write_video(frames, path, spec: VideoSpec, fps: float, *, bit_depth: int = 8,
                progress: bool = False) -> Path:
    """Write frames as a compressed video file.

    Parameters
    ----------
    frames : sequence of numpy.ndarray
        (H, W) uint8/uint16 frames (``len`` and indexing, e.g. a synth recording's frames).
    path : str or pathlib.Path
        The file to write (its suffix should be ``spec.suffix``).
    spec : VideoSpec
        Codec and quality.
    fps : float
        The recording's frame rate (Hz): the container's rate unless ``spec.playback_fps``.
    bit_depth : int
        The frames' bits (above 8 they are shifted down).
    progress : bool
        Show a progress bar.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    SynthError
        PyAV is not installed, or the codec cannot write these frames.
    """
    try:
        import av
    except ImportError:
        raise SynthError("writing a video needs PyAV: pip install av (or rollfric[suite])") \
            from None
    import cv2
    from tqdm import tqdm

    path = Path(path)
    n = len(frames)
    first = to_8bit(np.asarray(frames[0]), bit_depth)
    h, w = first.shape
    rate = fractions.Fraction(spec.playback_fps or fps).limit_denominator(1000)
    bar = tqdm(total=n, unit="frame", desc=f"video {spec.codec}", disable=not progress)
    try:
        with av.open(str(path), "w") as out:
            if spec.codec == "mjpeg":
                # baseline grayscale JPEGs of libjpeg's quality scale, muxed as they are
                st = out.add_stream("mjpeg", rate=rate)
                st.width, st.height, st.pix_fmt = w, h, "yuvj420p"
                tb = 1 / rate
                for i in range(n):
                    img = first if i == 0 else to_8bit(np.asarray(frames[i]), bit_depth)
                    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, spec.quality])
                    if not ok:
                        raise SynthError(f"JPEG encoding of frame {i} failed")
                    pkt = av.Packet(buf.tobytes())
                    pkt.stream, pkt.pts, pkt.dts, pkt.time_base = st, i, i, tb
                    pkt.is_keyframe = True
                    out.mux(pkt)
                    bar.update(1)
            else:
                st = out.add_stream("libx264", rate=rate)
                st.width, st.height, st.pix_fmt = w, h, "yuv420p"
                st.options = {"crf": str(spec.quality), "preset": H264_PRESET,
                              "g": str(H264_GOP), "x264-params": H264_PARAMS}
                st.codec_context.thread_type = "FRAME"
                st.codec_context.thread_count = H264_THREADS
                for i in range(n):
                    img = first if i == 0 else to_8bit(np.asarray(frames[i]), bit_depth)
                    for pkt in st.encode(av.VideoFrame.from_ndarray(img, format="gray")):
                        out.mux(pkt)
                    bar.update(1)
                for pkt in st.encode():
                    out.mux(pkt)
    except av.error.FFmpegError as exc:
        raise SynthError(f"{path}: {spec.codec} video could not be written ({exc})") from None
    finally:
        bar.close()
    return path


def export_video(recording, out_dir, spec: VideoSpec, *, progress: bool = False) -> dict:
    """A synth recording's frames and its background as compressed videos, as a lab has them.

    Writes ``out_dir/frames<suffix>`` (every frame) and ``out_dir/background<suffix>`` (the
    background frame, one frame through the same codec: the lab's background comes from the
    same camera export).

    Parameters
    ----------
    recording : str, pathlib.Path or synth.Recording
        The recording.
    out_dir : str or pathlib.Path
        An existing folder.
    spec : VideoSpec
        Codec and quality.
    progress : bool
        Show a progress bar.

    Returns
    -------
    dict
        ``{"frames": Path, "background": Path}``.
    """
    rec = recording if hasattr(recording, "frames") else open_recording(recording)
    out_dir = Path(out_dir)
    bits = int(rec.frames.sensor_config.bit_depth)
    fps = float(rec.attrs["fps"])
    frames = write_video(rec.frames, out_dir / f"frames{spec.suffix}", spec, fps,
                         bit_depth=bits, progress=progress)
    bg = write_video([rec.background], out_dir / f"background{spec.suffix}", spec, fps,
                     bit_depth=bits)
    return {"frames": frames, "background": bg}
