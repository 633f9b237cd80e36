"""The tracking loop: the ball located in every frame of a recording, one row a frame.

:class:`Tracker` follows the ball through a recording: each frame's centre is predicted from
the last ones, located in a small region about the prediction (a full-frame search when lost;
with a reader's ``read(i, roi)`` only that region is read, :class:`rollfric.locate.LazyFrame`),
accepted on the trough's circle and recorded; the ball's apparent radius is calibrated on the
way (:mod:`rollfric.track.radius`) and the partial arcs fitted before it settled are fitted
again. A long recording is tracked in segments on threads. The frames are then judged
(:mod:`rollfric.track.plausibility`, the frame times of :mod:`rollfric.track.dropped_frames`)
and the centres turned into angles (:mod:`rollfric.geometry.theta`).
:func:`track_recording` is the public function; :func:`measure` the whole measurement.

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
from tqdm import tqdm

from rollfric import jit, locate
from rollfric import parallel as cpus
from rollfric.errors import InputError
from rollfric.geometry.perspective import ball_plane_center, contour_depth_from_radius
from rollfric.geometry.theta import ANGLES, angles, centre_angles
from rollfric.geometry.trough import find_cylinder_center
from rollfric.io import ballfree, bitdepth
from rollfric.io import readers as io
from rollfric.io.background import sample
from rollfric.io.background_choice import resolve_background
from rollfric.locate.tile import ring_gain, same_pixels
from rollfric.registry import LOCATORS
from rollfric.setup.model import Setup, SetupError
from rollfric.track import dropped_frames as timing
from rollfric.track import plausibility
from rollfric.track.radius import CAL_MIN_INLIER, RadiusCalibration
from rollfric.track.setup_checks import (
    ball_radius_px,
    check_setup_fits,
    check_track_fits,
    setup_from_recording,
)
from rollfric.track.timestamps import (
    LOCATOR_FLAGS,
    TIMES_FPS,
    dropped_message,
    fps_mismatch,
    frame_times,
    irregular_message,
    located_frames_reason,
    located_irregular_message,
)
from rollfric.track.track_info import TrackInfo
from rollfric.uncertainty import quality

logger = logging.getLogger(__name__)  # messages: info (what was done), warning (check this)

TRACK_COLUMNS = ["frame", "t_s", "x_px", "y_px", "theta_rad", "found", "flag", "still"]
# the locator's kernels compiled by numba on a fresh install (a 2-core machine; once, then cached)
LOCATOR_COMPILE = "about 1-3 minutes"
# a recording of at least 2 x SEGMENT_MIN_FRAMES frames is tracked in 2 segments (halves), each
# from its own full-frame search, on 2 threads where the reader allows (track_segments)
SEGMENT_MIN_FRAMES = 500
SEGMENT_WARMUP = 20  # frames a later segment is located from before its first (then dropped)


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

@dataclasses.dataclass
class _Span:
    """One segment's state while it is tracked (segments run on threads: each its own)."""

    cal: RadiusCalibration  # the segment's radius calibration
    hist: list = dataclasses.field(default_factory=list)  # last found centres (frame, x, y)
    prev: object = None  # the previous frame (a repeated frame has the same ball tile)
    pred_err: float = math.inf  # how far the last prediction was off (px)
    # frame -> the radius its partial arc was fitted with (fitted again unless the final one)
    revisit: dict = dataclasses.field(default_factory=dict)
    n_warm: int = 0  # radii the warm-up frames gave


@dataclasses.dataclass(frozen=True)
class Verdict:
    """The frames judged (:meth:`Tracker.judge`): their times and flags, and the timing found."""

    pos: np.ndarray  # each frame's time in camera periods from frame 0
    flags: np.ndarray  # track.csv's flag of each frame ("" kept)
    counts: dict  # frames by flag, the flags that occur
    gaps: object  # the dropped-frame search (rollfric.track.dropped_frames.Gaps), or None
    irregular: tuple  # (frame, step ratio): the timing's irregular steps
    located_irregular: tuple  # the same, at frames the locator lost or got wrong


class Tracker:
    """One recording's tracking: the steps of :func:`track_recording` as methods.

    Each frame is predicted from the last centres (:meth:`predict`), located about the
    prediction (:meth:`locate`), accepted when on the trough's circle (:meth:`accept`) and
    recorded (:meth:`record`); :meth:`track_span` does that for a segment of frames,
    :meth:`track` for all (segments on threads), :meth:`refit` is the second pass with the
    calibrated radius, :meth:`judge` the plausibility and timing checks, :meth:`table` the
    DataFrame and its :class:`TrackInfo`. The arguments are :func:`track_recording`'s.
    """

    def __init__(self, source, setup: Setup, background: np.ndarray, *,
                 method: str = "subpixel", angle: str = "atan2",
                 center: tuple[float, float] | None = None, opts=None,
                 bit_depth: int | None = None) -> None:
        LOCATORS.check(method)
        self.source, self.setup, self.background = source, setup, background
        self.method, self.angle = method, angle
        self.n, self.h, self.w = source.shape
        self.r_px = ball_radius_px(setup)
        self.L_px = setup.track_radius / setup.pixel_size
        if center is None:
            center = setup.center_px
        self.lens = setup.calibration
        # with a lens calibration the centre is in the undistorted image; the locator works in
        # the recorded one (where the lens put the axis) and its centres are undistorted for
        # the angles
        self.center_ud = center
        if self.lens is not None:
            center = tuple(float(v) for v in self.lens.distort(np.asarray(center, dtype=float)))
        self.center = center
        n = self.n
        self.rows = np.full((n, 7), np.nan)  # x, y, r, sigma, inlier_frac, found, ring gain
        self.lost = np.zeros(n, dtype=bool)  # a ball located, but off the trough's circle
        self.identical = np.zeros(n, dtype=bool)  # the ball's tile equals the previous frame's
        # px: a tracked ball moves less than this from its prediction
        self.gate = 0.25 * self.r_px + 2.0
        self._read = getattr(source, "read", None)
        self.opts, self.opts_cal, self.cal_known = self._options(opts, bit_depth)
        self.locator = LOCATORS.load(method)  # as locate_frame, looked up once (not a frame)
        self.stop = threading.Event()  # a segment failed: the others end at their next frame
        self.clock = jit.CompileClock()
        self.bar = None  # the progress bar of track()

    def _options(self, opts, bit_depth):
        """(opts, opts_cal, cal_known): the locator's options before and after the radius is
        calibrated, and whether the calibration is of a known-radius fit."""
        base_radius = (opts if opts is not None else locate.SubpixelOptions()).radius
        # a small ball (known radius only): its apparent radius from its full rims' edge
        # points (it differs from the setup's by a fraction of a pixel)
        cal_known = self.method == "subpixel" and (
            base_radius == "known" or (base_radius == "auto" and self.r_px < 12))
        # once calibrated, a free radius only on (nearly) the full rim: on a partial arc the
        # free radius and the centre are confounded, the calibrated one pins the centre
        base = opts if opts is not None else locate.SubpixelOptions()
        if bit_depth is None:
            bit_depth = getattr(self.source, "bit_depth", None)
        if base.full_scale is None and bit_depth is not None:
            # the thresholds against the camera's full scale, not the 16-bit word's
            base = dataclasses.replace(base, full_scale=bitdepth.full_scale(bit_depth))
            opts = base
        setup = self.setup
        if setup.working_distance is not None and self.method == "subpixel" \
                and base.pinhole is None:
            # a pinhole at a stated working distance sees the ball as an ellipse
            # (rollfric.locate.silhouette_stretch), stretched away from the principal point
            lens, h, w = self.lens, self.h, self.w
            pp = (lens.K[0, 2], lens.K[1, 2]) if lens is not None else ((w - 1) / 2.0,
                                                                        (h - 1) / 2.0)
            base = dataclasses.replace(base, pinhole=(float(pp[0]), float(pp[1]),
                                                      setup.working_distance / setup.pixel_size))
            opts = base
        opts_cal = dataclasses.replace(base, free_min_frac=max(base.free_min_frac,
                                                               CAL_MIN_INLIER))
        return opts, opts_cal, cal_known

    @staticmethod
    def predict(hist: list, i: int):
        """Predicted centre at frame i from the last found centres [(frame, x, y), ...]; None
        when the ball was last found more than 3 frames before."""
        if not hist or i - hist[-1][0] > 3:
            return None
        if len(hist) >= 3 and hist[-1][0] == i - 1 and hist[-2][0] == i - 2 \
                and hist[-3][0] == i - 3:
            (_, x1, y1), (_, x2, y2), (_, x3, y3) = hist[-1], hist[-2], hist[-3]
            return 3 * x1 - 3 * x2 + x3, 3 * y1 - 3 * y2 + y3
        if len(hist) >= 2 and hist[-2][0] == hist[-1][0] - 1:
            (f1, x1, y1), (_, x2, y2) = hist[-1], hist[-2]
            k = i - f1
            return x1 + k * (x1 - x2), y1 + k * (y1 - y2)
        return hist[-1][1], hist[-1][2]

    def frame_at(self, i: int, guess):
        """Frame ``i``: tracking (a ``guess``) with a region reader, a LazyFrame from which the
        locator reads only the regions it crops (the same pixels as the full frame's); else
        the whole frame."""
        if self._read is not None and guess is not None:
            source = self.source
            return locate.LazyFrame(functools.partial(self._read, i),
                                    functools.partial(source.__getitem__, i),
                                    (self.h, self.w), source.dtype)
        return self.source[i]

    def locate(self, span: _Span, frame, guess):
        """(Location, radius fitted with): the ball in ``frame`` about ``guess``, searched in a
        band that follows how well the last prediction did, with the span's calibrated
        radius once there is one."""
        search = min(0.3 * self.r_px + 2.0, max(2.0, 4.0 * span.pred_err + 1.0))
        r_kn = span.cal.value
        loc = self.locator(frame, self.background, self.r_px, guess, self.center,
                           opts=self.opts if r_kn is None else self.opts_cal, search=search,
                           r_known=r_kn, r_known_sigma=span.cal.rel_sigma)
        if guess is not None and loc.found:
            span.pred_err = math.hypot(loc.x - guess[0], loc.y - guess[1])
        else:
            span.pred_err = math.inf
        return loc, r_kn

    def accept(self, loc) -> bool:
        """A ball found inside the frame and within 15 % of the track radius of the trough's
        circle."""
        w, h = self.w, self.h
        ok = (loc.found and math.isfinite(loc.x) and -0.5 <= loc.x <= w - 0.5
              and -0.5 <= loc.y <= h - 0.5)
        if ok:
            dist = math.hypot(loc.x - self.center[0], loc.y - self.center[1])
            ok = abs(dist - self.L_px) <= 0.15 * self.L_px
        return ok

    def calibrate(self, span: _Span, i: int, loc, ok: bool, keep: bool, r_kn) -> None:
        """An accepted frame into the span's radius calibration; a kept frame whose partial arc
        was fitted with another radius than the final one will be fitted again."""
        if not ok or self.method != "subpixel":
            return
        span.cal.add(loc)
        if not keep:
            return
        if loc.radius_free:
            if loc.inlier_frac < CAL_MIN_INLIER:
                span.revisit[i] = math.inf  # a free radius on a partial arc: always again
        elif r_kn is None or loc.inlier_frac < CAL_MIN_INLIER:
            # (a full rim's centre barely depends on the radius once calibrated)
            span.revisit[i] = self.r_px if r_kn is None else r_kn

    def follow(self, span: _Span, i: int, loc, guess, ok: bool) -> None:
        """An accepted centre near its prediction into the history the next ones are predicted
        from."""
        # a centre far from the prediction (a swapped frame, a ball found elsewhere by the
        # full-frame search) does not predict the next frames: that is the plausibility
        # checks' to judge, and one wrong centre would send the next searches astray
        near = guess is None or math.hypot(loc.x - guess[0], loc.y - guess[1]) <= self.gate
        if ok and near:
            span.hist.append((i, loc.x, loc.y))
            if len(span.hist) > 4:
                span.hist.pop(0)

    def record(self, i: int, frame, prev, loc, ok: bool) -> None:
        """Frame ``i``'s row: the centre, radius, sigma, rim share and ring gain of an accepted
        ball (and whether its tile repeats the previous frame's), else not found (lost: found
        off the trough's circle)."""
        if ok:
            r_loc = loc.r if math.isfinite(loc.r) else self.r_px  # thesis-small: no radius
            self.identical[i] = prev is not None and same_pixels(frame, prev, loc.x, loc.y,
                                                                 r_loc)
            self.rows[i] = (loc.x, loc.y, loc.r, loc.sigma, loc.inlier_frac, 1.0,
                            ring_gain(frame, self.background, loc.x, loc.y, r_loc))
        else:
            self.rows[i, 5] = 0.0
            self.lost[i] = bool(loc.found)

    def track_span(self, a: int, b: int):
        """Frames a..b-1 with the segment's own prediction, search band and radius calibration.

        A later segment starts SEGMENT_WARMUP frames early, from a full-frame search, and keeps
        its answers from frame a on (those before are the previous segment's): by then its
        prediction and search band are one pass's again. Writes rows, lost and identical
        [a:b]; returns the calibration, the radii of frames a..b-1 and the frames to fit again.
        """
        span = _Span(RadiusCalibration(self.r_px, known=self.cal_known))
        try:
            for i in range(max(0, a - SEGMENT_WARMUP) if a else 0, b):
                if self.stop.is_set():
                    break
                if i == a:
                    span.n_warm = len(span.cal.radii)
                keep = i >= a
                guess = self.predict(span.hist, i)
                frame = self.frame_at(i, guess)
                loc, r_kn = self.locate(span, frame, guess)
                ok = self.accept(loc)
                self.calibrate(span, i, loc, ok, keep, r_kn)
                self.follow(span, i, loc, guess, ok)
                if keep:
                    self.record(i, frame, span.prev, loc, ok)
                span.prev = frame
                if keep:
                    # the bar's clock restarted before the count: no line with the compiler's
                    # rate
                    self.clock.restart(self.bar)
                    self.bar.update(1)
        except BaseException:
            self.stop.set()
            raise
        return span.cal, span.cal.radii[span.n_warm:], span.revisit

    def track(self, segments: int | str = "auto", progress: bool = True):
        """Every frame, in segments (:func:`track_segments`): (the calibration of all their
        radii, the frames to fit again)."""
        n = self.n
        # a fresh install compiles the locator's kernels on the first frames: said before, and
        # the bar's clock restarted after it (else it shows an ETA of days for those minutes)
        jit.announce("rollfric.locate.kernels", "the locator's kernels", LOCATOR_COMPILE, logger)
        self.bar = tqdm(total=n, desc="locating ball", unit="frame", disable=not progress,
                        file=sys.stderr, mininterval=0.5)
        spans = track_segments(n, segments)
        # the segments on threads when the reader allows reads from two threads at once (the
        # locator's kernels, decoding and a synthetic recording's sensor model release the
        # GIL) and CPUs are free; else one after another: the track is the same either way
        # (five readings of the running threads: a wrong "busy" costs seconds of tracking here)
        workers = cpus.free_cpus(samples=5) if getattr(self.source, "concurrent_reads",
                                                        False) else 1
        logger.debug(f"tracking {n} frames in {len(spans)} segment(s) on "
                     f"{min(workers, len(spans))} thread(s)")
        with self.clock:
            done = cpus.map_ordered(lambda span: self.track_span(*span), spans,
                                    workers=workers, name="rollfric-track")
        self.bar.close()
        if len(done) == 1:
            cal, _, revisit = done[0]
        else:
            # one calibration from every segment's radii (in frame order), one second pass
            cal = RadiusCalibration(self.r_px, known=self.cal_known)
            revisit = {}
            for _, radii, revisit_s in done:
                cal.radii.extend(radii)
                revisit.update(revisit_s)
        cal.finish()
        return cal, revisit

    def refit(self, cal: RadiusCalibration, revisit: dict, progress: bool = True) -> list:
        """The second pass: the partial arcs fitted with a free radius or another radius than
        the calibrated one, again with it; returns the frames fitted again."""
        r_cal = cal.value
        if r_cal is None:
            return []
        tol = 0.25 * cal.rel_sigma * r_cal
        redo = [i for i, r_used in revisit.items() if abs(r_used - r_cal) > tol]
        rows = self.rows
        for i in tqdm(redo, desc="partial arcs, calibrated radius", unit="frame",
                      disable=not progress or not redo, file=sys.stderr, mininterval=0.5):
            guess = (rows[i, 0], rows[i, 1])
            loc = self.locator(self.frame_at(i, guess), self.background, self.r_px, guess,
                               self.center, opts=self.opts_cal, search=2.0, r_known=r_cal,
                               r_known_sigma=cal.rel_sigma)
            if self.accept(loc):
                rows[i, :5] = (loc.x, loc.y, loc.r, loc.sigma, loc.inlier_frac)
        return redo

    def judge(self, cal: RadiusCalibration, times, drops: bool, warnings: list) -> Verdict:
        """The per-frame plausibility checks and the frame times: the frames that fail leave the
        track (their centres NaN, found 0) with their flag.

        The timing's warnings are appended to ``warnings``.
        """
        rows, n, r_cal = self.rows, self.n, cal.value
        found = rows[:, 5] == 1.0
        gaps = None
        if times is not None:
            pos = np.asarray(times, dtype=float) * self.setup.fps
        elif drops:
            gaps = timing.find_gaps(rows[:, 0], rows[:, 1], found)
            pos = gaps.pos
            if gaps.dropped:
                msg = dropped_message(gaps)
                logger.warning(msg)
                warnings.append(msg)
        else:
            pos = np.arange(n, dtype=float)
        subpixel = self.method == "subpixel"
        flags = plausibility.flag_frames(
            rows[:, 0], rows[:, 1], found, same_pixels=self.identical, sigma=rows[:, 3],
            # the rim's share and the radius are the sub-pixel locator's own figures
            inlier_frac=rows[:, 4] if subpixel else None,
            gain=rows[:, 6], radius=rows[:, 2] if subpixel else None,
            r_ref=r_cal, r_rel_sigma=cal.rel_sigma if r_cal is not None else None, pos=pos,
            center=self.center, r_ball=r_cal if r_cal is not None else self.r_px)
        flags[~found] = np.where(self.lost[~found], "off_track", "not_found")
        located = (rows[:, 0].copy(), rows[:, 1].copy(), found.copy())  # before any rejected
        rejected = found & (flags != "")
        rows[rejected, :5] = np.nan
        rows[rejected, 5] = 0.0
        counts = {f: int(np.sum(flags == f)) for f in plausibility.FLAGS if np.any(flags == f)}
        irregular, located_irregular = (), ()
        if gaps is not None and gaps.irregular:
            # steps among frames the locator lost or got wrong are its, not the camera's
            # timing; a rejected glitch (a repeated, swapped or flashed frame) a few frames
            # away spoils the prediction of a clean step where the ball turns: judged again
            # without them
            again = timing.confirm_irregular(*located, flags != "", flags == "duplicate",
                                             gaps.irregular)
            irregular, located_irregular = timing.split_irregular(
                again, np.isin(flags, LOCATOR_FLAGS))
            for msg in ([irregular_message(irregular)] if irregular else []) + (
                    [located_irregular_message(located_irregular)] if located_irregular
                    else []):
                logger.warning(msg)
                warnings.append(msg)
        if rejected.any():
            logger.warning(f"{int(rejected.sum())} located frame(s) failed the plausibility "
                           "checks and are left out: " + ", ".join(
                               f"{k} {v}" for k, v in counts.items()
                               if k not in ("not_found", "off_track")))
        return Verdict(pos, flags, counts, gaps, irregular, located_irregular)

    def table(self, times, verdict: Verdict) -> pd.DataFrame:
        """The track DataFrame: the centres (lens-undistorted ones beside them with a lens
        calibration) turned into angles about the trough's centre."""
        rows = self.rows
        found = rows[:, 5] == 1.0
        x, y = np.where(found, rows[:, 0], np.nan), np.where(found, rows[:, 1], np.nan)
        theta, xu, yu = centre_angles(x, y, self.center_ud, self.setup, method=self.angle)
        df = pd.DataFrame({
            "frame": np.arange(self.n),
            "t_s": verdict.pos / self.setup.fps if times is None
            else np.asarray(times, dtype=float),
            "x_px": rows[:, 0],
            "y_px": rows[:, 1],
            "theta_rad": theta,
            "found": found.astype(int),
            "r_px": rows[:, 2],
            "sigma_px": rows[:, 3],
            "flag": verdict.flags.astype(str),
            "inlier_frac": rows[:, 4],
            "ring_gain": rows[:, 6],
        })
        if self.lens is not None:  # the undistorted centres the angles come from
            df["xu_px"], df["yu_px"] = xu, yu
        return df

    def info(self, cal: RadiusCalibration, verdict: Verdict, *, times, redo: list,
             warnings: list, warnings_radius: list) -> TrackInfo:
        """The :class:`TrackInfo` of the track: what the locating knows."""
        cal_keys = {"ball_radius_px_seen_rel_sigma": None, "ball_radius_px_seen_rel_dev": None,
                    **cal.summary()}
        center_ud = self.center_ud
        return TrackInfo(setup=self.setup, recording=str(getattr(self.source, "name", "")),
                         n_frames=self.n, n_found=int((self.rows[:, 5] == 1.0).sum()),
                         locator=self.method, angle=self.angle,
                         center_px=(float(center_ud[0]), float(center_ud[1])),
                         center_source="given", undistorted=self.lens is not None,
                         background="given", times=TIMES_FPS if times is None else "given",
                         ball_radius_px=self.r_px, track_radius_px=self.L_px, **cal_keys,
                         n_refitted=len(redo), flags=verdict.counts,
                         warnings=tuple(warnings), warnings_radius=tuple(warnings_radius),
                         frames_dropped=() if verdict.gaps is None else verdict.gaps.dropped,
                         timing_irregular=verdict.irregular,
                         located_irregular=verdict.located_irregular)


def track_recording(source, setup: Setup, background: np.ndarray, *, method: str = "subpixel",
                    angle: str = "atan2", center: tuple[float, float] | None = None,
                    progress: bool = True, opts=None,
                    times=None, drops: bool = True,
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
    segments : int or "auto"
        The recording is tracked in this many contiguous segments (:func:`track_segments`;
        "auto": 2 from 2 x SEGMENT_MIN_FRAMES frames on), each from its own full-frame search
        and radius calibration; the calibrations' radii are then pooled into one and the
        second pass (above) made with it. The segments run on as many threads (at most the
        CPUs not busy elsewhere at the start) when the reader says it can be read from several
        threads at once (its attribute ``concurrent_reads``; synth's recordings), else one
        after another: the track is the same either way. 1: one pass through the recording.
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
    tracker = Tracker(source, setup, background, method=method, angle=angle, center=center,
                      opts=opts, bit_depth=bit_depth)
    cal, revisit = tracker.track(segments, progress)
    redo = tracker.refit(cal, revisit, progress)
    warnings = [cal.warning()] if cal.warning() else []
    warnings_radius = list(warnings)
    for msg in warnings:
        logger.warning(msg)
    verdict = tracker.judge(cal, times, drops, warnings)
    df = tracker.table(times, verdict)
    info = tracker.info(cal, verdict, times=times, redo=redo, warnings=warnings,
                        warnings_radius=warnings_radius)
    return df, info


def measure(recording, setup: Setup | str | None = None, background=None, *,
            method: str = "subpixel", angle: str = "atan2", fit_method: str = "lsq",
            offset: bool | str = "auto", fit: bool = True, progress: bool = False,
            median_frames: int = 41, fit_kwargs: dict | None = None,
            times: str = "auto", drops: bool = True,
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
                               segments=segments, bit_depth=bits)
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
                                           drops=drops,
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
