"""What the uncertainty budget re-evaluates: one measurement's located centres (or given angles),
times, trough centre and angle formula, turned into theta(t) again with a moved setup.

:func:`measurement_from_track` makes a :class:`Measurement` from
:func:`rollfric.measure`'s track; :func:`rollfric.uncertainty.budget.budget` moves each
uncertain input of its setup and re-evaluates :meth:`Measurement.series` with it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rollfric.geometry.theta import centre_angles
from rollfric.setup.model import Setup


@dataclasses.dataclass(frozen=True)
class Measurement:
    """What a re-evaluation needs: the located centres (``x``, ``y`` px at ``frames``) about
    ``center`` with ``angle`` ("atan2" or "arcsin"), or the given angles ``theta`` at times
    ``t`` (a track CSV: no centres; its t_s taken as frame / camera.fps). Centres with ``t``:
    the recording's own timestamps (the frame rate then does not act). NaN entries are frames
    without a ball. ``center_u``: the standard uncertainty (px, x and y) of a ``center`` found
    from the background's contour (the setup then has no center_px); it makes the centre a
    source of the budget as a setup's ``center_px_u`` does. ``distorted``: ``x``, ``y`` are
    positions in the recorded image, undistorted with the setup's lens calibration before the
    angles (so a moved calibration moves them); ``center`` is in the undistorted image.

    Parameters
    ----------
    setup : Setup
        The nominal setup.
    frames, x, y : numpy.ndarray, optional
        Frame numbers and located centres (px).
    center : tuple of float, optional
        The cylinder axis the angles are taken about (px).
    angle : {"atan2", "arcsin"}, optional
        The angle formula (:func:`rollfric.geometry.theta.angles`).
    t, theta : numpy.ndarray, optional
        Times (s) and given angles (rad).
    center_u : tuple of float, optional
        Standard uncertainty of a contour-found ``center`` (px).
    distorted : bool, optional
        ``x``, ``y`` are in the recorded (distorted) image.
    angle_map : tuple, optional
        A tilted camera's compression undone before the angles.
    as_built : dict, optional
        The trough's contour and the ball's path as ellipses (fit.json's
        ``contour_ellipse``, ``path_ellipse``): their readings are budget rows
        (:mod:`rollfric.uncertainty.asbuilt`).
    camera_motion : dict, optional
        The camera's motion the measurement corrected (fit.json's ``camera_motion``): its
        correction's uncertainty is a budget row (:mod:`rollfric.uncertainty.motion`).

    Examples
    --------
    Two located centres, re-evaluated with the trough's centre 1 px to the right:

    >>> import numpy as np, rollfric
    >>> setup = rollfric.thesis_setup("10mm")
    >>> meas = rollfric.Measurement(setup=setup, frames=np.array([0.0, 1.0]),
    ...                             x=np.array([100.0, 110.0]), y=np.array([700.0, 700.0]),
    ...                             center=(100.0, 100.0))
    >>> t, theta = meas.series(setup)
    >>> t, theta.round(5)
    (array([0.   , 0.001]), array([0.     , 0.01667]))
    >>> meas.series(setup.replace(center_px=(101.0, 100.0)))[1].round(5)
    array([-0.00167,  0.015  ])
    """

    setup: Setup
    frames: np.ndarray | None = None
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    center: tuple[float, float] | None = None
    angle: str = "atan2"
    t: np.ndarray | None = None
    theta: np.ndarray | None = None
    center_u: tuple[float, float] | None = None
    distorted: bool = False
    # a tilted camera's compression undone about the centre before the angles
    # (rollfric.geometry.pathshape; TrackInfo.angle_map); None: none
    angle_map: tuple | None = None
    # the ellipses the measurement saw, as in fit.json: {"contour_ellipse": ...,
    # "path_ellipse": ...} (rollfric.uncertainty.asbuilt reads them); None: none
    as_built: dict | None = None
    # the camera's motion the measurement corrected, as in fit.json's camera_motion
    # (rollfric.uncertainty.motion makes its row); None: none
    camera_motion: dict | None = None

    @property
    def from_centres(self) -> bool:
        """True when the measurement holds located centres, False for given angles."""
        return self.x is not None

    def series(self, setup: Setup):
        """(t, theta) of the measurement with ``setup`` in place of the nominal one.

        Parameters
        ----------
        setup : Setup
            The setup to evaluate with (centre, pixel size, radius, frame rate).

        Returns
        -------
        t : numpy.ndarray
            Times, s.
        theta : numpy.ndarray
            Angles, rad (NaN where no ball).
        """
        if self.from_centres:
            center = setup.center_px if setup.center_px is not None else self.center
            # as the measurement did (rollfric.track.tracker): undistorted, mapped, the angles
            th, _, _ = centre_angles(self.x, self.y, center, setup, method=self.angle,
                                     distorted=self.distorted, angle_map=self.angle_map)
            if self.t is not None:
                return np.asarray(self.t, dtype=float), th
            return np.asarray(self.frames, dtype=float) / setup.fps, th
        return np.asarray(self.t, dtype=float) * (self.setup.fps / setup.fps), \
            np.asarray(self.theta, dtype=float)


def measurement_from_track(track, info) -> Measurement:
    """A :class:`Measurement` from ``rollfric.measurement.measure``'s track DataFrame.

    Parameters
    ----------
    track : pandas.DataFrame
        Columns ``frame``, ``found``, ``x_px``, ``y_px`` (in the recorded image), ``t_s``.
    info : rollfric.track.track_info.TrackInfo
        How it was measured: ``setup`` (the nominal setup), ``center_px``, ``angle`` and
        ``times`` (the recording's timestamps unless it is "frame / camera.fps").

    Returns
    -------
    Measurement
        Centres (NaN where the ball was not found), with the track's times when they are the
        recording's own timestamps, and the contour-found centre's uncertainty
        (``info.center_u_px``) when the setup gave no centre.

    Examples
    --------
    The shipped sample recording, measured, then its uncertainty budget:

    >>> import tempfile, rollfric
    >>> from pathlib import Path
    >>> from rollfric.sample import write_sample
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = write_sample(Path(tmp.name) / "sample")
    >>> track, info, result = rollfric.measure(folder / "frames.tif", folder / "setup.toml")
    >>> meas = rollfric.measurement_from_track(track, info)
    >>> meas.from_centres, meas.center, len(meas.x)
    (True, (191.0, -532.0), 400)
    >>> b = rollfric.budget(meas, result)
    >>> b.rows[0].source, abs(b.mu - 0.0079) < b.U_mu
    ('cylinder.center_px[x]', True)
    >>> tmp.cleanup()
    """
    center = tuple(info.center_px)
    center_u = getattr(info, "center_u_px", None)
    found = track["found"].to_numpy() == 1
    # located in the recorded image; with a lens calibration they are undistorted for the
    # angles (as the measurement did), so that a moved calibration can act
    x = np.where(found, track["x_px"].to_numpy(float), np.nan)
    y = np.where(found, track["y_px"].to_numpy(float), np.nan)
    stamped = info.times != "frame / camera.fps"
    # frame / fps times count the camera's periods: the frame number plus the periods of the
    # dropped frames found before it (rollfric.track.dropped_frames), which t_s holds
    frames = track["frame"].to_numpy(float) if stamped else \
        np.rint(track["t_s"].to_numpy(float) * info.setup.fps)
    return Measurement(setup=info.setup, frames=frames, x=x, y=y,
                       center=center, angle=info.angle,
                       t=track["t_s"].to_numpy(float) if stamped else None,
                       center_u=None if center_u is None or info.setup.center_px is not None
                       else tuple(float(v) for v in center_u),
                       distorted=bool(info.undistorted),
                       angle_map=getattr(info, "angle_map", None),
                       as_built={"contour_ellipse": getattr(info, "contour_ellipse", None),
                                 "path_ellipse": getattr(info, "path_ellipse", None)},
                       camera_motion=getattr(info, "camera_motion", None))
