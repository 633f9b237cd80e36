"""The ball's apparent radius, calibrated from the full rims the locator fits on the way.

The outline in the images is not the geometric one (anti-aliasing, gamma, the edge threshold,
optics blur shift it by a fraction of a pixel): :class:`RadiusCalibration` collects the radii
of good full-rim frames, and the tracker fits partial arcs with their median.
"""

from __future__ import annotations

import math

import numpy as np

# apparent-radius calibration: free-radius fits of frames with nearly the whole rim usable
CAL_MIN_INLIER = 0.9  # fraction of the rim a calibration frame must fit
CAL_MAX_SIGMA = 0.1  # px: centre sigma of a calibration frame
CAL_MIN_FRAMES = 5  # calibration frames before the calibrated radius is used
CAL_WARN_DEV = 0.03  # warn when the apparent radius differs from the setup's by more
# ... and by more than this (px): a rendered steel ball's outline lies 0.09-0.18 px outside
# its geometric radius whatever its size (3 to 20 px), 3 % of a ball under 6 px
CAL_WARN_PX = 0.25


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
        """A warning when the apparent radius differs from the setup's by more than 3 % and
        more than 0.25 px (the outline's own offset from the geometric radius).

        Returns
        -------
        str or None
            The message (naming ``ball.diameter_mm`` and ``camera.pixel_size_mm``), or None.
        """
        v = self.value
        if v is None or abs(v / self.r_setup - 1.0) <= CAL_WARN_DEV \
                or abs(v - self.r_setup) <= CAL_WARN_PX:
            return None
        return (f"the ball's outline measures {v:.2f} px in radius in {len(self.radii)} "
                f"full-rim frames, the setup says {self.r_setup:.2f} px "
                f"({100 * (v / self.r_setup - 1.0):+.1f} %): check ball.diameter_mm and "
                "camera.pixel_size_mm")
