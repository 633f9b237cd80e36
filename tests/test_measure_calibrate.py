"""The ball's apparent radius calibrated from its full-rim frames: drawn disks (exact area
coverage) whose edge radius is 0.3 % larger than the setup's, part of the rim in a shadow of
the ball's own level; the partial arcs fitted with the calibrated radius must give the centre
within their stated uncertainty, the setup's radius would not."""

import math

import numpy as np

from rollfric.locate import locate_subpixel
from rollfric.setup.model import Setup
from rollfric.track.radius import RadiusCalibration
from rollfric.track.tracker import track_recording
from synth.drawn.frames import disk_coverage

R = 37.2  # the setup's radius (px)
R_SEEN = 1.003 * R  # the radius of the drawn outline
H, W = 200, 400


def _shadowed(cx, cy, x_shadow, r=R_SEEN, noise=2.0, seed=0):
    """A dark ball (20 DN) on a 120 DN backdrop that is of the ball's level left of
    ``x_shadow``: (frame, background)."""
    xx = np.arange(W, dtype=float)[None, :].repeat(H, 0)
    bg = np.where(xx < x_shadow, 20.0, 120.0)
    cov = disk_coverage(H, W, cx, cy, r)
    img = bg * (1 - cov) + 20.0 * cov
    rng = np.random.default_rng(seed)
    f = np.clip(np.rint(img + rng.normal(0, noise, img.shape)), 0, 255).astype(np.uint8)
    return f, bg.astype(np.uint8)


def test_calibrated_radius_makes_partial_arcs_consistent():
    rng = np.random.default_rng(7)
    cal = RadiusCalibration(R)
    for k in range(6):  # full-rim frames (no shadow near the ball)
        cx, cy = rng.uniform(190, 210), rng.uniform(90, 110)
        f, bg = _shadowed(cx, cy, 0.0, seed=k)
        loc = locate_subpixel(f, bg, R, guess=(cx + 1.0, cy - 1.0))
        assert loc.found and loc.radius_free, loc.reason
        cal.add(loc)
    assert cal.value is not None and abs(cal.value - R_SEEN) < 0.03, cal.value
    n_worse = 0
    for k in range(6):  # 55-65 % of the rim in the shadow: known-radius fits
        cx, cy = rng.uniform(190, 210), rng.uniform(90, 110)
        x_shadow = cx - R * math.cos(math.pi * rng.uniform(0.55, 0.65))
        f, bg = _shadowed(cx, cy, x_shadow, seed=100 + k)
        guess = (cx + rng.uniform(-1, 1), cy + rng.uniform(-1, 1))
        loc = locate_subpixel(f, bg, R, guess=guess, r_known=cal.value,
                              r_known_sigma=cal.rel_sigma)
        assert loc.found and not loc.radius_free, loc.reason
        err = math.hypot(loc.x - cx, loc.y - cy)
        assert err < 3.0 * loc.sigma, (err, loc.sigma)
        assert loc.sigma < 0.1, loc.sigma
        # with the setup's radius the same arc lands 0.1-0.2 px off (0.3 % of r times the
        # arc's leverage), covered only by the setup radius's larger sigma
        old = locate_subpixel(f, bg, R, guess=guess)
        n_worse += math.hypot(old.x - cx, old.y - cy) > err
    assert n_worse >= 5


class _Frames:
    """A FrameSource of drawn frames: the ball along the track from inside the shadow out."""

    def __init__(self, centres, x_shadow):
        self.centres, self.x_shadow = centres, x_shadow
        self.shape = (len(centres), H, W)
        self.dtype = np.dtype(np.uint8)
        self.fps = 100.0
        self.background = _shadowed(0.0, -100.0, x_shadow)[1]
        self.attrs = {}
        self.reads = []

    def __len__(self):
        return len(self.centres)

    def __getitem__(self, i):
        self.reads.append(i)
        cx, cy = self.centres[i]
        return _shadowed(cx, cy, self.x_shadow, seed=i)[0]


def test_track_calibrates_and_refits_the_early_partial_arcs():
    L = 600.0
    setup = Setup(cylinder_radius=(L + R) * 1e-4, ball_diameter=2 * R * 1e-4,
                  ball_mass=1e-3, fps=100.0, pixel_size=1e-4, center_px=(200.0, 100.0 - L))
    x_shadow = 120.0
    # from 60 % of the rim in the shadow (found by the full search with the setup's radius,
    # tracked on partial arcs before any full rim is seen) to well clear of it
    th = np.linspace(math.asin((x_shadow - 0.31 * R - 200) / L),
                     math.asin((x_shadow + 1.6 * R - 200) / L), 40)
    centres = [(200 + L * math.sin(t), 100 - L + L * math.cos(t)) for t in th]
    src = _Frames(centres, x_shadow)
    df, info = track_recording(src, setup, src.background, progress=False)
    assert abs(info.ball_radius_px_seen - R_SEEN) < 0.03, info
    assert info.n_refitted >= 3, info
    assert info.warnings == ()
    # the second pass read only the refitted frames again
    assert len(src.reads) == len(src) + info.n_refitted
    # every partial arc (below 90 % of the rim) fitted with the calibrated radius
    known = (df["found"] == 1) & (df["inlier_frac"] < 0.9)
    assert known.sum() >= 15 and info.n_refitted >= known.sum()
    cx = np.array([c[0] for c in centres])
    cy = np.array([c[1] for c in centres])
    err = np.hypot(df["x_px"] - cx, df["y_px"] - cy)
    assert (err[known] < 3.0 * df["sigma_px"][known]).all(), (err[known], df["sigma_px"][known])
    assert (df["sigma_px"][known] < 0.1).all()
    # the setup's radius would put them 0.05-0.15 px off (0.11 px times the arcs' leverage)
    assert err[known].max() < 0.03, err[known].max()
    assert df["found"].iloc[:3].all()


def test_track_warns_when_the_setup_radius_is_off():
    rc = RadiusCalibration(R)

    class _Loc:
        found, radius_free, inlier_frac, sigma = True, True, 1.0, 0.02

    for r in np.linspace(1.05 * R - 0.05, 1.05 * R + 0.05, 7):
        loc = _Loc()
        loc.r = float(r)
        rc.add(loc)
    msg = rc.warning()
    assert msg is not None and "+5.0 %" in msg and "pixel_size_mm" in msg
    assert RadiusCalibration(R).warning() is None


def _calibrated(r_setup, r_seen, known=False):
    rc = RadiusCalibration(r_setup, known=known)

    class _Loc:
        found, radius_free, inlier_frac, sigma = True, not known, 1.0, 0.02

    for r in r_seen + np.linspace(-0.01, 0.01, 7):
        loc = _Loc()
        loc.r = float(r)
        rc.add(loc)
    return rc


def test_small_ball_outline_offset_is_no_warning():
    # the thesis's 1.58 mm ball at 0.25 mm/px (3.16 px) as synth renders it: its outline
    # measures 3.26 px (+0.10 px, +3.2 %), the offset every rendered ball's outline has
    assert _calibrated(3.16, 3.26, known=True).warning() is None
    # a diameter 10 % off on the same ball is still named (+0.32 px)
    msg = _calibrated(3.16, 3.48, known=True).warning()
    assert msg is not None and "+10.1 %" in msg and "ball.diameter_mm" in msg
    # a large ball keeps the relative limit: 3.5 % of 20 px is 0.7 px
    assert _calibrated(20.0, 20.7).warning() is not None
    assert _calibrated(20.0, 20.5).warning() is None
