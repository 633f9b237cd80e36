"""The pixel-level fit: the circle refined on the edge pixels themselves, each modelled by the
area of the pixel inside the disk (a straight-edge model), Gauss-Newton on the centre."""

from __future__ import annotations

import math

import numpy as np

from rollfric.jit import njit
from rollfric.locate.kernels.circle import solve3


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
    the centre: ``int(phi / (2 pi / n)) % n``, phi = arctan2(dy, dx) taken into [0, 2 pi). The
    angle comes from a polynomial (:data:`_ATAN_A`, within 2e-8 rad) where it lies farther
    than ATAN_GUARD from a ray's boundary (the index is then the same), else from arctan2
    itself: the same index everywhere, cheaper than arctan2. (dx, dy) not both 0."""
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
def pixel_fit(rel, bgr, cx, cy, r, free, ray_ok, a_lv, b_lv, inset, iters):
    """Refine the circle on the pixels themselves: each pixel within 1.5 px of the rim, on a
    ray kept by the robust fit, is modelled as b + (a - b) * (area of the pixel inside the
    disk) with a straight-edge area model, levels a, b of its ray; Gauss-Newton on the centre
    (and radius). The contrast is taken pixel by pixel against the background ``bgr``: where
    the ball covers a background that changes (the trough's contour at the contact, texture),
    frame - background = b + (a + B_in - B - b) * area, B_in the background ``inset`` px
    inside the rim where the level a was measured. Uses every edge pixel once with its own
    weight, which is what the noise allows (Cramer-Rao). Rays whose pixels do not fit are
    dropped after the first pass. Returns cx, cy, r, centre standard error (px), pixels used."""
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
        if not reuse:
            c_k, c_g, c_res, n_c = _rim_pixels(rel, bgr, cx, cy, r, ray_ok, a_lv, b_lv, inset)
        reuse = False
        jtj, jtr, ss, npix = _pixel_sums(c_k, c_g, c_res, n_c, ray_ok, ray_ss, ray_n)
        if npix < 20:
            return np.nan, np.nan, np.nan, np.nan, npix
        if it == 0 and _drop_misfits(ray_ok, ray_ss, ray_n) > 0:
            # then start again from the same circle, on the first pass's pixels
            reuse = True
            continue
        cx, cy, r, sig, done, ok = _pixel_step(jtj, jtr, cx, cy, r, free, ss, npix, npar)
        if not ok:
            return np.nan, np.nan, np.nan, np.nan, npix
        if done:
            break
    return cx, cy, r, sig, npix


@njit(nogil=True)
def _rim_pixels(rel, bgr, cx, cy, r, ray_ok, a_lv, b_lv, inset):
    """The pixels within 1.5 px of the circle (cx, cy, r) on the rays ``ray_ok``, row by row:
    each one's ray, the gradient of its model in (cx, cy, r) and its residual
    (:func:`_pixel_model`), and their count."""
    h, w = rel.shape
    n = len(ray_ok)
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
            res, g0, g1, g2 = _pixel_model(rel, bgr, ix, iy, cx, cy, r, dx, dy, d, u,
                                           a_lv[k], b_lv[k], inset)
            c_k[n_c] = k
            c_g[n_c, 0] = g0
            c_g[n_c, 1] = g1
            c_g[n_c, 2] = g2
            c_res[n_c] = res
            n_c += 1
    return c_k, c_g, c_res, n_c


# inlined where it is called (every edge pixel): a call for each slows the kernel
@njit(nogil=True, inline="always")
def _pixel_model(rel, bgr, ix, iy, cx, cy, r, dx, dy, d, u, a_ray, b, inset):
    """The edge pixel (ix, iy), at (dx, dy) from the centre, d from it and u outside the rim:
    its residual from b + (a - b) * (the area of the pixel inside the disk), a its ray's inside
    level ``a_ray`` plus the background's change from ``inset`` px inside the rim to the
    pixel, and the model's gradient in (cx, cy, r)."""
    h, w = rel.shape
    jx = int(np.rint(cx + dx * (r - inset) / d))
    jy = int(np.rint(cy + dy * (r - inset) / d))
    jx = min(max(jx, 0), w - 1)
    jy = min(max(jy, 0), h - 1)
    a = a_ray + bgr[jy, jx] - bgr[iy, ix]
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
    return res, g0, g1, g2


@njit(nogil=True)
def _drop_misfits(ray_ok, ray_ss, ray_n):
    """Leave out (in place) the rays whose pixels do not fit (shadow edges, spots): their rms
    residual above 2.5 x the typical ray's. Returns how many were left out."""
    used = ray_n > 0
    rr = np.sqrt(ray_ss[used] / ray_n[used])
    thr = 2.5 * np.median(rr)
    drop = 0
    for q in range(len(ray_ok)):
        if used[q] and np.sqrt(ray_ss[q] / ray_n[q]) > thr:
            ray_ok[q] = False
            drop += 1
    return drop


@njit(nogil=True)
def _pixel_sums(c_k, c_g, c_res, n_c, ray_ok, ray_ss, ray_n):
    """:func:`pixel_fit`'s sums over its kept pixels ``[:n_c]`` on the rays ``ray_ok``, in
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
    """:func:`pixel_fit`'s Gauss-Newton step from J^T J and J^T r: the new (cx, cy, r), the
    centre's standard error, whether the step was small enough to stop, and whether it was
    finite."""
    if free:
        st = solve3(jtj, jtr)
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
