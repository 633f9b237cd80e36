"""The answer of every ball locator for one frame: :class:`Location`."""

from __future__ import annotations

import dataclasses
import math


@dataclasses.dataclass(frozen=True)
class Location:
    """One frame's answer of a locator: centre, radius, found flag and quality.

    Attributes
    ----------
    x, y : float
        Centre (px; x right, y down, origin at the centre of the top-left pixel); NaN when not
        found.
    r : float
        Fitted (or known) radius (px).
    found : bool
        Whether the ball was located.
    sigma : float
        Estimated standard error of the centre (px); NaN if unknown.
    inlier_frac : float
        Fraction of edge rays kept by the robust fit.
    reason : str
        Why the ball was not found.
    radius_free : bool
        True when r was fitted (most of the rim); False when the known radius was used.
    """

    x: float = math.nan
    y: float = math.nan
    r: float = math.nan
    found: bool = False
    sigma: float = math.nan  # estimated standard error of the centre (px); nan if unknown
    inlier_frac: float = math.nan  # fraction of edge rays kept by the robust fit
    reason: str = ""  # why not found
    radius_free: bool = False  # r fitted (most of the rim); False: the known radius was used

    @staticmethod
    def missing(reason: str) -> Location:
        """A not-found answer.

        Parameters
        ----------
        reason : str
            Why the ball was not found.

        Returns
        -------
        Location
            ``found`` False, coordinates NaN.
        """
        return Location(reason=reason)
