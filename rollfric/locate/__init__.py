"""Ball locators: the thesis's two, and the sub-pixel silhouette-circle fit (the default).

All work on one frame and its background (same size), in pixels with x right, y down and the
origin at the centre of the top-left pixel. Each returns a :class:`Location`. The frame may be
a :class:`LazyFrame`, which reads only the regions a locator crops (the tracking loop's ROI).

One module per job:

- :mod:`rollfric.locate.location`: :class:`Location`, the answer for one frame, and
  :class:`Locator`, the interface the tracking loop calls a locator through (the locators
  are registered by name in :data:`rollfric.registry.LOCATORS`);
- :mod:`rollfric.locate.regions`: frames read by regions (:class:`LazyFrame`), crops;
- :mod:`rollfric.locate.search`: the full-frame search (:func:`coarse_candidates`);
- :mod:`rollfric.locate.thesis`: the thesis's locators (:func:`locate_small_thesis`,
  :func:`locate_large_thesis`);
- :mod:`rollfric.locate.subpixel`: the sub-pixel locator (:func:`locate_subpixel`);
- :mod:`rollfric.locate.pinhole`: a ball's silhouette seen by a pinhole camera
  (:func:`silhouette_stretch`);
- :mod:`rollfric.locate.kernels`: its numba kernels.
"""

from rollfric.locate.location import Location, Locator
from rollfric.locate.pinhole import silhouette_stretch
from rollfric.locate.regions import LazyFrame, _crop, as_array, relative_image
from rollfric.locate.search import coarse_candidates, coarse_find
from rollfric.locate.subpixel import (
    AUTO_MIRROR,
    MIRROR,
    NO_MIRROR,
    SubpixelOptions,
    locate_subpixel,
)
from rollfric.locate.thesis import locate_large_thesis, locate_small_thesis
from rollfric.registry import LOCATORS

METHODS = LOCATORS.names()

__all__ = [
    "METHODS",
    "LazyFrame",
    "LOCATORS",
    "AUTO_MIRROR",
    "MIRROR",
    "NO_MIRROR",
    "Location",
    "Locator",
    "SubpixelOptions",
    "_crop",
    "as_array",
    "coarse_candidates",
    "coarse_find",
    "locate_large_thesis",
    "locate_small_thesis",
    "locate_subpixel",
    "relative_image",
    "silhouette_stretch",
]
