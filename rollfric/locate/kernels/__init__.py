"""The sub-pixel locator's numba kernels (compiled once, cached on disk), one module per concept.

- :mod:`~rollfric.locate.kernels.rays`: the ray profiles;
- :mod:`~rollfric.locate.kernels.rim`: the median along the rim;
- :mod:`~rollfric.locate.kernels.edges`: each ray's edge point and levels;
- :mod:`~rollfric.locate.kernels.mirror`: a steel ball's rim (its signature, the Fresnel shift);
- :mod:`~rollfric.locate.kernels.selection`: the clean rays;
- :mod:`~rollfric.locate.kernels.circle`: the robust circle fit;
- :mod:`~rollfric.locate.kernels.pixelfit`: the pixel-level edge-model fit;
- :mod:`~rollfric.locate.kernels.passes`: one pass of the locator, the above in one call;
- :mod:`~rollfric.locate.kernels.crops`: the tracker's ring sums and pixel comparison.

numba renews a kernel's disk cache when its own module changes, not when a kernel it calls
from another module does: the package's kernels share one stamp of all its modules
(:func:`rollfric.jit.share_source_stamp`), so that an edit to any one renews them all.
"""

# every module imported with the package: rollfric.jit then knows all the kernels, and the
# tracker's notice that they are to be compiled counts them all
from rollfric import jit
from rollfric.locate.kernels import (  # noqa: F401
    circle,
    crops,
    edges,
    mirror,
    passes,
    pixelfit,
    rays,
    rim,
    selection,
)

jit.share_source_stamp(__name__)
