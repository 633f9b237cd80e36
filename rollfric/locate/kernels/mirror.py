"""A steel ball's rim, a curved mirror: the low-contrast sector where it mirrors the backdrop,
the mirror's signature (a low and a full sector), and the Fresnel rise's shift of each edge."""

from __future__ import annotations

import numpy as np

from rollfric.jit import njit
from rollfric.locate.kernels.rim import rim_median


@njit(nogil=True)
def rim_sectors(con, valid, out_sd, b_lv, noise):
    """The rays whose outside is the background itself (``ok``: there the contrast varies with
    the ball's inside only) and among them the low-contrast sector (``low``: the contrast along
    the rim, the median over about 1/8 of it, under 3/4 of its 90th percentile; on a mirror
    ball the rim mirrors something bright there, the backdrop). Both empty with fewer than 8
    such rays."""
    n = len(con)
    ok = np.zeros(n, np.bool_)
    low = np.zeros(n, np.bool_)
    nv = valid.sum()
    if nv < 8:
        return ok, low
    cmed = np.median(con[valid])
    nz = noise if noise >= 0 else np.median(out_sd[valid])
    loc = rim_median(con, valid, max(2, n // 16))
    for i in range(n):
        ok[i] = valid[i] and np.isfinite(loc[i]) and abs(b_lv[i]) <= 0.05 * cmed + 3.0 * nz
    m = ok.sum()
    if m < 8:
        ok[:] = False
        return ok, low
    q = int(0.9 * (m - 1))
    top = np.partition(loc[ok], q)[q]  # finite values: the sorted array's, to the bit
    for i in range(n):
        low[i] = ok[i] and loc[i] < 0.75 * top
    return ok, low


@njit(nogil=True)
def mirror_signature(con, valid, out_sd, b_lv, noise, least):
    """Whether the rim looks like a mirror's: where its outside is the background itself, the
    contrast along it falls into a low sector (the rim mirrors something bright, the backdrop)
    and a full one (it mirrors something dark, the trough), each at least ``least`` of those
    rays (:func:`rim_sectors`). A matt ball, one of uniform level or with spots inside its
    rim, has one sector only."""
    ok, low = rim_sectors(con, valid, out_sd, b_lv, noise)
    m = ok.sum()
    if m < 8:
        return False
    nlow = low.sum()
    return nlow >= least * m and m - nlow >= least * m


@njit(nogil=True)
def fresnel_shift(s_edge, valid, a_lv, b_lv, bgr, cx, cy, inset, kappa, most, relative):
    """Move each ray's edge out by the Fresnel rise of a mirror ball's rim: within a fraction
    of a pixel of the silhouette the ball reflects more (grazing incidence) than where its
    inside level ``a`` was measured, which moves the integral edge in by ``kappa`` x (the
    frame's level there, a + background) / (a - b). ``relative``: the level above the rim's
    darkest (the 10th percentile over the valid rays): a level common to the whole rim moves
    every edge alike (only the radius), and a matt ball's uniform level gets no correction.
    In place; returns the shifts (0 for rays not valid)."""
    h, w = bgr.shape
    n = len(s_edge)
    shift = np.zeros(n)
    level = np.zeros(n)
    for i in range(n):
        if not valid[i]:
            continue
        phi = (i + 0.5) * (2.0 * np.pi / n)
        x = cx + np.cos(phi) * (s_edge[i] - inset)
        y = cy + np.sin(phi) * (s_edge[i] - inset)
        ix = min(max(int(np.rint(x)), 0), w - 1)
        iy = min(max(int(np.rint(y)), 0), h - 1)
        level[i] = max(a_lv[i] + bgr[iy, ix], 0.0)
    base = 0.0
    nv = valid.sum()
    if relative and nv > 0:
        base = np.sort(level[valid])[int(0.1 * (nv - 1))]
    for i in range(n):
        if not valid[i]:
            continue
        c = a_lv[i] - b_lv[i]
        if c == 0.0:
            continue
        # the inside level over the contrast, at most ``most`` (a rim that mirrors the
        # backdrop: about 1; above, a ball too faint against its background to judge)
        q = min(max(level[i] - base, 0.0) / abs(c), most)
        shift[i] = -kappa * q * (1.0 if c > 0 else -1.0)
    for i in range(n):
        if valid[i]:
            s_edge[i] += shift[i]
    return shift
