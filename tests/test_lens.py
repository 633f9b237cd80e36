"""Lens distortion: synth's Brown-Conrady model against OpenCV, rollfric's undistortion, the
trough contour through a lens, the [camera] calibration keys, and a lens in the rendering."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from rollfric.geometry.trough import find_cylinder_center
from rollfric.setup.lens import Calibration
from rollfric.setup.model import SetupError, dumps_setup, setup_from_dict, thesis_setup
from synth.distortion import Lens, distort_image, ideal_window

K = [[2400.0, 0.0, 639.5], [0.0, 2390.0, 511.5], [0.0, 0.0, 1.0]]
D = [-0.18, 0.05, 0.001, -0.0005, 0.01]


def _points(n=2000, seed=0):
    return np.random.default_rng(seed).uniform([0, 0], [1280, 1024], (n, 2))


def test_synth_lens_moves_points_where_opencv_projectpoints_puts_them():
    p = _points()
    x = (p[:, 0] - K[0][2]) / K[0][0]
    y = (p[:, 1] - K[1][2]) / K[1][1]
    want, _ = cv2.projectPoints(np.column_stack([x, y, np.ones_like(x)]), np.zeros(3),
                                np.zeros(3), np.asarray(K), np.asarray(D))
    got = Lens(K, D).distort(p)
    np.testing.assert_allclose(got, want.reshape(-1, 2), atol=1e-9)
    # k1 < 0 (barrel) pulls a point towards the principal point by k1 r^2 of its distance
    q = np.array([[639.5, 978.0]])
    moved = Lens(K, [-0.18, 0, 0, 0, 0]).distort(q)[0]
    r = (978.0 - 511.5) / 2390.0
    assert moved[0] == pytest.approx(639.5)
    assert moved[1] - 978.0 == pytest.approx(-0.18 * r * r * (978.0 - 511.5), rel=1e-12)
    assert moved[1] - 978.0 == pytest.approx(-3.2, abs=0.05)  # "about 3 px at the ball"


def test_undistortion_round_trip():
    p = _points()
    cal, lens = Calibration(K, D), Lens(K, D)
    d = lens.distort(p)
    np.testing.assert_allclose(cal.undistort(d), p, atol=1e-9)
    np.testing.assert_allclose(lens.undistort(d), p, atol=1e-9)
    np.testing.assert_allclose(cal.distort(p), d, atol=1e-9)
    assert cal.undistort(np.empty((0, 2))).shape == (0, 2)


def _trough_background(lens: Lens | None, center=(640.3, 380.6), R=635.0):
    """A white backdrop with the dark trough wall (R..R+90 px, +-110 deg about the bottom),
    its edges anti-aliased (a one-pixel linear ramp across them), seen through ``lens``."""
    W, H = 1280, 1024
    win = ideal_window(lens, W, H) if lens is not None else None
    x0, y0 = (win.x0, win.y0) if win else (0, 0)
    w, h = (win.width, win.height) if win else (W, H)
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    u, v = xx + x0 - center[0], yy + y0 - center[1]
    rho = np.hypot(u, v)
    dark = np.clip(rho - R + 0.5, 0, 1) * np.clip(R + 90 - rho + 0.5, 0, 1) \
        * (np.degrees(np.abs(np.arctan2(u, v))) < 110)
    img = 200.0 - 170.0 * dark
    if lens is not None:
        img = distort_image(img, win)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_trough_centre_through_a_lens_is_found_in_the_undistorted_image():
    lens = Lens([[2400.0, 0.0, 639.5], [0.0, 2400.0, 511.5], [0.0, 0.0, 1.0]],
                [-0.18, 0.0, 0.0, 0.0, 0.0])
    bg = _trough_background(lens)
    cal = Calibration(lens.matrix, lens.distortion)
    c = find_cylinder_center(bg, radius_px=635.0, undistort=cal.undistort)
    assert math.hypot(c.center[0] - 640.3, c.center[1] - 380.6) < 0.1
    assert c.radius == pytest.approx(635.0, abs=0.1)
    # the distorted contour's own centre is 4.6 px away
    raw = find_cylinder_center(bg, radius_px=635.0)
    assert abs(raw.center[1] - 380.6) > 3.0
    # without a lens both ways agree with the truth
    flat = _trough_background(None)
    for und in (None, lambda p: p):
        c0 = find_cylinder_center(flat, radius_px=635.0, undistort=und)
        assert math.hypot(c0.center[0] - 640.3, c0.center[1] - 380.6) < 0.1


def test_setup_camera_calibration_keys():
    d = thesis_setup().to_toml_dict()
    d["camera"].update(matrix=[[2400, 0, 639.5], [0, 2400, 511.5], [0, 0, 1]],
                       distortion=[-0.18, 0.0, 0.0, 0.0, 0.0])
    s = setup_from_dict(d)
    assert s.calibration.matrix[0] == (2400.0, 0.0, 639.5)
    assert s.calibration.distortion == (-0.18, 0.0, 0.0, 0.0, 0.0)
    import tomllib

    assert setup_from_dict(tomllib.loads(dumps_setup(s))) == s
    # with the calibration's standard uncertainties (rollfric calibrate writes them)
    d["camera"].update(matrix_u=[[2.0, 0, 1.5], [0, 2.0, 1.5], [0, 0, 0]],
                       distortion_u=[0.004, 0.03, 0.0003, 0.0003, 0.0])
    su = setup_from_dict(d)
    assert su.calibration.distortion_u == (0.004, 0.03, 0.0003, 0.0003, 0.0)
    assert setup_from_dict(tomllib.loads(dumps_setup(su))) == su
    for cam, match in [({"matrix_u": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}, "matrix_u"),
                       ({"distortion_u": [0.1, 0.1]}, "distortion_u"),
                       ({"distortion_u": [-0.1, 0, 0, 0, 0]}, "distortion_u")]:
        with pytest.raises(SetupError, match=match):
            setup_from_dict({**d, "camera": {**d["camera"], **cam}})
    no_lens = {**d, "camera": {k: v for k, v in d["camera"].items()
                               if k not in ("matrix", "distortion", "matrix_u")}}
    with pytest.raises(SetupError, match="without camera.distortion"):
        setup_from_dict(no_lens)
    for cam, match in [({"matrix": d["camera"]["matrix"]}, "go together"),
                       ({"matrix": [[1, 0, 0], [0, 1, 0]], "distortion": [0] * 5}, "matrix"),
                       ({"matrix": d["camera"]["matrix"], "distortion": [0, 1, 2]},
                        "distortion"),
                       ({"matrix": d["camera"]["matrix"], "distortion": ["a"] * 5}, "numbers")]:
        bad = thesis_setup().to_toml_dict()
        bad["camera"].update(cam)
        with pytest.raises(SetupError, match=match):
            setup_from_dict(bad)


def test_calibration_image_size_is_kept_and_checked_against_the_frames():
    # audit 2026-11-24: a calibration made at another resolution or crop was applied to the
    # frames without a check (its centre and distortion then fall on other pixels)
    import tomllib

    from rollfric.track.setup_checks import check_setup_fits

    d = thesis_setup().to_toml_dict()
    d["camera"].update(matrix=K, distortion=D, image_size_px=[1280, 1024])
    s = setup_from_dict(d)
    assert s.calibration.image_size == (1280, 1024)
    assert setup_from_dict(tomllib.loads(dumps_setup(s))) == s
    assert s.calibration.moved("distortion[k1]", 0.01).image_size == (1280, 1024)
    check_setup_fits(s, (10, 1024, 1280))
    with pytest.raises(SetupError, match=r"made on 1280x1024 px images \(camera.image_size_px\)"
                                         r" but the frames are 640x512 px"):
        check_setup_fits(s, (10, 512, 640))
    # without the key nothing is checked (setups written before it)
    d["camera"].pop("image_size_px")
    check_setup_fits(setup_from_dict(d), (10, 512, 640))
    for size in ([1280], [1280.5, 1024], [0, 1024], "1280x1024", [True, 1024]):
        with pytest.raises(SetupError, match="image_size_px must be"):
            setup_from_dict({**d, "camera": {**d["camera"], "image_size_px": size}})
    no_lens = thesis_setup().to_toml_dict()
    no_lens["camera"]["image_size_px"] = [1280, 1024]
    with pytest.raises(SetupError, match="goes with camera.matrix"):
        setup_from_dict(no_lens)
    with pytest.raises(SetupError, match="image_size_px_u"):
        setup_from_dict({**d, "camera": {**d["camera"], "image_size_px": [1280, 1024],
                                         "image_size_px_u": [1, 1]}})


def test_a_recording_through_a_lens_measured_with_and_without_its_calibration(tmp_path):
    """The whole-trough camera (0.4 mm/px) through the target's lens scaled to its frame
    (k1 = -0.18 at fx = 600 px for 320 px, as 2400 px for 1280: 0.4 px at the ball's path,
    4 px at the corners): with the calibration the trough centre and the angles are the
    undistorted truth's; without it they are not."""
    from validation import case as C
    from validation import case_dict as CD
    from validation import e2e
    from validation.metrics import mode_metrics

    d = CD.default_case_dict()
    d["scenario"]["motion"].update(theta0_deg=8.0, seconds=0.3)
    d["scenario"]["camera"] = {"pixel_size_mm": 0.4}
    lens = {"lens_distortion": [-0.18, 0.0, 0.0, 0.0, 0.0],
            "lens_matrix": [[600.0, 0.0, 159.5], [0.0, 600.0, 127.5], [0.0, 0.0, 1.0]]}
    d["render"].update(shadows=False, camera={"width": 320, "height": 256,
                                              "center_px": [160.3, 20.6], **lens})
    d["lab"] = {"lens_calibrated": True}
    rec = tmp_path / "rec.zarr"
    r = e2e.run_case(d, recording=rec, render_workers=1)
    m = r.metrics
    assert m["undistorted"] and r.setup.calibration is not None
    # 0.4 mm pixels: the bore's edge level sits 0.45 px outside the bore in this render, which
    # the circle fit on the contour's +-60 deg of arc turns into up to 0.8 px in y (measured
    # 0.64 px on the clean background); without the calibration it is 3.9 px
    assert abs(m["trough_center_err_x_px"]) < 0.2 and abs(m["trough_center_err_y_px"]) < 1.0
    assert m["theta_rms_rad"] < math.radians(0.03)  # 0.4 mm pixels: 1 px is 0.29 deg
    assert m["center_rms_px"] < 0.15  # located vs the distorted projection of the centre
    # the budget re-evaluates the undistorted centres: its nominal re-fit is the fit
    from rollfric.uncertainty.budget import budget
    from rollfric.uncertainty.measured import measurement_from_track

    b = budget(measurement_from_track(r.track, r.track_info), r.fit)
    assert b.mu == pytest.approx(r.fit.mu, rel=1e-6)
    # the same recording, the lab without a calibration
    d["lab"] = {}
    case = C.case_from_dict(d)
    track, info, _, _, _ = e2e.measure_recording(rec, case)
    un = mode_metrics(case, info, r.truth)
    assert not un["undistorted"]
    xc, yc = info.center_px
    assert abs(yc - 20.6) > 2.0  # the distorted contour's centre
    th = track["theta_rad"].to_numpy() - r.truth["theta_rad"].to_numpy()
    # measured: centre 3.9 px off, theta rms 0.11 deg against 0.024 deg calibrated
    assert np.sqrt(np.nanmean(th ** 2)) > 3 * m["theta_rms_rad"]


class _DrawnThroughLens:
    """A 1280 x 1024 uint16 recording of a dark ball (radius ``r`` px in the undistorted
    image) on a flat bright backdrop, drawn exactly through ``lens``: each recorded pixel's
    value is its area's coverage by the ball, from 12 x 12 sub-pixel samples each undistorted
    by synth's own inverse of the model (not rollfric's) and tested against the round ball in
    the undistorted image."""

    BG, BALL, SS = 40000.0, 8000.0, 12

    def __init__(self, lens: Lens, centres, r: float):
        self.lens, self.centres, self.r = lens, np.asarray(centres, dtype=float), r
        self.shape = (len(self.centres), 1024, 1280)
        self.dtype = np.dtype(np.uint16)
        self.name, self.attrs = "drawn through a lens", {}
        self.background = np.full(self.shape[1:], self.BG, np.uint16)

    def __len__(self):
        return len(self.centres)

    def __getitem__(self, i):
        c = self.centres[i]
        img = np.full(self.shape[1:], self.BG)
        # the recorded pixels the ball can reach: around its distorted centre
        cd = self.lens.distort(c)
        m = int(self.r + 6)
        x0, y0 = int(cd[0]) - m, int(cd[1]) - m
        s = (np.arange(self.SS) + 0.5) / self.SS - 0.5
        yy, xx = np.mgrid[y0:y0 + 2 * m, x0:x0 + 2 * m].astype(float)
        # pixels whose centre is more than 2 px from the outline (the lens stretches a
        # pixel by < 3 % here) are wholly in or out: only the others are sub-sampled
        rho = np.hypot(*(self.lens.undistort(np.stack([xx, yy], axis=-1)) - c).T).T
        cover = (rho < self.r).astype(float)
        edge = np.abs(rho - self.r) < 2.0
        px = (xx[edge][:, None, None] + s[None, None, :]).repeat(self.SS, axis=1)
        py = (yy[edge][:, None, None] + s[None, :, None]).repeat(self.SS, axis=2)
        ideal = self.lens.undistort(np.stack([px, py], axis=-1))
        inside = np.hypot(ideal[..., 0] - c[0], ideal[..., 1] - c[1]) < self.r
        cover[edge] = inside.mean(axis=(1, 2))
        img[y0:y0 + 2 * m, x0:x0 + 2 * m] = self.BG + (self.BALL - self.BG) * cover
        return np.rint(img).astype(np.uint16)


def _target_lens_path(n: int):
    """The lens target (k1 = -0.18 at fx = 2400 px), its exact setup with the calibration and
    n ball centres along the thesis's path over +-24 deg: (lens, setup, theta, truth px,
    L px, r px)."""
    from rollfric.setup.model import Setup

    lens = Lens([[2400.0, 0.0, 639.5], [0.0, 2400.0, 511.5], [0.0, 0.0, 1.0]],
                [-0.18, 0.0, 0.0, 0.0, 0.0])
    pix, centre = 0.1343e-3, (640.0, 380.0)
    setup = Setup(cylinder_radius=85.3e-3, ball_diameter=10e-3, ball_mass=4.07612e-3,
                  fps=1000.0, pixel_size=pix, center_px=centre,
                  calibration=Calibration(lens.matrix, lens.distortion))
    L, r = (85.3e-3 - 5e-3) / pix, 5e-3 / pix
    th = np.radians(np.linspace(-24.0, 24.0, n))
    truth = np.column_stack([centre[0] + L * np.sin(th), centre[1] + L * np.cos(th)])
    return lens, setup, th, truth, L, r


def test_located_ball_undistorted_lands_on_the_true_centre():
    """The target's lens (k1 = -0.18 at fx = 2400 px, 3.2 px at the bottom of the ball's
    path): the ball drawn exactly through it along the thesis's path; the track's
    undistorted centres are the true ones to << 0.01 px (measured 0.004 px). Undistorting
    the located centre alone was off by up to 0.034 px along the path and 0.06 px across
    it (the bent outline is not round: its fitted circle is not centred on the bent
    centre)."""
    from rollfric.track.tracker import track_recording

    lens, setup, th, truth, L, r = _target_lens_path(9)
    src = _DrawnThroughLens(lens, truth, r)
    df, info = track_recording(src, setup, src.background, progress=False)
    assert info.undistorted and df["found"].all()
    err = df[["xu_px", "yu_px"]].to_numpy() - truth
    assert np.abs(err).max() < 0.005, err
    np.testing.assert_allclose(df["theta_rad"].to_numpy(), th, atol=0.005 / L)


class _BentBySynth(_DrawnThroughLens):
    """The same ball drawn the way synth renders through a lens: the ideal (undistorted)
    image at ``factor`` x ``factor`` render pixels per frame pixel, each render pixel its area's
    coverage by the ball (4 x 4 samples, as the rasteriser's multisampling averages its
    pixel), bent by :func:`synth.distortion.distort_tile` with ``samples`` x ``samples`` samples of
    each recorded pixel's footprint."""

    M = 4

    def __init__(self, lens: Lens, centres, r: float, factor: int, samples: int):
        super().__init__(lens, centres, r)
        self.win = ideal_window(lens, 1280, 1024, factor=factor)
        self.samples = samples

    def __getitem__(self, i):
        from synth.distortion import distort_tile

        c, win = self.centres[i], self.win
        q0 = win.to_render(c)
        m = int((self.r + 4) * win.factor)
        bx, by = int(q0[0]) - m, int(q0[1]) - m
        s = (np.arange(self.M) + 0.5) / self.M - 0.5
        qy, qx = np.mgrid[by:by + 2 * m, bx:bx + 2 * m].astype(float)
        p = win.to_frame(np.stack(np.broadcast_arrays(qx[..., None, None] + s,
                                                      qy[..., None, None] + s[:, None]),
                                  axis=-1))
        cover = (np.hypot(p[..., 0] - c[0], p[..., 1] - c[1]) < self.r).mean(axis=(2, 3))
        (x0, y0, w, h), vals = distort_tile((self.BALL - self.BG) * cover,
                                            (bx, by, 2 * m, 2 * m), win, self.lens,
                                            self.shape[1:], self.samples)
        img = np.full(self.shape[1:], self.BG)
        img[y0:y0 + h, x0:x0 + w] += vals
        return np.rint(img).astype(np.uint16)


def test_synth_lens_rendering_is_the_ball_bent_exactly():
    """The target's lens along the thesis's path (13 positions, +-24 deg): the ball as synth
    renders it through the lens (ideal image at 4 x 4 render pixels a frame pixel, 4 x 4
    samples of each recorded pixel's footprint) is located where the exactly bent drawing is
    (24 x 24 samples a pixel, each undistorted exactly) to << 0.01 px (measured 0.0027 px
    max, 0.0014 px rms); one bilinear sample of a frame-resolution ideal image (synth's
    rendering before) was 0.06 px off, as the pixel fit reads its kernel (1 - f, f) that
    follows the lens's fractional displacement f."""
    from rollfric.track.tracker import track_recording

    lens, setup, th, truth, L, r = _target_lens_path(13)
    exact = _DrawnThroughLens(lens, truth, r)
    exact.SS = 24

    def located(src):
        df, info = track_recording(src, setup, src.background, progress=False)
        assert info.undistorted and df["found"].all()
        return df[["xu_px", "yu_px"]].to_numpy()

    ref = located(exact)
    assert np.abs(ref - truth).max() < 0.01
    bent = _BentBySynth(lens, truth, r, factor=4, samples=4)
    # the frames themselves: a recorded pixel differs by at most 5 % of the ball's contrast
    # (measured 4.1 %, on the outline), nowhere else
    diff = np.abs(bent[6].astype(float) - exact[6].astype(float)) / (bent.BG - bent.BALL)
    assert diff.max() < 0.05 and np.mean(diff > 0.005) < 2e-3
    d = located(bent) - ref
    assert np.abs(d).max() < 0.004, d
    old = located(_BentBySynth(lens, truth, r, factor=1, samples=1)) - ref
    assert np.abs(old).max() > 0.03


def test_ideal_camera_renders_the_ideal_image_finer():
    """camera.ideal(): the lens-free camera of the render a lens bends, at FACTOR x FACTOR
    pixels a frame pixel: it projects every point where the window's map puts the ideal
    frame's projection (orthographic; perspective with its pinhole off the axis)."""
    from synth.camera import CameraModel
    from synth.distortion import FACTOR, cached_window

    lens = dict(lens_distortion=(-0.18, 0.0, 0.0, 0.0, 0.0),
                lens_matrix=((2400.0, 0.0, 639.5), (0.0, 2400.0, 511.5), (0.0, 0.0, 1.0)))
    pts = np.random.default_rng(2).uniform([-0.08, -0.09, -0.01], [0.08, 0.0, 0.01], (50, 3))
    for kw in ({}, {"projection": "perspective", "principal_px": (630.2, 500.7)}):
        cam = CameraModel(**kw, **lens)
        ideal = cam.ideal()
        win = cached_window(cam.lens, cam.width, cam.height)
        assert win.factor == FACTOR and ideal.lens is None
        assert ideal.pixel_size == pytest.approx(cam.pixel_size / FACTOR, rel=1e-15)
        plain = CameraModel(**kw)
        np.testing.assert_allclose(ideal.project(pts), win.to_render(plain.project(pts)),
                                   atol=1e-9)
        # frame pixel (u, v) undistorts to the render pixel the window maps it to
        uv = np.array([[3.0, 7.0], [640.0, 980.0], [1279.0, 1023.0]])
        q = win.to_render(cam.lens.undistort(uv))
        np.testing.assert_allclose(q[:, 0], win.map_x[uv[:, 1].astype(int), uv[:, 0].astype(int)],
                                   atol=1e-3)


def test_undistort_ball_inverts_the_bent_outline_circle_fit():
    """Anywhere in the frame, through a lens with k1, k2 and tangential terms: a ball of
    37.2 px whose bent outline (720 points, projectPoints) has its least-squares circle at
    ``loc``: undistort_ball(loc) is the true centre to 1e-4 px (its algebraic fit and this
    geometric one differ by 1e-5 px at the corners); undistorting ``loc`` alone
    is up to 0.07 px off."""
    rng = np.random.default_rng(1)
    c = rng.uniform([40, 40], [1240, 984], (300, 2))
    r = 37.2
    phi = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    cal = Calibration(K, D)
    pts = c[:, None, :] + r * np.stack([np.cos(phi), np.sin(phi)], axis=-1)[None]
    x = (pts[..., 0] - K[0][2]) / K[0][0]
    y = (pts[..., 1] - K[1][2]) / K[1][1]
    bent, _ = cv2.projectPoints(np.stack([x, y, np.ones_like(x)], -1).reshape(-1, 3),
                                np.zeros(3), np.zeros(3), np.asarray(K), np.asarray(D))
    bent = bent.reshape(len(c), -1, 2)
    loc = []
    for b in bent:  # geometric circle fit of each outline (scipy, not rollfric's)
        from scipy.optimize import least_squares

        res = least_squares(lambda p, b=b: np.hypot(*(b - p[:2]).T) - p[2],
                            [*b.mean(0), r], xtol=1e-14, ftol=1e-14)
        loc.append(res.x[:2])
    loc = np.array(loc)
    assert np.abs(cal.undistort(loc) - c).max() > 0.03
    np.testing.assert_allclose(cal.undistort_ball(loc, r), c, atol=1e-4)
    assert cal.undistort_ball(np.empty((0, 2)), r).shape == (0, 2)
