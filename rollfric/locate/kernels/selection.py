"""The clean rays: those whose contrast is the ball's typical one and whose outside is flat;
their edge points are what the robust circle fit gets."""

from __future__ import annotations

import numpy as np

from rollfric.jit import njit
from rollfric.locate.kernels.mirror import rim_sectors
from rollfric.locate.kernels.rim import rim_median


@njit(nogil=True)
def select_rays(s_edge, con, out_sd, valid, lcx, lcy, bands, min_rays, noise, floor, local,
                b_lv, flank):
    """Edge points of the clean rays: the ball's typical contrast (a tight band first, widened
    only when too few rays pass: real balls vary around the rim) and a flat outside (shadow
    gradients, spots, the trough contact and occluders fail). ``local``: the typical contrast
    of a ray whose outside is the background itself (``b_lv`` about 0: the contrast varies
    with the ball's inside only) is that of its neighbours; and the full-contrast rays within
    ``flank`` rays of the low-contrast sector
    (:func:`~rollfric.locate.kernels.mirror.rim_sectors`) are left out when at least
    ``min_rays`` others remain: on a mirror ball the rim there mirrors the bright backdrop in
    a crescent that tapers from the low sector's width to nothing, too thin to show in the
    profile, which moves the edge in (0.6 px next to the sector). Returns status, xs, ys, ray
    index."""
    n = len(s_edge)
    empty = np.empty(0)
    iempty = np.empty(0, np.int64)
    nv = valid.sum()
    if nv < min_rays:
        return 1, empty, empty, iempty
    cmed = np.median(con[valid])
    nz = noise if noise >= 0 else np.median(out_sd[valid])
    if cmed < max(4.0 * nz, floor):
        return 2, empty, empty, iempty
    keep = np.zeros(n, np.bool_)
    # the typical contrast: the median, or (``local``) that of the ray's neighbours over about
    # 1/8 of the rim (a mirror ball's rim: bright where it mirrors the backdrop) where the ray's
    # outside is the background (a shadow, a glitch or an occluder changes the outside: those
    # rays keep the median)
    cref = np.full(n, cmed)
    low = np.zeros(n, np.bool_)
    if local:
        # the rays whose outside is not the background keep one typical contrast: that of
        # the rim outside the mirrored sector (the median over both is between them)
        _, low = rim_sectors(con, valid, out_sd, b_lv, noise)
        full = valid & ~low
        if full.sum() >= min_rays:
            cref[:] = np.median(con[full])
        loc = rim_median(con, valid, max(2, n // 16))
        for i in range(n):
            if np.isfinite(loc[i]) and abs(b_lv[i]) <= 0.05 * cmed + 3.0 * nz:
                cref[i] = loc[i]
    for tol in bands:
        cnt = 0
        for i in range(n):
            keep[i] = (valid[i] and out_sd[i] < 0.02 * cmed + 2.5 * nz
                       and abs(con[i] - cref[i]) < tol * cref[i] + 3.0 * nz)
            cnt += keep[i]
        if cnt >= max(min_rays, 0.4 * nv):
            break
    if local and flank > 0:
        near = np.zeros(n, np.bool_)
        for i in range(n):
            if low[i]:
                for j in range(-flank, flank + 1):
                    near[(i + j) % n] = True
        rest = 0
        for i in range(n):
            if keep[i] and not (near[i] and not low[i]):
                rest += 1
        if rest >= min_rays:
            for i in range(n):
                if near[i] and not low[i]:
                    keep[i] = False
    m = keep.sum()
    if m < min_rays:
        return 3, empty, empty, iempty
    xs = np.empty(m)
    ys = np.empty(m)
    idx = np.empty(m, np.int64)
    j = 0
    for i in range(n):
        if keep[i]:
            phi = (i + 0.5) * (2.0 * np.pi / n)
            xs[j] = lcx + np.cos(phi) * s_edge[i]
            ys[j] = lcy + np.sin(phi) * s_edge[i]
            idx[j] = i
            j += 1
    return 0, xs, ys, idx
