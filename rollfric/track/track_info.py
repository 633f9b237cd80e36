"""TrackInfo: what a measured track was measured with and how, returned beside the track.

:func:`rollfric.track_recording` fills what the locating knows, the measurement
(:func:`rollfric.measure`) the rest; :meth:`TrackInfo.json_keys` gives the keys
``rollfric measure`` and ``rollfric track`` write to fit.json and track.json.
"""

from __future__ import annotations

import dataclasses

from rollfric.setup.model import Setup


@dataclasses.dataclass(frozen=True)
class TrackInfo:
    """What a measured track was measured with and how: returned beside the track DataFrame.

    :func:`rollfric.track_recording` fills what the locating knows; :func:`rollfric.measure`
    adds the rest
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
        The angle formula: "atan2" or "arcsin" (:func:`rollfric.geometry.theta.angles`).
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
        The ball's apparent radius calibrated from full-rim frames (px;
        :class:`rollfric.track.radius.RadiusCalibration`);
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
        Why (:func:`rollfric.fit.offset.resolve_offset`); None without a fit.
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
        that does not depend on the frame times rejected
        (:data:`rollfric.track.timestamps.LOCATOR_FLAGS`; a ball
        leaving a deep shadow): the located centres', not the timing's (a quality reason
        "located_frames").
    path_ellipse : dict or None
        The ball's path fitted as an ellipse about the centre used and what it means
        (:mod:`rollfric.geometry.pathreading`: the verdict, mu read as a tilted camera and as an
        out-of-round bore, the lengths the period and the path give); None without a fit.
    angle_map : tuple or None
        The 2 x 2 map about the centre applied to the centres before the angles (a tilted
        camera's compression undone, :mod:`rollfric.geometry.pathshape`); None: none applied.
    camera_motion : dict or None
        The camera's motion found from the static scene (:mod:`rollfric.track.camera_motion`:
        "still", a "bump" at a frame or a "drift", the shifts sampled); the centres in the
        track are moved back into the background's frame by it. None: not looked for.
    locator_precision : dict or None
        The locator's Cramér-Rao bound on the recording's own frames and the precision the fit
        reached (:meth:`rollfric.track.precision.LocatorPrecision.json`); None without a fit.
    seconds : dict of str to float
        Wall time of each stage of :func:`rollfric.measure` (s): "open" (the recording, the
        setup, the
        frame times), "background", "trough centre", "tracking", "fit", "turning points"
        (the dropped-frame search where the ball turns), "ellipse check", "path check" (the
        path's ellipse: a tilted camera or an out-of-round bore), "checks", "locator
        precision"; empty
        from :func:`rollfric.track_recording` alone. Not written to fit.json.
    background_from : str
        How the background was had: "given" (an image), "recording" (the recording's own),
        or made from the frames: "median", "clip" or "max".

    Examples
    --------
    The shipped sample recording, measured (:func:`rollfric.measure` returns its TrackInfo):

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
    locator_precision: dict | None = None


    def json_keys(self, track, *, fitted: bool = False) -> dict:
        """The keys of fit.json (``fitted``) or track.json that say how the track was measured.

        Parameters
        ----------
        track : pandas.DataFrame
            The track beside it (:func:`rollfric.measure`): its ``still`` and
            ``sigma_px`` columns give ``frames_held``, ``frames_rest`` and ``median_sigma_px``.
        fitted : bool, optional
            Add the keys of a fit (``offset_fitted``, ``offset_reason``, ``path_ellipse``,
            ``camera_motion``).

        Returns
        -------
        dict
            n_frames, n_found, locator, angle, the centre and where it came from, background,
            times, the ball's radius, flagged and dropped frames, irregular steps, warnings,
            median_sigma_px, recording, contour_ellipse (and the fit's keys), in that order.
        """
        keys = {"n_frames": int(self.n_frames), "n_found": int(self.n_found),
                "locator": self.locator, "angle": self.angle,
                "center_px": list(self.center_px),
                "center_source": self.center_source,
                # standard uncertainty of a contour-found centre (null: from the setup)
                "center_u_px": None if self.center_u_px is None else list(self.center_u_px),
                # angles from lens-undistorted centres ([camera] matrix, distortion)
                "undistorted": bool(self.undistorted),
                "background": self.background,
                # how: given (--background), recording (its own), median, clip or max
                "background_from": self.background_from,
                "times": self.times,
                "ball_radius_px": self.ball_radius_px,
                # the apparent radius calibrated from full-rim frames (None: too few)
                "ball_radius_px_seen": self.ball_radius_px_seen,
                "ball_radius_px_seen_n": self.ball_radius_px_seen_n,
                "n_refitted": self.n_refitted,
                # frames left out of the fit, by track.csv flag
                "frames_flagged": dict(self.flags),
                # a held start and a rest, left out of the fit (rollfric.track.still)
                "frames_held": int((track["still"] == "held").sum()),
                "frames_rest": int((track["still"] == "rest").sum()),
                "frames_dropped": [{"after_frame": int(k), "frames": int(m)}
                                   for k, m in self.frames_dropped],
                "timing_irregular": [{"frame": int(k), "step_ratio": float(r)}
                                     for k, r in self.timing_irregular],
                "located_irregular": [{"frame": int(k), "step_ratio": float(r)}
                                      for k, r in self.located_irregular],
                "warnings": list(self.warnings),
                "median_sigma_px": float(track["sigma_px"].median())
                if track["sigma_px"].notna().any() else None,
                "recording": self.recording}
        if not fitted:
            keys["contour_ellipse"] = self.contour_ellipse
            return keys
        keys.update({"offset_fitted": bool(self.offset_fitted),
                     "offset_reason": self.offset_reason,
                     # the contour as an ellipse and the mu bias it implies
                     # (rollfric.geometry.ellipse)
                     "contour_ellipse": self.contour_ellipse,
                     # the ball's path as an ellipse and what it means
                     # (rollfric.geometry.pathreading)
                     "path_ellipse": self.path_ellipse,
                     # the camera's motion from the static scene (rollfric.track.camera_motion)
                     "camera_motion": self.camera_motion,
                     # the centre's Cramér-Rao bound from the recording's contrast, noise and
                     # edge width beside the fit's reached scatter (rollfric.track.precision)
                     "locator_precision": self.locator_precision})
        return keys
