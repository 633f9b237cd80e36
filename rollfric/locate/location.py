"""What every ball locator is: its answer for one frame (:class:`Location`) and the interface
the tracking loop calls it through (:class:`Locator`)."""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol, runtime_checkable


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


@runtime_checkable
class Locator(Protocol):
    """A ball locator as the tracking loop (:func:`rollfric.track.tracker.locate_frame`) calls it.

    Registered by name in :data:`rollfric.registry.LOCATORS` (the CLI's ``--method``).

    Parameters
    ----------
    frame : ndarray or LazyFrame
        One (H, W) frame (a :class:`rollfric.locate.LazyFrame` reads only what is cropped).
    background : ndarray
        The (H, W) background, same size.
    r_px : float
        The ball's radius from the setup (px).
    guess : (float, float) or None
        The predicted centre (px) from the previous frames, or None: search the whole frame.
    center : (float, float)
        The trough's axis in the image (px): which side of the bottom the ball is on.
    opts, search, r_known, r_known_sigma
        The sub-pixel locator's options (:class:`rollfric.locate.SubpixelOptions`), how far
        (px) the edge may be from the predicted circle, the radius (px) partial arcs are
        fitted with and its relative uncertainty; None for the defaults. A locator that has
        no use for one ignores it.

    Returns
    -------
    Location
        The centre (px) and whether it was found.
    """

    def __call__(self, frame, background, r_px: float, guess: tuple[float, float] | None,
                 center: tuple[float, float], *, opts=None, search: float | None = None,
                 r_known: float | None = None,
                 r_known_sigma: float | None = None) -> Location: ...
