"""Statistics along the rim: the median of each ray's neighbours over about 1/8 of the rim
(a sliding sorted window, the same values as ``np.median`` of each window)."""

from __future__ import annotations

import numpy as np

from rollfric.jit import njit


@njit(nogil=True)
def rim_median(values, ok, min_count):
    """Per ray, the median of ``values`` over the rays within 1/16 of the rim each side (about
    1/8 of it, the ring wrapping round) where ``ok``; NaN where fewer than ``min_count``."""
    n = values.shape[0]
    out = np.full(n, np.nan)
    half = max(2, n // 16)
    for i in range(n):
        if ok[i] and not np.isfinite(values[i]):
            return _rim_median_plain(values, ok, min_count, half)
    # a sliding window kept sorted (one value out, one in, a ray to the next) instead of a
    # median of each window anew: the same values, the same medians ((a + b) / 2 of the middle
    # two of an even count, as np.median), in a fraction of the time
    buf = np.empty(2 * half + 1)
    m = 0
    for j in range(-half, half + 1):
        q = j % n
        if ok[q]:
            m = _sorted_insert(buf, m, values[q])
    for i in range(n):
        if i > 0:
            q_out = (i - 1 - half) % n
            if ok[q_out]:
                m = _sorted_remove(buf, m, values[q_out])
            q_in = (i + half) % n
            if ok[q_in]:
                m = _sorted_insert(buf, m, values[q_in])
        if m >= min_count and m > 0:
            k = m >> 1
            out[i] = buf[k] if m & 1 else (buf[k - 1] + buf[k]) / 2
    return out


@njit(nogil=True)
def _rim_median_plain(values, ok, min_count, half):
    """:func:`rim_median` window by window (np.median of each): what it does with NaN."""
    n = values.shape[0]
    out = np.full(n, np.nan)
    buf = np.empty(2 * half + 1)
    for i in range(n):
        m = 0
        for j in range(-half, half + 1):
            q = (i + j) % n
            if ok[q]:
                buf[m] = values[q]
                m += 1
        if m >= min_count and m > 0:
            out[i] = np.median(buf[:m])
    return out


@njit(nogil=True)
def _sorted_insert(buf, m, v):
    """Insert v into the ascending buf[:m]; returns m + 1."""
    k = m
    while k > 0 and buf[k - 1] > v:
        buf[k] = buf[k - 1]
        k -= 1
    buf[k] = v
    return m + 1


@njit(nogil=True)
def _sorted_remove(buf, m, v):
    """Remove one value equal to v from the ascending buf[:m]; returns m - 1."""
    k = 0
    while k < m - 1 and buf[k] != v:
        k += 1
    for j in range(k, m - 1):
        buf[j] = buf[j + 1]
    return m - 1
