"""The tracking loop: the ball located in every frame of a recording, one row a frame.

:class:`Tracker` follows the ball through a recording: each frame's centre is predicted from
the last ones, located in a small region about the prediction (a full-frame search when lost;
with a reader's ``read(i, roi)`` only that region is read, :class:`rollfric.locate.LazyFrame`),
accepted on the trough's circle and recorded; the ball's apparent radius is calibrated on the
way (:mod:`rollfric.track.radius`) and the partial arcs fitted before it settled are fitted
again. A long recording is tracked in segments on threads. The frames are then judged
(:mod:`rollfric.track.plausibility`, the frame times of :mod:`rollfric.track.dropped_frames`)
and the centres turned into angles (:mod:`rollfric.geometry.theta`).
:func:`track_recording` is the public function; :func:`rollfric.measurement.measure` runs it
as a step of the measurement.

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

import numpy as np
import pandas as pd
from tqdm import tqdm

from rollfric import jit, locate
from rollfric import parallel as cpus
from rollfric.errors import InputError
from rollfric.geometry.theta import centre_angles
from rollfric.io import bitdepth
from rollfric.locate.tile import ring_gain, same_pixels
from rollfric.registry import LOCATORS
from rollfric.setup.model import Setup
from rollfric.track import dropped_frames as timing
from rollfric.track import plausibility
from rollfric.track.radius import CAL_MIN_INLIER, RadiusCalibration
from rollfric.track.setup_checks import (
    ball_radius_px,
)
from rollfric.track.timestamps import (
    LOCATOR_FLAGS,
    TIMES_FPS,
    dropped_message,
    irregular_message,
    located_irregular_message,
)
from rollfric.track.track_info import TrackInfo

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
            gaps = timing.find_gaps(rows[:, 0], rows[:, 1], found, rows[:, 3])
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
        sigma = rows[:, 3].copy()
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
                                             gaps.irregular, sigma)
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
