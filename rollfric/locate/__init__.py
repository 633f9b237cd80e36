"""Ball locators (a package: one module per job; this module re-exports the public names)."""

from rollfric.locate.subpixel import (
    METHODS,
    LazyFrame,
    Location,
    SubpixelOptions,
    _crop,
    as_array,
    coarse_candidates,
    coarse_find,
    locate_large_thesis,
    locate_small_thesis,
    locate_subpixel,
    relative_image,
)

__all__ = [
    "METHODS",
    "LazyFrame",
    "Location",
    "SubpixelOptions",
    "_crop",
    "as_array",
    "coarse_candidates",
    "coarse_find",
    "locate_large_thesis",
    "locate_small_thesis",
    "locate_subpixel",
    "relative_image",
]
