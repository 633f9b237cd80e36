"""The edge point of every ray: the steepest step of the ball's polarity, the inside and outside
levels beside it, and the edge position from the integral of the normalised profile."""

from __future__ import annotations

import numpy as np

from rollfric.jit import njit
from rollfric.locate.kernels.rays import background_step
from rollfric.locate.kernels.rim import rim_median


@njit(nogil=True)
def ray_edges(prof, s0, ds, r, w, ne, nl, ksm, min_rel, local_lv, wide_out, bgr, cx, cy):
    """Per ray: the steepest step of the ball's polarity in [r - w, r + w], then the edge
    position from the integral of the normalised profile across a window of 2 ne + 2 samples
    (exact for a sampled step), with the inside/outside levels from nl samples either side.

    Rays whose step is below ``min_rel`` x the 75th percentile of the rays' steps have no
    usable contrast and are not valid. Nor are rays whose step is the background's own: where
    the ball covers an edge of the background (the dark bore's edge behind a ball seen in
    perspective), frame - background steps there although the frame does not (the ball's level
    on both sides), a chord of the silhouette; such a ray's step in the frame itself (the step
    of frame - background plus the background's step ``bgr`` across the same windows, rays
    from (cx, cy)) is under a quarter of its step in frame - background, and it lies more than
    1.5 px inside the expected rim (a contour touching the ball from outside, the trough at
    the contact in the orthographic view, steps at the rim itself and keeps its rays). Where
    the ball's rim lies over a region of its own level, it is not seen: no edge to find there.

    Returns s_edge, contrast (inside - outside, signed by polarity), outside std, valid,
    and the inside and outside levels used."""
    n, ns = prof.shape
    s_edge = np.full(n, np.nan)
    spread = np.full(n, np.nan)
    a_used = np.full(n, np.nan)
    b_used = np.full(n, np.nan)
    con = np.full(n, np.nan)
    osd = np.full(n, np.nan)
    valid = np.zeros(n, np.bool_)
    m, sgn = polarity(prof, nl)
    if m < 3:
        return s_edge, con, osd, valid, a_used, b_used, spread
    lo = max(ne + nl, int(np.floor((r - w - s0) / ds)))
    hi = min(ns - ne - nl - 3, int(np.ceil((r + w - s0) / ds)))
    kbs, a_in, b_out, a_deep, a_near, osd = ray_steps(prof, s0, ds, r, ne, nl, sgn, lo, hi, bgr,
                                                      cx, cy)
    fin = with_contrast(a_in, b_out, sgn, min_rel)
    if fin.sum() < 3:
        return s_edge, con, osd, valid, a_used, b_used, spread
    cres, a_loc, a_med, spoiled, drop = inside_levels(a_in, b_out, a_deep, a_near, osd, fin, sgn,
                                                      local_lv)
    a_sm, b_sm = smoothed_levels(a_in, b_out, fin, spoiled, ksm)
    for i in range(n):
        kb = kbs[i]
        if kb < 0 or not fin[i]:
            continue
        ref = a_loc[i] if local_lv and np.isfinite(a_loc[i]) else a_med
        a = a_sm[i] if np.isfinite(a_sm[i]) else ref
        if spoiled[i]:
            if drop:
                continue
            a = ref
        b = b_sm[i]
        c = a - b
        if c * sgn <= 0:
            continue
        se = edge_integral(prof, i, kb, s0, ds, ne, b, c, cres[i])
        if not np.isfinite(se) or se <= s0 + (kb - ne) * ds or se >= s0 + (kb + ne + 1) * ds:
            continue
        s_edge[i] = se
        spread[i] = edge_spread(prof, i, kb, s0, ds, ne, nl, b, c, cres[i], se)
        con[i] = abs(c)
        valid[i] = True
        a_used[i] = a
        b_used[i] = b
    drop_wide(s_edge, valid, spread, wide_out)
    return s_edge, con, osd, valid, a_used, b_used, spread


@njit(nogil=True)
def polarity(prof, nl):
    """The ball's polarity against its background: (rays with both ends of the band inside the
    crop, +1 where the ball is brighter than its surroundings, else -1)."""
    n, ns = prof.shape
    # polarity: inside minus outside at the ends of the band, median over rays
    diffs = np.empty(n)
    m = 0
    for i in range(n):
        a = 0.0
        b = 0.0
        for j in range(nl):
            a += prof[i, j]
            b += prof[i, ns - 1 - j]
        if np.isfinite(a) and np.isfinite(b):
            diffs[m] = (a - b) / nl
            m += 1
    if m < 3:
        return m, 1.0
    # polarity: the majority sign among the rays with a clear step (rays where the ball sits
    # in front of a region of its own level -- a cast shadow, the trough -- have none and
    # must not outvote the arc that has contrast)
    # (an order statistic of finite values: a partition's is the sorted array's, to the bit)
    q = int(0.9 * (m - 1))
    tpol = 0.3 * np.partition(np.abs(diffs[:m]), q)[q]
    npos = 0
    nneg = 0
    for i in range(m):
        if diffs[i] > tpol:
            npos += 1
        elif diffs[i] < -tpol:
            nneg += 1
    return m, 1.0 if npos >= nneg else -1.0


@njit(nogil=True)
def ray_steps(prof, s0, ds, r, ne, nl, sgn, lo, hi, bgr, cx, cy):
    """Per ray, the steepest step of polarity ``sgn`` between samples ``lo`` and ``hi`` and the
    levels beside it: the step's sample (-1: none), the inside level over nl samples (NaN where
    the step is the background's own), the outside level, the inside level a further nl
    samples in, the level over the 3 nl / 8 samples next to the edge window, and the outside's
    standard deviation."""
    n = prof.shape[0]
    kbs = np.full(n, -1)
    a_in = np.full(n, np.nan)
    b_out = np.full(n, np.nan)
    a_deep = np.full(n, np.nan)
    a_near = np.full(n, np.nan)
    osd = np.full(n, np.nan)
    nh = max(2, (3 * nl) // 8)
    for i in range(n):
        best = -np.inf
        kb = -1
        for k in range(lo, hi + 1):
            g = sgn * ((prof[i, k - 1] + prof[i, k]) - (prof[i, k + 1] + prof[i, k + 2]))
            if g > best:  # NaN never wins
                best = g
                kb = k
        if kb < 0:
            continue
        a = 0.0
        b = 0.0
        b2 = 0.0
        for j in range(nl):
            a += prof[i, kb - ne - 1 - j]
            v = prof[i, kb + ne + 2 + j]
            b += v
            b2 += v * v
        an = 0.0  # the level over the nh samples next to the edge window
        for j in range(nh):
            an += prof[i, kb - ne - 1 - j]
        a_near[i] = an / nh
        a /= nl
        b /= nl
        # the level a further nl samples inside: a flat inside (a rim's reflection), a
        # gradient towards the background's level (a specular spot's tail) or away from it (a
        # crescent of reflection narrower than the windows)
        j0 = kb - ne - 1 - 2 * nl
        if j0 >= 0:
            a2 = 0.0
            for j in range(nl):
                a2 += prof[i, j0 + 1 + j]
            a_deep[i] = a2 / nl
        kbs[i] = kb
        a_in[i] = a
        b_out[i] = b
        osd[i] = np.sqrt(max(b2 / nl - b * b, 0.0))
        # the background's own step across the same windows: the frame's step is this plus
        # (a - b); a step of the ball's polarity that the frame does not have is the
        # background's edge behind the ball, not the ball's rim
        # (only inside the rim: a trough of the ball's level whose contour touches the
        # ball from outside, the orthographic view at the contact, steps at the rim itself;
        # the background's step is computed only there)
        if s0 + kb * ds < r - 1.5:
            dbg = background_step(bgr, cx, cy, (i + 0.5) * (2.0 * np.pi / n),
                                  s0 + (kb - ne - 1) * ds, s0 + (kb + ne + 2) * ds, nl, ds)
            if np.isfinite(dbg) and sgn * ((a - b) + dbg) < 0.25 * sgn * (a - b):
                a_in[i] = np.nan
    return kbs, a_in, b_out, a_deep, a_near, osd


@njit(nogil=True)
def with_contrast(a_in, b_out, sgn, min_rel):
    """The rays with contrast: a step of at least ``min_rel`` x the typical strong ray's (the
    75th percentile); none where fewer than 3 rays have levels."""
    # the others (the ball in front of a cast shadow or of anything of its own level) carry
    # no edge and are left out of the level statistics
    fin = np.isfinite(a_in) & np.isfinite(b_out)
    if fin.sum() < 3:
        return fin
    cr = sgn * (a_in[fin] - b_out[fin])
    q = int(0.75 * (len(cr) - 1))
    cref = np.partition(cr, q)[q]
    for i in range(len(a_in)):
        if fin[i] and sgn * (a_in[i] - b_out[i]) < min_rel * cref:
            fin[i] = False
    return fin


@njit(nogil=True)
def inside_levels(a_in, b_out, a_deep, a_near, osd, fin, sgn, local_lv):
    """The ball's inside level next to each ray's edge: ``a_in`` taken next to the edge window
    on a crescent's rays (in place), and which rays a spot or shading spoils. Returns the
    crescent rays, the median of the neighbours' levels along the rim, the median level, the
    spoiled rays and whether to drop them (enough clean ones remain)."""
    n = len(a_in)
    # per ray, unless a spot or shading spoils it (then the median)
    c_med = np.median(np.abs(a_in[fin] - b_out[fin]))
    sd_med = np.median(osd[fin])
    # a ray whose level a further nl samples in has more contrast than its own (``local_lv``):
    # a rim brighter than the ball's inside towards the background, the crescent a mirror ball
    # reflects of its surroundings, whose inner edge reaches into the level window on a small
    # ball (4 px from the edge at 18.6 px radius). Its level is taken next to the edge window
    # (3 nl / 8 samples nearest it, 0.75 px), and the profile is clipped at that level in the
    # edge's integral and spread (``cres``): the crescent's inner step is no part of the edge.
    # A specular spot's tail is the other way round (less contrast further in): still spoiled
    cres = np.zeros(n, np.bool_)
    if local_lv:
        tol0 = 0.08 * c_med + 3.0 * sd_med
        for i in range(n):
            if fin[i] and sgn * (a_deep[i] - a_in[i]) > tol0:
                a_in[i] = a_near[i]
                cres[i] = True
    # the inside level next to the rim varies along it (a mirror ball's rim reflects the
    # bright backdrop on one side, the dark trough on the other): a ray's level is compared
    # with the median of its neighbours' over about 1/8 of the rim, not with one median
    a_loc = rim_median(a_in, fin, 1)
    a_med = np.median(a_in[fin])
    spoiled = np.zeros(n, np.bool_)
    for i in range(n):
        ref = a_loc[i] if np.isfinite(a_loc[i]) else a_med
        tol = 0.08 * c_med + 3.0 * sd_med
        spoiled[i] = abs(a_in[i] - a_med) > tol and (not local_lv or abs(a_in[i] - ref) > tol
                                                     or not sgn * (a_in[i] - a_deep[i]) <= tol)
    # drop those rays when enough clean ones remain, else use the median inside level
    drop = (fin & ~spoiled).sum() >= 0.5 * fin.sum()
    return cres, a_loc, a_med, spoiled, drop


@njit(nogil=True)
def smoothed_levels(a_in, b_out, fin, spoiled, ksm):
    """The inside and outside levels averaged over 2 ``ksm`` + 1 neighbouring rays (the rays
    with contrast; the inside over the clean ones only): less noise. NaN where none."""
    n = len(a_in)
    a_sm = np.full(n, np.nan)
    b_sm = np.full(n, np.nan)
    for i in range(n):
        sa = 0.0
        sb = 0.0
        na = 0
        nb = 0
        for j in range(-ksm, ksm + 1):
            q = (i + j) % n
            if fin[q]:
                sb += b_out[q]
                nb += 1
                if not spoiled[q]:
                    sa += a_in[q]
                    na += 1
        if na > 0:
            a_sm[i] = sa / na
        if nb > 0:
            b_sm[i] = sb / nb
    return a_sm, b_sm


# inlined where it is called (every ray), as edge_spread is
@njit(nogil=True, inline="always")
def edge_integral(prof, i, kb, s0, ds, ne, b, c, clip):
    """Ray ``i``'s edge position: the integral (trapezoid) of its profile normalised by the
    levels (outside ``b``, contrast ``c``) across the 2 ``ne`` + 2 samples about its step
    ``kb``; ``clip``: the normalised profile at most 1 (a crescent's rays)."""
    acc = 0.0
    nw = 2 * ne + 2
    for j in range(nw):
        f = (prof[i, kb - ne + j] - b) / c
        if clip:
            f = min(f, 1.0)
        acc += 0.5 * f if (j == 0 or j == nw - 1) else f
    return s0 + (kb - ne) * ds + ds * acc


@njit(nogil=True, inline="always")
def edge_spread(prof, i, kb, s0, ds, ne, nl, b, c, clip, se):
    """Ray ``i``'s edge spread: the rms distance from its edge ``se`` of the profile's drop,
    over the edge window and the level windows beside it (a clean step: the blur's width; a
    rim that mirrors a narrow band of the surroundings: wider). NaN without a drop."""
    gs = 0.0
    gm = 0.0
    for j in range(kb - ne - nl // 2, kb + ne + 1 + nl // 2):
        if clip:
            g = max(min((prof[i, j] - b) / c, 1.0) - min((prof[i, j + 1] - b) / c, 1.0), 0.0)
        else:
            g = max((prof[i, j] - prof[i, j + 1]) / c, 0.0)
        dd = s0 + (j + 0.5) * ds - se
        gs += g
        gm += g * dd * dd
    return np.sqrt(max(gm, 0.0) / gs) if gs > 0 else np.nan


@njit(nogil=True)
def drop_wide(s_edge, valid, spread, wide_out):
    """Leave out (in place) the rays whose edge is wider than the rim's sharpest quarter by
    more than ``wide_out`` px (or 6 MADs of the sharper half), when at least 8 rays are valid
    and 30 % of them stay: a rim that mirrors a narrow band of bright surroundings has its
    edge inside the silhouette."""
    n = len(s_edge)
    nv = valid.sum()
    if wide_out > 0 and nv >= 8:
        sp = np.sort(spread[valid])
        ref = sp[int(0.25 * (nv - 1))]
        low = sp[:max(2, nv // 2)]
        mad = np.median(np.abs(low - np.median(low)))
        lim = ref + max(wide_out, 6.0 * 1.4826 * mad)
        nsharp = 0
        for i in range(n):
            if valid[i] and spread[i] <= lim:
                nsharp += 1
        if nsharp >= 0.3 * nv:
            for i in range(n):
                if valid[i] and not spread[i] <= lim:
                    valid[i] = False
                    s_edge[i] = np.nan
