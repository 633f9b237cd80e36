"""The sub-pixel locator's pass as one kernel call (rollfric.locate.kernels.passes.locate_pass_raw,
issue 16)
gives the answers of the pass made kernel by kernel from Python (``_reference_guess`` below,
the code before the fold, kept as the oracle), to the bit: on analytically drawn balls (8 and
16 bit, small balls of a known radius, noise, spots and shadows), a mirror ball's rim, partial
arcs, a pinhole's stretched silhouette, balls at and beyond the frame's edge, frames without a
ball, rendered frames (orthographic and in perspective) and whole measured tracks."""

from __future__ import annotations

import dataclasses
import math
import struct

import cv2
import numba
import numpy as np
import pytest

from rollfric.locate import subpixel
from rollfric.locate.kernels.circle import fit_circle as _fit_circle
from rollfric.locate.kernels.circle import fit_stats as _fit_stats
from rollfric.locate.kernels.circle import solve3 as _solve3
from rollfric.locate.kernels.edges import ray_edges as _edges
from rollfric.locate.kernels.mirror import fresnel_shift as _mirror_rim
from rollfric.locate.kernels.mirror import mirror_signature as _mirror_signature
from rollfric.locate.kernels.pixelfit import _edge_cdf
from rollfric.locate.kernels.pixelfit import pixel_fit as _pixel_fit
from rollfric.locate.kernels.rays import profiles as _profiles
from rollfric.locate.kernels.selection import select_rays as _select
from rollfric.locate.location import Location
from rollfric.locate.pinhole import silhouette_stretch
from rollfric.locate.pinhole import squeeze as _squeeze
from rollfric.locate.regions import _crop, _full_scale
from rollfric.locate.subpixel import (
    AUTO_MIRROR,
    MIRROR,
    NO_MIRROR,
    SubpixelOptions,
    _arc_leverage,
    _fresnel_kappa,
    _n_rays,
    _shift_circle,
    locate_subpixel,
    subpixel_locator,
)
from synth.drawn.frames import Scene, disk_coverage, make_frames

_SELECT_FAIL = {
    1: "too few edge points (ball missing, occluded or at the border)",
    2: "ball edge contrast below the noise",
    3: "too few clean edge points (shadows or occlusion)",
}


def _reference_guess(frame, background, r_px, guess, search, opts, noise, partial,
                     rk) -> Location:
    """rollfric.locate.subpixel._locate_guess as it was before its passes were folded into one
    kernel call (main at 4b9d5a4): the kernels called one by one, the lines between in
    Python."""
    r_kn, r_kn_sig = rk
    w = search if search is not None else 0.3 * r_px + 2.0
    w = max(w, 1.5)
    w0 = w
    h, wd = frame.shape
    cx, cy = float(guess[0]), float(guess[1])
    if not (-r_px < cx < wd - 1 + r_px and -r_px < cy < h - 1 + r_px):
        return Location.missing("predicted centre outside the frame")
    r = float(r_px)
    edge_half = min(opts.edge_half, max(1.5, 0.25 * r_px))
    level_len = min(opts.level_len, max(0.75, 0.2 * r_px))
    n_coarse = _n_rays(r_px)
    n_fine = max(n_coarse, _n_rays(r_px, opts.ray_spacing, opts.max_rays))
    fine = False
    free = opts.radius == "free" or (opts.radius == "auto" and r_px >= 12)
    loc = Location.missing("no edge found")
    for p in range(opts.passes + 1):
        n = n_fine if fine else n_coarse
        ds = opts.ds if w <= 3.0 else 2 * opts.ds
        ne = max(2, int(round(edge_half / ds)))
        nl = max(2, int(round(level_len / ds)))
        m = (ne + 2 * nl + 3) * ds
        s0 = max(0.5, r - w - m)
        ns = int(math.ceil((r + w + m - s0) / ds)) + 1
        stretch = None
        if opts.pinhole is not None:
            ux, uy, kst = silhouette_stretch((cx, cy), r_px, opts.pinhole)
            stretch = ((ux, uy), kst) if kst > 1.0 + 1e-6 else None
        grow = stretch[1] if stretch is not None else 1.0
        half = int(math.ceil(grow * (s0 + ns * ds))) + 2
        x0, y0 = int(math.floor(cx)) - half, int(math.floor(cy)) - half
        fr, x0c, y0c = _crop(frame, x0, y0, x0 + 2 * half + 2, y0 + 2 * half + 2)
        if fr is None:
            return Location.missing("ball outside the frame")
        bg = background[y0c:y0c + fr.shape[0], x0c:x0c + fr.shape[1]]
        rel = cv2.subtract(fr, bg, dtype=cv2.CV_32F)
        bgr = bg.astype(np.float32)
        lcx, lcy = cx - x0c, cy - y0c
        if stretch is not None:
            rel = _squeeze(rel, (lcx, lcy), *stretch)
            bgr = _squeeze(bgr, (lcx, lcy), *stretch)
        prof = _reference_profiles(rel, lcx, lcy, s0, ds, ns, n)
        s_edge, con, out_sd, valid, a_lv, b_lv, spread = _edges(
            prof, s0, ds, r, w, ne, nl, opts.level_smooth, opts.min_contrast_rel,
            opts.rim_levels, opts.sharp_excess if opts.sharp_rays and r_px >= 12 and w <= 3.0
            else 0.0, bgr, lcx, lcy)
        rim_shift = None
        mirror = (opts.mirror_rim, opts.local_contrast)
        if None in mirror:
            sig = bool(r_px >= 12 and _mirror_signature(
                con, valid, out_sd, b_lv, -1.0 if noise is None else float(noise),
                opts.mirror_sector))
            mirror = tuple(sig if m is None else bool(m) for m in mirror)
        if mirror[0]:
            inset = (ne + 0.5 * nl + 1) * ds
            kappa = _fresnel_kappa(round(r_px, 1), inset, opts.steel_eta, opts.steel_k)
            rim_shift = _mirror_rim(s_edge, valid, a_lv, b_lv, bgr, lcx, lcy,
                                    inset, kappa, 1.5, opts.mirror_relative)
        status, xs, ys, idx = _select(s_edge, con, out_sd, valid, lcx, lcy,
                                      opts.contrast_bands, opts.min_rays,
                                      -1.0 if noise is None else float(noise),
                                      0.004 * _full_scale(frame.dtype),
                                      mirror[1] and r_px >= 12, b_lv,
                                      int(round(opts.mirror_flank / 360.0 * n)))
        if status:
            return Location.missing(_SELECT_FAIL[status])
        free_p = free and len(xs) >= opts.free_min_frac * n
        fcx, fcy, fr_, wts, res = _fit_circle(xs, ys, r_kn, free_p, opts.tukey_c,
                                              opts.sigma_floor)
        n_in, med_res, rms = _fit_stats(wts, res)
        if free_p and (n_in < opts.free_min_frac * n or not math.isfinite(fcx)):
            free_p = False
            fcx, fcy, fr_, wts, res = _fit_circle(xs, ys, r_kn, False, opts.tukey_c,
                                                  opts.sigma_floor)
            n_in, med_res, rms = _fit_stats(wts, res)
        if n_in < opts.min_rays or not math.isfinite(fcx):
            return Location.missing("robust circle fit failed")
        r_seen = fr_ if free_p else r_kn + med_res
        if abs(r_seen - r_px) > opts.max_radius_dev * r_px:
            return Location.missing(f"the ball's edge lies on a circle of {r_seen:.2f} px "
                                    f"radius, not {r_px:.2f} px")
        sigma = rms * math.sqrt(2.0 / n_in)
        inl = idx[wts > 0]
        if fine and opts.pixel_fit:
            ray_ok = np.zeros(n, np.bool_)
            ray_ok[inl] = True
            pcx, pcy, pr, psig, npix = _reference_pixel_fit(rel, bgr, fcx, fcy,
                                                            fr_ if free_p else r_kn, free_p,
                                                            ray_ok, a_lv, b_lv,
                                                            (ne + 0.5 * nl + 1) * ds, 5)
            if math.isfinite(pcx) and math.hypot(pcx - fcx, pcy - fcy) < 0.5:
                if rim_shift is not None:
                    pcx, pcy, pr = _shift_circle(pcx, pcy, pr, inl, n, rim_shift[inl], free_p)
                fcx, fcy, sigma = pcx, pcy, psig
                if free_p:
                    r_seen = pr
        if not free_p:
            sigma = math.hypot(sigma, _arc_leverage(inl, n) * r_kn_sig * r_kn)
        if stretch is not None:
            (ux, uy), kst = stretch
            along = (kst - 1.0) * ((fcx - lcx) * ux + (fcy - lcy) * uy)
            fcx, fcy = fcx + along * ux, fcy + along * uy
        shift = math.hypot(fcx - lcx, fcy - lcy)
        cx, cy, r = fcx + x0c, fcy + y0c, float(r_seen)
        frac = n_in / n
        need = opts.min_inlier_frac if free_p or not partial else min(opts.min_inlier_frac,
                                                                        opts.min_arc_frac)
        if frac < need:
            ok, why = False, f"only {100 * frac:.0f} % of the edge fits a circle"
        elif not sigma <= opts.max_sigma:
            ok, why = False, f"centre uncertain ({sigma:.2f} px)"
        elif math.hypot(cx - guess[0], cy - guess[1]) > w0 + 1.0:
            ok, why = False, "the fitted circle lies outside the searched band"
        else:
            ok, why = True, ""
        loc = Location(x=cx, y=cy, r=r, found=ok, sigma=sigma, inlier_frac=frac, reason=why,
                       radius_free=bool(free_p))
        if fine:
            break
        w = min(w, max(1.5, 2.0 * shift + 1.0))
        if shift < 0.1 or p >= opts.passes - 1:
            fine = True
    return loc


@numba.njit
def _reference_profiles(rel, cx, cy, s0, ds, ns, n):
    """rollfric.locate.kernels.rays.profiles before its rays inside the crop went untested (main at
    b37681f), kept as the oracle."""
    h, w = rel.shape
    prof = np.empty((n, ns), np.float64)
    for i in range(n):
        phi = (i + 0.5) * (2.0 * np.pi / n)
        c, sn = np.cos(phi), np.sin(phi)
        for j in range(ns):
            t = s0 + j * ds
            x = cx + c * t
            y = cy + sn * t
            if x < 0.0 or y < 0.0 or x > w - 1 or y > h - 1:
                prof[i, j] = np.nan
                continue
            ix = min(int(x), w - 2)
            iy = min(int(y), h - 2)
            fx = x - ix
            fy = y - iy
            prof[i, j] = ((1 - fy) * ((1 - fx) * rel[iy, ix] + fx * rel[iy, ix + 1])
                          + fy * ((1 - fx) * rel[iy + 1, ix] + fx * rel[iy + 1, ix + 1]))
    return prof


@numba.njit
def _reference_pixel_fit(rel, bgr, cx, cy, r, free, ray_ok, a_lv, b_lv, inset, iters):
    """rollfric.locate.kernels.pixelfit.pixel_fit before its second pass reused the first's pixels
    (main
    at 2a10b8e), kept as the oracle."""
    h, w = rel.shape
    n = len(ray_ok)
    npar = 3 if free else 2
    sig = np.nan
    npix = 0
    ray_ok = ray_ok.copy()
    ray_ss = np.zeros(n)
    ray_n = np.zeros(n)
    for it in range(iters):
        # J^T J's upper triangle and J^T r as scalars (gg[p] gg[q] is gg[q] gg[p] to the bit:
        # the lower triangle is its mirror)
        j00 = j01 = j02 = j11 = j12 = j22 = 0.0
        r0 = r1 = r2 = 0.0
        ss = 0.0
        npix = 0
        ray_ss[:] = 0.0
        ray_n[:] = 0.0
        x0 = max(0, int(cx - r - 2))
        x1 = min(w - 1, int(cx + r + 3))
        y0 = max(0, int(cy - r - 2))
        y1 = min(h - 1, int(cy + r + 3))
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
                phi = np.arctan2(dy, dx)
                if phi < 0:
                    phi += 2 * np.pi
                k = int(phi / (2 * np.pi / n)) % n
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
                continue
        if free:
            st = _solve3(jtj, jtr)
            s0, s1, s2 = st[0], st[1], st[2]
        else:
            det = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
            if det == 0.0:
                return np.nan, np.nan, np.nan, np.nan, npix
            s0 = (jtj[1, 1] * jtr[0] - jtj[0, 1] * jtr[1]) / det
            s1 = (-jtj[1, 0] * jtr[0] + jtj[0, 0] * jtr[1]) / det
            s2 = 0.0
        if not (np.isfinite(s0) and np.isfinite(s1) and np.isfinite(s2)):
            return np.nan, np.nan, np.nan, np.nan, npix
        cx += s0
        cy += s1
        r += s2
        # centre standard error from the residual variance and the 2 x 2 block of J^T J
        var = ss / max(npix - npar, 1)
        det2 = jtj[0, 0] * jtj[1, 1] - jtj[0, 1] * jtj[1, 0]
        sig = np.sqrt(var * (jtj[0, 0] + jtj[1, 1]) / det2) if det2 > 0 else np.nan
        if abs(s0) + abs(s1) + abs(s2) < 1e-4:
            break
    return cx, cy, r, sig, npix


def _bits(v):
    """A value as compared: floats by their bits (every NaN alike), the rest as they are."""
    if isinstance(v, float):
        return "nan" if math.isnan(v) else struct.pack("<d", v)
    return v


def _same_location(a: Location, b: Location) -> bool:
    return all(_bits(getattr(a, f.name)) == _bits(getattr(b, f.name))
               and type(getattr(a, f.name)) is type(getattr(b, f.name))
               for f in dataclasses.fields(Location))


class _Count:
    """How often the pass took which way: the cases below must reach each."""

    def __init__(self):
        self.found = self.missing = 0
        self.reasons = set()


def _check(monkeypatch, count, fn, *args, **kwargs):
    """fn(*args, **kwargs) with the folded pass and with the reference: the same Location to
    the bit."""
    new = fn(*args, **kwargs)
    with monkeypatch.context() as m:
        m.setattr(subpixel, "_locate_guess", _reference_guess)
        old = fn(*args, **kwargs)
    assert _same_location(new, old), (new, old)
    if count is not None:
        if new.found:
            count.found += 1
        else:
            count.missing += 1
            count.reasons.add(" ".join(new.reason.split()[:3]))
    return new


def _guesses(rng, cx, cy, k=3, spread=2.5):
    return [(cx + rng.uniform(-spread, spread), cy + rng.uniform(-spread, spread))
            for _ in range(k)]


@pytest.mark.parametrize("bit_depth", [8, 16])
@pytest.mark.parametrize("r_px,noise,shadow", [(37.23, 0.0, 0.0), (37.23, 3.0, 0.5),
                                               (47.2, 2.0, 0.0), (18.6, 2.0, 0.3),
                                               (5.88, 1.0, 0.0), (9.0, 0.0, 0.0)])
def test_drawn_balls_to_the_bit(monkeypatch, bit_depth, r_px, noise, shadow):
    scene = Scene(width=240, height=200, center=(120.0, 100.0 - 598.0), R_px=635.14,
                  r_px=r_px, bit_depth=bit_depth, noise=noise * (257 if bit_depth == 16 else 1),
                  shadow=shadow)
    rng = np.random.default_rng(int(10 * r_px) + bit_depth)
    centres = [(120 + rng.uniform(-20, 20), 100 + rng.uniform(-15, 15)) for _ in range(4)]
    bg, frames = make_frames(scene, centres, seed=int(r_px))
    count = _Count()
    for f, (cx, cy) in zip(frames, centres, strict=True):
        for g in _guesses(rng, cx, cy):
            _check(monkeypatch, count, locate_subpixel, f, bg, r_px, guess=g)
            # the tracker's call: a partial arc's known radius and its uncertainty
            _check(monkeypatch, count, subpixel_locator, f, bg, r_px, g, scene.center,
                   r_known=r_px * 1.01, r_known_sigma=0.004)
        # no guess: the full search's candidates
        _check(monkeypatch, count, subpixel_locator, f, bg, r_px, None, scene.center)
        # a known radius, and one free, whatever the size
        for radius in ("known", "free"):
            _check(monkeypatch, count, locate_subpixel, f, bg, r_px, guess=(cx + 1.0, cy - 1.0),
                   opts=SubpixelOptions(radius=radius))
    assert count.found > 0


def test_balls_at_and_beyond_the_frame_edge_and_frames_without_a_ball(monkeypatch):
    r_px = 37.23
    scene = Scene(width=240, height=200, center=(120.0, 100.0 - 598.0), r_px=r_px, noise=2.0)
    centres = [(3.0, 100.0), (-20.0, 90.0), (236.5, 50.0), (260.0, 120.0), (120.0, -30.0),
               (120.4, 197.7), (10.0, 12.0), (None, None)]
    bg, frames = make_frames(scene, centres, seed=5)
    rng = np.random.default_rng(7)
    count = _Count()
    for f, (cx, cy) in zip(frames, centres, strict=True):
        near = [(cx, cy)] if cx is not None else [(120.0, 100.0), (5.0, 5.0), (250.0, 220.0),
                                                  (-40.0, 100.0)]
        for x, y in near:
            for g in [(x, y)] + _guesses(rng, x, y, 2, 4.0):
                _check(monkeypatch, count, locate_subpixel, f, bg, r_px, guess=g)
                _check(monkeypatch, count, subpixel_locator, f, bg, r_px, g, scene.center)
    assert count.found > 0 and count.missing > 0
    assert len(count.reasons) >= 3, count.reasons  # several ways of not finding it


def _shadow_frame(cx, cy, shadow_frac, r=37.2, noise=2.0, seed=0):
    """A dark ball whose rim lies ``shadow_frac`` in a shadow of its own level
    (tests/test_measure_partial.py)."""
    h, w = 200, 240
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    t = r * math.cos(math.pi * shadow_frac)
    shade = np.clip(((xx - cx) + (yy - cy)) / math.sqrt(2) - t + 0.5, 0.0, 1.0)
    bg = 120.0 * (1 - shade) + 20.0 * shade
    cov = disk_coverage(h, w, cx, cy, r)
    img = bg * (1 - cov) + 20.0 * cov
    rng = np.random.default_rng(seed)
    f = np.clip(np.rint(img + rng.normal(0, noise, img.shape)), 0, 255).astype(np.uint8)
    return f, np.clip(np.rint(bg), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("shadow_frac", [0.33, 0.5, 0.6, 0.75, 0.85])
def test_partial_arcs_to_the_bit(monkeypatch, shadow_frac):
    rng = np.random.default_rng(int(100 * shadow_frac))
    count = _Count()
    for k in range(3):
        cx, cy = rng.uniform(100, 140), rng.uniform(85, 115)
        f, bg = _shadow_frame(cx, cy, shadow_frac, seed=k)
        for g in _guesses(rng, cx, cy, 2, 2.0):
            _check(monkeypatch, count, locate_subpixel, f, bg, 37.2, guess=g)
            _check(monkeypatch, count, locate_subpixel, f, bg, 37.2, guess=g, r_known=37.0,
                   r_known_sigma=0.01, noise=2.0)
        # a new start: the most disk-like candidate's partial arc
        _check(monkeypatch, count, subpixel_locator, f, bg, 37.2, None, (120.0, -500.0))
    assert count.found + count.missing == 3 * 5


@pytest.mark.parametrize("opts", [None, AUTO_MIRROR, MIRROR, NO_MIRROR,
                                  SubpixelOptions(mirror_rim=True, local_contrast=None),
                                  SubpixelOptions(pixel_fit=False, passes=1)])
@pytest.mark.parametrize("pixel_mm", [0.1343, 0.2686])
def test_mirror_balls_to_the_bit(monkeypatch, opts, pixel_mm):
    from synth.drawn.mirror import MirrorScene, make_mirror_frames

    rng = np.random.default_rng(3)
    count = _Count()
    kw = {} if opts is None else {"opts": opts}
    for i in range(3):
        th = rng.uniform(-0.3, 0.3)
        tx, ty = 100 + rng.uniform(-0.5, 0.5), 100 + rng.uniform(-0.5, 0.5)
        lpx = (85.3 - 5.0) / pixel_mm
        sc = MirrorScene(width=200, height=200, pixel_mm=pixel_mm, noise=2.0,
                         center=(tx - lpx * math.sin(th), ty - lpx * math.cos(th)))
        bg, (f,) = make_mirror_frames(sc, [(tx, ty)], seed=i)
        for g in _guesses(rng, tx, ty, 2, 1.5):
            _check(monkeypatch, count, locate_subpixel, f, bg, sc.r_px, guess=g, **kw)
    assert count.found > 0


def _ellipse_frame(c, r_px, pinhole, size=200, noise=2.0, seed=0, chord=None):
    """A dark ball's silhouette stretched as a pinhole stretches it about ``c``
    (:func:`silhouette_stretch`: axes k r_px along u and r_px across), 8 x 8 samples a pixel,
    on a bright backdrop (below row ``chord`` as dark as the ball)."""
    ux, uy, k = silhouette_stretch(c, r_px, pinhole)
    ss = 8
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    yy, xx = np.mgrid[0:size, 0:size].astype(float)
    dx = xx[..., None, None] + sub[None, None, None, :] - c[0]
    dy = yy[..., None, None] + sub[None, None, :, None] - c[1]
    along, across = dx * ux + dy * uy, -dx * uy + dy * ux
    cov = ((along / (k * r_px)) ** 2 + (across / r_px) ** 2 <= 1.0).mean(axis=(2, 3))
    bg = 200.0 + 12.0 * (xx / size - 0.5)
    if chord is not None:
        bg = np.where(yy > chord, 30.0, bg)
    img = bg * (1 - cov) + 30.0 * cov
    rng = np.random.default_rng(seed)
    f = np.clip(np.rint(img + rng.normal(0, noise, img.shape)), 0, 255).astype(np.uint8)
    return f, np.clip(np.rint(bg), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("focal,chord", [(3723.0, None), (1489.0, None), (1489.0, 118.0)])
def test_a_pinhole_s_stretched_silhouette_to_the_bit(monkeypatch, focal, chord):
    pp = (100.0, -500.0)
    opts = SubpixelOptions(pinhole=(*pp, focal))
    rng = np.random.default_rng(int(focal))
    count = _Count()
    for i in range(3):
        c = (100 + rng.uniform(-3, 3), 100 + rng.uniform(-3, 3))
        f, bg = _ellipse_frame(c, 37.23, opts.pinhole, seed=i, chord=chord)
        for g in _guesses(rng, *c, 2, 1.5):
            new = _check(monkeypatch, count, locate_subpixel, f, bg, 37.23, guess=g, opts=opts)
            if new.found:  # the stretch was undone: the ellipse's centre
                assert math.hypot(new.x - c[0], new.y - c[1]) < 0.1
    assert count.found > 0


def test_frames_of_other_types_go_through_opencv_to_the_bit(monkeypatch):
    # float frames (and a uint8 frame beside a float background) take OpenCV's subtraction
    scene = Scene(width=200, height=200, center=(100.0, 100.0 - 598.0), noise=2.0)
    bg, (f,) = make_frames(scene, [(101.3, 99.2)], seed=2)
    for fr, b in ((f.astype(np.float32), bg.astype(np.float32)), (f, bg.astype(np.float32)),
                  (f.astype(np.float64), bg.astype(np.float64))):
        loc = _check(monkeypatch, None, locate_subpixel, fr, b, 37.23, guess=(102.0, 98.0))
        assert loc.found


def _same_frame(a, b):
    return list(a.columns) == list(b.columns) and all(
        [_bits(float(x)) if isinstance(x, float | np.floating) else x for x in a[k]]
        == [_bits(float(x)) if isinstance(x, float | np.floating) else x for x in b[k]]
        for k in a.columns)


@pytest.mark.parametrize("kw", [{"noise": 1.0, "missing": (5, 6, 40), "seed": 2},
                                {"bit_depth": 16, "noise": 2.0, "ball_mm": 3.0, "seed": 4}])
def test_measured_tracks_to_the_bit(monkeypatch, kw):
    from measure_data import MemorySource, make_recording

    from rollfric import measurement as track

    rec = make_recording(240, mu=0.01, theta0=0.5, fps=200.0, **kw)

    def run():
        df, info, res = track.measure(MemorySource(rec.frames), rec.setup, rec.background)
        return df, res

    (df_new, r_new) = run()
    with monkeypatch.context() as m:
        m.setattr(subpixel, "_locate_guess", _reference_guess)
        (df_old, r_old) = run()
    assert df_new["found"].sum() > 160  # most frames located (and so compared)
    assert _same_frame(df_new, df_old)
    assert _bits(float(r_new.mu)) == _bits(float(r_old.mu))


def test_rendered_frames_to_the_bit(monkeypatch, tmp_path):
    # synth's renders: the thesis camera (orthographic) and one in perspective at 0.3 m, whose
    # ball shows a partial arc over the bore's edge and a stretched silhouette
    import os

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    import sim
    import synth

    traj = sim.simulate(sim.Scenario(theta0=math.radians(20.0), duration=0.004))
    count = _Count()
    for name, cam in (("ortho", synth.CameraModel()),
                      ("persp", synth.CameraModel(projection="perspective", working_distance=0.3,
                                                  principal_px=(639.5, 511.5)))):
        rec = synth.open_recording(synth.render(traj, tmp_path / f"{name}.zarr",
                                                scene=synth.SceneConfig(camera=cam),
                                                sensor=synth.noise_preset("realistic"), seed=0,
                                                workers=1))
        truth = rec.truth[["sil_x_px", "sil_y_px"]].to_numpy()
        r_px = 5e-3 / 0.1343e-3
        opts = [SubpixelOptions()]
        if name == "persp":
            opts.append(SubpixelOptions(pinhole=(639.5, 511.5, 0.3 / 0.1343e-3)))
        bg = rec.background
        for i in range(len(rec)):
            f = rec.frames[i]
            g = (truth[i, 0] + 0.7, truth[i, 1] - 0.4)
            for o in opts:
                _check(monkeypatch, count, locate_subpixel, f, bg, r_px, guess=g, opts=o)
            _check(monkeypatch, count, subpixel_locator, f, bg, r_px, None, (640.0, 380.0))
    assert count.found > 0


@pytest.mark.parametrize("seed", range(4))
def test_the_pixel_fit_s_second_pass_reuses_the_first_s_pixels_to_the_bit(seed):
    # drawn balls (shadows and spots: rays whose pixels do not fit and are dropped), circles
    # started off the ball's, free and known radius, random rays left out, crops cut by the
    # frame's edge
    rng = np.random.default_rng(seed)
    scene = Scene(width=160, height=140, center=(80.0, 70.0 - 598.0), r_px=37.23, noise=2.0,
                  shadow=0.5 * seed / 3)
    cases = 0
    for k in range(12):
        cx, cy = 80 + rng.uniform(-30, 30), 70 + rng.uniform(-25, 25)
        bg, (f,) = make_frames(scene, [(cx, cy)], seed=seed * 100 + k)
        rel = cv2.subtract(f, bg, dtype=cv2.CV_32F)
        bgr = bg.astype(np.float32)
        n = int(rng.choice([94, 234]))
        a_lv = np.full(n, -0.66 * 255) + rng.normal(0, 2, n)
        b_lv = rng.normal(0, 1, n)
        a_lv[rng.integers(0, n, 6)] += 60.0  # rays whose levels are off: their pixels misfit
        for free in (True, False):
            ray_ok = rng.random(n) > rng.uniform(0.0, 0.6)
            args = (rel, bgr, cx + rng.uniform(-0.6, 0.6), cy + rng.uniform(-0.6, 0.6),
                    37.23 * rng.uniform(0.98, 1.02), free, ray_ok, a_lv, b_lv, 3.5, 5)
            new, old = _pixel_fit(*args), _reference_pixel_fit(*args)
            assert [_bits(float(v)) for v in new] == [_bits(float(v)) for v in old], (new, old)
            cases += 1
    assert cases == 24


@pytest.mark.parametrize("seed", range(3))
def test_the_ray_profiles_to_the_bit(seed):
    # rays wholly inside the crop (no test a sample) and rays leaving it (NaN outside), centres
    # inside, near and beyond the crop's edges, sample steps that are powers of two and not
    rng = np.random.default_rng(seed)
    for _ in range(60):
        h, w = rng.integers(20, 120, 2)
        rel = rng.normal(0, 40, (h, w)).astype(np.float32)
        cx, cy = rng.uniform(-10, w + 10), rng.uniform(-10, h + 10)
        if rng.random() < 0.5:
            cx, cy = rng.uniform(0.3, 0.7) * w, rng.uniform(0.3, 0.7) * h
        args = (cx, cy, rng.uniform(0.5, 0.4 * min(h, w)), float(rng.choice([0.25, 0.5, 0.3,
                                                                              0.37])),
                int(rng.integers(1, 80)), int(rng.choice([48, 94, 234, 57])))
        new, old = _profiles(rel, *args), _reference_profiles(rel, *args)
        assert new.shape == old.shape
        assert np.array_equal(new.view(np.int64), old.view(np.int64))


@numba.njit
def _order_statistics(x, q):
    return np.sort(x)[q], np.partition(x, q)[q]


def test_an_order_statistic_by_partition_is_the_sorted_array_s():
    # what the edges' polarity threshold, their contrast reference and the rim's mirror
    # sectors rely on since they select their quantile instead of sorting (finite values)
    rng = np.random.default_rng(11)
    for _ in range(500):
        m = int(rng.integers(1, 300))
        x = rng.normal(0, 50, m)
        if rng.random() < 0.5:
            x = np.round(x / 7.0) * 7.0  # ties
        for frac in (0.9, 0.75, 0.1, 0.0, 1.0):
            q = int(frac * (m - 1))
            by_sort, by_partition = _order_statistics(x.copy(), q)
            assert _bits(float(by_sort)) == _bits(float(by_partition))
