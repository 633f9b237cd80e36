"""One pass of the sub-pixel locator as one GIL-free kernel call: the ray profiles, their
edges, the mirror checks, the clean rays, the robust circle fit and the pixel fit in turn."""

from __future__ import annotations

import numpy as np

from rollfric.jit import njit
from rollfric.locate.kernels.circle import fit_circle, fit_stats
from rollfric.locate.kernels.edges import ray_edges
from rollfric.locate.kernels.mirror import fresnel_shift, mirror_signature
from rollfric.locate.kernels.pixelfit import pixel_fit
from rollfric.locate.kernels.rays import profiles
from rollfric.locate.kernels.selection import select_rays


@njit(nogil=True)
def locate_pass_raw(fr, bg, lcx, lcy, s0, ds, ns, n, r, w, ne, nl, ksm, min_rel, rim_levels,
                    wide_out, mirror_rim, local_contrast, big, noise, sector, inset, kappa,
                    relative, bands, min_rays, floor, flank, free, free_min_frac, r_kn, tukey_c,
                    sigma_floor, pixel):
    """:func:`locate_pass` on the crops of the frame and the background themselves (uint8 or
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
    return locate_pass(rel, bgr, lcx, lcy, s0, ds, ns, n, r, w, ne, nl, ksm, min_rel,
                       rim_levels, wide_out, mirror_rim, local_contrast, big, noise, sector,
                       inset, kappa, relative, bands, min_rays, floor, flank, free,
                       free_min_frac, r_kn, tukey_c, sigma_floor, pixel)


@njit(nogil=True)
def locate_pass(rel, bgr, lcx, lcy, s0, ds, ns, n, r, w, ne, nl, ksm, min_rel, rim_levels,
                wide_out, mirror_rim, local_contrast, big, noise, sector, inset, kappa, relative,
                bands, min_rays, floor, flank, free, free_min_frac, r_kn, tukey_c, sigma_floor,
                pixel):
    """One pass of the sub-pixel locator about (lcx, lcy) in the crop ``rel`` (frame -
    background, float32) with the background ``bgr``: the ray profiles, their edges, the
    mirror signature and the rim's Fresnel shift (``mirror_rim``, ``local_contrast``: 1 on, 0
    off, -1 where the rim shows a mirror's signature and the ball is ``big``), the clean rays,
    the robust circle fit (free radius when ``free`` and at least ``free_min_frac`` of the
    ``n`` rays are kept, else the known radius ``r_kn``) and, with ``pixel``, the pixel-level
    fit of that circle; the kernels one after another.

    Returns status (0 fitted; 1-3
    :func:`~rollfric.locate.kernels.selection.select_rays`'s failures; 4 the robust fit
    failed), the circle (cx, cy, r), whether its radius was free, the inliers, their median
    residual and weighted rms residual, the pixel fit's cx, cy, r and centre error (NaN
    without ``pixel``), the inlier rays, whether the Fresnel shift was applied, each ray's
    shift and the inlier rays' median edge spread (px; NaN on failure)."""
    prof = profiles(rel, lcx, lcy, s0, ds, ns, n)
    s_edge, con, out_sd, valid, a_lv, b_lv, spread = ray_edges(
        prof, s0, ds, r, w, ne, nl, ksm, min_rel, rim_levels, wide_out, bgr, lcx, lcy)
    mr = mirror_rim
    lc = local_contrast
    if mr < 0 or lc < 0:
        sig = big and mirror_signature(con, valid, out_sd, b_lv, noise, sector)
        if mr < 0:
            mr = 1 if sig else 0
        if lc < 0:
            lc = 1 if sig else 0
    rim = mr == 1
    if rim:
        rim_shift = fresnel_shift(s_edge, valid, a_lv, b_lv, bgr, lcx, lcy, inset, kappa, 1.5,
                                  relative)
    else:
        rim_shift = np.zeros(0)
    status, xs, ys, idx = select_rays(s_edge, con, out_sd, valid, lcx, lcy, bands, min_rays,
                                      noise, floor, lc == 1 and big, b_lv, flank)
    nan = np.nan
    if status:
        return (status, nan, nan, nan, False, 0, nan, nan, nan, nan, nan, nan,
                np.empty(0, np.int64), rim, rim_shift, nan)
    free_p = free and len(xs) >= free_min_frac * n
    fcx, fcy, fr_, wts, res = fit_circle(xs, ys, r_kn, free_p, tukey_c, sigma_floor)
    n_in, med_res, rms = fit_stats(wts, res)
    if free_p and (n_in < free_min_frac * n or not np.isfinite(fcx)):
        free_p = False
        fcx, fcy, fr_, wts, res = fit_circle(xs, ys, r_kn, False, tukey_c, sigma_floor)
        n_in, med_res, rms = fit_stats(wts, res)
    inl = idx[wts > 0]
    if n_in < min_rays or not np.isfinite(fcx):
        return (4, fcx, fcy, fr_, free_p, n_in, med_res, rms, nan, nan, nan, nan, inl, rim,
                rim_shift, nan)
    pcx = pcy = pr = psig = nan
    if pixel:
        ray_ok = np.zeros(n, np.bool_)
        ray_ok[inl] = True
        pcx, pcy, pr, psig, _ = pixel_fit(rel, bgr, fcx, fcy, fr_ if free_p else r_kn, free_p,
                                          ray_ok, a_lv, b_lv, inset, 5)
    # the inlier rays' median edge spread: a sharp area-sampled step's is about 0.55 px
    sp = spread[inl]
    sp = sp[np.isfinite(sp)]
    spread_med = np.median(sp) if len(sp) > 0 else nan
    return (0, fcx, fcy, fr_, free_p, n_in, med_res, rms, pcx, pcy, pr, psig, inl, rim,
            rim_shift, spread_med)
