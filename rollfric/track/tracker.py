"""From a recording to the track theta(t) and mu: the streaming measurement loop.

``measure(recording, setup, background=None, method="subpixel")`` reads the frames one at a
time, locates the ball in each (tracking it with a small region of interest predicted from the
previous frames, a full-frame search when it is lost), turns centres into angles about the
cylinder centre, and fits mu with :func:`rollfric.fit.estimate.fit_mu`. When the source has
``read(i, roi)`` (see :mod:`rollfric.io.readers`), a tracked frame is read only where the locator
looks
(:class:`rollfric.locate.LazyFrame`); the track is the same as from whole frames.

Angles: theta = atan2(x - xc, y - yc) with image y down (positive right of the bottom), or the
thesis's theta = arcsin((x - xc) / L_px) with L = R - r (``angle="arcsin"``).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
import sys
import threading
import time

import numpy as np
import pandas as pd

from rollfric import jit, locate
from rollfric import parallel as cpus
from rollfric.errors import InputError
from rollfric.geometry.perspective import ball_plane_center, contour_depth_from_radius
from rollfric.geometry.trough import find_cylinder_center
from rollfric.io import ballfree, bitdepth
from rollfric.io import readers as io
from rollfric.io.background import repaired_median, sample
from rollfric.locate.kernels.crops import ring_sums as _ring_sums
from rollfric.locate.kernels.crops import same_values as _same_values
from rollfric.registry import LOCATORS
from rollfric.setup.model import Setup, SetupError, setup_from_dict
from rollfric.track import dropped_frames as timing
from rollfric.track import plausibility
from rollfric.track.readahead import ReadAhead
from rollfric.uncertainty import quality

logger = logging.getLogger(__name__)  # messages: info (what was done), warning (check this)

TRACK_COLUMNS = ["frame", "t_s", "x_px", "y_px", "theta_rad", "found", "flag", "still"]
ANGLES = ("atan2", "arcsin")
TIMES = ("auto", "fps")
# the recording's timestamps are checked against the setup's rate and for even spacing
TIMES_RATE_TOL = 1e-3  # relative: a median interval further from 1 / camera.fps is reported
TIMES_JITTER_TOL = 0.01  # relative: an interval further from the median one is reported
TIMES_FPS = "frame / camera.fps"  # TrackInfo.times when the times are not the recording's
# timestamps whose median step is ~1000 or ~1e6 frame periods of the setup's rate are in ms or
# us, not s (read as seconds they gave mu 0.297 for 0.02): within this factor of the unit's
# ratio (a camera clock 10 % off, or a setup's rate that is, is still told from 1000x)
TIMES_UNITS = (("ms", 1e-3), ("us", 1e-6))
TIMES_UNIT_FACTOR = 1.5
# the frame flags that do not depend on the frame times (the tracker's and the plausibility
# checks' but jump and duplicate, which a timing error also raises): an irregular step at or
# next to such a frame is the locator's (rollfric.track.dropped_frames.split_irregular)
LOCATOR_FLAGS = tuple(f for f in plausibility.FLAGS if f not in ("jump", "duplicate"))
# the locator's kernels compiled by numba on a fresh install (a 2-core machine; once, then cached)
LOCATOR_COMPILE = "about 1-3 minutes"


@dataclasses.dataclass(frozen=True)
class TrackInfo:
    """What a measured track was measured with and how: returned beside the track DataFrame.

    :func:`track_recording` fills what the locating knows; :func:`measure` adds the rest
    (``setup``, ``recording``, ``center_source``, ``background``, ``times``, the warnings of the
    background and the frame times, ``offset_fitted``, ``offset_reason``). ``rollfric measure``
    writes most of it to fit.json under the same names (``flags`` as ``frames_flagged``).

    Attributes
    ----------
    setup : Setup
        The setup the track was measured with.
    recording : str
        The recording's name (its path, or the FrameSource's ``name``).
    n_frames : int
        Frames in the recording (rows of the track).
    n_found : int
        Frames where the ball was found and kept (``found == 1``).
    locator : str
        The locator used: "subpixel", "thesis-large" or "thesis-small".
    angle : str
        The angle formula: "atan2" or "arcsin" (:func:`angles`).
    center_px : tuple of float
        The trough centre (xc, yc) the angles were taken about (px; lens-undistorted when
        ``undistorted``).
    center_source : str
        Where ``center_px`` came from ("setup center_px", or the background contour's fit).
    undistorted : bool
        Whether the angles come from lens-undistorted centres (the setup's [camera] matrix and
        distortion).
    background : str
        Where the background image came from (given, stored in the recording, median of N
        frames; "repaired" when a resting ball was removed from it).
    times : str
        Where t_s came from: "the recording's timestamps" or ``TIMES_FPS`` (frame /
        camera.fps).
    ball_radius_px : float
        The ball's radius from the setup (px): ball.diameter_mm / 2 / camera.pixel_size_mm.
    track_radius_px : float
        L = R - r, the radius of the ball centre's path, from the setup (px).
    ball_radius_px_seen : float or None
        The ball's apparent radius calibrated from full-rim frames (px; :class:`RadiusCalibration`);
        None when too few frames showed a full rim.
    ball_radius_px_seen_n : int
        Frames in that calibration.
    ball_radius_px_seen_rel_sigma : float or None
        Relative scatter of one frame's apparent radius (1); None when not calibrated.
    ball_radius_px_seen_rel_dev : float or None
        ball_radius_px_seen / ball_radius_px - 1 (1); None when not calibrated.
    n_refitted : int
        Frames fitted again with the calibrated radius in the second pass.
    flags : dict of str to int
        Frames by track.csv ``flag`` (:data:`rollfric.track.plausibility.FLAGS`), only the flags
        that
        occur; the rejected ones are left out of the fit.
    warnings : tuple of str
        What to check about the measurement (also logged as warnings).
    warnings_radius : tuple of str
        The warnings of the radius calibration (a quality reason "ball_radius" of the fit).
    offset_fitted : bool
        Whether the angle offset of the trough's bottom was fitted (False without a fit).
    offset_reason : str or None
        Why (:func:`resolve_offset`); None without a fit.
    center_u_px : tuple of float or None
        Standard uncertainty (ux, uy) of a ``center_px`` found from the background's contour
        (px; :class:`rollfric.geometry.trough.CylinderContour` ``center_u``: the circle fit's and
        the
        edge definition's); None when the centre came from the setup (its ``center_px_u``, if
        any, is in ``setup``).
    contour_ellipse : dict or None
        The trough's contour fitted as an ellipse (:mod:`rollfric.geometry.ellipse`: centre,
        semi-axes,
        angle, eccentricity) and, after a fit, the mu bias it implies if the camera made it
        (``mu_bias_if_camera``) or the trough is out of round (``mu_bias_if_trough``); None
        when the centre came from the setup.
    frames_dropped : tuple of (int, int)
        Dropped frames found from the motion (:mod:`rollfric.track.dropped_frames`) and repaired in
        t_s:
        (recorded frame k, camera periods lost between frames k and k + 1); empty when the
        times are the recording's own timestamps (they show a gap themselves).
    timing_irregular : tuple of (int, float)
        (frame k, step ratio): steps of the ball that fit no whole number of frame periods
        (timing that cannot be repaired: a quality reason "timing").
    located_irregular : tuple of (int, float)
        The same, for steps at or next to frames the locator lost or whose centre a check
        that does not depend on the frame times rejected (:data:`LOCATOR_FLAGS`; a ball
        leaving a deep shadow): the located centres', not the timing's (a quality reason
        "located_frames").
    path_ellipse : dict or None
        The ball's path fitted as an ellipse about the centre used and what it means
        (:mod:`rollfric.geometry.pathshape`: the verdict, mu read as a tilted camera and as an
        out-of-round bore, the lengths the period and the path give); None without a fit.
    angle_map : tuple or None
        The 2 x 2 map about the centre applied to the centres before the angles (a tilted
        camera's compression undone, :mod:`rollfric.geometry.pathshape`); None: none applied.
    camera_motion : dict or None
        The camera's motion found from the static scene (:mod:`rollfric.track.camera_motion`:
        "still", a "bump" at a frame or a "drift", the shifts sampled); the centres in the
        track are moved back into the background's frame by it. None: not looked for.
    seconds : dict of str to float
        Wall time of each stage of :func:`measure` (s): "open" (the recording, the setup, the
        frame times), "background", "trough centre", "tracking", "fit", "turning points"
        (the dropped-frame search where the ball turns), "ellipse check", "path check" (the
        path's ellipse: a tilted camera or an out-of-round bore), "checks"; empty
        from :func:`track_recording` alone. Not written to fit.json.
    background_from : str
        How the background was had: "given" (an image), "recording" (the recording's own),
        or made from the frames: "median", "clip" or "max".

    Examples
    --------
    The shipped sample recording, measured (:func:`measure` returns its TrackInfo):

    >>> import tempfile, rollfric
    >>> from pathlib import Path
    >>> from rollfric.sample import write_sample
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = write_sample(Path(tmp.name) / "sample")
    >>> track, info, result = rollfric.measure(folder / "frames.tif", folder / "setup.toml")
    >>> info.n_frames, info.n_found, info.locator, info.center_source
    (400, 400, 'subpixel', 'setup center_px')
    >>> round(info.ball_radius_px, 1), info.times
    (37.2, 'frame / camera.fps')
    >>> tmp.cleanup()
    """

    setup: Setup
    recording: str
    n_frames: int
    n_found: int
    locator: str
    angle: str
    center_px: tuple[float, float]
    center_source: str
    undistorted: bool
    background: str
    times: str
    ball_radius_px: float
    track_radius_px: float
    ball_radius_px_seen: float | None
    ball_radius_px_seen_n: int
    ball_radius_px_seen_rel_sigma: float | None
    ball_radius_px_seen_rel_dev: float | None
    n_refitted: int
    flags: dict
    warnings: tuple[str, ...]
    warnings_radius: tuple[str, ...]
    offset_fitted: bool = False
    offset_reason: str | None = None
    center_u_px: tuple[float, float] | None = None
    contour_ellipse: dict | None = None
    frames_dropped: tuple = ()
    timing_irregular: tuple = ()
    located_irregular: tuple = ()
    seconds: dict = dataclasses.field(default_factory=dict)
    background_from: str = "given"  # given, recording (its own), median, clip or max
    path_ellipse: dict | None = None
    angle_map: tuple | None = None
    camera_motion: dict | None = None


def ball_radius_px(setup: Setup) -> float:
    """The setup's ball radius in pixels.

    Parameters
    ----------
    setup : Setup

    Returns
    -------
    float
        ball radius / pixel size.
    """
    return setup.ball_radius / setup.pixel_size


def angles(x, y, center, *, method: str = "atan2", track_radius_px: float | None = None):
    """theta (rad) of ball centres about the cylinder centre.

    "atan2": atan2(x - xc, y - yc) (image y down: y > yc below the axis). "arcsin": the
    thesis's arcsin((x - xc) / L_px), L_px = (R - r) / pixel size.

    Parameters
    ----------
    x, y : array_like
        Ball centres (px).
    center : tuple of float
        (xc, yc), the cylinder axis (px).
    method : {"atan2", "arcsin"}, optional
        The formula.
    track_radius_px : float, optional
        L_px, needed by "arcsin".

    Returns
    -------
    numpy.ndarray
        theta, > 0 right of the bottom.

    Raises
    ------
    InputError
        An unknown method.
    ValueError
        "arcsin" without ``track_radius_px``.

    Examples
    --------
    A ball 100 px straight below the axis, and one 0.1 rad to its right:

    >>> import numpy as np
    >>> from rollfric import angles
    >>> x = [100.0, 100.0 + 100.0 * np.sin(0.1)]
    >>> y = [200.0, 100.0 + 100.0 * np.cos(0.1)]
    >>> angles(x, y, (100.0, 100.0)).round(6)
    array([0. , 0.1])
    >>> angles(x, y, (100.0, 100.0), method="arcsin", track_radius_px=100.0).round(6)
    array([0. , 0.1])
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    xc, yc = center
    if method == "atan2":
        return np.arctan2(x - xc, y - yc)
    if method == "arcsin":
        if not track_radius_px:
            raise ValueError("arcsin angles need track_radius_px")
        return np.arcsin(np.clip((x - xc) / track_radius_px, -1.0, 1.0))
    raise InputError(f"unknown angle method {method!r} (known: {', '.join(ANGLES)})")


def setup_from_recording(source) -> Setup:
    """The setup stored in a Zarr recording's attributes.

    Parameters
    ----------
    source : FrameSource
        A recording whose ``attrs["setup"]`` holds the lab-file form (dict, JSON or TOML text).

    Returns
    -------
    Setup

    Raises
    ------
    SetupError
        The recording holds no setup, or a bad one.
    """
    data = source.attrs.get("setup") if hasattr(source, "attrs") else None
    if data is None:
        raise SetupError(f"{source.name}: no setup given (--setup) and the recording holds "
                         "none in its attrs")
    if isinstance(data, str):
        import json
        import tomllib

        try:
            data = json.loads(data)
        except ValueError:
            try:
                data = tomllib.loads(data)
            except tomllib.TOMLDecodeError as exc:
                raise SetupError(f"{source.name} attrs['setup']: neither JSON nor valid TOML "
                                 f"({exc})") from None
    if not isinstance(data, dict):
        raise SetupError(f"{source.name} attrs['setup']: a table of the setup file's sections "
                         f"wanted, got {type(data).__name__}")
    return setup_from_dict(dict(data), source=f"{source.name} attrs['setup']")


def check_setup_fits(setup: Setup, shape: tuple[int, int, int]) -> None:
    """Refuse a setup whose ball cannot be seen in frames of this size.

    Parameters
    ----------
    setup : Setup
    shape : tuple of int
        (T, H, W) of the recording.

    Raises
    ------
    SetupError
        The ball is under 1.5 px in radius or larger than the frame, (with ``center_px``)
        its track circle does not cross the frame, or the lens calibration was made on images
        of another size (:func:`rollfric.setup.lens.check_image_size`).
    """
    from rollfric.setup.lens import CalibrationError, check_image_size

    _, h, w = shape
    try:
        check_image_size(setup.calibration, w, h)
    except CalibrationError as exc:
        raise SetupError(str(exc)) from None
    r = ball_radius_px(setup)
    if r < 1.5:
        raise SetupError(f"the setup's ball is {2 * r:.2f} px across (diameter "
                         f"{setup.ball_diameter * 1e3:g} mm / pixel {setup.pixel_size * 1e3:g} "
                         "mm): too small to locate")
    if 2 * r >= min(h, w):
        raise SetupError(f"the setup's ball is {2 * r:.0f} px across but the frames are "
                         f"{w}x{h} px: check ball.diameter_mm and camera.pixel_size_mm")
    if setup.center_px is not None:
        xc, yc = setup.center_px
        L = setup.track_radius / setup.pixel_size
        # nearest and farthest frame points from the axis: the track circle must cross the frame
        nx, ny = min(max(xc, 0), w - 1), min(max(yc, 0), h - 1)
        near = math.hypot(nx - xc, ny - yc)
        far = max(math.hypot(cx - xc, cy - yc) for cx in (0, w - 1) for cy in (0, h - 1))
        if not (near - r <= L <= far + r):
            raise SetupError(f"with center_px = ({xc:g}, {yc:g}) and a track radius of "
                             f"{L:.0f} px the ball never appears in the {w}x{h} px frames: "
                             "check center_px, cylinder.radius_mm and camera.pixel_size_mm")


def _predict(hist: list, i: int):
    """Predicted centre at frame i from the last found centres [(frame, x, y), ...]."""
    if not hist or i - hist[-1][0] > 3:
        return None
    if len(hist) >= 3 and hist[-1][0] == i - 1 and hist[-2][0] == i - 2 and hist[-3][0] == i - 3:
        (_, x1, y1), (_, x2, y2), (_, x3, y3) = hist[-1], hist[-2], hist[-3]
        return 3 * x1 - 3 * x2 + x3, 3 * y1 - 3 * y2 + y3
    if len(hist) >= 2 and hist[-2][0] == hist[-1][0] - 1:
        (f1, x1, y1), (_, x2, y2) = hist[-1], hist[-2]
        k = i - f1
        return x1 + k * (x1 - x2), y1 + k * (y1 - y2)
    return hist[-1][1], hist[-1][2]


# apparent-radius calibration: free-radius fits of frames with nearly the whole rim usable
CAL_MIN_INLIER = 0.9  # fraction of the rim a calibration frame must fit
CAL_MAX_SIGMA = 0.1  # px: centre sigma of a calibration frame
CAL_MIN_FRAMES = 5  # calibration frames before the calibrated radius is used
CAL_WARN_DEV = 0.03  # warn when the apparent radius differs from the setup's by more
READ_AHEAD_PAD = 4  # px a side the next frame's region read ahead grows the last one by
# a recording of at least 2 x SEGMENT_MIN_FRAMES frames is tracked in 2 segments (halves), each
# from its own full-frame search, on 2 threads where the reader allows (track_segments)
SEGMENT_MIN_FRAMES = 500
SEGMENT_WARMUP = 20  # frames a later segment is located from before its first (then dropped)


class RadiusCalibration:
    """The ball's apparent radius (px) from the free-radius fits of good full-rim frames.

    The outline in the images is not the geometric one (anti-aliasing, gamma, the edge
    threshold, optics blur shift it by a fraction of a pixel), so a partial arc fitted with the
    setup's radius is off systematically; fitted with the radius the full rims show, it is not.
    ``value`` is the median of the radii seen (None until ``min_frames``), ``rel_sigma`` the
    relative uncertainty of the radius of any one frame (the radii's robust scatter, whatever
    varies from frame to frame is in it) - what a partial arc's leverage multiplies.
    """

    def __init__(self, r_setup: float, min_frames: int = CAL_MIN_FRAMES, *,
                 known: bool = False) -> None:
        self.r_setup = float(r_setup)
        self.min_frames = min_frames
        # a ball the locator fits with a known radius only (under 12 px: too few edge points
        # for a free one): its full rims' radius is the known one plus the median offset of
        # the edge points from that circle (the full rim's centre does not depend on it)
        self.known = bool(known)
        self.radii: list[float] = []  # one float a frame: bounded by the frame count
        self._n = 0  # len(radii) when value and rel_sigma were last computed
        self._value: float | None = None
        self._rel_sigma: float | None = None

    def add(self, loc) -> None:
        """Take one frame's answer into the calibration if it is a good full-rim, free-radius fit
        (or, with ``known``, a full-rim fit of the known radius).

        Parameters
        ----------
        loc : rollfric.locate.Location
        """
        if (loc.found and (loc.radius_free or self.known) and loc.inlier_frac >= CAL_MIN_INLIER
                and loc.sigma <= CAL_MAX_SIGMA and math.isfinite(loc.r)):
            self.radii.append(float(loc.r))

    def _update(self, final: bool = False) -> None:
        n = len(self.radii)
        # recomputed on every new radius while few, then every 32nd (or when asked): the
        # median barely moves, and the streaming loop asks once a frame
        if n == self._n or n < self.min_frames or (n > 64 and n % 32 and not final):
            return
        r = np.asarray(self.radii)
        v = float(np.median(r))
        mad = 1.4826 * float(np.median(np.abs(r - v)))
        self._n, self._value = n, v
        # the scatter of one frame's radius, not the median's error: a partial arc's own
        # apparent radius varies as much; floored at 0.05 % (0.02 px on a 37 px ball)
        self._rel_sigma = max(mad / v, 5e-4)

    def finish(self) -> None:
        """Compute the final value from all the radii seen."""
        self._update(final=True)

    @property
    def value(self) -> float | None:
        """The calibrated apparent radius (px): the median of the radii seen.

        None until ``min_frames`` radii were seen.
        """
        self._update()
        return self._value

    @property
    def rel_sigma(self) -> float | None:
        """Relative uncertainty of one frame's radius (robust scatter, at least 0.05 %).

        None until ``min_frames`` radii were seen.
        """
        self._update()
        return self._rel_sigma

    def summary(self) -> dict:
        """The calibration's keys of fit.json.

        Returns
        -------
        dict
            ``ball_radius_px_seen``, ``ball_radius_px_seen_n`` and, once calibrated,
            ``ball_radius_px_seen_rel_sigma`` and ``ball_radius_px_seen_rel_dev`` (against the
            setup's radius).
        """
        v = self.value
        out = {"ball_radius_px_seen": v, "ball_radius_px_seen_n": len(self.radii)}
        if v is not None:
            out["ball_radius_px_seen_rel_sigma"] = self.rel_sigma
            out["ball_radius_px_seen_rel_dev"] = v / self.r_setup - 1.0
        return out

    def warning(self) -> str | None:
        """A warning when the apparent radius differs from the setup's by more than 3 %.

        Returns
        -------
        str or None
            The message (naming ``ball.diameter_mm`` and ``camera.pixel_size_mm``), or None.
        """
        v = self.value
        if v is None or abs(v / self.r_setup - 1.0) <= CAL_WARN_DEV:
            return None
        return (f"the ball's outline measures {v:.2f} px in radius in {len(self.radii)} "
                f"full-rim frames, the setup says {self.r_setup:.2f} px "
                f"({100 * (v / self.r_setup - 1.0):+.1f} %): check ball.diameter_mm and "
                "camera.pixel_size_mm")


def ring_gain(frame, background, x: float, y: float, r: float) -> float:
    """Brightness of the frame against the background in a ring 2-6 px outside the ball at
    (x, y) of radius r: sum(frame) / sum(background) over the ring (NaN when the ring is off
    the frame or dark). A flash or a dropped exposure moves it; the ball does not."""
    m = int(math.ceil(r + 7))
    x0, y0 = int(math.floor(x)) - m, int(math.floor(y)) - m
    fr, x0c, y0c = locate.regions._crop(frame, x0, y0, x0 + 2 * m + 2, y0 + 2 * m + 2)
    if fr is None:
        return math.nan
    bg = background[y0c:y0c + fr.shape[0], x0c:x0c + fr.shape[1]]
    num, den, count = _ring_sums(np.asarray(fr), np.asarray(bg), x0c, y0c, float(x), float(y),
                                 r + 2, r + 6)
    if count < 8 or den <= 0:
        return math.nan
    return num / den


def same_pixels(frame, prev, x: float, y: float, r: float) -> bool:
    """True when the ball's tile (the box of the ball at (x, y) of radius r, 4 px more a side)
    holds the same pixels in ``frame`` and ``prev``: a repeated frame (two exposures always
    differ by the sensor's noise)."""
    m = int(math.ceil(r + 4))
    x0, y0 = int(math.floor(x)) - m, int(math.floor(y)) - m
    a, _, _ = locate.regions._crop(frame, x0, y0, x0 + 2 * m + 2, y0 + 2 * m + 2)
    b, _, _ = locate.regions._crop(prev, x0, y0, x0 + 2 * m + 2, y0 + 2 * m + 2)
    return (a is not None and b is not None and a.shape == b.shape
            and _same_values(np.asarray(a), np.asarray(b)))


def locate_frame(frame, bg, r_px, method, guess, center, *, opts=None, search=None,
                 r_known=None, r_known_sigma=None):
    """One frame with the chosen locator.

    A region search at ``guess`` (the edge within ``search`` px of the guessed circle), the full
    frame when lost. The locators are registered in :data:`rollfric.registry.LOCATORS`.

    Parameters
    ----------
    frame, bg : numpy.ndarray or LazyFrame
        The frame and the background.
    r_px : float
        The ball's radius (px).
    method : str
        A registered locator: "subpixel", "thesis-large", "thesis-small".
    guess : tuple of float or None
        The predicted centre (px), or None for a full-frame search.
    center : tuple of float
        The cylinder axis (px).
    opts : SubpixelOptions, optional
        Tuning of the sub-pixel locator.
    search : float, optional
        How far (px) the edge may be from the guessed circle.
    r_known, r_known_sigma : float, optional
        The radius that partial arcs are fitted with and its relative uncertainty (subpixel;
        default the setup's).

    Returns
    -------
    rollfric.locate.Location
    """
    return LOCATORS.load(method)(frame, bg, r_px, guess, center, opts=opts, search=search,
                                 r_known=r_known, r_known_sigma=r_known_sigma)


def _tiff_pages(path) -> int:
    """Pages in a TIFF file (1 for other files, and for a TIFF tifffile cannot read: reading it
    as an image then says what is wrong)."""
    from pathlib import Path

    if Path(path).suffix.lower() not in io.TIFF_SUFFIXES:
        return 1
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            return len(tif.pages)
    except Exception:  # noqa: BLE001 - any failure is read_image's to report
        return 1


def resolve_background(source, background, *, r_px: float, median_frames: int = 41,
                       kind: str = "median", full_scale: float | None = None):
    """The background: the given image, the recording's own, or one made from the frames.

    Made from ``median_frames`` frames spread over the recording, by ``kind``
    (:data:`rollfric.io.ballfree.KINDS`): "median", the per-pixel median
    (:func:`rollfric.io.background.median_background`), repaired where the ball of radius
    ``r_px`` rested in most of the frames; "max", the per-pixel maximum less its noise bias
    (a backlit rig's dark ball, :func:`rollfric.io.ballfree.max_background`); "clip", a flat
    field at the backlight's level (:func:`rollfric.io.ballfree.clip_background`). The median
    and the maximum are then made free of the ball where it goes
    (:func:`rollfric.io.ballfree.check_ball_free`), or refused. The notes say what was repaired
    or rebuilt, also as warnings of the ``rollfric.track.tracker`` logger.

    Parameters
    ----------
    source : FrameSource
        The recording.
    background : numpy.ndarray, str, pathlib.Path or None
        An image, an image file, or None.
    r_px : float
        The ball's radius (px).
    median_frames : int, optional
        Frames in the median.
    kind : {"median", "max", "clip"}, optional
        How a background is made from the frames when none is given.
    full_scale : float, optional
        The camera's full scale (DN) the ball is searched with in the sampled frames.

    Returns
    -------
    background : numpy.ndarray
        (H, W), the frames' size.
    description : str
        Where it came from (written to fit.json).
    notes : list of str
        What was repaired, or why not.

    Raises
    ------
    RecordingError
        An unreadable image, or one of another size than the frames.
    InputError
        An unknown ``kind``, or one given with a background image; a background made from
        the frames that holds the ball (:func:`rollfric.io.ballfree.check_ball_free`).
    """
    if kind not in ballfree.KINDS:
        raise InputError(f"unknown background {kind!r} (known: {', '.join(ballfree.KINDS)})")
    if background is not None and kind != "median":
        raise InputError(f"a background image and --background-from {kind} are two "
                         "backgrounds: give one")
    if background is not None:
        if isinstance(background, np.ndarray):
            return io.check_background(background, source), "given array", []
        pages = _tiff_pages(background)
        if pages > 1:
            raise InputError(f"background {background} holds {pages} pages (a recording?): give"
                             " one image of the scene without the ball, or no --background to"
                             " use the median of the recording's frames")
        bg = io.read_image(background)
        return io.check_background(bg, source, f"background {background}"), str(background), []
    if getattr(source, "background", None) is not None and kind == "median":
        return io.check_background(source.background, source, "the recording's background"), \
            "stored in the recording", []
    k = min(len(source), median_frames)
    idx, stack = sample(source, median_frames)
    if kind == "clip":
        bg, level = ballfree.clip_background(stack)
        logger.info(f"background: a flat field at the backlight's level, {level:g} DN")
        return bg, (f"clip level: a flat field at {level:g} DN (the backlight's level, the "
                    f"{ballfree.CLIP_PERCENTILE:g}th percentile of the median of {k} frames)"), []
    if kind == "max":
        bg, sigma = ballfree.max_background(stack)
        desc = (f"per-pixel maximum of {k} frames less its noise bias ({sigma:.3g} DN noise x "
                f"{ballfree.expected_max_normal(len(stack)):.3f})")
        bg, notes = ballfree.check_ball_free(stack, bg, r_px, kind="max", sigma=sigma,
                                             what=f"the per-pixel maximum of {k} frames",
                                             full_scale=full_scale)
    else:
        logger.info(f"no background given: using the per-pixel median of {k} frames spread "
                    "over the recording")
        bg, notes, sources = repaired_median(stack, r_px, full_scale=full_scale)
        desc = f"per-pixel median of {k} frames" + (", repaired" if notes else "")
        bg, more = ballfree.check_ball_free(stack, bg, r_px, sources=sources,
                                            what=f"the per-pixel median of {k} frames",
                                            full_scale=full_scale)
        notes = notes + more
        desc += ", rebuilt where it held the ball" if more else ""
    for msg in notes:
        logger.warning(msg)
    return bg, desc, notes


def track_segments(n: int, segments: int | str = "auto") -> list[tuple[int, int]]:
    """The contiguous frame ranges a recording of ``n`` frames is tracked in.

    Each segment is tracked from a full-frame search at its first frame, with its own
    prediction and radius calibration (:func:`track_recording`), so that the segments can be
    located at the same time on as many cores; they depend on ``n`` and ``segments`` only (not
    on the machine), and so does the track.

    Parameters
    ----------
    n : int
        Frames in the recording.
    segments : int or "auto"
        How many segments (at most ``n``); "auto": 2 when ``n >= 2 * SEGMENT_MIN_FRAMES``,
        else 1.

    Returns
    -------
    list of (int, int)
        (first frame, end frame) of each segment, in order, covering 0..n; the first
        ``n % segments`` are a frame longer.

    Raises
    ------
    rollfric.errors.InputError
        ``segments`` neither "auto" nor a positive integer.
    """
    if segments == "auto":
        k = 2 if n >= 2 * SEGMENT_MIN_FRAMES else 1
    elif isinstance(segments, (int, np.integer)) and not isinstance(segments, bool) \
            and segments >= 1:
        k = int(segments)
    else:
        raise InputError(f"segments must be a positive integer or 'auto', got {segments!r}")
    k = max(1, min(k, n))
    size, extra = divmod(n, k)
    bounds = [0]
    for j in range(k):
        bounds.append(bounds[-1] + size + (1 if j < extra else 0))
    return list(zip(bounds[:-1], bounds[1:], strict=True))


def track_recording(source, setup: Setup, background: np.ndarray, *, method: str = "subpixel",
                    angle: str = "atan2", center: tuple[float, float] | None = None,
                    progress: bool = True, opts=None,
                    times=None, drops: bool = True,
                    read_ahead: bool = False,
                    segments: int | str = "auto",
                    bit_depth: int | None = None) -> tuple[pd.DataFrame, TrackInfo]:
    """Locate the ball in every frame of ``source``; one row a frame (see TRACK_COLUMNS), plus
    r_px, sigma_px (estimated centre error) and inlier_frac where the locator gives them.
    ``times``: t_s of each frame (default frame / setup.fps; see :func:`frame_times`).
    Without ``times`` and with ``drops`` the frames the camera dropped are found from the
    ball's steps (:func:`rollfric.track.dropped_frames.find_gaps`) and t_s is (frame + periods lost
    before
    it) / setup.fps; the plausibility checks predict each frame at those times.

    subpixel: the ball's apparent radius is calibrated on the way (:class:`RadiusCalibration`)
    and partial arcs are fitted with it; the frames fitted with the known radius before the
    calibration settled (or with a value that moved since) are read once more at the end and
    fitted again with the final one (a second pass over just those frames). The
    :class:`TrackInfo` gets the calibration (ball_radius_px_seen, ...) and ``warnings``, which
    also go to the logger.

    Parameters
    ----------
    source : FrameSource
        The recording (:func:`rollfric.io.readers.open_recording`).
    setup : Setup
        The lab setup (ball radius, trough radius, pixel size, lens calibration).
    background : numpy.ndarray
        The background image without the ball.
    method : str
        The locator: "subpixel", "thesis-large" or "thesis-small".
    angle : str
        "atan2" or "arcsin" (:func:`angles`).
    center : sequence of 2 floats
        The trough centre (px) the angles are taken about.
    progress : bool
        Show a progress bar on stderr.
    opts : dict or None
        Options of the locator.
    times : array_like or None
        t_s of each frame (s); None: frame / setup.fps, repaired for dropped frames.
    drops : bool
        Find dropped frames from the motion when ``times`` is None.
    read_ahead : bool
        Read the next frame's region on a second thread while a frame is located
        (:class:`rollfric.track.readahead.ReadAhead`; a reader with ``read`` only). The track is the
        same either way; off by default: on a loaded 2-core machine it cost 10 % more CPU
        and no wall time (docs/how/locator.md, "Where the time goes").
    segments : int or "auto"
        The recording is tracked in this many contiguous segments (:func:`track_segments`;
        "auto": 2 from 2 x SEGMENT_MIN_FRAMES frames on), each from its own full-frame search
        and radius calibration; the calibrations' radii are then pooled into one and the
        second pass (above) made with it. The segments run on as many threads (at most the
        CPUs not busy elsewhere at the start) when the reader says it can be read from several
        threads at once (its attribute ``concurrent_reads``; synth's recordings), else one
        after another: the track is the same either way. 1: one pass through the recording,
        as before 2026-11-23.
    bit_depth : int or None
        The camera's effective bit depth (:func:`rollfric.io.bitdepth.resolve_bit_depth`): the
        locators' contrast floors are fractions of its full scale, 2**bit_depth - 1; None: the
        source's ``bit_depth``, else its frames' word's.

    Returns
    -------
    track : pandas.DataFrame
        One row a frame: TRACK_COLUMNS, r_px, sigma_px, inlier_frac, ring_gain (+ xu_px, yu_px
        with a lens calibration).
    info : TrackInfo
        How it was measured; ``recording`` is the source's ``name`` (else ""), and
        ``center_source``, ``background`` and ``times`` say "given" (:func:`measure` fills
        them in).

    Raises
    ------
    rollfric.errors.InputError
        An unknown locator.

    Examples
    --------
    The shipped sample recording, tracked with a median background made from its frames:

    >>> import tempfile, rollfric
    >>> from pathlib import Path
    >>> from rollfric.sample import write_sample
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = write_sample(Path(tmp.name) / "sample")
    >>> from rollfric.io.background import median_background
    >>> setup = rollfric.load_setup(folder / "setup.toml")
    >>> source = rollfric.open_recording(folder / "frames.tif")
    >>> background, notes = median_background(source, setup.ball_radius / setup.pixel_size)
    >>> track, info = rollfric.track_recording(source, setup, background, progress=False)
    >>> info.n_found, round(float(track["theta_rad"][0]), 3)  # released at 15 deg
    (400, 0.262)
    >>> tmp.cleanup()
    """
    from tqdm import tqdm

    LOCATORS.check(method)
    n, h, w = source.shape
    r_px = ball_radius_px(setup)
    L_px = setup.track_radius / setup.pixel_size
    if center is None:
        center = setup.center_px
    lens = setup.calibration
    # with a lens calibration the centre is in the undistorted image; the locator works in the
    # recorded one (where the lens put the axis) and its centres are undistorted for the angles
    center_ud = center
    if lens is not None:
        center = tuple(float(v) for v in lens.distort(np.asarray(center, dtype=float)))
    rows = np.full((n, 7), np.nan)  # x, y, r, sigma, inlier_frac, found, ring gain
    lost = np.zeros(n, dtype=bool)  # a ball located, but off the trough's circle
    identical = np.zeros(n, dtype=bool)  # the ball's tile equals the previous frame's
    # a fresh install compiles the locator's kernels on the first frames: said before, and
    # the bar's clock restarted after it (else it shows an ETA of days for those minutes)
    jit.announce("rollfric.locate.kernels", "the locator's kernels", LOCATOR_COMPILE, logger)
    clock = jit.CompileClock()
    bar = tqdm(total=n, desc="locating ball", unit="frame", disable=not progress,
               file=sys.stderr, mininterval=0.5)
    gate = 0.25 * r_px + 2.0  # px: a tracked ball moves less than this from its prediction
    read = getattr(source, "read", None)
    base_radius = (opts if opts is not None else locate.SubpixelOptions()).radius
    # a small ball (known radius only): its apparent radius from its full rims' edge points;
    # the 1.58 mm ball (5.9 px) under a harsh side lamp measured 1.7 % (0.10 px) larger than
    # the setup's in synth's renders, which put its half-shadowed arcs 0.15-0.3 px off
    cal_known = method == "subpixel" and (
        base_radius == "known" or (base_radius == "auto" and r_px < 12))
    # once calibrated, a free radius only on (nearly) the full rim: on a partial arc the free
    # radius and the centre are confounded (centres 0.1-0.15 px off on the harsh lamp's arcs
    # over half of the rim), the calibrated one pins the centre
    base = opts if opts is not None else locate.SubpixelOptions()
    if bit_depth is None:
        bit_depth = getattr(source, "bit_depth", None)
    if base.full_scale is None and bit_depth is not None:
        # the thresholds against the camera's full scale, not the 16-bit word's
        base = dataclasses.replace(base, full_scale=bitdepth.full_scale(bit_depth))
        opts = base
    if setup.working_distance is not None and method == "subpixel" and base.pinhole is None:
        # a pinhole at a stated working distance sees the ball as an ellipse
        # (rollfric.locate.silhouette_stretch), stretched away from the principal point
        pp = (lens.K[0, 2], lens.K[1, 2]) if lens is not None else ((w - 1) / 2.0,
                                                                    (h - 1) / 2.0)
        base = dataclasses.replace(base, pinhole=(float(pp[0]), float(pp[1]),
                                                  setup.working_distance / setup.pixel_size))
        opts = base
    opts_cal = dataclasses.replace(base, free_min_frac=max(base.free_min_frac, CAL_MIN_INLIER))
    locator = LOCATORS.load(method)  # as locate_frame, looked up once (not once a frame)
    stop = threading.Event()  # a segment failed: the others end at their next frame

    def frame_at(i, guess, ahead=None):
        if read is not None and guess is not None:
            # tracking: the locator reads only the regions it crops around the prediction
            # (the same pixels as the full frame's; a full-frame search reads the whole frame)
            if ahead is not None:
                return locate.LazyFrame(functools.partial(ahead.read, i),
                                        functools.partial(ahead.frame, i), (h, w),
                                        source.dtype)
            return locate.LazyFrame(functools.partial(read, i),
                                    functools.partial(source.__getitem__, i), (h, w),
                                    source.dtype)
        return source[i] if ahead is None else ahead.frame(i)

    def accept(loc):
        ok = (loc.found and math.isfinite(loc.x) and -0.5 <= loc.x <= w - 0.5
              and -0.5 <= loc.y <= h - 0.5)
        if ok:
            dist = math.hypot(loc.x - center[0], loc.y - center[1])
            ok = abs(dist - L_px) <= 0.15 * L_px
        return ok

    def track_span(a, b):
        # frames a..b-1 with the segment's own prediction, search band and radius calibration;
        # a later segment starts SEGMENT_WARMUP frames early, from a full-frame search, and
        # keeps its answers from frame a on (those before are the previous segment's): by then
        # its prediction and search band are one pass's again. Writes rows, lost and
        # identical [a:b]; returns the calibration, the radii of frames a..b-1 and the frames
        # to fit again
        cal = RadiusCalibration(r_px, known=cal_known)
        n_warm = 0  # radii the warm-up frames gave
        revisit: dict[int, float] = {}  # frame -> radius its partial arc was fitted with
        hist: list = []
        prev = None
        pred_err = math.inf  # how far the last prediction was off (px)
        # the next frame's region read on a second thread while this one is located
        ahead = ReadAhead(source) if read is not None and read_ahead else None
        box_at = None  # the last region read about its frame's guess, (dy0, dy1, dx0, dx1)
        try:
            for i in range(max(0, a - SEGMENT_WARMUP) if a else 0, b):
                if stop.is_set():
                    break
                if i == a:
                    n_warm = len(cal.radii)
                keep = i >= a
                guess = _predict(hist, i)
                frame = frame_at(i, guess, ahead)
                # frame i + 1's region as far as it is known now: the last region read, moved
                # to the centre predicted two frames ahead, grown by READ_AHEAD_PAD px a side
                g = None if ahead is None or box_at is None or i + 1 >= b \
                    else _predict(hist, i + 1)
                if g is not None:
                    gx, gy, p = math.floor(g[0]), math.floor(g[1]), READ_AHEAD_PAD
                    ahead.prefetch(i + 1, (gy + box_at[0] - p, gy + box_at[1] + p,
                                           gx + box_at[2] - p, gx + box_at[3] + p))
                search = min(0.3 * r_px + 2.0, max(2.0, 4.0 * pred_err + 1.0))
                r_kn = cal.value
                loc = locator(frame, background, r_px, guess, center,
                              opts=opts if r_kn is None else opts_cal, search=search,
                              r_known=r_kn, r_known_sigma=cal.rel_sigma)
                box = getattr(frame, "_box", None) if guess is not None else None
                if box is not None:
                    gx, gy = math.floor(guess[0]), math.floor(guess[1])
                    box_at = (box[0] - gy, box[1] - gy, box[2] - gx, box[3] - gx)
                if guess is not None and loc.found:
                    pred_err = math.hypot(loc.x - guess[0], loc.y - guess[1])
                else:
                    pred_err = math.inf
                ok = accept(loc)
                if ok and method == "subpixel":
                    cal.add(loc)
                if keep and ok and method == "subpixel":
                    if loc.radius_free:
                        if loc.inlier_frac < CAL_MIN_INLIER:
                            revisit[i] = math.inf  # a free radius on a partial arc: always again
                    elif r_kn is None or loc.inlier_frac < CAL_MIN_INLIER:
                        # (a full rim's centre barely depends on the radius once calibrated)
                        revisit[i] = r_px if r_kn is None else r_kn
                # a centre far from the prediction (a swapped frame, a ball found elsewhere by
                # the full-frame search) does not predict the next frames: that is the
                # plausibility checks' to judge, and one wrong centre would send the next
                # searches astray
                near = guess is None or math.hypot(loc.x - guess[0], loc.y - guess[1]) <= gate
                if ok and near:
                    hist.append((i, loc.x, loc.y))
                    if len(hist) > 4:
                        hist.pop(0)
                if keep and ok:
                    r_loc = loc.r if math.isfinite(loc.r) else r_px  # thesis-small: no radius
                    identical[i] = prev is not None and same_pixels(frame, prev, loc.x, loc.y,
                                                                    r_loc)
                    rows[i] = (loc.x, loc.y, loc.r, loc.sigma, loc.inlier_frac, 1.0,
                               ring_gain(frame, background, loc.x, loc.y, r_loc))
                elif keep:
                    rows[i, 5] = 0.0
                    lost[i] = bool(loc.found)
                prev = frame
                if keep:
                    clock.restart(bar)  # before the count: no line with the compiler's rate
                    bar.update(1)
        except BaseException:
            stop.set()
            raise
        finally:
            if ahead is not None:  # its worker thread ends
                ahead.close()
                logger.debug(f"read ahead: {ahead.hits} regions read ahead, {ahead.misses} "
                             "when asked")
        return cal, cal.radii[n_warm:], revisit

    spans = track_segments(n, segments)
    # the segments on threads when the reader allows reads from two threads at once (the
    # locator's kernels, decoding and a synthetic recording's sensor model release the GIL)
    # and CPUs are free; else one after another: the track is the same either way
    # (five readings of the running threads: a wrong "busy" costs seconds of tracking here)
    workers = cpus.free_cpus(samples=5) if getattr(source, "concurrent_reads", False) else 1
    logger.debug(f"tracking {n} frames in {len(spans)} segment(s) on "
                 f"{min(workers, len(spans))} thread(s)")
    with clock:
        done = cpus.map_ordered(lambda span: track_span(*span), spans, workers=workers,
                                name="rollfric-track")
    bar.close()
    if len(done) == 1:
        cal, _, revisit = done[0]
    else:
        # one calibration from every segment's radii (in frame order), one second pass
        cal = RadiusCalibration(r_px, known=cal_known)
        revisit = {}
        for _, radii, revisit_s in done:
            cal.radii.extend(radii)
            revisit.update(revisit_s)
    cal.finish()
    r_cal = cal.value
    if r_cal is not None:
        # second pass: the partial arcs fitted with a free radius or another radius than the
        # final one, again
        tol = 0.25 * cal.rel_sigma * r_cal
        redo = [i for i, r_used in revisit.items() if abs(r_used - r_cal) > tol]
        for i in tqdm(redo, desc="partial arcs, calibrated radius", unit="frame",
                      disable=not progress or not redo, file=sys.stderr, mininterval=0.5):
            guess = (rows[i, 0], rows[i, 1])
            loc = locator(frame_at(i, guess), background, r_px, guess, center,
                          opts=opts_cal, search=2.0, r_known=r_cal, r_known_sigma=cal.rel_sigma)
            if accept(loc):
                rows[i, :5] = (loc.x, loc.y, loc.r, loc.sigma, loc.inlier_frac)
    warnings = [cal.warning()] if cal.warning() else []
    warnings_radius = list(warnings)
    for msg in warnings:
        logger.warning(msg)
    # per-frame plausibility: frames that fail leave the track with their flag
    found = rows[:, 5] == 1.0
    gaps = None
    if times is not None:
        pos = np.asarray(times, dtype=float) * setup.fps
    elif drops:
        gaps = timing.find_gaps(rows[:, 0], rows[:, 1], found)
        pos = gaps.pos
        if gaps.dropped:
            msg = dropped_message(gaps)
            logger.warning(msg)
            warnings.append(msg)
    else:
        pos = np.arange(n, dtype=float)
    flags = plausibility.flag_frames(
        rows[:, 0], rows[:, 1], found, same_pixels=identical, sigma=rows[:, 3],
        # the rim's share and the radius are the sub-pixel locator's own figures
        inlier_frac=rows[:, 4] if method == "subpixel" else None,
        gain=rows[:, 6], radius=rows[:, 2] if method == "subpixel" else None,
        r_ref=r_cal, r_rel_sigma=cal.rel_sigma if r_cal is not None else None, pos=pos,
        center=center, r_ball=r_cal if r_cal is not None else r_px)
    flags[~found] = np.where(lost[~found], "off_track", "not_found")
    located = (rows[:, 0].copy(), rows[:, 1].copy(), found.copy())  # before any is rejected
    rejected = found & (flags != "")
    rows[rejected, :5] = np.nan
    rows[rejected, 5] = 0.0
    found = rows[:, 5] == 1.0
    counts = {f: int(np.sum(flags == f)) for f in plausibility.FLAGS if np.any(flags == f)}
    irregular, located_irregular = (), ()
    if gaps is not None and gaps.irregular:
        # steps among frames the locator lost or got wrong are its, not the camera's timing
        # a rejected glitch (a repeated, swapped or flashed frame) a few frames away spoils
        # the prediction of a clean step where the ball turns: judged again without them
        again = timing.confirm_irregular(*located, flags != "", flags == "duplicate",
                                         gaps.irregular)
        irregular, located_irregular = timing.split_irregular(
            again, np.isin(flags, LOCATOR_FLAGS))
        for msg in ([irregular_message(irregular)] if irregular else []) + (
                [located_irregular_message(located_irregular)] if located_irregular else []):
            logger.warning(msg)
            warnings.append(msg)
    if rejected.any():
        logger.warning(f"{int(rejected.sum())} located frame(s) failed the plausibility checks "
                       "and are left out: " + ", ".join(f"{k} {v}" for k, v in counts.items()
                                     if k not in ("not_found", "off_track")))
    theta = np.full(n, np.nan)
    xy = rows[:, :2].copy()
    if lens is not None:
        # the lens bends the round outline: the fitted circle's centre is not the bent
        # image of the ball's centre (rollfric.setup.lens.Calibration.undistort_ball)
        xy[found] = lens.undistort_ball(rows[found, :2], r_px)
    theta[found] = angles(xy[found, 0], xy[found, 1], center_ud, method=angle,
                          track_radius_px=L_px)
    frame_idx = np.arange(n)
    df = pd.DataFrame({
        "frame": frame_idx,
        "t_s": pos / setup.fps if times is None else np.asarray(times, dtype=float),
        "x_px": rows[:, 0],
        "y_px": rows[:, 1],
        "theta_rad": theta,
        "found": found.astype(int),
        "r_px": rows[:, 2],
        "sigma_px": rows[:, 3],
        "flag": flags.astype(str),
        "inlier_frac": rows[:, 4],
        "ring_gain": rows[:, 6],
    })
    if lens is not None:  # the undistorted centres the angles come from
        df["xu_px"], df["yu_px"] = xy[:, 0], xy[:, 1]
    cal_keys = {"ball_radius_px_seen_rel_sigma": None, "ball_radius_px_seen_rel_dev": None,
                **cal.summary()}
    info = TrackInfo(setup=setup, recording=str(getattr(source, "name", "")), n_frames=n,
                     n_found=int(found.sum()), locator=method, angle=angle,
                     center_px=(float(center_ud[0]), float(center_ud[1])),
                     center_source="given", undistorted=lens is not None, background="given",
                     times=TIMES_FPS if times is None else "given",
                     ball_radius_px=r_px, track_radius_px=L_px, **cal_keys,
                     n_refitted=len(redo) if r_cal is not None else 0, flags=counts,
                     warnings=tuple(warnings), warnings_radius=tuple(warnings_radius),
                     frames_dropped=() if gaps is None else gaps.dropped,
                     timing_irregular=irregular, located_irregular=located_irregular)
    return df, info


def dropped_message(gaps) -> str:
    """The message of the dropped frames found (:func:`rollfric.track.dropped_frames.find_gaps`).

    Parameters
    ----------
    gaps : rollfric.track.dropped_frames.Gaps

    Returns
    -------
    str
    """
    where = ", ".join(f"{m} after frame {k}" for k, m in gaps.dropped[:8])
    more = f" and {len(gaps.dropped) - 8} more" if len(gaps.dropped) > 8 else ""
    return (f"{gaps.n_dropped} dropped frame(s) found from the ball's steps ({where}{more}): "
            "the later frames' t_s are moved by the periods lost; a step slower than "
            f"{gaps.min_step_px:.2g} px a frame (near the turning points) would hide one")


def irregular_message(irregular) -> str:
    """The message (and quality reason "timing") of steps that fit no whole number of periods.

    Parameters
    ----------
    irregular : sequence of (int, float)
        (frame, step ratio) pairs (:attr:`rollfric.track.dropped_frames.Gaps.irregular`).

    Returns
    -------
    str
    """
    return (f"{_irregular_steps(irregular)}: the timing is irregular there and cannot be "
            "repaired from the motion; a recording with timestamps would tell")


def _irregular_steps(steps) -> str:
    """"N step(s) of the ball fit no whole number of frame periods (frame k (r x), ...)"."""
    where = ", ".join(f"frame {k} ({r:.2f} x)" for k, r in steps[:8])
    return f"{len(steps)} step(s) of the ball fit no whole number of frame periods ({where})"


def located_irregular_message(located_irregular) -> str:
    """The message of irregular steps among frames the locator lost or got wrong.

    Parameters
    ----------
    located_irregular : sequence of (int, float)
        (frame, step ratio) pairs (:attr:`TrackInfo.located_irregular`).

    Returns
    -------
    str
    """
    return (f"{_irregular_steps(located_irregular)} at frames the locator lost or that failed "
            "the plausibility checks: the located centres are off there (a ball in shadow, half "
            "lit), not the timing")


def located_frames_reason(info: TrackInfo) -> str:
    """The quality reason "located_frames": what the locator lost or got wrong, with the
    irregular steps it caused (:attr:`TrackInfo.located_irregular`).

    Parameters
    ----------
    info : TrackInfo

    Returns
    -------
    str
    """
    bad = ", ".join(f"{k} {v}" for k, v in info.flags.items() if k in LOCATOR_FLAGS)
    return (f"the ball was located and accepted in {info.n_found} of {info.n_frames} frames "
            f"({100.0 * info.n_found / max(info.n_frames, 1):.1f} %; {bad}); "
            + located_irregular_message(info.located_irregular)
            + ": the centres next to the lost and rejected frames may be off too (check the "
            "lighting, the shadows, the overlays)")


def check_track_fits(df: pd.DataFrame, setup: Setup) -> None:
    """Refuse a track whose ball radius contradicts the setup, or without any ball found.

    Parameters
    ----------
    df : pandas.DataFrame
        The track of :func:`track_recording`.
    setup : Setup
        The setup used.

    Raises
    ------
    rollfric.errors.InputError
        The ball was found in no frame.
    rollfric.setup.model.SetupError
        The ball's median fitted radius is more than 10 % off the setup's.
    """
    found = df["found"] == 1
    if not found.any():
        raise InputError(
            f"the ball was found in none of the {len(df)} frames: is it in the recording, is the "
            f"background right, and is its size right (setup: {ball_radius_px(setup):.1f}"
            " px radius)?")
    rfit = df.loc[found, "r_px"].dropna()
    r_px = ball_radius_px(setup)
    if len(rfit) and abs(float(rfit.median()) - r_px) > 0.1 * r_px:
        raise SetupError(f"the setup does not fit the images: the ball measures "
                         f"{float(rfit.median()):.1f} px in radius, the setup says {r_px:.1f} px"
                         " (ball.diameter_mm / camera.pixel_size_mm)")


def fps_mismatch(recording_fps, setup_fps: float) -> str | None:
    """A note when the recording carries a frame rate other than the setup's, else None.

    The setup's rate is the one used: a high-speed camera's video export often carries a
    playback rate (25, 30 fps), not the rate the frames were taken at.

    Parameters
    ----------
    recording_fps : float or None
        The frame rate in the recording's header (Hz); None or 0 when it has none.
    setup_fps : float
        The setup's camera.fps (Hz).

    Returns
    -------
    str or None
        The note, or None when the rates agree to 1e-6 or the recording gives none.
    """
    if not recording_fps or abs(recording_fps - setup_fps) <= 1e-6 * setup_fps:
        return None
    return (f"the recording says {recording_fps:g} frames/s, the setup {setup_fps:g} Hz: times "
            "use the setup's (camera.fps); a video export's rate is often a playback rate")


def frame_times(source, setup_fps: float, times: str = "auto"):
    """(t, description, notes): the time (s) of each frame of ``source`` from frame 0.

    ``times="auto"``: the recording's own per-frame times when it has them (``timestamps``, e.g.
    a Phantom cine's TIME64 block: the camera's clock, so a dropped frame or a rate other than
    the nominal one shows), else frame / ``setup_fps``; ``"fps"``: always frame / ``setup_fps``.
    ``notes`` say where the timestamps disagree with the setup's rate (by more than
    TIMES_RATE_TOL and the clock's step) or are unevenly spaced (an interval more than
    TIMES_JITTER_TOL from the median one, beyond the step of the camera's clock,
    ``attrs["timestamp_resolution_s"]``: times rounded to whole microseconds are 28 or 29 us
    apart at 35087 Hz, no dropped frame). Timestamps whose steps are ~1000 or ~1e6 of the
    setup's frame periods (within TIMES_UNIT_FACTOR) are read as ms or us, and a note names
    the unit.

    Parameters
    ----------
    source : FrameSource
        The recording; its ``timestamps`` (s) are used when it has them.
    setup_fps : float
        The setup's camera.fps (Hz).
    times : str
        "auto" or "fps".

    Returns
    -------
    t : numpy.ndarray
        The time of each frame (s), 0 at frame 0.
    description : str
        "the recording's timestamps" or "frame / camera.fps".
    notes : list of str
        What to check about the timestamps.

    Raises
    ------
    rollfric.errors.InputError
        An unknown ``times``.
    """
    if times not in TIMES:
        raise InputError(f"unknown times {times!r} (known: {', '.join(TIMES)})")
    n = len(source)
    stamps = getattr(source, "timestamps", None) if times == "auto" else None
    if stamps is None:
        return np.arange(n) / setup_fps, TIMES_FPS, []
    t = np.asarray(stamps, dtype=float)
    if t.shape != (n,) or not np.all(np.isfinite(t)) or (n > 1 and np.any(np.diff(t) <= 0)):
        return np.arange(n) / setup_fps, TIMES_FPS, [
            "the recording's timestamps are not one increasing time a frame: times use the "
            "setup's camera.fps"]
    t = t - t[0]
    notes = []
    if n > 1:
        ratio = float(np.median(np.diff(t))) * setup_fps
        for unit, scale in TIMES_UNITS:
            if abs(math.log(ratio * scale)) <= math.log(TIMES_UNIT_FACTOR):
                t = t * scale
                notes.append(f"the recording's timestamps step by {ratio / setup_fps:.6g} a "
                             f"frame, {ratio:.4g} x the setup's frame period (camera.fps = "
                             f"{setup_fps:g} Hz): they are in {unit}, not seconds, and are "
                             f"read as {unit}")
                break
        d = np.diff(t)
        dt = float(np.median(d))
        # a clock that counts in steps (a cine's microseconds) makes intervals a step apart
        res = (getattr(source, "attrs", None) or {}).get("timestamp_resolution_s")
        res = float(res) if isinstance(res, (int, float)) and res > 0 else 0.0
        if abs(dt * setup_fps - 1.0) > TIMES_RATE_TOL + res * setup_fps:
            notes.append(f"the recording's timestamps are {dt * 1e3:.6g} ms apart (median: "
                         f"{1 / dt:.6g} frames/s), the setup says {setup_fps:g} Hz: times are "
                         "the recording's timestamps; check camera.fps")
        off = np.abs(d - dt) > TIMES_JITTER_TOL * dt + res
        if off.any():
            notes.append(f"{int(off.sum())} of the recording's {n - 1} frame intervals differ "
                         f"from the median {dt * 1e3:.6g} ms by more than "
                         f"{100 * TIMES_JITTER_TOL:g} % ({float(d.min()) * 1e3:.6g} to "
                         f"{float(d.max()) * 1e3:.6g} ms: dropped frames?); times are the "
                         "recording's timestamps")
    return t, "the recording's timestamps", notes


def measure(recording, setup: Setup | str | None = None, background=None, *,
            method: str = "subpixel", angle: str = "atan2", fit_method: str = "lsq",
            offset: bool | str = "auto", fit: bool = True, progress: bool = False,
            median_frames: int = 41, fit_kwargs: dict | None = None,
            times: str = "auto", drops: bool = True, read_ahead: bool = False,
            segments: int | str = "auto", background_from: str = "median"):
    """Measure mu from a recording: (track DataFrame, TrackInfo, FitResult or None).

    ``recording``: a path (see :func:`rollfric.io.readers.open_recording`) or a FrameSource.
    ``setup``: a Setup, a path to a setup TOML, or None to take it from the recording's attrs.
    ``background``: an image path or array; None: the recording's own, else the per-pixel
    median of ``median_frames`` frames (reported in ``info.background``).
    Messages go to the ``rollfric.track.tracker`` logger: info (what was chosen), warning (what to
    check; the warnings are also in ``info.warnings``).
    ``method``: "subpixel" (default), "thesis-large" or "thesis-small".
    ``times``: "auto" (the recording's per-frame timestamps when it has them, else frame /
    camera.fps) or "fps" (always frame / camera.fps); see :func:`frame_times`.
    ``drops``: without timestamps, find dropped frames from the ball's steps
    (:func:`rollfric.track.dropped_frames.find_gaps`) and, with the "lsq" fit, where it turns
    (:func:`turning_gaps`), and move the later frames' t_s by the periods lost.
    ``offset``: fit the angle of the trough's bottom too (True), not (False), or "auto" (the
    default): where the data support it (:func:`offset_supported`), which corrects a camera
    rolled about its axis (0.5 deg of roll: mu +0.67 % without the offset).
    The track has the columns TRACK_COLUMNS (+ r_px, sigma_px, inlier_frac); the
    :class:`TrackInfo` beside it holds the setup used, center_px, background, n_frames, n_found,
    the locator, the warnings and the rest.

    Parameters
    ----------
    recording : str, path-like or FrameSource
        The recording.
    setup : Setup, str, path-like or None
        The setup, a setup TOML, or None: the recording's own.
    background : str, path-like, numpy.ndarray or None
        The background image without the ball.
    method, angle, times : str
        The locator, the angle formula and the frame times (above).
    fit_method : str
        How mu is fitted (:func:`rollfric.fit.estimate.fit_mu`).
    offset : bool or "auto"
        Fit the angle of the trough's bottom.
    fit : bool
        Fit mu; False returns the track only, its centres as located (the camera's motion
        is not looked for).
    progress : bool
        Show a progress bar on stderr.
    median_frames : int
        Frames in the median background when there is none.
    background_from : {"median", "max", "clip"}
        How the background is made from the frames when none is given
        (:func:`resolve_background`): the per-pixel median (default), or for a backlit rig
        (a dark ball on a bright field) the per-pixel maximum less its noise bias, or a flat
        field at the backlight's level. A median or maximum that holds the ball where it goes
        is rebuilt from the frames clear of it, or refused.
    fit_kwargs : dict or None
        More keywords of :func:`rollfric.fit.estimate.fit_mu`.
    drops : bool
        Find and repair dropped frames (above).
    read_ahead : bool
        Read the next frame's region on a second thread (:func:`track_recording`).
    segments : int or "auto"
        Track the recording in this many segments (:func:`track_recording`).

    Returns
    -------
    track : pandas.DataFrame
        One row a frame (above).
    info : TrackInfo
        How the track was measured (above).
    result : rollfric.fit.estimate.FitResult or None
        The fit, its quality reasons including the track's
        (:func:`rollfric.uncertainty.quality.check_track`);
        None when ``fit=False``.

    Raises
    ------
    rollfric.errors.InputError
        Bad input: an unreadable recording, an unknown method, angle or offset, too few frames
        (refused on opening, before the tracking) or found frames to fit.
    rollfric.setup.model.SetupError
        A setup that does not fit the images (recording size, trough contour, ball radius).

    Examples
    --------
    The sample recording shipped with rollfric (400 frames of a 10 mm steel ball rendered
    with mu = 0.0079), measured with its lab setup file:

    >>> import tempfile, rollfric
    >>> from pathlib import Path
    >>> from rollfric.sample import write_sample
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = write_sample(Path(tmp.name) / "sample")
    >>> track, info, result = rollfric.measure(folder / "frames.tif", folder / "setup.toml")
    >>> len(track), int(track["found"].sum())
    (400, 400)
    >>> round(result.mu, 4), result.quality
    (0.0079, 'ok')
    >>> tmp.cleanup()
    """
    from rollfric.fit import estimate as fitmod
    from rollfric.setup.model import load_setup

    seconds: dict = {}  # stage -> wall time (TrackInfo.seconds)
    mark = [time.perf_counter()]

    def lap(stage):
        now = time.perf_counter()
        seconds[stage] = seconds.get(stage, 0.0) + now - mark[0]
        mark[0] = now

    source = io.open_recording(recording) if isinstance(recording, (str, bytes)) or \
        hasattr(recording, "__fspath__") else recording
    if setup is None:
        setup = setup_from_recording(source)
    elif not isinstance(setup, Setup):
        setup = load_setup(setup)
    if angle not in ANGLES:
        raise InputError(f"unknown angle method {angle!r} (known: {', '.join(ANGLES)})")
    LOCATORS.check(method)
    check_setup_fits(setup, source.shape)
    if fit and len(source) < fitmod.MIN_SAMPLES:  # refused before any frame is tracked
        raise InputError(f"{getattr(source, 'name', recording)}: the recording has only "
                         f"{len(source)} frames: at least {fitmod.MIN_SAMPLES} are needed to fit "
                         "mu; rollfric track writes the track of a recording of any length")
    # the camera's bit depth: every threshold and the saturation test use its full scale
    bits, bits_how, bits_notes = bitdepth.resolve_bit_depth(source, setup.bit_depth)
    fs = bitdepth.full_scale(bits)
    logger.info(f"the camera's bit depth: {bits} (from the {bits_how}; full scale {fs:.0f} DN)")
    t, times_desc, time_notes = frame_times(source, setup.fps, times)
    # a recording with its own per-frame times is checked against them (frame_times), one
    # without against the rate in its header
    fps_note = fps_mismatch(getattr(source, "fps", None), setup.fps) \
        if times_desc == TIMES_FPS else None
    time_notes = time_notes + ([fps_note] if fps_note else []) + bits_notes
    for msg in time_notes:
        logger.warning(msg)
    lap("open")
    bg, bg_desc, bg_notes = resolve_background(source, background, median_frames=median_frames,
                                               r_px=ball_radius_px(setup), kind=background_from,
                                               full_scale=fs)
    lap("background")
    center_u, contour_notes = None, []
    ellipse = None
    if setup.center_px is not None:
        center, center_desc = setup.center_px, "setup center_px"
    else:
        R_px = setup.cylinder_radius / setup.pixel_size
        lens = setup.calibration
        contour = find_cylinder_center(bg, radius_px=R_px,
                                       undistort=None if lens is None else lens.undistort,
                                       full_scale=fs)
        if abs(contour.radius - R_px) > 0.1 * R_px:
            raise SetupError(
                f"the setup does not fit the images: the trough contour in the background has a "
                f"radius of {contour.radius:.1f} px, the setup says {R_px:.1f} px "
                "(cylinder.radius_mm / camera.pixel_size_mm); fix those or give "
                "[cylinder] center_px")
        ellipse = contour.ellipse
        center, center_u, center_desc = contour.center, contour.center_u, (
            f"contour in the background ({contour.n_points} points over "
            f"{contour.arc_deg:.0f} deg, radius {contour.radius:.1f} px, u = "
            f"({contour.center_u[0]:.2g}, {contour.center_u[1]:.2g}) px)")
        if ellipse is not None and ellipse.significant:
            # an elliptic contour (a tilted camera, an out-of-round bore) has its axis at the
            # ellipse's centre; a circle fitted to its arc sits off it (2 px low at 8 deg yaw)
            center = ellipse.center
            center_desc += (f", the centre of its ellipse ({center[0]:.2f}, {center[1]:.2f}) "
                            "px: the contour is an ellipse")
        if setup.working_distance is not None:
            # the contour's edge is not in the ball's plane (rollfric.geometry.perspective)
            D = setup.working_distance
            z, how = setup.contour_depth, "stated"
            if z is None:
                z, how = contour_depth_from_radius(contour.radius, R_px, D), \
                    "from the contour's radius"
            h, w = source.shape[1:]
            pp = (lens.K[0, 2], lens.K[1, 2]) if lens is not None else \
                ((w - 1) / 2.0, (h - 1) / 2.0)
            center = ball_plane_center(center, pp, D, z)
            center_desc += (f", moved to the ball's plane (edge {z * 1e3:+.1f} mm, {how}; "
                            f"working distance {D * 1e3:g} mm)")
        logger.info(f"cylinder centre from the background contour: ({center[0]:.2f}, "
                    f"{center[1]:.2f}) px")
        check_setup_fits(setup.replace(center_px=center), source.shape)
        if contour.saturated_fraction > 0.1:
            note = (f"the trough contour is saturated at {100 * contour.saturated_fraction:.0f} "
                    "% of its edge points: a clipped edge moves with the local contrast, the "
                    "contour centre may be off by a few tenths of a px beyond its uncertainty; "
                    "expose the background less or give [cylinder] center_px")
            logger.warning(note)
            contour_notes.append(note)
    lap("trough centre")
    df, info = track_recording(source, setup, bg, method=method, angle=angle, center=center,
                               progress=progress,
                               times=None if times_desc == TIMES_FPS else t, drops=drops,
                               read_ahead=read_ahead, segments=segments, bit_depth=bits)
    check_track_fits(df, setup)
    still_notes = _mark_still(df, setup)
    bg_coded = bg_notes  # the background's notes that make the measurement suspect
    if still_notes and bg_notes and bg_desc.startswith("per-pixel median"):
        # the ball held or at rest made the median hold it: the median of the other frames
        got = _median_without_still(source, df, bg, ball_radius_px(setup), median_frames,
                                    full_scale=fs)
        if got is not None:
            bg2, same, k2 = got
            if not same:
                logger.warning("the median background differs from the median of the frames "
                               "in which the ball is neither held nor at rest: tracking again "
                               "with the latter")
                df, info = track_recording(source, setup, bg2, method=method, angle=angle,
                                           center=center, progress=progress,
                                           times=None if times_desc == TIMES_FPS else t,
                                           drops=drops, read_ahead=read_ahead,
                                           segments=segments, bit_depth=bits)
                check_track_fits(df, setup)
                still_notes = _mark_still(df, setup)
                bg = bg2
                bg_desc = (f"per-pixel median of the {k2} sampled frames in which the ball is "
                           "neither held nor at rest")
            else:
                bg_desc += (f" (as the median of the {k2} sampled frames in which the ball is "
                            "neither held nor at rest)")
            bg_notes = [f"{m} (the ball held or at rest there: the median of the {k2} sampled "
                        "frames without it agrees)" if same else
                        f"{m} (the ball held or at rest there: tracked again with the median of "
                        f"the {k2} sampled frames without it)" for m in bg_notes]
            bg_coded = []
    if fit:  # the measurement's; without a fit the track as located
        df, info = _camera_motion(source, bg, df, info, setup, angle)
    n_found = int(df["found"].sum())
    info = dataclasses.replace(info, setup=setup, background=bg_desc, center_source=center_desc,
                               background_from="given" if background is not None else
                               "recording" if bg_desc == "stored in the recording" else
                               background_from,
                               center_u_px=center_u,
                               n_frames=len(df), n_found=n_found,
                               recording=str(getattr(source, "name", recording)),
                               times=times_desc,
                               warnings=info.warnings + tuple(bg_notes) + tuple(contour_notes)
                               + tuple(time_notes) + tuple(still_notes))
    if n_found < len(df):
        logger.info(f"ball not found in {len(df) - n_found} of {len(df)} frames"
                    + (" (left out of the fit)" if fit else ""))
    lap("tracking")
    result = None
    if fit:
        if len(df) < fitmod.MIN_SAMPLES:
            raise InputError(f"the recording has only {len(df)} frames: at least "
                             f"{fitmod.MIN_SAMPLES} are needed to fit mu")
        if n_found < fitmod.MIN_SAMPLES:
            raise InputError(f"the ball was found in only {n_found} of {len(df)} frames: at "
                             f"least {fitmod.MIN_SAMPLES} are needed to fit mu")
        t_s, th = df["t_s"].to_numpy(), df["theta_rad"].to_numpy()
        still_rows = (df["still"] != "").to_numpy()  # a held start, a rest: not the motion
        th = np.where(still_rows, np.nan, th)
        use, why = resolve_offset(offset, t_s, th, setup, fit_method)
        info = dataclasses.replace(info, offset_fitted=use, offset_reason=why)
        if offset == "auto":
            logger.info(f"angle offset of the trough bottom {'fitted' if use else 'not fitted'}: "
                        f"{why}")
        result = fitmod.fit_mu(t_s, th, setup, method=fit_method, offset=use,
                               **(fit_kwargs or {}))
        lap("fit")
        if info.times == TIMES_FPS and drops and fit_method == "lsq":
            t_new, result, turned = turning_gaps(t_s, th, result, setup, use, fit_kwargs)
            if turned:
                df["t_s"] = t_s = t_new
                dropped = tuple(sorted(info.frames_dropped + turned))
                msg = (f"{len(turned)} dropped frame(s) found where the ball turns (after "
                       f"frame(s) {', '.join(str(k) for k, _ in turned)}), by the fit: the "
                       "later frames' t_s are moved by a period each")
                logger.warning(msg)
                info = dataclasses.replace(info, frames_dropped=dropped,
                                           warnings=info.warnings + (msg,))
            lap("turning points")
        coded = [("background_repaired", f"{msg}: a background image without the ball "
                  "(--background) rules out a trace of it") for msg in bg_coded]
        if ellipse is not None:
            info, ell_coded = _ellipse_check(ellipse, info, t_s, th, setup, result, use,
                                             fit_method, fit_kwargs)
            coded += ell_coded
            lap("ellipse check")
        info, result, path_coded = _path_check(df, info, center, setup, result, use,
                                               fit_method, fit_kwargs, angle)
        coded += path_coded
        if info.path_ellipse is not None and info.path_ellipse["verdict"] in ("camera",
                                                                              "trough"):
            # the path's reading, decided by the period, replaces the contour's two readings
            coded = [c for c in coded if c[0] != "contour_ellipse"]
            info = dataclasses.replace(info, warnings=tuple(
                w for w in info.warnings if not w.startswith(ELLIPSE_WARNING_START)))
        th = df["theta_rad"].to_numpy()
        lap("path check")
        coded += [("ball_radius", msg) for msg in info.warnings_radius]
        if info.timing_irregular:
            coded.append(("timing", irregular_message(info.timing_irregular)))
        if info.located_irregular:
            coded.append(("located_frames", located_frames_reason(info)))
        # a held start and a rest are no part of the swing (their times left out)
        swung = result if not still_rows.any() or np.shape(result.t) != still_rows.shape else \
            dataclasses.replace(result, t=np.where(still_rows, np.nan, result.t))
        side = quality.swing_coverage_reason(df["found"].to_numpy() == 1, swung, setup)
        if side is not None:
            coded.append((side.code, side.message))
        track_reasons = quality.check_track(df, setup, center, warnings=coded,
                                            flag_counts=info.flags)
        # a period off is judged again with the ball's path in the image: it tells a wrong
        # radius from a camera clock that is off
        seen = quality.track_radius_seen(df, setup, center)
        fit_reasons = tuple(result.quality_reasons) if seen is None else tuple(
            quality.period_with_image(r, setup, seen) for r in result.quality_reasons)
        result = dataclasses.replace(result, quality_reasons=fit_reasons + tuple(track_reasons))
        lap("checks")
    return df, dataclasses.replace(info, seconds=seconds), result


def _median_without_still(source, df, bg, r_px: float, median_frames: int, *,
                          full_scale: float | None = None):
    """The median background of the sampled frames whose ball is neither held nor at rest:
    (background, whether it agrees with ``bg``, frames in it), or None when fewer than
    :data:`rollfric.io.ballfree.MIN_CLEAR` are left or it still holds the ball."""
    import cv2

    from rollfric.io.background import median

    idx, stack = sample(source, median_frames)
    still_rows = df["still"].to_numpy() != ""
    keep = [j for j, i in enumerate(idx) if not still_rows[int(i)]]
    if len(keep) < ballfree.MIN_CLEAR:
        return None
    sub = stack[keep]
    try:
        bg2, _ = ballfree.check_ball_free(sub, median(sub), r_px, full_scale=full_scale)
    except InputError:
        return None
    # a ball's trace is a ball-sized difference: averaged over r x r, above the noise
    d = cv2.blur(np.abs(bg2.astype(np.float32) - bg.astype(np.float32)),
                 (max(1, int(r_px)), max(1, int(r_px))))
    tol = max(2.0, ballfree.noise_sigma(stack))
    return bg2, bool(d.max() <= tol), len(keep)


def _mark_still(df, setup) -> list:
    """Frames of a held start or a rest (:func:`rollfric.track.still.still_spells`) marked ``held``
    /
    ``rest`` in the column ``still`` (kept out of the fit); the warnings saying so."""
    from rollfric.track import still

    df["still"] = ""
    found = df["found"].to_numpy() == 1
    spells = still.still_spells(df["t_s"].to_numpy(), df["theta_rad"].to_numpy(), found, setup)
    notes = []
    for name, what in (("held", "held still before its release"),
                       ("rest", "at rest from there on")):
        mask = spells[name] & found
        if not mask.any():
            continue
        k = np.flatnonzero(mask)
        t = df["t_s"].to_numpy()
        nat = spells["natural_s"][0 if name == "held" else 1]
        df.loc[mask, "still"] = name
        notes.append(f"the ball was {what}: frames {int(k[0])}-{int(k[-1])} "
                     f"({t[k[-1]] - t[k[0]]:.3g} s, more than {still.STILL_FACTOR:g} x the "
                     f"{nat * 1e3:.3g} ms a ball turning there is still), flagged '{name}' and "
                     "left out of the fit")
        logger.warning(notes[-1])
    return notes
ELLIPSE_WARNING_START = "the trough's contour is an ellipse"


def _ellipse_check(ellipse, info, t_s, th, setup, result, offset, fit_method, fit_kwargs):
    """The mu bias the contour's ellipse implies (:mod:`rollfric.geometry.ellipse`): into
    ``info.contour_ellipse``, a warning above BIAS_WARN, a quality reason above BIAS_SUSPECT."""
    from rollfric.fit import estimate as fitmod
    from rollfric.geometry import ellipse as ell

    out = ellipse.to_dict()
    # the swing's turning points (of the fitted curve): where the amplitude loss is measured
    swing = np.asarray(result.curve, dtype=float) - result.offset
    k = np.flatnonzero(np.diff(np.sign(np.diff(swing))) != 0) + 1
    amp = float(np.median(np.abs(swing[k]))) if len(k) else float(np.nanmax(np.abs(swing)))
    cam = ell.camera_bias(ellipse, amp)
    r_eff, f_b = ell.trough_scale(ellipse, info.ball_radius_px, amp)
    try:
        refit = fitmod.fit_mu(t_s, th, setup.replace(cylinder_radius=setup.cylinder_radius
                                                     * r_eff),
                              method=fit_method, offset=offset, **(fit_kwargs or {}))
        trough = ell.trough_bias(result.mu, refit.mu, f_b)
    except (InputError, ValueError):
        trough = math.nan
    out.update(mu_bias_if_camera=cam, mu_bias_if_trough=trough, swing_amplitude_rad=amp,
               bottom_radius_over_mean=r_eff, trough_angle_scale=f_b)
    worst = max(abs(cam), abs(trough) if math.isfinite(trough) else 0.0)
    coded, warns = [], ()
    if ellipse.significant and worst > ell.BIAS_WARN:
        msg = ell.warning_text(ellipse, cam, trough)
        logger.warning(msg)
        warns = (msg,)
        if worst > ell.BIAS_SUSPECT:
            coded.append(("contour_ellipse", msg))
    return dataclasses.replace(info, contour_ellipse=out,
                               warnings=info.warnings + warns), coded


def _camera_motion(source, bg, df, info, setup, angle):
    """The camera's motion from the static scene (:func:`rollfric.track.camera_motion.find_motion`):
    the centres moved back into the background's frame and the angles taken again; the
    steps the motion made are no timing's (left out of ``timing_irregular`` and
    ``located_irregular``)."""
    from rollfric.track import camera_motion as cm

    found = df["found"].to_numpy() == 1
    xy = np.column_stack([df["x_px"].to_numpy(float), df["y_px"].to_numpy(float)])
    try:
        # frames the checks rejected (flash, repeated, ...) are not sampled
        flags = df["flag"].astype(str).to_numpy()
        motion = cm.find_motion(source, bg, xy, info.ball_radius_px,
                                usable=flags == "")
    except (io.RecordingError, ValueError) as exc:
        logger.info(f"the camera's motion was not looked for: {exc}")
        return df, info
    if motion.kind in ("still", "unknown"):
        if motion.kind == "unknown":
            logger.info("the camera's motion could not be measured: the scene around the "
                        "ball is too plain")
        return df, dataclasses.replace(info, camera_motion=motion.to_dict())
    per = motion.per_frame(len(df))
    cols = [("x_px", "y_px")] + ([("xu_px", "yu_px")] if "xu_px" in df.columns else [])
    for cx, cy in cols:
        df[cx] = df[cx].to_numpy(float) - per[:, 0]
        df[cy] = df[cy].to_numpy(float) - per[:, 1]
    ax, ay = cols[-1]
    th = np.full(len(df), np.nan)
    th[found] = angles(df[ax].to_numpy(float)[found], df[ay].to_numpy(float)[found],
                       info.center_px, method=angle,
                       track_radius_px=setup.track_radius / setup.pixel_size)
    df["theta_rad"] = th
    warnings = list(info.warnings)
    kept = {}
    for name, text_of in (("timing_irregular", irregular_message),
                          ("located_irregular", located_irregular_message)):
        old = getattr(info, name)
        new = tuple(e for e in old if motion.kind != "bump" or abs(e[0] - motion.frame) > 1)
        if old and new != old and text_of(old) in warnings:
            warnings.remove(text_of(old))
            if new:
                warnings.append(text_of(new))
        kept[name] = new
    msg = (f"{motion.message()}: the centres were moved back into the background's frame "
           "and the angles taken again")
    logger.warning(msg)
    return df, dataclasses.replace(info, camera_motion=motion.to_dict(),
                                   warnings=tuple(warnings) + (msg,), **kept)


def _path_check(df, info, center, setup, result, offset, fit_method, fit_kwargs, angle):
    """The ball's path as an ellipse (:mod:`rollfric.geometry.pathshape`): into
    ``info.path_ellipse``;
    a tilted camera the period singles out corrected (the angles in ``df`` and the fit
    replaced, ``info.angle_map`` set), a reason ``camera_orientation`` when the readings
    cannot be told apart and differ by more than BIAS_WARN of mu."""
    from rollfric.fit import estimate as fitmod
    from rollfric.geometry import ellipse as ell
    from rollfric.geometry import pathshape

    found = df["found"].to_numpy() == 1
    cx_col, cy_col = ("xu_px", "yu_px") if "xu_px" in df.columns else ("x_px", "y_px")
    x = np.where(found, df[cx_col].to_numpy(float), np.nan)
    y = np.where(found, df[cy_col].to_numpy(float), np.nan)
    t_s, th = df["t_s"].to_numpy(float), df["theta_rad"].to_numpy(float)
    L_px = setup.track_radius / setup.pixel_size

    def refit(t, theta, s):
        return fitmod.fit_mu(t, theta, s, method=fit_method, offset=offset,
                             **(fit_kwargs or {}))

    def angle_of(xx, yy):
        return angles(xx, yy, center, method=angle, track_radius_px=L_px)

    # the centre's uncertainty: the lab's center_px_u, else the contour's
    u_c = setup.u("center_px") if setup.center_px is not None else info.center_u_px
    try:
        reading = pathshape.read_path(x, y, center, t_s, th, setup, result, offset=offset,
                                      refit=refit, ball_radius_px=info.ball_radius_px,
                                      angle_of=angle_of, center_u=u_c)
    except (InputError, ValueError, np.linalg.LinAlgError) as exc:
        logger.info(f"the ball's path was not fitted as an ellipse: {exc}")
        return info, result, []
    msg = reading.message()
    coded, warns, amap = [], (), None
    if reading.verdict == "camera":
        df["theta_rad"] = np.where(found & np.isfinite(th), reading.theta_camera, th)
        result = reading.result_camera
        amap = tuple(map(tuple, reading.path.round_map(L_px)))
    elif reading.verdict == "undecided" and reading.spread > ell.BIAS_WARN:
        coded.append(("camera_orientation", msg))
    if msg is not None and (reading.verdict != "undecided" or reading.spread > ell.BIAS_WARN):
        logger.warning(msg)
        warns = (msg,)
    return dataclasses.replace(info, path_ellipse=reading.to_dict(), angle_map=amap,
                               warnings=info.warnings + warns), result, coded


def turning_gaps(t, theta, result, setup: Setup, offset: bool, fit_kwargs=None):
    """Dropped frames where the ball turns, found by the fit (:mod:`rollfric.track.dropped_frames`).

    A lost frame at a turning point leaves no step to see, but the later frames are a period
    late: the best-scoring turning point
    (:func:`rollfric.track.dropped_frames.turning_gap_candidates`) gets a
    period counted in and the fit is made again (the ``timing.TURN_TRIES`` best, in turn); it
    is kept when the likelihood ratio (with the effective number of samples of a correlated
    residual) exceeds ``timing.TURN_LR_MIN``, then the next is looked for (at most
    ``timing.TURN_MAX``).

    Parameters
    ----------
    t, theta : array_like
        The track's times (s, frame / fps with the step-found gaps) and angles (rad).
    result : rollfric.fit.estimate.FitResult
        The "lsq" fit of them.
    setup : Setup
        The setup.
    offset : bool
        Whether the fit has the angle offset.
    fit_kwargs : dict or None
        More keywords of :func:`rollfric.fit.estimate.fit_mu`.

    Returns
    -------
    t : numpy.ndarray
        The times with the gaps found counted in.
    result : rollfric.fit.estimate.FitResult
        The fit of them.
    gaps : tuple of (int, int)
        (frame k, 1): a period lost after frame k, one entry a gap found.
    """
    from rollfric.fit import estimate as fitmod

    t = np.asarray(t, dtype=float).copy()
    th = np.asarray(theta, dtype=float)
    finite = np.isfinite(th)

    def ssr(res):
        # over every located sample: the fitter may leave a whole stretch out as outliers
        # (the frames before a gap it did not see), a repaired one takes it back
        d = th[finite] - np.asarray(res.curve, dtype=float)[finite]
        return float(np.mean(d[np.isfinite(d)] ** 2))

    def refit(k):
        t2 = t.copy()
        t2[k + 1:] += 1.0 / setup.fps
        return t2, fitmod.fit_mu(t2, th, setup, method="lsq", offset=offset,
                                 **(fit_kwargs or {}))

    def better(k, fitted):
        # correlated residuals (a systematic misfit, not noise) hold fewer independent
        # samples: n (1 - rho) / (1 + rho), rho the lag-1 autocorrelation of the new fit's
        # residual over the samples it used
        r2 = fitted[1]
        res2 = th - np.asarray(r2.curve, dtype=float)
        if r2.used is not None and r2.used.shape == res2.shape:
            res2 = np.where(r2.used, res2, np.nan)
        rho = quality.lag1_autocorrelation(res2)
        rho = min(max(rho, 0.0), 0.999) if math.isfinite(rho) else 0.999
        n = int(finite.sum()) * (1.0 - rho) / (1.0 + rho)
        return timing.likelihood_ratio(ssr(result), ssr(r2), n) >= timing.TURN_LR_MIN

    found = []
    for _ in range(timing.TURN_MAX):
        # the candidates' refits are independent: on the CPUs that are free, the first that
        # passes in their order is the loop's (rollfric.parallel.first_ordered)
        cands = [k for k, _z in timing.turning_gap_candidates(t, th, result.curve,
                                                              setup.fps)[:timing.TURN_TRIES]]
        step = cpus.first_ordered(refit, cands, better, name="rollfric-fit")
        if step is None:
            break
        k, (t, result) = step
        found.append((int(k), 1))
    return t, result, tuple(found)


OFFSET_MIN_TURNS = 3  # turning points inside the track before the offset is fitted by default


def offset_supported(t, theta, setup: Setup) -> tuple[bool, str]:
    """Whether theta(t) pins down the angle of the trough's bottom, and why.

    With Coulomb friction each half-swing is a cosine about +-eps/omega^2 on either side of the
    bottom: an angle offset moves both centres alike, friction moves them apart, so whole
    half-swings to both sides (three turning points inside the track, the release not
    counted) separate the two. With two the fit's start is unreliable (measured: a 0.8 s
    record of an 8 deg swing ran to the offset's bound); with fewer the offset and mu are one.

    Parameters
    ----------
    t, theta : array_like
        The track: times (s) and angles (rad), NaN where the ball was not found.
    setup : Setup
        The setup (for the fitter's self-start).

    Returns
    -------
    supported : bool
        Whether there are at least OFFSET_MIN_TURNS turning points.
    why : str
        The reason, for the user.
    """
    from rollfric.fit import estimate as fitmod

    try:
        n = len(fitmod.initial_guess(t, theta, setup)["turning_points_s"])
    except (InputError, ValueError) as exc:
        return False, f"no turning points found ({exc})"
    if n >= OFFSET_MIN_TURNS:
        return True, f"{n} turning points: the bottom's angle is separable from mu"
    return False, (f"{n} turning point(s): fewer than {OFFSET_MIN_TURNS}, the bottom's angle "
                   "cannot be told from mu")


def resolve_offset(offset, t, theta, setup: Setup, fit_method: str = "lsq") -> tuple[bool, str]:
    """Decide whether the angle offset of the trough's bottom is fitted.

    Parameters
    ----------
    offset : bool or "auto"
        What was asked for; "auto": where the data support it (:func:`offset_supported`).
    t, theta : array_like
        The track: times (s) and angles (rad).
    setup : Setup
        The setup.
    fit_method : str
        The fitting method; "paper1_eps" and "paper2_grid" have no offset.

    Returns
    -------
    fitted : bool
        Whether the offset is fitted.
    why : str
        The reason, for the user.

    Raises
    ------
    rollfric.errors.InputError
        ``offset`` is neither True, False nor "auto".
    """
    if offset is True or offset is False:
        return offset, "asked for" if offset else "not asked for"
    if offset != "auto":
        raise InputError(f"offset must be true, false or 'auto', got {offset!r}")
    if fit_method in ("paper1_eps", "paper2_grid"):  # the thesis's procedures have none
        return False, f"the {fit_method} method has no offset"
    return offset_supported(t, theta, setup)
