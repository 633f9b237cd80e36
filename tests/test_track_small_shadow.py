"""A small ball (6 px, the 1.58 mm ball on the thesis camera) whose rim runs into a sloped cast
shadow of its own level (a low side lamp's shadow of the trough's wall), drawn with exact area
coverage and an outline 1.7 % larger than the setup's radius (as synth's renders of that ball
measured): the tracker calibrates the apparent radius from the full rims (the locator fits a
known radius below 12 px) and fits the half-shadowed arcs with it; the setup's radius puts them
off towards the lit side."""

import math

import numpy as np

from rollfric.locate import locate_subpixel
from rollfric.setup.model import Setup
from rollfric.track.radius import RadiusCalibration
from rollfric.track.tracker import track_recording
from synth.drawn.frames import disk_coverage

R = 5.9  # the setup's radius (px)
R_SEEN = 1.017 * R  # the drawn outline's
L = 600.0
H, W = 130, 400
XC, YC = 200.0, 100.0 - L
SLOPE = math.tan(math.radians(35.0))  # the shadow's edge rises to the right
X_SHADOW = XC + L * math.sin(math.radians(5.0))  # where it crosses y = 100


def _background():
    """A 120 DN backdrop, 20 DN (the ball's level) below the sloped edge: exact coverage of
    the half-plane (a pixel's area below the line, supersampled 16 x 16)."""
    ss = 16
    off = (np.arange(ss) + 0.5) / ss - 0.5
    yy = np.arange(H, dtype=float)[:, None, None, None] + off[None, None, :, None]
    xx = np.arange(W, dtype=float)[None, :, None, None] + off[None, None, None, :]
    shade = (yy > 100.0 - (xx - X_SHADOW) * SLOPE).mean(axis=(2, 3))
    return 120.0 - 100.0 * shade


BG = _background()


def _frame(cx, cy, seed):
    cov = disk_coverage(H, W, cx, cy, R_SEEN)
    img = BG * (1 - cov) + 20.0 * cov
    rng = np.random.default_rng(seed)
    return np.clip(np.rint(img + rng.normal(0, 1.0, img.shape)), 0, 255).astype(np.uint8)


class _Frames:
    def __init__(self, centres):
        self.centres = centres
        self.shape = (len(centres), H, W)
        self.dtype = np.dtype(np.uint8)
        self.fps = 100.0
        self.background = np.rint(BG).astype(np.uint8)
        self.attrs = {}

    def __len__(self):
        return len(self.centres)

    def __getitem__(self, i):
        return _frame(*self.centres[i], seed=i)


def test_small_ball_partial_arcs_use_the_calibrated_radius():
    setup = Setup(cylinder_radius=(L + R) * 1e-4, ball_diameter=2 * R * 1e-4, ball_mass=1e-3,
                  fps=100.0, pixel_size=1e-4, center_px=(XC, YC + 0.0))
    # from the lit left into the shadow: the last frames have about half the rim in it
    th = np.radians(np.linspace(-2.0, 4.9, 80))
    centres = [(XC + L * math.sin(t), YC + L * math.cos(t)) for t in th]
    src = _Frames(centres)
    df, info = track_recording(src, setup, src.background, progress=False)
    assert info.ball_radius_px_seen is not None
    assert abs(info.ball_radius_px_seen - R_SEEN) < 0.03, info.ball_radius_px_seen
    assert info.warnings == ()
    cx = np.array([c[0] for c in centres])
    cy = np.array([c[1] for c in centres])
    err = np.hypot(df["x_px"] - cx, df["y_px"] - cy)
    part = (df["found"] == 1) & (df["inlier_frac"] < 0.9)
    assert part.sum() >= 8, df["inlier_frac"].to_numpy()
    assert (err[part] < 3.0 * df["sigma_px"][part]).all(), (err[part], df["sigma_px"][part])
    assert err[part].max() < 0.05, err[part].max()
    # the setup's radius: the same arcs land 0.1 px and more towards the lit side
    old = []
    for i in np.flatnonzero(part.to_numpy()):
        loc = locate_subpixel(src[i], src.background, R, guess=(cx[i] - 0.5, cy[i] + 0.5))
        old.append(math.hypot(loc.x - cx[i], loc.y - cy[i]) if loc.found else math.inf)
    assert np.median(old) > 0.08 and np.median(old) > 2 * np.median(err[part]), old


def test_known_radius_full_rims_calibrate_only_a_small_ball():
    class _Loc:
        found, radius_free, inlier_frac, sigma = True, False, 0.97, 0.03

    small, large = RadiusCalibration(R, known=True), RadiusCalibration(R)
    for r in np.linspace(R_SEEN - 0.02, R_SEEN + 0.02, 7):
        loc = _Loc()
        loc.r = float(r)
        small.add(loc)
        large.add(loc)
    assert abs(small.value - R_SEEN) < 1e-9 and large.value is None
    loc = _Loc()
    loc.r, loc.inlier_frac = 7.0, 0.6  # a partial arc's radius is not a calibration
    small.add(loc)
    assert len(small.radii) == 7
