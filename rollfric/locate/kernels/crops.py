"""The tracker's kernels on frame crops: the ring sums of its contrast figure and the
comparison of a ball's pixels with the previous frame's."""

from __future__ import annotations

import math

import numpy as np

from rollfric.jit import njit


@njit(nogil=True)
def ring_sums(fr, bg, x0, y0, cx, cy, r_in, r_out):
    """(sum of ``fr``, sum of ``bg``, pixels) over the pixels of the crops ``fr``, ``bg`` (whose
    top-left pixel is (x0, y0) of the frame) at a distance in [r_in, r_out] from (cx, cy), the
    sums in float64 (:func:`rollfric.locate.tile.ring_gain`)."""
    h, w = fr.shape
    sf = 0.0
    sb = 0.0
    cnt = 0
    # the squared distance screens out the pixels clearly off the ring (0.01 px: far beyond
    # its rounding); the distance of the others is hypot's, as numpy.hypot's
    lo2 = max(r_in - 0.01, 0.0) ** 2
    hi2 = (r_out + 0.01) ** 2
    in2 = (max(r_in, 0.0) + 1e-6) ** 2
    out2 = (r_out - 1e-6) ** 2 if r_out > 1e-6 else -1.0
    for iy in range(h):
        dy = (iy + y0) - cy
        q = hi2 - dy * dy
        if q < 0.0:
            continue
        # a row's columns that can pass the screen: within the outer circle's chord, a pixel
        # more a side, less the inner circle's chord, a pixel less a side (the others fail the
        # screen by far); those are visited in the same order as in a scan of the whole row,
        # so the sums are the same to the bit
        xo = math.sqrt(q)
        ia = max(0, int(math.floor(cx - xo)) - x0 - 1)
        ib = min(w - 1, int(math.ceil(cx + xo)) - x0 + 1)
        ga = ib + 1  # the inner gap's first and last column
        gb = ib
        qi = lo2 - dy * dy
        if qi > 0.0:
            xi = math.sqrt(qi)
            ga = int(math.ceil(cx - xi)) - x0 + 1
            gb = int(math.floor(cx + xi)) - x0 - 1
        ix = ia - 1
        while ix < ib:
            ix += 1
            if ga <= ix <= gb:
                ix = gb
                continue
            dx = (ix + x0) - cx
            d2 = dx * dx + dy * dy
            if d2 < lo2 or d2 > hi2:
                continue
            # clearly inside the ring (1e-6 px from its edges: far beyond the roundings of
            # d2 and hypot) without hypot; near its edges hypot decides
            if (in2 < d2 < out2) or (math.hypot(dx, dy) >= r_in
                                     and math.hypot(dx, dy) <= r_out):
                sf += np.float64(fr[iy, ix])
                sb += np.float64(bg[iy, ix])
                cnt += 1
    return sf, sb, cnt


@njit(nogil=True)
def same_values(a, b):
    """Whether the 2-D arrays ``a`` and ``b`` (the same shape) hold the same values:
    ``numpy.array_equal``'s answer, up to the first pixel that differs
    (:func:`rollfric.locate.tile.same_pixels`)."""
    h, w = a.shape
    for iy in range(h):
        for ix in range(w):
            if a[iy, ix] != b[iy, ix]:
                return False
    return True
