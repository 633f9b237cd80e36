"""The sub-pixel locator (beyond the thesis, the default): ``locate_subpixel``.

Sub-pixel edge points of the ball silhouette along rays from the current centre (the integral
of the normalised edge profile: exact for an area-sampled step), a robust geometric circle fit
(Tukey-weighted, known or free radius) that drops rays whose edge contrast or background is
spoiled (shadows, specular spots, contact with the trough, occluders), then a Gauss-Newton fit
of an exact area-coverage edge model to the edge pixels of the kept rays (contrast taken
against the background pixel by pixel), and a per-frame quality: the estimated standard error
of the centre in pixels. The numba kernels are in :mod:`rollfric.locate.kernels`.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import cv2
import numpy as np

from rollfric.locate.kernels.passes import locate_pass, locate_pass_raw
from rollfric.locate.location import Location
from rollfric.locate.pinhole import silhouette_stretch, squeeze, unsqueeze
from rollfric.locate.regions import _crop, _full_scale
from rollfric.locate.search import coarse_candidates


@dataclasses.dataclass(frozen=True)
class SubpixelOptions:
    """Tuning of :func:`locate_subpixel` (defaults suit balls of 3-60 px radius)."""

    radius: str = "auto"  # "free": fit the radius too; "known": use r_px; "auto": free when
    # r_px >= 12 (enough edge points to afford it), known below
    ds: float = 0.25  # sample step along a ray (px)
    edge_half: float = 1.5  # half-width of the window integrated across the edge (px)
    level_len: float = 2.0  # length of the inside/outside level windows (px)
    min_rays: int = 12
    min_inlier_frac: float = 0.35
    max_radius_dev: float = 0.15  # fitted radius within this fraction of r_px
    tukey_c: float = 4.685
    sigma_floor: float = 0.03  # px: residual scale floor of the robust fit
    passes: int = 3
    ray_spacing: float = 1.0  # px between rays along the rim
    max_rays: int = 360
    pixel_fit: bool = True  # final Gauss-Newton fit on the edge pixels themselves
    graded_spread: float = 0.75  # px: an edge whose rays' median spread exceeds this is
    # graded, not a step (a backlit ball's dark limb shading into its inside: 0.79-0.81 px on
    # a real shadowgraph; a sharp area-sampled step 0.55, blurred by a 0.5 px psf 0.70-0.73);
    # its fine pass is redone with the edge window widened to graded_window x the spread and
    # without the pixel fit, whose sharp-step model locks such an edge to the pixel grid
    graded_window: float = 4.0
    graded_min_cnr: float = 25.0  # the edge's contrast to the noise at least this for the
    # spread to tell a graded edge: noise widens a step's measured spread (a 100 DN step under
    # 15 DN of noise reads as graded), and a wide window without the pixel fit is then worse
    level_smooth: int = 3  # levels averaged over 2 k + 1 neighbouring rays
    contrast_bands: tuple[float, ...] = (0.15, 0.3, 0.5)  # |contrast - median| / median kept
    min_contrast_rel: float = 0.3  # rays with a step below this x the strong rays' carry no edge
    min_arc_frac: float = 0.2  # fraction of the rim that must fit (known radius, partial arc)
    free_min_frac: float = 0.45  # free radius only when at least this fraction of the rim fits
    radius_sigma: float = 0.003  # relative uncertainty of r_px (centre error on partial arcs)
    max_sigma: float = 0.5  # px: a centre less certain than this is reported not found
    # a steel ball's rim, a curved mirror (docs/how/locator.md, "A steel ball's rim"); mirror_rim
    # and local_contrast are on by default where the rim shows a mirror's signature (None),
    # MIRROR turns them on everywhere:
    rim_levels: bool = True  # a ray's inside level is checked against its neighbours' (and
    # its own further in), not against one median: the rim mirrors bright and dark surroundings;
    # where the level further in has more contrast (a crescent of reflection narrower than the
    # level windows, a small ball), the level next to the edge is used
    sharp_rays: bool = True  # rays whose edge is much wider than the rim's sharpest are left
    # out (r_px >= 12): a rim that mirrors a narrow band of bright surroundings
    sharp_excess: float = 0.25  # px: how much wider than the rim's sharpest quarter
    mirror_rim: bool | None = None  # correct each ray's edge for the Fresnel rise at the rim
    mirror_relative: bool = True  # ... for the inside level above the rim's darkest only (its
    # variation along the rim; a matt ball's uniform level gets none); False: the whole level
    # (the radius then comes out as the sphere's on a mirror ball, a matt ball's too small)
    steel_eta: float = 2.9  # the ball's complex refractive index (steel, green)
    steel_k: float = 3.0
    local_contrast: bool | None = None  # the contrast band about the neighbouring rays'
    # contrast (r_px >= 12), not one median: a mirror ball's rim is bright where it mirrors
    # the backdrop
    # mirror_rim, local_contrast None: on where the rim shows a mirror's signature (a sector
    # of low and one of full contrast against the background, each >= mirror_sector of it;
    # the default, AUTO_MIRROR), off elsewhere; False: off
    mirror_sector: float = 0.25
    mirror_flank: float = 30.0  # deg: with local_contrast on, the full-contrast rays this close
    # to the low-contrast sector are left out (the rim's tapering crescent of mirrored backdrop)
    full_scale: float | None = None  # the camera's full scale, 2**bit_depth - 1 (DN), which
    # the search's and the edges' contrast floors are fractions of; None: the frame's word's
    # (255 or 65535), too high for a 12-bit camera's frames in 16-bit words
    pinhole: tuple | None = None  # (principal x, principal y, focal length) px of a pinhole
    # camera whose image plane is parallel to the ball's plane (rollfric.geometry.perspective): the
    # ball's silhouette is then an ellipse (:func:`silhouette_stretch`), fitted as one; None:
    # a circle (orthographic, or a camera far away)


# a new start's partial arc (locate_subpixel ``arcs``): the search's disk-likeness (ring
# correlation) of the candidate at least this; a quarter of the rendered ball's rim showing
# (perspective at 0.3 m) scores 0.35, a ball of half the setup's radius 0.11 (whose arc of a
# circle twice its size a partial fit then took)
ARC_MIN_DISK = 0.2

AUTO_MIRROR = SubpixelOptions(mirror_rim=None, local_contrast=None)
"""The sub-pixel locator's default options, named: the mirror-rim handling (``mirror_rim``,
``local_contrast``; relative Fresnel correction) on where a frame's rim shows a mirror's
signature and off elsewhere (a matt ball, pyrender's ball, a rim whose mirrored backdrop is
too short an arc): docs/how/locator.md, "A steel ball's rim"."""

NO_MIRROR = SubpixelOptions(mirror_rim=False, local_contrast=False, graded_spread=math.inf)
"""The sub-pixel locator's options without the mirror-rim handling (the default before it:
one contrast band about the rays' median, no Fresnel correction) and without the
graded-edge handling (``graded_spread``: a mirror rim that is not corrected is graded)."""

MIRROR = SubpixelOptions(mirror_rim=True, local_contrast=True, mirror_relative=False)
"""The sub-pixel locator's options for a polished steel ball whose rim mirrors its surroundings:
the Fresnel correction for the whole inside level, not only its part above the rim's darkest
(the default), so that the radius comes out as the sphere's (a matt ball's too large)."""


@functools.lru_cache(maxsize=64)
def _fresnel_kappa(r_px: float, depth: float, eta: float, k: float) -> float:
    """How far (px) the Fresnel rise at a mirror ball's rim moves the integral edge in, per
    unit of (inside level / contrast): the integral over the depth below the silhouette of
    F / F(depth) - 1 (where positive), F the unpolarised reflectance of a conductor of index
    eta + i k at the incidence a ball of radius r_px has there (orthographic view)."""
    d = np.linspace(0.0, depth, 4001)[1:]
    cos_i = np.sqrt(np.clip(1.0 - (1.0 - d / r_px) ** 2, 0.0, 1.0))
    n2 = complex(eta, k) ** 2
    root = np.sqrt(n2 - (1.0 - cos_i ** 2))
    f = 0.5 * (np.abs((cos_i - root) / (cos_i + root)) ** 2
               + np.abs((n2 * cos_i - root) / (n2 * cos_i + root)) ** 2)
    excess = np.clip(f / f[-1] - 1.0, 0.0, None)
    return float(np.sum(excess) * (d[1] - d[0]))


def _shift_circle(cx, cy, r, rays, n, shift, free):
    """(cx, cy, r) moved by the least-squares fit of dx cos + dy sin (+ dr) to the radial
    ``shift`` of rays ``rays`` (of n around the rim)."""
    if len(rays) < 3:
        return cx, cy, r
    phi = (rays + 0.5) * (2.0 * math.pi / n)
    cols = [np.cos(phi), np.sin(phi)] + ([np.ones_like(phi)] if free else [])
    sol = np.linalg.lstsq(np.column_stack(cols), shift, rcond=None)[0]
    return cx + sol[0], cy + sol[1], r + (sol[2] if free else 0.0)


def _n_rays(r_px: float, spacing: float = 2.5, most: int = 128) -> int:
    """Rays around a ball of radius r_px: about ``spacing`` px apart along the rim."""
    return int(min(most, max(48, round(2 * math.pi * r_px / spacing))))


def _arc_leverage(rays: np.ndarray, n: int) -> float:
    """|(N^T N)^-1 N^T 1| for the unit normals N of rays ``rays`` (of n around the rim): how
    far a known-radius fit's centre moves per pixel of radius error (0 for the full rim, about
    1.3 for half of it; large for a short arc)."""
    if len(rays) < 3:
        return math.inf
    phi = (rays + 0.5) * (2.0 * math.pi / n)
    c, s = np.cos(phi), np.sin(phi)
    m = np.array([[c @ c, c @ s], [c @ s, s @ s]])
    v = np.array([c.sum(), s.sum()])
    try:
        b = np.linalg.solve(m, v)
    except np.linalg.LinAlgError:
        return math.inf
    return float(math.hypot(b[0], b[1]))


_SELECT_FAIL = {
    1: "too few edge points (ball missing, occluded or at the border)",
    2: "ball edge contrast below the noise",
    3: "too few clean edge points (shadows or occlusion)",
}


def _edge_cnr(fr, bg, cx: float, cy: float, r: float) -> float:
    """The ball's contrast against the backdrop over the noise of the frame's difference from
    the background: the medians of the difference just inside the rim (0.55-0.85 r) and just
    outside it (r + 3 .. r + 8 px), over the outside ring's robust sd (MAD); inf without an
    outside ring in the crop or without noise."""
    rel = fr.astype(np.float32) - bg.astype(np.float32)
    yy, xx = np.ogrid[0:rel.shape[0], 0:rel.shape[1]]
    d = np.hypot(xx - cx, yy - cy)
    inner = rel[(d > 0.55 * r) & (d < 0.85 * r)]
    outer = rel[(d > r + 3.0) & (d < r + 8.0)]
    if inner.size == 0 or outer.size < 16:
        return math.inf
    mo = float(np.median(outer))
    noise = 1.4826 * float(np.median(np.abs(outer - mo)))
    contrast = abs(float(np.median(inner)) - mo)
    return contrast / noise if noise > 0 else math.inf


def locate_subpixel(frame: np.ndarray, background: np.ndarray, r_px: float, *,
                    guess: tuple[float, float] | None = None, search: float | None = None,
                    opts: SubpixelOptions = SubpixelOptions(),
                    noise: float | None = None, r_known: float | None = None,
                    r_known_sigma: float | None = None, arcs: bool = False) -> Location:
    """Sub-pixel centre of the ball of radius about ``r_px`` px.

    Without a guess, a full-frame search (:func:`coarse_candidates`) comes first; its candidates
    are fitted in turn, the most disk-like first, and the first the fit accepts is the answer.
    With ``arcs`` (a ball of 12 px and more), when no candidate shows most of a rim, the most
    disk-like candidate (if at least ``ARC_MIN_DISK``) is fitted once more as a partial arc of
    the known radius (a ball half over a region of its own level, whose cast shadow, a whole
    disk, would else be taken).

    Parameters
    ----------
    frame, background : numpy.ndarray or LazyFrame
        The frame and the background image (same size).
    r_px : float
        The ball's radius (px); also sets the search and the radius check.
    guess : tuple of float, optional
        Where the ball centre is expected (x, y px, from tracking).
    search : float, optional
        How far (px) the edge may be from the guessed circle (default 0.3 r + 2).
    opts : SubpixelOptions, optional
        Tuning.
    noise : float, optional
        Pixel noise (DN) used to reject low-contrast rays (default: estimated from the rays).
    r_known : float, optional
        The radius (px) a partial arc is fitted with (default ``r_px``; the tracker passes the
        ball's apparent radius calibrated from its full-rim frames).
    r_known_sigma : float, optional
        Its relative uncertainty (default ``opts.radius_sigma``), which adds the arc's leverage
        times it to the centre's sigma.
    arcs : bool, optional
        Without a guess: accept the most disk-like candidate's partial arc (at least
        ``opts.min_arc_frac`` of the rim) when no candidate's rim mostly fits.

    Returns
    -------
    Location
        The centre, radius, ``sigma`` and ``inlier_frac``; ``found`` False with a ``reason``
        when no candidate fits.
    """
    rk = (float(r_px) if r_known is None else float(r_known),
          opts.radius_sigma if r_known_sigma is None else float(r_known_sigma))
    if guess is None:
        cands = coarse_candidates(frame, background, r_px, full_scale=opts.full_scale)
        if not cands:
            return Location.missing("no ball-like change in the frame")
        # the most disk-like candidate that the fit accepts (a cast shadow may look more
        # disk-like than the ball; the fit checks the radius and the edge)
        first = None
        for cx, cy, _ in cands:
            # no prediction to check a partial arc against: the full search accepts only a
            # ball whose rim mostly fits (a cast shadow's arc would pass a partial-arc fit)
            loc = _locate_guess(frame, background, r_px, (cx, cy),
                                max(search or 0.0, 0.5 * r_px + 2), opts, noise, False, rk)
            if loc.found:
                return loc
            first = first or loc
        if arcs and r_px >= 12 and cands[0][2] >= ARC_MIN_DISK:
            # (not below 12 px: the 1.58 mm ball's arcs beside a harsh lamp's shadow came out
            # 0.3-0.9 px off at a stated 0.06-0.11 px; the shadow's edge pulls them)
            # the search ranks the ball first (its edge is where the ring votes) even where
            # only part of its rim has contrast; a cast shadow ranks lower but shows its whole
            # rim, and the strict pass above would take it in a later frame
            cx, cy, _ = cands[0]
            loc = _locate_guess(frame, background, r_px, (cx, cy),
                                max(search or 0.0, 0.5 * r_px + 2), opts, noise, True, rk)
            if loc.found:
                return loc
        return first
    return _locate_guess(frame, background, r_px, guess, search, opts, noise, True, rk)


def subpixel_locator(frame, background, r_px: float, guess: tuple[float, float] | None,
                     center: tuple[float, float], *, opts: SubpixelOptions | None = None,
                     search: float | None = None, r_known: float | None = None,
                     r_known_sigma: float | None = None) -> Location:
    """The :class:`rollfric.locate.Locator` ``"subpixel"``.

    :func:`locate_subpixel` in the region around ``guess`` (the edge within ``search`` px of the
    predicted circle), then over the whole frame when the ball is not found there.

    Parameters
    ----------
    frame, background : numpy.ndarray or LazyFrame
    r_px : float
        The ball's radius (px).
    guess : tuple of float or None
        The predicted centre (px); None searches the whole frame.
    center : tuple of float
        The cylinder axis (px); not used.
    opts : SubpixelOptions, optional
    search : float, optional
    r_known, r_known_sigma : float, optional
        As in :func:`locate_subpixel`.

    Returns
    -------
    Location
    """
    kw = {"opts": opts} if opts is not None else {}
    kw.update(r_known=r_known, r_known_sigma=r_known_sigma)
    loc = None
    if guess is not None:
        loc = locate_subpixel(frame, background, r_px, guess=guess, search=search, **kw)
    if loc is None or not loc.found:
        # a partial arc only where nothing predicts the ball (a frame after a tracked one
        # that failed is the plausibility checks' to judge, not a new start's)
        loc = locate_subpixel(frame, background, r_px, guess=None, arcs=guess is None, **kw)
    return loc


def _locate_guess(frame, background, r_px, guess, search, opts, noise, partial,
                  rk) -> Location:
    """:func:`locate_subpixel` from a guess; ``partial``: accept a known-radius fit of a
    partial arc (at least ``opts.min_arc_frac`` of the rim) near the guess; ``rk``: (radius
    of the known-radius fits, its relative uncertainty).

    Each pass (coarse ones until the centre settles, then a fine one) is one call of the
    GIL-free kernel :func:`~rollfric.locate.kernels.passes.locate_pass_raw` on the crops of
    the frame and the background (profiles, edges, mirror checks, clean rays, robust circle
    fit, pixel fit); a pinhole's stretched silhouette or a frame that is not uint8 / uint16
    goes through OpenCV first (the subtraction, the squeeze) and then
    :func:`~rollfric.locate.kernels.passes.locate_pass`. Here only what steers the passes and
    judges the result."""
    r_kn, r_kn_sig = rk
    w = search if search is not None else 0.3 * r_px + 2.0
    w = max(w, 1.5)
    w0 = w
    h, wd = frame.shape
    cx, cy = float(guess[0]), float(guess[1])
    if not (-r_px < cx < wd - 1 + r_px and -r_px < cy < h - 1 + r_px):
        return Location.missing("predicted centre outside the frame")
    r = float(r_px)
    # window sizes scale down for small balls
    edge_half = min(opts.edge_half, max(1.5, 0.25 * r_px))
    level_len = min(opts.level_len, max(0.75, 0.2 * r_px))
    # coarse passes (rays ~2.5 px apart) until the centre settles, then one fine pass
    n_coarse = _n_rays(r_px)
    n_fine = max(n_coarse, _n_rays(r_px, opts.ray_spacing, opts.max_rays))
    fine = False
    if opts.radius not in ("auto", "free", "known"):
        raise ValueError(f"radius must be auto, free or known, got {opts.radius!r}")
    big = r_px >= 12
    free = opts.radius == "free" or (opts.radius == "auto" and big)
    floor = 0.004 * (_full_scale(frame.dtype) if opts.full_scale is None else opts.full_scale)
    bg_dtype = background.dtype
    raw = bg_dtype == frame.dtype and bg_dtype in (np.uint8, np.uint16)
    loc = Location.missing("no edge found")
    graded = False
    # (one more pass than the coarse and fine ones: a graded edge's fine pass is redone)
    for p in range(opts.passes + 2):
        n = n_fine if fine else n_coarse
        sampling = _ray_sampling(r, w, opts.ds, edge_half, level_len)
        ds, ns, _, _, s0 = sampling
        params = _kernel_params(opts, r_px, r, w, n, sampling, big, free, noise, floor, r_kn,
                                fine and opts.pixel_fit and not graded)
        run = _run_pass(frame, background, cx, cy, r_px, s0 + ns * ds, opts.pinhole, raw,
                        params)
        if run is None:
            return Location.missing("ball outside the frame")
        out, fr, bg, (x0c, y0c), (lcx, lcy), stretch = run
        status, fcx, fcy, fr_, free_p, n_in, med_res, rms, pcx, pcy, pr, psig, inl, rim, \
            rim_shift, spread = out
        if status:
            return Location.missing(_SELECT_FAIL.get(status, "robust circle fit failed"))
        wide = min(opts.graded_window * spread, 0.1 * r_px)
        if fine and not graded and not rim and spread > opts.graded_spread and \
                wide > edge_half and _edge_cnr(fr, bg, lcx, lcy, r) >= opts.graded_min_cnr:
            # a graded edge (not a mirror rim's, corrected above; a ball big enough for a
            # wider window): the fine pass again, its edge window wide enough to hold the
            # whole transition (the integral is then exact for any profile), no pixel fit
            graded = True
            edge_half = wide
            continue
        # the ball's radius as seen: the fitted one (free on most of the rim only: on a partial
        # arc the radius and the centre are confounded, and the known radius is what makes the
        # arc usable), or (known radius) the known one plus the median offset of the edge
        # points from that circle
        r_seen = fr_ if free_p else r_kn + med_res
        if abs(r_seen - r_px) > opts.max_radius_dev * r_px:
            return Location.missing(f"the ball's edge lies on a circle of {r_seen:.2f} px "
                                    f"radius, not {r_px:.2f} px")
        sigma = rms * math.sqrt(2.0 / n_in)
        if fine and opts.pixel_fit and not graded:
            fcx, fcy, r_seen, sigma = _with_pixel_fit(out, n, r_seen, sigma)
        if stretch is not None:
            fcx, fcy = unsqueeze(fcx, fcy, (lcx, lcy), *stretch)
        shift = math.hypot(fcx - lcx, fcy - lcy)
        cx, cy, r = fcx + x0c, fcy + y0c, float(r_seen)
        last = fine or p >= opts.passes
        if last:
            # (only the pass whose result is returned is judged)
            loc = _judge(cx, cy, r, sigma, n_in, n, free_p, partial, inl, rk, guess, w0, opts)
            break
        w = min(w, max(1.5, 2.0 * shift + 1.0))
        if shift < 0.1 or p >= opts.passes - 1:
            fine = True
    return loc


def _with_pixel_fit(out, n, r_seen, sigma):
    """The centre, radius and sigma of a fine pass (the kernel's answer ``out`` on ``n``
    rays): the pixel fit's where it lies within 0.5 px of the robust fit's (its radius where
    the radius was free), else the robust fit's and the given ``r_seen`` and ``sigma``."""
    _, fcx, fcy, _, free_p, _, _, _, pcx, pcy, pr, psig, inl, rim, rim_shift, _ = out
    if not (math.isfinite(pcx) and math.hypot(pcx - fcx, pcy - fcy) < 0.5):
        return fcx, fcy, r_seen, sigma
    if rim:
        # the pixels' edge model has the same Fresnel rise: the circle moves by the
        # least-squares circle through the rays' shifts
        pcx, pcy, pr = _shift_circle(pcx, pcy, pr, inl, n, rim_shift[inl], free_p)
    return pcx, pcy, pr if free_p else r_seen, psig


def _ray_sampling(r, w, ds_opt, edge_half, level_len):
    """A pass's sampling of its rays for a rim of radius ``r`` searched within ``w`` px: the
    step ``ds`` (twice ``ds_opt`` while the search is wide), the number of samples, the edge
    window's and the level windows' half-width and length in samples and the first sample's
    distance from the centre (the inside levels at two depths within reach)."""
    ds = ds_opt if w <= 3.0 else 2 * ds_opt  # coarse sampling while the search is wide
    ne = max(2, int(round(edge_half / ds)))
    nl = max(2, int(round(level_len / ds)))
    m = (ne + 2 * nl + 3) * ds  # the inside levels at two depths
    s0 = max(0.5, r - w - m)
    ns = int(math.ceil((r + w + m - s0) / ds)) + 1
    return ds, ns, ne, nl, s0


def _kernel_params(opts, r_px, r, w, n, sampling, big, free, noise, floor, r_kn, pixel):
    """The kernel's arguments after the centre for a pass on ``n`` rays with ``sampling``
    (:func:`_ray_sampling`) about a rim of radius ``r`` searched within ``w`` px: the options'
    values, the mirror settings (-1: by the rim's signature), the level's depth inside the
    rim and the Fresnel rise's width there."""
    ds, ns, ne, nl, s0 = sampling
    mirror_rim = -1 if opts.mirror_rim is None else int(bool(opts.mirror_rim))
    local = -1 if opts.local_contrast is None else int(bool(opts.local_contrast))
    nz = -1.0 if noise is None else float(noise)
    inset = (ne + 0.5 * nl + 1) * ds
    # the Fresnel rise's width (cached), where the rim's correction may be on
    kappa = _fresnel_kappa(round(r_px, 1), inset, opts.steel_eta, opts.steel_k) \
        if mirror_rim == 1 or (mirror_rim < 0 and big) else 0.0
    return (s0, ds, ns, n, r, w, ne, nl, opts.level_smooth, opts.min_contrast_rel,
            opts.rim_levels, opts.sharp_excess if opts.sharp_rays and big and w <= 3.0 else 0.0,
            mirror_rim, local, big, nz, opts.mirror_sector, inset, kappa, opts.mirror_relative,
            opts.contrast_bands, opts.min_rays, floor, int(round(opts.mirror_flank / 360.0 * n)),
            free, opts.free_min_frac, r_kn, opts.tukey_c, opts.sigma_floor, pixel)


def _run_pass(frame, background, cx, cy, r_px, reach, pinhole, raw, params):
    """One pass's kernel on the crops of the frame and the background about (cx, cy) that hold
    its rays (``reach`` px long, stretched by a pinhole's silhouette): the GIL-free kernel on
    the crops themselves where they are ``raw`` (uint8 / uint16 of one type), else frame -
    background
    by OpenCV first (and a pinhole's ellipse squeezed back to a circle about the centre).
    Returns the kernel's answer, the crops, their top-left pixel, the centre in the crop and
    the stretch (None without one); None where the crop is outside the frame."""
    stretch = None
    if pinhole is not None:
        ux, uy, kst = silhouette_stretch((cx, cy), r_px, pinhole)
        stretch = ((ux, uy), kst) if kst > 1.0 + 1e-6 else None
    grow = stretch[1] if stretch is not None else 1.0
    half = int(math.ceil(grow * reach)) + 2
    x0, y0 = int(math.floor(cx)) - half, int(math.floor(cy)) - half
    fr, x0c, y0c = _crop(frame, x0, y0, x0 + 2 * half + 2, y0 + 2 * half + 2)
    if fr is None:
        return None
    bg = background[y0c:y0c + fr.shape[0], x0c:x0c + fr.shape[1]]
    lcx, lcy = cx - x0c, cy - y0c
    if stretch is None and raw:
        out = locate_pass_raw(fr, bg, lcx, lcy, *params)
    else:
        rel = cv2.subtract(fr, bg, dtype=cv2.CV_32F)
        bgr = bg.astype(np.float32)
        if stretch is not None:
            # a pinhole's ellipse made a circle again about the current centre: everything
            # below works on the squeezed crop, its centre is taken back at the end
            rel = squeeze(rel, (lcx, lcy), *stretch)
            bgr = squeeze(bgr, (lcx, lcy), *stretch)
        out = locate_pass(rel, bgr, lcx, lcy, *params)
    return out, fr, bg, (x0c, y0c), (lcx, lcy), stretch


def _judge(cx, cy, r, sigma, n_in, n, free_p, partial, inl, rk, guess, w0, opts) -> Location:
    """The Location of a pass's circle: found when enough of the rim fits, the centre is
    certain enough and lies within the searched band."""
    r_kn, r_kn_sig = rk
    if not free_p:
        # a known radius that is off by dr moves the centre of a partial arc by |b| dr,
        # b = (N^T N)^-1 N^T 1 over the arc's unit normals N (0 on the full rim)
        sigma = math.hypot(sigma, _arc_leverage(inl, n) * r_kn_sig * r_kn)
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
    return Location(x=cx, y=cy, r=r, found=ok, sigma=sigma, inlier_frac=frac, reason=why,
                    radius_free=bool(free_p))
