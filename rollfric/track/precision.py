"""The locator's precision on a recording's own frames: the centre's Cramér-Rao bound from
the recording's contrast, noise and edge width, beside the precision the fit reached
(:func:`estimate_precision`)."""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
from scipy import optimize, special, stats

from rollfric.locate.precision import centre_crb

logger = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class LocatorPrecision:
    """The locator's attainable and reached precision on one recording (fit.json's
    ``locator_precision``); NaN where it cannot be estimated.

    Attributes
    ----------
    crb_px : float
        The Cramér-Rao bound on the centre (px, rms of both axes together,
        :func:`rollfric.locate.precision.centre_crb`).
    reached_px : float
        The centre's scatter along the path: the fit's residual rms (rad) times L (px).
    ratio : float
        ``reached_px / (crb_px / sqrt(2))``: the reached scatter over the bound's per-axis
        share (1: the bound is reached along the path).
    contrast_dn, noise_dn, edge_sigma_px : float
        The ball's step at the rim (DN, absolute), the pixel noise's std (DN, rounding
        included) and the Gaussian edge blur's std (px, pixel area excluded).
    frames_used : int
        Frames the estimate was made from.
    """

    crb_px: float = math.nan
    reached_px: float = math.nan
    ratio: float = math.nan
    contrast_dn: float = math.nan
    noise_dn: float = math.nan
    edge_sigma_px: float = math.nan
    frames_used: int = 0

    def json(self) -> dict:
        """The fit.json object: the attributes, None where NaN or infinite."""
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in dataclasses.asdict(self).items()}


def estimate_precision(source, background, track, *, r_px: float,
                       rms_residual_rad: float | None = None,
                       track_radius_px: float | None = None,
                       n_frames: int = 30) -> LocatorPrecision:
    """The locator's Cramér-Rao bound estimated from the recording's own frames, and the
    precision the fit reached.

    From ``n_frames`` found frames spread over the track: the contrast and the edge width
    from an erf fit to the radial profile of frame - background about the located centres,
    the noise from the differences of two frames away from both balls (robust std / sqrt 2,
    a noisy background does not count).

    Parameters
    ----------
    source : FrameSource or sequence of ndarray
        The recording (frame ``i`` as ``source[i]``; a ``read(i, roi)`` is used where there).
    background : ndarray
        The (H, W) background.
    track : pandas.DataFrame
        The track (``x_px``, ``y_px``, ``found``; ``r_px`` where there).
    r_px : float
        The ball's radius (px) where the track has none.
    rms_residual_rad : float, optional
        The fit's residual rms (rad); None: no reached precision.
    track_radius_px : float, optional
        L, the ball centre's path radius (px).
    n_frames : int, optional
        How many frames to use.

    Returns
    -------
    LocatorPrecision
        NaN (and ``frames_used`` 0) where too few frames were found.
    """
    reached = math.nan
    if rms_residual_rad is not None and track_radius_px is not None:
        reached = float(rms_residual_rad) * float(track_radius_px)
    ok = (np.asarray(track["found"]) == 1) & np.isfinite(np.asarray(track["x_px"], float)) \
        & np.isfinite(np.asarray(track["y_px"], float))
    idx = np.flatnonzero(ok)
    if len(idx) < 2:
        return LocatorPrecision(reached_px=reached)
    pick = idx[np.unique(np.linspace(0, len(idx) - 1, min(n_frames, len(idx))).round()
                         .astype(int))]
    xs = np.asarray(track["x_px"], float)
    ys = np.asarray(track["y_px"], float)
    rs = np.asarray(track["r_px"], float) if "r_px" in track else np.full(len(xs), np.nan)
    rs = np.where(np.isfinite(rs) & (rs > 0), rs, float(r_px))
    bg = np.asarray(background, dtype=np.float64)
    h, w = bg.shape
    dists, vals, diffs = [], [], []
    for k, i in enumerate(pick):
        j = pick[(k + 1) % len(pick)]
        cx, cy, r = xs[i], ys[i], rs[i]
        half = int(math.ceil(1.5 * r + 10))
        y0, y1 = max(0, int(cy) - half), min(h, int(cy) + half + 1)
        x0, x1 = max(0, int(cx) - half), min(w, int(cx) + half + 1)
        if y1 <= y0 or x1 <= x0:
            continue
        fi = _region(source, int(i), (y0, y1, x0, x1))
        fj = _region(source, int(j), (y0, y1, x0, x1))
        yy, xx = np.mgrid[y0:y1, x0:x1]
        d = np.hypot(xx - cx, yy - cy)
        band = (d > r - min(0.3 * r, 8.0)) & (d < r + 8.0)
        dists.append(d[band] - r)
        vals.append((fi - bg[y0:y1, x0:x1])[band])
        away = (d > r + 4.0) & (np.hypot(xx - xs[j], yy - ys[j]) > rs[j] + 4.0)
        if np.count_nonzero(away) >= 50:
            diffs.append((fi - fj)[away])
    if not dists or not diffs:
        return LocatorPrecision(reached_px=reached)
    noise = _robust_std(np.concatenate(diffs)) / math.sqrt(2.0)
    contrast, edge = _edge_fit(np.concatenate(dists), np.concatenate(vals), noise)
    crb = centre_crb(float(np.median(rs[pick])), contrast, noise, edge) \
        if math.isfinite(contrast) and noise > 0 else math.nan
    ratio = reached / (crb / math.sqrt(2.0)) if crb > 0 else math.nan
    return LocatorPrecision(crb_px=crb, reached_px=reached, ratio=ratio, contrast_dn=contrast,
                            noise_dn=noise, edge_sigma_px=edge, frames_used=int(len(pick)))


def _region(source, i, roi):
    """Region ``roi`` (y0, y1, x0, x1) of frame ``i`` as float64."""
    y0, y1, x0, x1 = roi
    if hasattr(source, "read"):
        return np.asarray(source.read(i, roi), dtype=np.float64)
    return np.asarray(source[i], dtype=np.float64)[y0:y1, x0:x1]


def _robust_std(v):
    """The std of ``v`` within 4 robust sigmas of its median (the MAD's sigma where the values
    spread, else their plain std): outliers left out, integer steps no trouble."""
    med = np.median(v)
    s0 = 1.4826 * np.median(np.abs(v - med))
    if not s0 > 0:
        s0 = float(np.std(v))
    if not s0 > 0:
        return 0.0
    keep = np.abs(v - med) < 4.0 * s0
    return float(np.std(v[keep]))


def _edge_fit(u, v, noise):
    """(contrast DN, edge sigma px) of an erf step fitted to the values ``v`` at signed
    distances ``u`` from the rim (inside negative): to their medians in 0.1 px bins (robust to
    the ball's texture, and a few hundred points whatever the frames), the pixels' own area
    (variance 1/12 px^2 across any edge direction) taken out of the fitted width."""
    if u.size < 50 or not np.all(np.isfinite(v)):
        return math.nan, math.nan
    edges = np.arange(u.min(), u.max() + 0.1, 0.1)
    med, _, _ = stats.binned_statistic(u, v, "median", bins=edges)
    cnt, _, _ = stats.binned_statistic(u, v, "count", bins=edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    keep = cnt >= 3
    if np.count_nonzero(keep) < 8:
        return math.nan, math.nan
    uu, vv, ww = mid[keep], med[keep], np.sqrt(cnt[keep])
    outside = np.median(vv[uu > 4.0]) if np.any(uu > 4.0) else np.median(vv)
    inside = np.median(vv[uu < -2.0]) if np.any(uu < -2.0) else np.median(vv)

    def resid(p):
        a, c, du, s = p
        return ww * (a + c * 0.5 * special.erfc((uu - du) / (math.sqrt(2.0) * s)) - vv)

    p0 = [outside, inside - outside, 0.0, 0.7]
    try:
        fit = optimize.least_squares(resid, p0, loss="soft_l1",
                                     f_scale=max(2.0 * noise, 0.5) * float(np.median(ww)),
                                     bounds=([-np.inf, -np.inf, -3.0, 0.2],
                                             [np.inf, np.inf, 3.0, 10.0]))
    except (ValueError, np.linalg.LinAlgError):
        return math.nan, math.nan
    if not fit.success:
        return math.nan, math.nan
    _, c, _, s = fit.x
    return float(abs(c)), float(math.sqrt(max(s * s - 1.0 / 12.0, 0.0)))
