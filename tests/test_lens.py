"""Lens distortion: synth's Brown-Conrady model against OpenCV, rollfric's undistortion, the
trough contour through a lens, the [camera] calibration keys, and a lens in the rendering."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from rollfric.cylinder import find_cylinder_center
from rollfric.lens import Calibration
from rollfric.setup import SetupError, dumps_setup, setup_from_dict, thesis_setup
from synth.lens import Lens, distort_image, ideal_window

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
    for cam, match in [({"matrix": d["camera"]["matrix"]}, "go together"),
                       ({"matrix": [[1, 0, 0], [0, 1, 0]], "distortion": [0] * 5}, "matrix"),
                       ({"matrix": d["camera"]["matrix"], "distortion": [0, 1, 2]},
                        "distortion"),
                       ({"matrix": d["camera"]["matrix"], "distortion": ["a"] * 5}, "numbers")]:
        bad = thesis_setup().to_toml_dict()
        bad["camera"].update(cam)
        with pytest.raises(SetupError, match=match):
            setup_from_dict(bad)


def test_a_recording_through_a_lens_measured_with_and_without_its_calibration(tmp_path):
    """The whole-trough camera (0.4 mm/px) through the target's lens scaled to its frame
    (k1 = -0.18 at fx = 600 px for 320 px, as 2400 px for 1280: 0.4 px at the ball's path,
    4 px at the corners): with the calibration the trough centre and the angles are the
    undistorted truth's; without it they are not."""
    from validation import case as C
    from validation import e2e

    d = C.default_case_dict()
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
    # the same recording, the lab without a calibration
    d["lab"] = {}
    case = C.case_from_dict(d)
    track, info, _, _, _ = e2e.measure_recording(rec, case)
    un = e2e.mode_metrics(case, info, r.truth)
    assert not un["undistorted"]
    xc, yc = info.center_px
    assert abs(yc - 20.6) > 2.0  # the distorted contour's centre
    th = track["theta_rad"].to_numpy() - r.truth["theta_rad"].to_numpy()
    # measured: centre 3.9 px off, theta rms 0.11 deg against 0.024 deg calibrated
    assert np.sqrt(np.nanmean(th ** 2)) > 3 * m["theta_rms_rad"]
