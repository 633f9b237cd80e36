"""The sub-pixel locator's numba kernels: ray profiles, edge points, the robust circle fit and
the pixel-level edge-model fit, and the ring sums of the tracker's contrast figure (compiled
once, cached on disk)."""

from __future__ import annotations

import math

import numpy as np

from rollfric.jit import njit


@njit(nogil=True)
def _profiles(rel, cx, cy, s0, ds, ns, n):
    """Bilinear samples of rel along n rays from (cx, cy) at s0 + j ds; NaN outside rel."""
    h, w = rel.shape
    prof = np.empty((n, ns), np.float64)
    te = s0 + (ns - 1) * ds
    for i in range(n):
        phi = (i + 0.5) * (2.0 * np.pi / n)
        c, sn = np.cos(phi), np.sin(phi)
        # x and y of the samples are monotone along the ray (each rounding is): a ray whose
        # first and last samples lie inside rel lies inside it all along, and its samples need
        # no test (the same values, 18 % less time)
        xa, ya, xb, yb = cx + c * s0, cy + sn * s0, cx + c * te, cy + sn * te
        test = not (0.0 <= xa <= w - 1 and 0.0 <= ya <= h - 1 and 0.0 <= xb <= w - 1
                    and 0.0 <= yb <= h - 1)
        for j in range(ns):
            t = s0 + j * ds
            x = cx + c * t
            y = cy + sn * t
            if test and (x < 0.0 or y < 0.0 or x > w - 1 or y > h - 1):
                prof[i, j] = np.nan
                continue
            ix = min(int(x), w - 2)
            iy = min(int(y), h - 2)
            fx = x - ix
            fy = y - iy
            prof[i, j] = ((1 - fy) * ((1 - fx) * rel[iy, ix] + fx * rel[iy, ix + 1])
                          + fy * ((1 - fx) * rel[iy + 1, ix] + fx * rel[iy + 1, ix + 1]))
    return prof


@njit(nogil=True)
def _bilinear(img, x, y):
    """img at (x, y) by bilinear interpolation; NaN outside."""
    h, w = img.shape
    if not (0.0 <= x <= w - 1 and 0.0 <= y <= h - 1):
        return np.nan
    ix = min(int(x), w - 2)
    iy = min(int(y), h - 2)
    fx = x - ix
    fy = y - iy
    return ((1 - fy) * ((1 - fx) * img[iy, ix] + fx * img[iy, ix + 1])
            + fy * ((1 - fx) * img[iy + 1, ix] + fx * img[iy + 1, ix + 1]))


@njit(nogil=True)
def _bg_step(bgr, cx, cy, phi, s_in, s_out, nl, ds):
    """The background's own change along a ray at angle phi from (cx, cy): the mean over nl
    samples ending at s_in (inwards) minus the mean over nl samples from s_out outwards."""
    c, sn = np.cos(phi), np.sin(phi)
    a = 0.0
    b = 0.0
    for j in range(nl):
        a += _bilinear(bgr, cx + c * (s_in - j * ds), cy + sn * (s_in - j * ds))
        b += _bilinear(bgr, cx + c * (s_out + j * ds), cy + sn * (s_out + j * ds))
    return (a - b) / nl


@njit(nogil=True)
def _rim_median(values, ok, min_count):
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
    # two of an even count, as np.median), a seventh of the time on the fine pass's 232 rays
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
    """:func:`_rim_median` window by window (np.median of each): what it does with NaN."""
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


@njit(nogil=True)
def _edges(prof, s0, ds, r, w, ne, nl, ksm, min_rel, local_lv, wide_out, bgr, cx, cy):
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
    s_edge = np.full(n, np.nan)
    spread = np.full(n, np.nan)
    a_used = np.full(n, np.nan)
    b_used = np.full(n, np.nan)
    con = np.full(n, np.nan)
    osd = np.full(n, np.nan)
    valid = np.zeros(n, np.bool_)
    if m < 3:
        return s_edge, con, osd, valid, a_used, b_used, spread
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
    sgn = 1.0 if npos >= nneg else -1.0
    lo = max(ne + nl, int(np.floor((r - w - s0) / ds)))
    hi = min(ns - ne - nl - 3, int(np.ceil((r + w - s0) / ds)))
    kbs = np.full(n, -1)
    a_in = np.full(n, np.nan)
    b_out = np.full(n, np.nan)
    a_deep = np.full(n, np.nan)
    a_near = np.full(n, np.nan)
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
            dbg = _bg_step(bgr, cx, cy, (i + 0.5) * (2.0 * np.pi / n), s0 + (kb - ne - 1) * ds,
                           s0 + (kb + ne + 2) * ds, nl, ds)
            if np.isfinite(dbg) and sgn * ((a - b) + dbg) < 0.25 * sgn * (a - b):
                a_in[i] = np.nan
    # rays with contrast: a step of at least min_rel x the typical strong ray's (the 75th
    # percentile); the others (the ball in front of a cast shadow or of anything of its own
    # level) carry no edge and are left out of the level statistics below
    fin = np.isfinite(a_in) & np.isfinite(b_out)
    if fin.sum() < 3:
        return s_edge, con, osd, valid, a_used, b_used, spread
    cr = sgn * (a_in[fin] - b_out[fin])
    q = int(0.75 * (len(cr) - 1))
    cref = np.partition(cr, q)[q]
    for i in range(n):
        if fin[i] and sgn * (a_in[i] - b_out[i]) < min_rel * cref:
            fin[i] = False
    if fin.sum() < 3:
        return s_edge, con, osd, valid, a_used, b_used, spread
    # the ball's inside level: per ray, unless a spot or shading spoils it (then the median)
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
    a_loc = _rim_median(a_in, fin, 1)
    a_med = np.median(a_in[fin])
    spoiled = np.zeros(n, np.bool_)
    for i in range(n):
        ref = a_loc[i] if np.isfinite(a_loc[i]) else a_med
        tol = 0.08 * c_med + 3.0 * sd_med
        spoiled[i] = abs(a_in[i] - a_med) > tol and (not local_lv or abs(a_in[i] - ref) > tol
                                                     or not sgn * (a_in[i] - a_deep[i]) <= tol)
    # drop those rays when enough clean ones remain, else use the median inside level
    drop = (fin & ~spoiled).sum() >= 0.5 * fin.sum()
    # levels averaged over neighbouring rays (2 ksm + 1, clean ones only): less noise
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
        acc = 0.0
        nw = 2 * ne + 2
        clip = cres[i]
        for j in range(nw):
            f = (prof[i, kb - ne + j] - b) / c
            if clip:
                f = min(f, 1.0)
            acc += 0.5 * f if (j == 0 or j == nw - 1) else f
        se = s0 + (kb - ne) * ds + ds * acc
        if not np.isfinite(se) or se <= s0 + (kb - ne) * ds or se >= s0 + (kb + ne + 1) * ds:
            continue
        s_edge[i] = se
        # the edge's spread: the rms distance from se of the profile's drop, over the edge
        # window and the level windows beside it (a clean step: the blur's width; a rim that
        # mirrors a narrow band of the surroundings: wider)
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
        spread[i] = np.sqrt(max(gm, 0.0) / gs) if gs > 0 else np.nan
        con[i] = abs(c)
        valid[i] = True
        a_used[i] = a
        b_used[i] = b
    # rays whose edge is much wider than the rim's sharpest (a rim that mirrors a narrow band
    # of bright surroundings: its edge lies inside the silhouette) are left out, when enough
    # sharp ones remain
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
    return s_edge, con, osd, valid, a_used, b_used, spread


@njit(nogil=True)
def _solve3(m, v):
    det = (m[0, 0] * (m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1])
           - m[0, 1] * (m[1, 0] * m[2, 2] - m[1, 2] * m[2, 0])
           + m[0, 2] * (m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]))
    out = np.empty(3)
    if det == 0.0 or not np.isfinite(det):
        out[:] = np.nan
        return out
    for c in range(3):
        mm = m.copy()
        for r in range(3):
            mm[r, c] = v[r]
        out[c] = (mm[0, 0] * (mm[1, 1] * mm[2, 2] - mm[1, 2] * mm[2, 1])
                  - mm[0, 1] * (mm[1, 0] * mm[2, 2] - mm[1, 2] * mm[2, 0])
                  + mm[0, 2] * (mm[1, 0] * mm[2, 1] - mm[1, 1] * mm[2, 0])) / det
    return out


@njit(nogil=True)
def _fit_circle(xs, ys, r_known, free, tukey_c, sigma_floor):
    """Robust geometric circle fit: algebraic (Kasa) start, then Gauss-Newton on the
    point-to-circle distances with Tukey biweights (scale from the MAD, floored at
    sigma_floor). Returns cx, cy, r, weights, residuals."""
    n = len(xs)
    ata = np.zeros((3, 3))
    atb = np.zeros(3)
    for i in range(n):
        row = (xs[i], ys[i], 1.0)
        z = xs[i] * xs[i] + ys[i] * ys[i]
        for p in range(3):
            atb[p] += row[p] * z
            for q in range(3):
                ata[p, q] += row[p] * row[q]
    sol = _solve3(ata, atb)
    cx = 0.5 * sol[0]
    cy = 0.5 * sol[1]
    r = np.sqrt(max(sol[2] + cx * cx + cy * cy, 1e-12)) if free else r_known
    wts = np.ones(n)
    res = np.zeros(n)
    d = np.zeros(n)
    if not (np.isfinite(cx) and np.isfinite(cy)):
        return np.nan, np.nan, np.nan, wts, res
    for it in range(30):
        for i in range(n):
            d[i] = max(np.hypot(xs[i] - cx, ys[i] - cy), 1e-9)
            res[i] = d[i] - r
        good = res[wts > 0]
        if len(good) < 3:
            return np.nan, np.nan, np.nan, wts, res
        med = np.median(good)
        scale = max(1.4826 * np.median(np.abs(good - med)), sigma_floor)
        jtj = np.zeros((3, 3))
        jtr = np.zeros(3)
        wsum = 0.0
        for i in range(n):
            u = (res[i] - med) / (tukey_c * scale)
            wi = (1.0 - u * u) ** 2 if abs(u) < 1.0 else 0.0
            wts[i] = wi
            wsum += wi
            j0 = -(xs[i] - cx) / d[i]
            j1 = -(ys[i] - cy) / d[i]
            jj = (j0, j1, -1.0)
            for p in range(3):
                jtr[p] += wi * jj[p] * res[i]
                for q in range(3):
                    jtj[p, q] += wi * jj[p] * jj[q]
        if wsum < 3.0:
            return np.nan, np.nan, np.nan, wts, res
        if not free:  # 2 x 2 system
            det = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
            if det == 0.0:
                return np.nan, np.nan, np.nan, wts, res
            s0 = -(jtj[1, 1] * jtr[0] - jtj[0, 1] * jtr[1]) / det
            s1 = -(-jtj[1, 0] * jtr[0] + jtj[0, 0] * jtr[1]) / det
            s2 = 0.0
        else:
            st = _solve3(jtj, -jtr)
            s0, s1, s2 = st[0], st[1], st[2]
        if not (np.isfinite(s0) and np.isfinite(s1) and np.isfinite(s2)):
            return np.nan, np.nan, np.nan, wts, res
        cx += s0
        cy += s1
        r += s2
        if abs(s0) + abs(s1) + abs(s2) < 1e-6 and it > 1:
            break
    for i in range(n):
        res[i] = np.hypot(xs[i] - cx, ys[i] - cy) - r
    return cx, cy, r, wts, res


@njit(nogil=True)
def _edge_cdf(t, a, b):
    """Area of a unit pixel on the inner side of a straight edge at signed distance t from its
    centre, for an edge normal (cos, sin) with |cos| = a >= |sin| = b: the CDF of the sum of
    two uniform variables of widths a and b. Returns (coverage, density)."""
    if b < 1e-6:
        if t <= -0.5 * a:
            return 0.0, 0.0
        if t >= 0.5 * a:
            return 1.0, 0.0
        return t / a + 0.5, 1.0 / a
    lo, mid = -0.5 * (a + b), 0.5 * (a - b)
    if t <= lo:
        return 0.0, 0.0
    if t <= -mid:
        return (t - lo) ** 2 / (2 * a * b), (t - lo) / (a * b)
    if t <= mid:
        return (t + 0.5 * a) / a, 1.0 / a
    if t < -lo:
        return 1.0 - (-lo - t) ** 2 / (2 * a * b), (-lo - t) / (a * b)
    return 1.0, 0.0


# atan(t) = t (1 + sum a_k t^k), 0 <= t <= 1, to within 2e-8 rad (Abramowitz & Stegun 4.4.49)
_ATAN_A = (-0.3333314528, 0.1999355085, -0.1420889944, 0.1065626393, -0.0752896400,
           0.0429096138, -0.0161657367, 0.0028662257)
ATAN_GUARD = 1e-6  # rad: 50 x that error; nearer a ray's boundary, arctan2 decides


@njit(nogil=True)
def _ray_index(dx, dy, n):
    """The ray k of n (ray k spans angles [k, k + 1) x 2 pi / n) of a point at (dx, dy) from
    the centre: ``int(phi / (2 pi / n)) % n``, phi = arctan2(dy, dx) taken into [0, 2 pi), as
    :func:`_pixel_fit` had it. The angle comes from a polynomial (:data:`_ATAN_A`, within 2e-8
    rad) where it lies farther than ATAN_GUARD from a ray's boundary (the index is then the
    same), else from arctan2 itself: the same index everywhere, for about a third of
    arctan2's time. (dx, dy) not both 0."""
    ax = abs(dx)
    ay = abs(dy)
    t = ay / ax if ay <= ax else ax / ay
    t2 = t * t
    p = _ATAN_A[7]
    p = _ATAN_A[6] + t2 * p
    p = _ATAN_A[5] + t2 * p
    p = _ATAN_A[4] + t2 * p
    p = _ATAN_A[3] + t2 * p
    p = _ATAN_A[2] + t2 * p
    p = _ATAN_A[1] + t2 * p
    p = _ATAN_A[0] + t2 * p
    a = t * (1.0 + t2 * p)
    if ay > ax:
        a = 0.5 * np.pi - a
    if dx < 0:
        a = np.pi - a
    if dy < 0:
        a = 2 * np.pi - a
    step = 2 * np.pi / n
    q = a / step
    g = ATAN_GUARD / step
    lo = q - g
    hi = q + g
    if lo > 0.0 and hi < n and int(lo) == int(hi):
        return int(lo)
    phi = np.arctan2(dy, dx)
    if phi < 0:
        phi += 2 * np.pi
    return int(phi / (2 * np.pi / n)) % n


@njit(nogil=True)
def _pixel_fit(rel, bgr, cx, cy, r, free, ray_ok, a_lv, b_lv, inset, iters):
    """Refine the circle on the pixels themselves: each pixel within 1.5 px of the rim, on a
    ray kept by the robust fit, is modelled as b + (a - b) * (area of the pixel inside the
    disk) with a straight-edge area model, levels a, b of its ray; Gauss-Newton on the centre
    (and radius). The contrast is taken pixel by pixel against the background ``bgr``: where
    the ball covers a background that changes (the trough's contour at the contact, texture),
    frame - background = b + (a + B_in - B - b) * area, B_in the background ``inset`` px
    inside the rim where the level a was measured. Uses every edge pixel once with its own
    weight, which is what the noise allows (Cramer-Rao). Rays whose pixels do not fit are
    dropped after the first pass. Returns cx, cy, r, centre standard error (px), pixels used."""
    h, w = rel.shape
    n = len(ray_ok)
    npar = 3 if free else 2
    sig = np.nan
    npix = 0
    ray_ok = ray_ok.copy()
    ray_ss = np.zeros(n)
    ray_n = np.zeros(n)
    # every pass's pixels (ray, gradient, residual) are kept, then summed by _pixel_sums: after
    # the first pass drops rays, the second is about the same circle, so its pixels are the
    # first's on the rays kept, their values the same to the bit; they are summed again from
    # the first pass's, in the same order
    c_k = np.empty(0, np.int64)
    c_g = np.empty((0, 3))
    c_res = np.empty(0)
    n_c = 0
    reuse = False
    for it in range(iters):
        if reuse:
            reuse = False
            jtj, jtr, ss, npix = _pixel_sums(c_k, c_g, c_res, n_c, ray_ok, ray_ss, ray_n)
            if npix < 20:
                return np.nan, np.nan, np.nan, np.nan, npix
            cx, cy, r, sig, done, ok = _pixel_step(jtj, jtr, cx, cy, r, free, ss, npix, npar)
            if not ok:
                return np.nan, np.nan, np.nan, np.nan, npix
            if done:
                break
            continue
        x0 = max(0, int(cx - r - 2))
        x1 = min(w - 1, int(cx + r + 3))
        y0 = max(0, int(cy - r - 2))
        y1 = min(h - 1, int(cy + r + 3))
        m_c = max(0, (y1 - y0 + 1) * (x1 - x0 + 1))
        c_k = np.empty(m_c, np.int64)
        c_g = np.empty((m_c, 3))
        c_res = np.empty(m_c)
        n_c = 0
        # per row, only the pixels within the rim's band widened by 1 px radially and 1 px
        # each side are tested (the others fail the test |d - r| <= 1.5 by far); the pixels
        # that pass are taken in the same order, so the sums are the same to the bit
        ro2 = (r + 2.5) * (r + 2.5)
        ri = r - 2.5
        for iy in range(y0, y1 + 1):
            dy0 = iy - cy
            q2 = ro2 - dy0 * dy0
            if q2 < 0.0:
                continue
            xo = np.sqrt(q2)
            xi = -1.0
            if ri > abs(dy0):
                xi = np.sqrt(ri * ri - dy0 * dy0)
            la = max(x0, int(math.floor(cx - xo)) - 1)
            rb = min(x1, int(math.ceil(cx + xo)) + 1)
            lb = rb
            ra = rb + 1
            if xi > 1.0:
                lb = int(math.ceil(cx - xi)) + 1
                ra = int(math.floor(cx + xi)) - 1
                if ra <= lb + 1:
                    lb = rb
                    ra = rb + 1
            ix = la - 1
            while ix < rb:
                ix += 1
                if lb < ix < ra:  # the band's inside: on to its right part
                    ix = ra - 1
                    continue
                dx = ix - cx
                dy = iy - cy
                d = np.sqrt(dx * dx + dy * dy)
                u = d - r
                if abs(u) > 1.5 or d == 0.0:
                    continue
                k = _ray_index(dx, dy, n)
                if not ray_ok[k]:
                    continue
                b = b_lv[k]
                jx = int(np.rint(cx + dx * (r - inset) / d))
                jy = int(np.rint(cy + dy * (r - inset) / d))
                jx = min(max(jx, 0), w - 1)
                jy = min(max(jy, 0), h - 1)
                a = a_lv[k] + bgr[jy, jx] - bgr[iy, ix]
                c = abs(dx) / d
                s_ = abs(dy) / d
                if s_ > c:
                    c, s_ = s_, c
                cov, dens = _edge_cdf(-u, c, s_)
                res = rel[iy, ix] - (b + (a - b) * cov)
                # d model / d (cx, cy, r): (a - b) * dens * (dx/d, dy/d, 1)
                g0 = (a - b) * dens * dx / d
                g1 = (a - b) * dens * dy / d
                g2 = (a - b) * dens
                c_k[n_c] = k
                c_g[n_c, 0] = g0
                c_g[n_c, 1] = g1
                c_g[n_c, 2] = g2
                c_res[n_c] = res
                n_c += 1
        jtj, jtr, ss, npix = _pixel_sums(c_k, c_g, c_res, n_c, ray_ok, ray_ss, ray_n)
        if npix < 20:
            return np.nan, np.nan, np.nan, np.nan, npix
        if it == 0:
            # drop rays whose pixels do not fit (shadow edges, spots): rms residual above
            # 2.5 x the typical ray's, then start again from the same circle
            used = ray_n > 0
            rr = np.sqrt(ray_ss[used] / ray_n[used])
            thr = 2.5 * np.median(rr)
            drop = 0
            for q in range(n):
                if used[q] and np.sqrt(ray_ss[q] / ray_n[q]) > thr:
                    ray_ok[q] = False
                    drop += 1
            if drop > 0:
                reuse = True
                continue
        cx, cy, r, sig, done, ok = _pixel_step(jtj, jtr, cx, cy, r, free, ss, npix, npar)
        if not ok:
            return np.nan, np.nan, np.nan, np.nan, npix
        if done:
            break
    return cx, cy, r, sig, npix


@njit(nogil=True)
def _pixel_sums(c_k, c_g, c_res, n_c, ray_ok, ray_ss, ray_n):
    """:func:`_pixel_fit`'s sums over its kept pixels ``[:n_c]`` on the rays ``ray_ok``, in
    their order: J^T J (from its upper triangle as scalars: gg[p] gg[q] is gg[q] gg[p] to the
    bit, so the lower triangle is its mirror), J^T r, the residuals' sum of squares and the
    pixels' count; ``ray_ss`` and ``ray_n`` get each ray's sum of squares and count."""
    j00 = j01 = j02 = j11 = j12 = j22 = 0.0
    r0 = r1 = r2 = 0.0
    ss = 0.0
    npix = 0
    ray_ss[:] = 0.0
    ray_n[:] = 0.0
    for q in range(n_c):
        k = c_k[q]
        if not ray_ok[k]:
            continue
        g0 = c_g[q, 0]
        g1 = c_g[q, 1]
        g2 = c_g[q, 2]
        res = c_res[q]
        r0 += g0 * res
        j00 += g0 * g0
        j01 += g0 * g1
        j02 += g0 * g2
        r1 += g1 * res
        j11 += g1 * g1
        j12 += g1 * g2
        r2 += g2 * res
        j22 += g2 * g2
        ss += res * res
        npix += 1
        ray_ss[k] += res * res
        ray_n[k] += 1
    jtj = np.array([[j00, j01, j02], [j01, j11, j12], [j02, j12, j22]])
    jtr = np.array([r0, r1, r2])
    return jtj, jtr, ss, npix


@njit(nogil=True)
def _pixel_step(jtj, jtr, cx, cy, r, free, ss, npix, npar):
    """:func:`_pixel_fit`'s Gauss-Newton step from J^T J and J^T r: the new (cx, cy, r), the
    centre's standard error, whether the step was small enough to stop, and whether it was
    finite."""
    if free:
        st = _solve3(jtj, jtr)
        s0, s1, s2 = st[0], st[1], st[2]
    else:
        det = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
        if det == 0.0:
            return cx, cy, r, np.nan, False, False
        s0 = (jtj[1, 1] * jtr[0] - jtj[0, 1] * jtr[1]) / det
        s1 = (-jtj[1, 0] * jtr[0] + jtj[0, 0] * jtr[1]) / det
        s2 = 0.0
    if not (np.isfinite(s0) and np.isfinite(s1) and np.isfinite(s2)):
        return cx, cy, r, np.nan, False, False
    cx += s0
    cy += s1
    r += s2
    # centre standard error from the residual variance and the 2 x 2 block of J^T J
    var = ss / max(npix - npar, 1)
    det2 = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
    sig = np.sqrt(var * (jtj[0, 0] + jtj[1, 1]) / det2) if det2 > 0 else np.nan
    return cx, cy, r, sig, abs(s0) + abs(s1) + abs(s2) < 1e-4, True


@njit(nogil=True)
def _select(s_edge, con, out_sd, valid, lcx, lcy, bands, min_rays, noise, floor, local, b_lv,
            flank):
    """Edge points of the clean rays: the ball's typical contrast (a tight band first, widened
    only when too few rays pass: real balls vary around the rim) and a flat outside (shadow
    gradients, spots, the trough contact and occluders fail). ``local``: the typical contrast
    of a ray whose outside is the background itself (``b_lv`` about 0: the contrast varies
    with the ball's inside only) is that of its neighbours; and the full-contrast rays within
    ``flank`` rays of the low-contrast sector (:func:`_rim_sectors`) are left out when at
    least ``min_rays`` others remain: on a mirror ball the rim there mirrors the bright
    backdrop in a crescent that tapers from the low sector's width to nothing, too thin to
    show in the profile, which moves the edge in (0.6 px next to the sector). Returns status,
    xs, ys, ray index."""
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
        _, low = _rim_sectors(con, valid, out_sd, b_lv, noise)
        full = valid & ~low
        if full.sum() >= min_rays:
            cref[:] = np.median(con[full])
        loc = _rim_median(con, valid, max(2, n // 16))
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


@njit(nogil=True)
def _rim_sectors(con, valid, out_sd, b_lv, noise):
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
    loc = _rim_median(con, valid, max(2, n // 16))
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
def _mirror_signature(con, valid, out_sd, b_lv, noise, least):
    """Whether the rim looks like a mirror's: where its outside is the background itself, the
    contrast along it falls into a low sector (the rim mirrors something bright, the backdrop)
    and a full one (it mirrors something dark, the trough), each at least ``least`` of those
    rays (:func:`_rim_sectors`). A matt ball, one of uniform level or with spots inside its
    rim, has one sector only."""
    ok, low = _rim_sectors(con, valid, out_sd, b_lv, noise)
    m = ok.sum()
    if m < 8:
        return False
    nlow = low.sum()
    return nlow >= least * m and m - nlow >= least * m


@njit(nogil=True)
def _fit_stats(wts, res):
    """Inliers, their median residual and weighted rms residual."""
    inl = wts > 0
    n_in = inl.sum()
    if n_in == 0:
        return 0, np.nan, np.nan
    sw = wts.sum()
    return n_in, np.median(res[inl]), np.sqrt((wts * res * res).sum() / max(sw, 1e-12))


@njit(nogil=True)
def _mirror_rim(s_edge, valid, a_lv, b_lv, bgr, cx, cy, inset, kappa, most, relative):
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


@njit(nogil=True)
def _ring_sums(fr, bg, x0, y0, cx, cy, r_in, r_out):
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
def _same_values(a, b):
    """Whether the 2-D arrays ``a`` and ``b`` (the same shape) hold the same values:
    ``numpy.array_equal``'s answer, up to the first pixel that differs
    (:func:`rollfric.locate.tile.same_pixels`)."""
    h, w = a.shape
    for iy in range(h):
        for ix in range(w):
            if a[iy, ix] != b[iy, ix]:
                return False
    return True


@njit(nogil=True)
def _pass_raw(fr, bg, lcx, lcy, s0, ds, ns, n, r, w, ne, nl, ksm, min_rel, rim_levels,
              wide_out, mirror_rim, local_contrast, big, noise, sector, inset, kappa, relative,
              bands, min_rays, floor, flank, free, free_min_frac, r_kn, tukey_c, sigma_floor,
              pixel):
    """:func:`_pass` on the crops of the frame and the background themselves (uint8 or
    uint16, the same shape): frame - background and the background as float32 first, as
    ``cv2.subtract(fr, bg, dtype=cv2.CV_32F)`` and ``bg.astype(np.float32)`` make them (both
    values and their difference are exact in float32)."""
    h, wd = fr.shape
    rel = np.empty((h, wd), np.float32)
    bgr = np.empty((h, wd), np.float32)
    for iy in range(h):
        for ix in range(wd):
            b = np.float32(bg[iy, ix])
            rel[iy, ix] = np.float32(fr[iy, ix]) - b
            bgr[iy, ix] = b
    return _pass(rel, bgr, lcx, lcy, s0, ds, ns, n, r, w, ne, nl, ksm, min_rel, rim_levels,
                 wide_out, mirror_rim, local_contrast, big, noise, sector, inset, kappa, relative,
                 bands, min_rays, floor, flank, free, free_min_frac, r_kn, tukey_c, sigma_floor,
                 pixel)


@njit(nogil=True)
def _pass(rel, bgr, lcx, lcy, s0, ds, ns, n, r, w, ne, nl, ksm, min_rel, rim_levels, wide_out,
          mirror_rim, local_contrast, big, noise, sector, inset, kappa, relative, bands,
          min_rays, floor, flank, free, free_min_frac, r_kn, tukey_c, sigma_floor, pixel):
    """One pass of the sub-pixel locator about (lcx, lcy) in the crop ``rel`` (frame -
    background, float32) with the background ``bgr``: the ray profiles, their edges, the
    mirror signature and the rim's Fresnel shift (``mirror_rim``, ``local_contrast``: 1 on, 0
    off, -1 where the rim shows a mirror's signature and the ball is ``big``), the clean rays,
    the robust circle fit (free radius when ``free`` and at least ``free_min_frac`` of the
    ``n`` rays are kept, else the known radius ``r_kn``) and, with ``pixel``, the pixel-level
    fit of that circle; the kernels one after another, as
    :func:`rollfric.locate.subpixel._locate_guess` called them one by one before.

    Returns status (0 fitted; 1-3 :func:`_select`'s failures; 4 the robust fit failed), the
    circle (cx, cy, r), whether its radius was free, the inliers, their median residual and
    weighted rms residual, the pixel fit's cx, cy, r and centre error (NaN without
    ``pixel``), the inlier rays, whether the Fresnel shift was applied, each ray's shift and
    the inlier rays' median edge spread (px; NaN on failure)."""
    prof = _profiles(rel, lcx, lcy, s0, ds, ns, n)
    s_edge, con, out_sd, valid, a_lv, b_lv, spread = _edges(prof, s0, ds, r, w, ne, nl, ksm,
                                                            min_rel, rim_levels, wide_out, bgr,
                                                            lcx, lcy)
    mr = mirror_rim
    lc = local_contrast
    if mr < 0 or lc < 0:
        sig = big and _mirror_signature(con, valid, out_sd, b_lv, noise, sector)
        if mr < 0:
            mr = 1 if sig else 0
        if lc < 0:
            lc = 1 if sig else 0
    rim = mr == 1
    if rim:
        rim_shift = _mirror_rim(s_edge, valid, a_lv, b_lv, bgr, lcx, lcy, inset, kappa, 1.5,
                                relative)
    else:
        rim_shift = np.zeros(0)
    status, xs, ys, idx = _select(s_edge, con, out_sd, valid, lcx, lcy, bands, min_rays, noise,
                                  floor, lc == 1 and big, b_lv, flank)
    nan = np.nan
    if status:
        return (status, nan, nan, nan, False, 0, nan, nan, nan, nan, nan, nan,
                np.empty(0, np.int64), rim, rim_shift, nan)
    free_p = free and len(xs) >= free_min_frac * n
    fcx, fcy, fr_, wts, res = _fit_circle(xs, ys, r_kn, free_p, tukey_c, sigma_floor)
    n_in, med_res, rms = _fit_stats(wts, res)
    if free_p and (n_in < free_min_frac * n or not np.isfinite(fcx)):
        free_p = False
        fcx, fcy, fr_, wts, res = _fit_circle(xs, ys, r_kn, False, tukey_c, sigma_floor)
        n_in, med_res, rms = _fit_stats(wts, res)
    inl = idx[wts > 0]
    if n_in < min_rays or not np.isfinite(fcx):
        return (4, fcx, fcy, fr_, free_p, n_in, med_res, rms, nan, nan, nan, nan, inl, rim,
                rim_shift, nan)
    pcx = pcy = pr = psig = nan
    if pixel:
        ray_ok = np.zeros(n, np.bool_)
        ray_ok[inl] = True
        pcx, pcy, pr, psig, _ = _pixel_fit(rel, bgr, fcx, fcy, fr_ if free_p else r_kn, free_p,
                                           ray_ok, a_lv, b_lv, inset, 5)
    # the inlier rays' median edge spread: a sharp area-sampled step's is about 0.55 px
    sp = spread[inl]
    sp = sp[np.isfinite(sp)]
    spread_med = np.median(sp) if len(sp) > 0 else nan
    return (0, fcx, fcy, fr_, free_p, n_in, med_res, rms, pcx, pcy, pr, psig, inl, rim,
            rim_shift, spread_med)
