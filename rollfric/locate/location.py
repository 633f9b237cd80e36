"""The answer of every ball locator for one frame: :class:`Location`."""

from __future__ import annotations

import dataclasses
import math


@dataclasses.dataclass(frozen=True)
class Location:
    """One frame's answer: centre (px), fitted radius (px), found flag and quality."""

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
        return Location(reason=reason)
